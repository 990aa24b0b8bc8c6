"""The beam after the direct paths' kernels (issue 51, item 2): each ray's two-way gain from its direction, once.

The kernels of the direct paths (:func:`kernels.fan_echoes`, :func:`kernels.arc_echoes`) weigh rays with unit
gain; :func:`weigh_by_beam` multiplies the fan's separable beam in after them, whatever the beam
(:mod:`sonar_embree.instrument.beams`: the membrane, a Gaussian).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels.args import Fan

_NONE = np.zeros(0)


def weigh_by_beam(pattern, tilt_rad: float, fan: Fan, rx_shift: np.ndarray, weight: np.ndarray,
                  layout: np.ndarray = kernels.NO_LAYOUT) -> None:
    """Multiply the weights of a block's direct rays by their two-way gain Γ²(u)·Γ_rx²(u), in place (issue 51: the
    beam after the path kernels; docs/physics.md §2, §16).

    Γ = along(s)·across(v) is the separable beam ``pattern`` (:attr:`~sonar_embree.propagation.fan.FanPlan.pattern`)
    at each ray's direction cosines s along track and v = cos ψ·sin(β − δ) across (δ = ``tilt_rad``,
    :func:`kernels.beam_cosines`), and Γ_rx the same with s shifted
    by the ping's ``rx_shift`` δ = 2·v_fwd/c (pings,). ``fan`` (:data:`~sonar_embree.kernels.args.Fan`) gives the
    rows, azimuth-major over their elevation cells (the along-track factors then go once per line and ping; the
    across-track factor in one kernel pass, :func:`kernels.weigh_fan`, for a beam that names its form there,
    ``kernel_form``, else from ``pattern.across``, :func:`kernels.weigh_lines`); with ``layout`` (n, 5) each ray
    has its own s, cos β, sin β (:func:`kernels.weigh_rays`, or the beam's NumPy factors)."""
    if layout.shape[0] == 0:
        a, a_rx = pattern.along(fan.s), pattern.along(fan.s[None, :] - rx_shift[:, None])
        line = (a * a)[None, :] * (a_rx * a_rx)
        if pattern.kernel_form is not None:                    # one pass, the factor where there is an echo
            kernels.weigh_fan(fan, float(tilt_rad), *pattern.kernel_form, line, weight)
            return
        v = np.empty(weight.shape[0])
        kernels.beam_cosines(fan, float(tilt_rad), layout, v)
        e2 = pattern.across(v) ** 2
        kernels.weigh_lines(fan.el_start, fan.s.shape[0], line, e2 * e2, weight)
        return
    if pattern.kernel_form is not None:
        kernels.weigh_rays(layout, fan.el_start, rx_shift, float(tilt_rad), *pattern.kernel_form, weight)
        return
    v = np.empty(weight.shape[0])
    kernels.beam_cosines(fan, float(tilt_rad), layout, v)
    e = pattern.across(v)
    e2 = e * e
    s = layout[:, 0]
    shift = np.repeat(rx_shift, np.diff(fan.el_start[::2]))       # rows 2·ping + side: the ping of each ray
    a, a_rx = pattern.along(s), pattern.along(s - shift)
    weight *= (a * a) * (a_rx * a_rx) * (e2 * e2)


def weigh_pairs(pattern, tilt_rad: float, ray_start: np.ndarray, body: np.ndarray, leg: np.ndarray, rot: np.ndarray,
                rx_shift: np.ndarray, w_pair: np.ndarray, w_mono: np.ndarray = _NONE) -> None:
    """Multiply the gains of the surface's paths in after their kernels, in place (issue 51, item 2; docs/physics.md
    §2, §13, §16): ``w_pair`` (n,) by Γ²(u)·Γ_rx²(d) + Γ²(d)·Γ_rx²(u) (a one-bounce echo leaves along one direction
    and returns along the other, and the other way round) and ``w_mono`` (n,) (or nothing) by Γ²(u)·Γ_rx²(u).

    u = ``body`` (n, 3) is each echo's launch direction in the body frame (forward, starboard, down), ``leg`` (n, 3)
    the other leg's world direction at the sonar (turned by the row's ``rot`` (pings, 3, 3), body → world); rows
    2·ping + side of ``ray_start``. Γ = along(s)·across(v)·gate of the separable beam ``pattern``, v = e₂·cos δ −
    side·e₁·sin δ (δ = ``tilt_rad``), gate 0 behind the baffle, Γ_rx with s shifted by the ping's ``rx_shift`` δ:
    :func:`kernels.weigh_pairs` for a beam whose form the kernels know (``kernel_form``), else the beam's own NumPy
    factors (any separable beam)."""
    if pattern.kernel_form is not None:
        kernels.weigh_pairs(ray_start, np.ascontiguousarray(body), np.ascontiguousarray(leg), rot, rx_shift,
                            float(tilt_rad), *pattern.kernel_form, w_pair, w_mono)
        return
    row = np.repeat(np.arange(ray_start.shape[0] - 1), np.diff(ray_start))
    if w_mono.shape[0] > 0:                                 # only where lit: the unlit may hold no direction
        i = np.flatnonzero(w_mono > 0)
        g1, g1r = _factors(pattern, tilt_rad, body[i], row[i], rx_shift)
        w_mono[i] *= g1 * g1 * (g1r * g1r)
    i = np.flatnonzero(w_pair > 0)
    g1, g1r = _factors(pattern, tilt_rad, body[i], row[i], rx_shift)
    g2, g2r = _factors(pattern, tilt_rad, np.einsum("nji,nj->ni", rot[row[i] // 2], leg[i]), row[i], rx_shift)
    w_pair[i] *= g1 * g1 * g2r * g2r + g1r * g1r * g2 * g2


def _factors(pattern, tilt_rad, e, row, rx_shift):
    """(Γ, Γ_rx) of body directions e (n, 3) of rays in rows 2·ping + side (n,) (:func:`weigh_pairs`)."""
    side, shift = np.where(row % 2 == 1, 1.0, -1.0), rx_shift[row // 2]
    c, s = np.cos(tilt_rad), np.sin(tilt_rad)
    across = pattern.across(e[:, 2] * c - side * e[:, 1] * s) * (side * e[:, 1] * c + e[:, 2] * s > 0.0)
    return pattern.along(e[:, 0]) * across, pattern.along(e[:, 0] - shift) * across


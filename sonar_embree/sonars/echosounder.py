"""A down-looking single-beam echo sounder: one channel, a baffled piston (docs/physics.md §11).

The transducer is a beam of :mod:`sonar_embree.instrument.beams` (``beam``): by default the baffled
circular piston of radius a, b(θ) = 2·J1(ka·sin θ)/(ka·sin θ) (Kinsler et al., *Fundamentals of
Acoustics*, 4th ed., §8.8), θ from the body's down axis, ka·sin(θ3/2) = 1.6163 for the −3 dB full
width θ3; or the square piston. The beam is modelled out to :data:`SPAN_NULLS` times its first
null and sampled in rings of θ and azimuth φ (dΩ = sin θ dθ dφ), the rings :data:`RINGS` per
span near the axis and narrower further out, so that a ring's footprint spans at most
:data:`FOOTPRINT_BINS` range bins at the far range (:func:`ring_edges`); each ray's echo is
w = b²(u)·b²(u_rx)·σ(θi)·e^(−2α'R)·dΩ/(R²·cos θi) (eq. 1), b from the ray's body-frame direction,
spread over the travel-time extent of its ring's footprint. In a sound-speed profile the rings
are curved rays; under a sea surface nothing changes (the surface's paths reach the sonar from
above, behind the baffle). Over a flat floor at altitude h the first echo arrives at 2h/c.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..propagation import multipath, paths, refraction
from ..propagation.buffers import Buffers
from ..propagation.aim import AimPlan, lattice_rays
from ..config import FanSettings, Transducer
from ..instrument.receiver import Receiver
from ..propagation.echoes import Echoes
from ..laws import apply_laws
from ..signal.processing import absorption_np_per_m
from ..validation import check_number
from ..instrument.beams import BEAMS, Beam, beam_for
from .base import FrontEnd

#: The fan reaches this many times the first null's angle (the first side lobes; b⁴ < −70 dB beyond).
SPAN_NULLS = 4.0
#: Rings of θ over the span (near the axis) and rays per ring at quality 1.
RINGS, RAYS_PER_RING = 400, 32
#: A far ring's footprint spans at most this many range bins at quality 1 (:func:`ring_edges`): with uniform
#: rings (400 over the span) a 30° beam's far side lobes were 0.05 dB off the closed form of absorption at
#: 0.2 dB/m (tests/sonars/test_sonar_types.py); 4 bins cost 4.8 → 7.7 ms per ping of the default echo sounder.
FOOTPRINT_BINS = 4.0
#: Far-range rings (:func:`ring_edges`) add at most this factor to the ring count.
MAX_RINGS_FACTOR = 16.0


@dataclass(frozen=True)
class EchoSounder(Transducer):
    """A down-looking single-beam echo sounder.

    Parameters
    ----------
    frequency_hz : float
        Carrier frequency, Hz.
    beamwidth_deg : float
        Full one-way −3 dB beamwidth of the beam, degrees, in (0, 60].
    max_range_m : float
        Slant range of the last sample, m.
    sample_rate_hz : float or None
        Record sample rate, Hz (``None``: from the pulse, as for :class:`~sonar_embree.Sonar`).
    source_level_db, self_noise_db_per_hz, receiver
        As for :class:`~sonar_embree.Sonar`.
    beam : str
        The transducer, a key of :data:`~sonar_embree.instrument.beams.BEAMS`: ``"piston"`` (circular, default) or
        ``"square"``; ``beamwidth_deg`` is its one-way −3 dB full width (in a principal plane for the square).
    """

    frequency_hz: float = 200e3
    beamwidth_deg: float = 10.0
    max_range_m: float = 50.0
    sample_rate_hz: float | None = None
    source_level_db: float | None = None
    self_noise_db_per_hz: float | None = None
    receiver: Receiver | None = None
    beam: str = "piston"

    channels = ("down",)
    tilted = False   # it looks down: the set-up checks judge no tilt

    def __post_init__(self):
        check_number("EchoSounder", "frequency_hz", self.frequency_hz, positive=True)
        check_number("EchoSounder", "beamwidth_deg", self.beamwidth_deg, positive=True, hi=60.0)
        if self.beam not in BEAMS:
            raise ConfigError(f"EchoSounder.beam must be one of {', '.join(repr(k) for k in BEAMS)}, got {self.beam!r}")
        check_number("EchoSounder", "max_range_m", self.max_range_m, positive=True)
        if self.sample_rate_hz is not None:
            check_number("EchoSounder", "sample_rate_hz", self.sample_rate_hz, positive=True)
        self._check_levels("EchoSounder")

    def transducer_in(self, sound_speed_m_s: float) -> Beam:
        """The beam (:data:`~sonar_embree.instrument.beams.BEAMS`) with this beamwidth in water of sound speed
        ``sound_speed_m_s`` (m/s); its speckle cell (the piston's radius a, its near-field resolution) is the
        default lattice spacing."""
        return beam_for(self.beam, self.beamwidth_deg, sound_speed_m_s / self.frequency_hz)


def ring_edges(span_rad: float, d_theta: float, k: float) -> np.ndarray:
    """Edges of the rings of θ over [0, span], (n + 1,) rad: widths dθ(θ) = d_theta/(1 + k·tan θ), uniform in
    θ − k·ln cos θ (at most :data:`MAX_RINGS_FACTOR` times span/d_theta rings).

    A ring's footprint on a floor spans R·tan θ·dθ of slant range, so with k = R_max·d_theta/Δ it stays within
    Δ at the far range where tan θ is large, while the main lobe keeps d_theta (:class:`EchoSounderFrontEnd`
    takes Δ = the range bin / quality, the side-scan fan's rays per bin).
    """
    k = min(k, (MAX_RINGS_FACTOR - 1.0) * span_rad / -math.log(math.cos(span_rad)))
    grid = np.linspace(0.0, span_rad, 20001)
    xi = grid - k * np.log(np.cos(grid))
    n = int(math.ceil(xi[-1] / d_theta))
    return np.interp(np.linspace(0.0, xi[-1], n + 1), xi, grid)


class EchoSounderFrontEnd(FrontEnd):
    """Poses → echoes for an :class:`EchoSounder`: a cone of rays around the body's down axis."""

    channels = EchoSounder.channels
    supports_labels = False

    def __init__(self, sonar: EchoSounder, fan: FanSettings):
        fan = fan.resolved()
        self.beam = sonar.transducer
        span = min(SPAN_NULLS * self.beam.first_null_rad, math.radians(89.0))
        d_theta = span / (RINGS * fan.quality)
        far = FOOTPRINT_BINS * sonar.range_bin_m / fan.quality              # the far rings' footprint, m
        edges = ring_edges(span, d_theta, sonar.max_range_m * d_theta / far)
        theta, widths = 0.5 * (edges[1:] + edges[:-1]), np.diff(edges)
        n_phi = np.full(theta.size, max(int(math.ceil(RAYS_PER_RING * fan.quality)), 8))
        self.theta = np.repeat(theta, n_phi)
        phi = np.concatenate([(np.arange(k) + 0.5) * 2 * np.pi / k for k in n_phi])
        self.ray_d_theta = np.repeat(widths, n_phi)
        self.d_omega = np.sin(self.theta) * self.ray_d_theta * np.repeat(2 * np.pi / n_phi, n_phi)
        st, ct = np.sin(self.theta), np.cos(self.theta)
        self.body = np.stack([st * np.cos(phi), st * np.sin(phi), ct], axis=1)          # body z is down
        self.body_dtheta = np.stack([ct * np.cos(phi), ct * np.sin(phi), -st], axis=1)  # ∂u/∂θ
        self.d_theta = d_theta
        self.rings, self.ring_widths, self.n_phi = theta, widths, int(n_phi[0])
        self.b = self.beam.one_way(*self.body.T)
        self.gain4 = self.b ** 4
        self.sonar = sonar
        self.two_way_np_per_m = absorption_np_per_m(sonar.alpha_db_per_m)
        self.span_rad, self.quality, self.aims = span, fan.quality, fan.aim_objects
        self.direct_path = paths.path_models(sonar.environment)[0]     # straight or curved rings, picked once

    def aim_plan(self, compiled) -> AimPlan | None:
        """The objects of ``compiled`` to aim rays at (docs/physics.md §7b), in the side-scan's coordinates about
        the forward axis: s = u_fwd, β the depression in each side's half (β = 90° straight down), over the cone's
        span; None for none. Made once per run (:func:`~sonar_embree.propagation.prepared.prepare`)."""
        if not self.aims:
            return None
        sp = self.span_rad
        span = (-math.sin(sp), math.sin(sp), 0.5 * math.pi - sp, 0.5 * math.pi, self.d_theta, self.d_theta)
        dr = self.sonar.sound_speed_m_s / (2.0 * self.sonar.sample_rate_hz) / self.quality
        return AimPlan.of(compiled, span, (True, True), self.quality, dr)

    def _gain_of(self, body: np.ndarray, rx_shift: np.ndarray | None) -> np.ndarray:
        """b²(u)·b²(u_rx) of body-frame unit directions (n, 3), the receive beam's along-track cosine shifted by
        ``rx_shift`` (n,) per direction (or None: b⁴); docs/physics.md §16."""
        b = self.beam.one_way(body[:, 0], body[:, 1], body[:, 2])
        if rx_shift is None or not np.any(rx_shift):
            return b ** 4
        return b * b * self.beam.one_way(body[:, 0] - rx_shift, body[:, 1], body[:, 2]) ** 2

    def _gain(self, rx_shift, n_p: int) -> np.ndarray:
        """b⁴·dΩ of every ray of the block, (n_p·n,); moving during the ping (``rx_shift`` (n_p,) δ = 2·v_fwd/c, not
        all 0) the receive factor is b² at (u_fwd − δ, u_side) (docs/physics.md §16)."""
        if rx_shift is None or not np.any(rx_shift):
            return np.tile(self.gain4 * self.d_omega, n_p)
        fwd = self.body[None, :, 0] - np.asarray(rx_shift, dtype=np.float64)[:, None]
        b_rx = self.beam.one_way(fwd, self.body[None, :, 1], self.body[None, :, 2])      # (n_p, n): the ring's b once
        return ((self.b * self.b)[None, :] * b_rx ** 2 * self.d_omega[None, :]).reshape(-1)

    def cast(self, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift=None):
        """Echoes of a block of pings (one channel each); arguments as for the side-scan front end, ``rx_shift``
        the receiver's motion during the ping (see :meth:`_gain`). With objects to aim at, their aimed rays'
        echoes join the rings' (whose hits on those objects then count nothing; docs/physics.md §7b). In a
        sound-speed profile the rings are curved rays (:meth:`_curved`). A sea surface adds nothing: every path
        by it leaves or reaches the sonar upwards, where the baffled piston has no gain (:meth:`check_tilt`)."""
        self.check_tilt(rot)
        return self.direct_path.rings(self, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift)

    def _straight(self, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift):
        """The rings as straight rays (:meth:`cast` without a sound-speed profile), with the rays aimed at objects."""
        n_p, n, caster = rot.shape[0], self.body.shape[0], run.caster
        u = np.einsum("pij,nj->pni", rot, self.body).reshape(-1, 3)
        f = np.einsum("pij,nj->pni", rot, self.body_dtheta).reshape(-1, 3)
        hits = caster.cast(np.repeat(pos_local, n, axis=0), u, max_range_m)
        w, ext, pts = self._weights(run, hits, u, f, np.repeat(pos_local, n, axis=0),
                                    self._gain(rx_shift, n_p), np.tile(self.ray_d_theta, n_p), want_points)
        ids = np.where((w > 0), hits.object_id, -1).astype(np.int32) if want_ids else np.zeros(0, np.int32)
        nadir = caster.cast(pos_local, np.broadcast_to([0.0, 0.0, -1.0], (n_p, 3)), max_range_m)
        per_m = 2.0 / self.sonar.sound_speed_m_s
        r = np.where(w > 0, hits.range_m, np.inf)
        rings = Echoes(1, np.arange(n_p + 1, dtype=np.int64) * n, r * per_m, ext * per_m, w, pts, ids)
        aim = run.aim
        if aim is None:
            return rings, _Block(np.where(nadir.tri >= 0, nadir.range_m, np.nan), np.full(n_p, n + 1))
        aimed, mask, n_aimed = self._aimed(run, aim, rot, pos_local, max_range_m, rx_shift, want_points, want_ids)
        if not mask.any():                                                 # nothing in reach to aim at
            return rings, _Block(np.where(nadir.tri >= 0, nadir.range_m, np.nan), np.full(n_p, n + 1))
        side = (self.body[:, 1] > 0).astype(np.int64)                      # the lattices' half each ring ray is in
        k = aim.cand_of_object[np.maximum(hits.object_id, 0)]
        drop = (hits.object_id >= 0) & (k >= 0) & mask[2 * np.repeat(np.arange(n_p), n) + np.tile(side, n_p),
                                                       np.maximum(k, 0)]
        w[drop] = 0.0
        info = _Block(np.where(nadir.tri >= 0, nadir.range_m, np.nan), np.full(n_p, n + 1) + n_aimed)
        return multipath.PathEchoes([rings, aimed], want_points, None, (0, 0)), info

    def check_tilt(self, rot: np.ndarray) -> None:
        """Under a sea surface, refuse a block in which the modelled cone reaches above the horizontal (the surface's
        paths would then have gain)."""
        if self.sonar.environment.surface is None:
            return
        tilt = np.arccos(np.clip(-np.asarray(rot)[:, 2, 2], -1.0, 1.0))   # the body's down axis from world down
        if np.any(tilt + self.span_rad >= 0.5 * math.pi):
            raise ConfigError(f"EchoSounder under a sea surface: the vehicle is tilted {math.degrees(tilt.max()):.1f} "
                              f"degrees, so the beam's {math.degrees(self.span_rad):.1f} degree cone reaches above "
                              "the horizontal, where the surface's paths are not modelled for it")

    def _curved(self, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift):
        """The rings as curved rays in the profile (docs/physics.md §11, §12): each ring azimuth φ is the starboard
        half-plane of a virtual side-scan ping turned by φ − 90° about the body's down axis, so its rays' cells
        (s = 0, β = 90° − θ, dβ = dθ, ds = sin θ·dφ: dΩ = sin θ dθ dφ) and footprints (∂u/∂β = −∂u/∂θ) are the
        rings'; the curved-ray kernels weigh them with unit gain, and b²(θ)·b²(θ_rx) is applied after them. The
        rings alone: no rays are aimed at objects in a profile."""
        n_p, n_t, n_phi = rot.shape[0], self.rings.size, self.n_phi
        rot_v = np.einsum("pij,kjl->pkil", np.asarray(rot, dtype=np.float64), self._turns()).reshape(-1, 3, 3)
        pos_v = np.ascontiguousarray(np.repeat(pos_local, n_phi, axis=0), dtype=np.float64)
        n_v = n_p * n_phi
        ray_start = (np.arange(2 * n_v + 1, dtype=np.int64) // 2) * n_t
        st, ct = np.sin(self.rings), np.cos(self.rings)
        ring = np.stack([np.zeros(n_t), st, ct, self.ring_widths, st * 2.0 * np.pi / n_phi], axis=1)
        layout = np.ascontiguousarray(np.tile(ring, (n_v, 1)))
        s, env = self.sonar, self.sonar.environment
        reach = max_range_m * (1.0 + 1e-3) + 0.05
        m = refraction.Marching.of(run.caster, env, refraction.SAGITTA_FRACTION * s.range_bin_m,
                                   reach / s.sound_speed_m_s)
        t_s, ext, w, pts, prim, _ = refraction.layout_echoes(
            run, layout, ray_start, _Cone.of(s), rot_v, pos_v, np.zeros(n_v), m, self.two_way_np_per_m, s,
            want_points, clock, Buffers())
        body = np.einsum("kij,nj->kni", self._turns(), np.stack([np.zeros(n_t), st, ct], axis=1)).reshape(-1, 3)
        shift = np.zeros(n_p) if rx_shift is None else np.asarray(rx_shift, dtype=np.float64)
        w *= self._gain_of(np.tile(body, (n_p, 1)), np.repeat(shift, n_phi * n_t))
        ids = np.where(w > 0, run.compiled.face_object[np.maximum(prim, 0)], -1).astype(np.int32) if want_ids \
            else np.zeros(0, np.int32)
        nadir = run.caster.cast(pos_local, np.broadcast_to([0.0, 0.0, -1.0], (n_p, 3)), max_range_m)
        e = Echoes(1, np.ascontiguousarray(ray_start[::2 * n_phi]), t_s, ext, w, pts, ids)
        return e, _Block(np.where(nadir.tri >= 0, nadir.range_m, np.nan), np.full(n_p, n_phi * n_t + 1))

    def _turns(self) -> np.ndarray:
        """(n_phi, 3, 3) body-frame turns about the down axis by φ_k − 90°: the virtual pings of :meth:`_curved`."""
        a = (np.arange(self.n_phi) + 0.5) * 2.0 * np.pi / self.n_phi - 0.5 * np.pi
        out = np.zeros((self.n_phi, 3, 3))
        out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1], out[:, 2, 2] = np.cos(a), -np.sin(a), np.sin(a), \
            np.cos(a), 1.0
        return out

    def _weights(self, run, hits, u, f, origin, gain_domega, d_beta, want_points):
        """(w, extent (m), points) of hits along world directions u (n, 3) with ∂u/∂θ ``f`` from ``origin``:
        w = gain·dΩ·e^(−2α'R)/max(R, λ)² × σ/cos θi (eq. 1), extent = min(R·|n̂·f|/cos θi, cap)·dθ."""
        ok = hits.echo
        r = np.where(ok, hits.range_m, np.inf)
        cos_i = np.where(ok, hits.cos_inc, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(ok, gain_domega * np.exp(-self.two_way_np_per_m * r)
                         / np.maximum(r, self.sonar.wavelength_m) ** 2, 0.0)
            slope = np.abs(np.einsum("ij,ij->i", hits.normal, f)) * r / cos_i
        c = run.compiled
        pts = (origin + np.where(ok, r, 0.0)[:, None] * u) if want_points or c.needs_points else np.zeros((0, 3))
        apply_laws(run.law_table, c, hits.tri.astype(np.int32), cos_i, w, pts)
        ext = np.where(ok, np.minimum(slope, 10.0 * self.sonar.max_range_m) * d_beta, 0.0)
        return w, ext, np.ascontiguousarray(pts)

    def _aimed(self, run, aim, rot, pos_local, max_range_m, rx_shift, want_points, want_ids):
        """(Echoes of the rays aimed at objects, one row per ping; which candidates each (ping, side) aims at;
        aimed rays per ping): only hits on the aimed object count, and only inside the rings' cone."""
        n_p = rot.shape[0]
        shift = np.zeros(n_p) if rx_shift is None else np.asarray(rx_shift, dtype=np.float64)
        table, start, counts, dirs, _, layout = lattice_rays(aim, rot, pos_local, shift, max_range_m)
        row = np.repeat(np.arange(2 * n_p), counts.sum(axis=1))
        ping, side = row // 2, np.where(row % 2, 1.0, -1.0)
        obj = np.repeat(np.tile(aim.objects, 2 * n_p), counts.ravel())
        u = dirs.astype(np.float64)
        u /= np.linalg.norm(u, axis=1)[:, None]
        body = np.einsum("nji,nj->ni", rot[ping], u)                       # Rᵀ·u
        f = np.einsum("nij,nj->ni", rot[ping], np.stack([np.zeros(len(u)), -side * body[:, 2], side * body[:, 1]], 1))
        hb, hs = layout[:, 3], layout[:, 4]
        inside = body[:, 2] >= math.cos(self.span_rad)
        gain = np.where(inside, self._gain_of(body, shift[ping]), 0.0) * hs * hb
        hits = run.caster.cast(pos_local[ping], u, max_range_m)
        w, ext, pts = self._weights(run, hits, u, f, pos_local[ping], gain, hb, want_points)
        w[hits.object_id != obj] = 0.0
        per_m = 2.0 / self.sonar.sound_speed_m_s
        r = np.where(w > 0, hits.range_m, np.inf)
        ids = np.where(w > 0, obj, -1).astype(np.int32) if want_ids else np.zeros(0, np.int32)
        e = Echoes(1, np.ascontiguousarray(start[::2 * aim.objects.size]), r * per_m, ext * per_m, w, pts, ids)
        return e, counts > 0, counts.reshape(n_p, -1).sum(axis=1)


@dataclass(frozen=True, eq=False)
class _Cone:
    """What the curved-ray kernels read of a fan for the rings (:meth:`EchoSounderFrontEnd._curved`): the baffle
    tilted 90° (its rings look down: everything below the horizontal; the beam's gain is applied after), the
    near-field bound λ, the slope cap 10·R_max."""

    s: np.ndarray
    ds: float
    tilt_rad: float
    min_range_m: float
    slope_cap_m_rad: float
    footprint: bool = True

    @classmethod
    def of(cls, sonar: EchoSounder) -> "_Cone":
        return cls(np.zeros(1), 0.0, 0.5 * math.pi, sonar.wavelength_m, 10.0 * sonar.max_range_m)


@dataclass(frozen=True, eq=False)
class _Block:
    altitude_m: np.ndarray
    n_rays: np.ndarray

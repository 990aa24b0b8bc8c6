"""MSIS speed against error (docs/benchmarks.md, issue 18): pings per second at several ray budgets, with the
error of the flat-floor record against a quadrature of eq. (1) with the MSIS beam.

    python scripts/bench_msis.py

A still head 10 m over a flat Lambert floor (−20 dB), 36 pings of a 10° step, 25 m range, 50 µs CW,
speckle-free, at quality 0.5, 1 and 2; the error (max and RMS, dB) over the samples within 30 dB of the peak and
away from the onset. The quadrature integrates Γ⁴·μ·cos²θi·e^(−2α'R)/R⁴ over the floor on a polar grid
(tests/test_msis.py holds the same reference). Prints one JSON line. No test reads it.
"""
import json
import math
import os
import sys
import time

import numpy as np
from scipy.optimize import brentq

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402

H, MU_DB, TAU, FS = 10.0, -20.0, 50e-6, 100e3


def _membrane(width_deg, lam):
    x0 = brentq(lambda x: math.sin(x) / x - 2 ** -0.5, 1e-9, math.pi)
    return x0 * lam / (math.pi * math.sin(math.radians(width_deg) / 2))


def quadrature(t, sonar):
    acq = se.Acquisition.of(sonar)
    lam, k, d = acq.wavelength_m, acq.wavenumber_rad_m, math.radians(sonar.tilt_deg)
    lx, ly = _membrane(sonar.horizontal_beamwidth_deg, lam), _membrane(sonar.vertical_beamwidth_deg, lam)
    rho = np.concatenate([np.linspace(0, 2, 801)[:-1], np.linspace(2, 30, 5601)])
    phi = np.unique(np.concatenate([np.linspace(-0.1, 0.1, 801), np.linspace(-np.pi, np.pi, 1441)]))
    p, f = rho[:, None], phi[None, :]
    r = np.sqrt(p ** 2 + H ** 2)
    ux, uy, uz = p * np.cos(f) / r, p * np.sin(f) / r, H / r
    g = np.sinc(k * lx / 2 * uy / np.pi) * np.sinc(k * ly / 2 * (-ux * math.sin(d) + uz * math.cos(d)) / np.pi)
    g = np.where(ux * math.cos(d) + uz * math.sin(d) > 0, g, 0.0)
    alpha = se.Acquisition.of(sonar).alpha_db_per_m * math.log(10) / 10
    dens = g ** 4 * 10 ** (MU_DB / 10) * (H / r) ** 2 * np.exp(-2 * alpha * r) / r ** 4
    per_rho = np.trapezoid(dens, phi, axis=1) * rho
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (per_rho[1:] + per_rho[:-1]) * np.diff(rho))])
    two_r, c = 2 * np.sqrt(rho ** 2 + H ** 2), se.Acquisition.of(sonar).sound_speed_m_s
    return (np.interp(c * t, two_r, cum, left=0, right=cum[-1])
            - np.interp(c * (t - TAU), two_r, cum, left=0, right=cum[-1]))


def main() -> int:
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=MU_DB),
                           label="seafloor")
    traj = se.Trajectory(np.tile([[0.0, 0.0, H]], (36, 1)), times_s=np.arange(36.0))
    sonar = se.MSIS(step_deg=10.0, sample_rate_hz=FS, max_range_m=25.0)
    pulse = se.Pulse.cw(duration_s=TAU, taper=0.0)
    se.simulate(scene, traj[:2], sonar, pulse)  # compile
    rows = []
    for q in (0.5, 1.0, 2.0):
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            rec = se.simulate(scene, traj, sonar, pulse, quality=q)
            best = min(best, time.perf_counter() - t0)
        ref = quadrature(rec.time_s, sonar)
        c = se.Acquisition.of(sonar).sound_speed_m_s
        edge = (np.abs(rec.time_s - 2 * H / c) <= 1.5 / FS) | (np.abs(rec.time_s - 2 * H / c - TAU) <= 1.5 / FS)
        ok = (ref > 1e-3 * ref.max()) & ~edge
        err = 10 * np.log10(rec.data[:, 0].mean(axis=0)[ok] / ref[ok])
        rows.append({"quality": q, "rays_per_ping": round(rec.attrs["rays_per_ping"]),
                     "ms_per_ping": round(1e3 * best / len(traj), 2), "pings_per_s": round(len(traj) / best, 1),
                     "max_db": round(float(np.max(np.abs(err))), 3), "rms_db": round(float(np.sqrt(np.mean(err ** 2))), 3)})
    print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

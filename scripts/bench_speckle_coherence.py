"""Speckle from ping to ping: the adjacent pings' intensity correlation against the displaced-aperture closed form,
and what the speckle synthesis costs (docs/benchmarks.md, "Speckle from ping to ping"; docs/physics.md §4).

    python scripts/bench_speckle_coherence.py           # prints one JSON line per case
    python scripts/bench_speckle_coherence.py --quick   # the first case only, 40 pings

Cases: a flat floor 8 m below the sonar, stop and hop, 30 µs and 100 µs CW, pings d apart along track; each ping's
starboard intensity over 13–19 m divided by the speckle-free record, the correlation of adjacent pings pooled over
the line, against |ρ|² = |∫B(u − δ/2)B(u + δ/2)e^(−j2kdu)du / ∫B²|², B(u) = sinc²(D·u/λ), δ = d/R, averaged over
the band. Then ms per ping of the whole run and of its synthesis stage (best of two), on the 30 m line of the
default sonar. No test reads the numbers; run the script at two commits to compare them.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy.integrate import quad

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402

H, BAND = 8.0, (13.0, 19.0)


def closed_form(f_hz: float, length_m: float, d_m: float) -> float:
    """|ρ|² of pings d_m apart, averaged over the band (van Cittert–Zernike for a displaced aperture)."""
    lam = 1500.0 / f_hz
    k = 2 * math.pi / lam
    b = lambda u: np.sinc(length_m * u / lam) ** 2                                  # noqa: E731
    lim = 6 * lam / length_m
    norm = quad(lambda u: b(u) ** 2, -lim, lim, limit=400, points=[0.0])[0]
    out = []
    for r in np.linspace(*BAND, 7):
        dl = d_m / r
        re = quad(lambda u: b(u - dl / 2) * b(u + dl / 2) * np.cos(2 * k * d_m * u), -lim, lim, limit=800)[0]
        im = quad(lambda u: b(u - dl / 2) * b(u + dl / 2) * np.sin(2 * k * d_m * u), -lim, lim, limit=800)[0]
        out.append((re * re + im * im) / norm ** 2)
    return float(np.mean(out))


def correlation(f_hz, length_m, tau_s, d_m, n):
    """The simulated adjacent-ping correlation (starboard, the band, normalised by the speckle-free record)."""
    sonar = se.Sonar(frequency_hz=f_hz, length_m=length_m, max_range_m=BAND[1] + 0.5)
    traj = se.Trajectory.line((0.0, 0.0, H), (d_m * (n - 1), 0.0, H), n).stop_and_hop()
    scene = se.Scene().add(se.seafloor.flat((80.0, 80.0)), label="seafloor")
    pulse = se.Pulse.cw(duration_s=tau_s)
    rec = se.simulate(scene, traj, sonar, pulse, speckle=True, seed=3, start_time="2000-01-01")
    mean = se.simulate(scene, traj, sonar, pulse, start_time="2000-01-01")
    band = (rec.slant_range_m > BAND[0]) & (rec.slant_range_m < BAND[1])
    ratio = rec.starboard[:, band] / mean.starboard[:, band]
    return float(np.corrcoef(ratio[:-1].ravel(), ratio[1:].ravel())[0, 1])


def cost(sonar, pulse, n):
    """ms per ping (whole run, set-up excluded) and of the synthesis stage, best of two, on a 30 m line."""
    scene = se.Scene().add(se.seafloor.flat((300.0, 300.0)), label="seafloor")
    traj = se.Trajectory.line((0.0, 0.0, 10.0), (0.2 * (n - 1), 0.0, 10.0), n)
    best = None
    for _ in range(2):
        t = {}
        t0 = time.perf_counter()
        se.simulate(scene, traj, sonar, pulse, speckle=True, seed=1, start_time="2000-01-01", timings=t)
        wall = time.perf_counter() - t0 - t.get("setup", 0.0)
        if best is None or wall < best[0]:
            best = (wall, t.get("synthesis", 0.0))
    return round(1e3 * best[0] / n, 2), round(1e3 * best[1] / n, 2)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the first case only, 40 pings")
    args = ap.parse_args(argv)
    cases = [(600e3, 0.19, 30e-6, 0.1), (600e3, 0.19, 30e-6, 0.3), (600e3, 0.19, 100e-6, 0.3),
             (400e3, 0.19, 100e-6, 0.2)]
    n = 40 if args.quick else 160
    for f, length, tau, dd in cases[:1] if args.quick else cases:
        d = dd * length
        want, got = closed_form(f, length, d), correlation(f, length, tau, d, n)
        total, synth = cost(se.Sonar(frequency_hz=f, length_m=length, max_range_m=30.0), se.Pulse.cw(duration_s=tau),
                            n)
        print(json.dumps({"f_khz": f / 1e3, "tau_us": round(tau * 1e6), "d_over_D": dd, "closed": round(want, 3),
                          "simulated": round(got, 3), "error": round(got - want, 3), "ms_per_ping": total,
                          "synthesis_ms_per_ping": synth}), flush=True)


if __name__ == "__main__":
    main()

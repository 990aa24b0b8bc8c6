"""Forward-looking sonar speed against error (docs/benchmarks.md, issue 18): frames (pings) per second at several
ray budgets, with the error of the boresight beam over a flat floor against a quadrature of eq. (1).

    python scripts/bench_fls.py

Two sonars over a flat Lambert floor (−20 dB) at 5 m altitude, 25 m range, 50 µs CW, speckle-free, heading along
the floor: the test's small array (900 kHz, 32 elements, 61 beams over 60°, 20° × 10° tilt, 100 kHz sampling)
and the shipped config's (128 elements, 256 beams over 130°, sampled for the pulse). The error (max and RMS, dB)
is the small array's boresight beam against the quadrature over the samples within 25 dB of its peak and away
from the onset (tests/test_forward_looking.py holds the same reference). Frames per second are the best of two
runs of 8 pings, setup excluded. Prints one JSON line. No test reads it.
"""
import json
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir)
sys.path.insert(0, ROOT)
sys.path[:0] = [os.path.join(ROOT, "tests"), os.path.join(ROOT, "tests", "sonars")]

import sonar_embree as se  # noqa: E402
import test_forward_looking as ref  # noqa: E402


def _fps(scene, traj, sonar, pulse, q):
    best = math.inf
    for _ in range(2):
        t = {}
        t0 = time.perf_counter()
        rec = se.simulate(scene, traj, sonar, pulse, quality=q, start_time="2000-01-01", timings=t)
        best = min(best, time.perf_counter() - t0 - t.get("setup", 0.0))
    return len(traj) / best, rec


def main() -> int:
    floor = se.Scene().add(se.seafloor.flat((300.0, 300.0)), material=se.Material(backscatter_db=-20.0),
                           label="seafloor")
    traj = se.Trajectory.line((0.0, 0.0, ref.H), (7.0, 0.0, ref.H), 8).stop_and_hop()
    pulse = se.Pulse.cw(duration_s=ref.TAU, taper=0.0)
    small, big = ref._sonar(), se.ForwardLooking(max_range_m=25.0)
    se.simulate(floor, traj[:1], small, pulse, start_time="2000-01-01")  # compile
    rows = []
    for q in (0.5, 1.0, 2.0):
        fps, rec = _fps(floor, traj, small, pulse, q)
        qd = ref._floor_quadrature(rec.time_s, rec.acquisition.alpha_db_per_m)
        lit = (qd > 10 ** -2.5 * qd.max()) & (np.abs(rec.time_s - 2 * ref.H / ref.C) > 2.5 / ref.FS) & (
            rec.time_s < 2 * 24.0 / ref.C)
        err = 10 * np.log10(rec.data[0, 30][lit] / qd[lit])
        fps_big, rec_big = _fps(floor, traj, big, pulse, q)
        rows.append({"quality": q, "small_fps": round(fps, 2), "small_rays_per_ping": rec.attrs["rays_per_ping"],
                     "max_err_db": round(float(np.abs(err).max()), 3),
                     "rms_err_db": round(float(np.sqrt(np.mean(err ** 2))), 3),
                     "shipped_fps": round(fps_big, 2), "shipped_rays_per_ping": rec_big.attrs["rays_per_ping"],
                     "shipped_samples": rec_big.data.shape[2]})
    print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

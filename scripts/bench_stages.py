"""Absolute time per ping of every stage of simulate(), for before/after comparisons of the per-ping path.

    python scripts/bench_stages.py            # prints one JSON line
    PYTHONPATH=/path/to/other/checkout python /path/to/other/checkout/scripts/bench_stages.py

Cases: the flat floor and the shipwreck (quality 1, speckle-free) and the shipwreck with coherent
baseband speckle; best of three runs each. "other" is the wall time no stage claims (Python glue).
Used for the before/after table of docs/benchmarks.md; no test reads it.
"""
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree import shipwreck  # noqa: E402

STAGES = ("embree", "rays", "synthesis", "processing")


def _best(scene, traj, **kw):
    best = None
    for _ in range(3):
        t = {}
        t0 = time.perf_counter()
        se.simulate(scene, traj, se.Sonar(), se.Pulse.cw(), start_time="2000-01-01", timings=t, **kw)
        wall = time.perf_counter() - t0 - t.get("setup", 0.0)
        if best is None or wall < best[0]:
            best = (wall, t)
    wall, t = best
    row = {k: 1e3 * t.get(k, 0.0) / len(traj) for k in STAGES}
    row["other"] = 1e3 * wall / len(traj) - sum(row.values())
    row["total"] = 1e3 * wall / len(traj)
    return {k: round(v, 3) for k, v in row.items()}


def main() -> int:
    flat = se.Scene().add(se.seafloor.flat((400.0, 200.0)), label="seafloor")
    line = se.Trajectory.line((-3.2, 0.0, 10.0), (3.2, 0.0, 10.0), 64)
    ship = shipwreck.shipwreck_scene(resolution_m=0.2)
    ship_pass = shipwreck.straight_pass(30, ping_rate_hz=1.0)
    se.simulate(flat, line[:2], start_time="2000-01-01")  # compile
    out = {"flat": _best(flat, line), "ship": _best(ship, ship_pass),
           "ship_speckle": _best(ship, shipwreck.straight_pass(100, ping_rate_hz=10.0), speckle=True)}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Cost of sea-surface multipath against the direct-path ping (docs/benchmarks.md, issue 15).

    python scripts/bench_multipath.py            # prints one JSON line
    python scripts/bench_multipath.py --no-swell # the direct and flat-surface cases only (a third of the time)
    python scripts/bench_multipath.py --line     # also the flat surface with its surface line (backscatter −40 dB)
    python scripts/bench_multipath.py --paired 7 # the ratios only: 7 rounds of direct, surface, swell in turn, one
                                                 # process; each round's ratios and their medians

Cases: the flat floor (10 m altitude, 60 m range) and the shipwreck pass, each without a surface and with a flat
surface 5 m above the sonar, and with a swell (H = 0.4 m, Λ = 8 m: the meshed surface, one Embree reflection per
ray); speckle-free (multipath is synthesised in expected intensity). ms per ping, best of three, and the stage
times of the multipath runs. No test reads it.
"""
import dataclasses
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree import shipwreck  # noqa: E402


def _best(scene, traj, sonar):
    best = None
    for _ in range(3):
        t = {}
        t0 = time.perf_counter()
        se.simulate(scene, traj, sonar, se.Pulse.cw(), start_time="2000-01-01", timings=t)
        wall = time.perf_counter() - t0 - t.get("setup", 0.0)
        if best is None or wall < best[0]:
            best = (wall, t)
    wall, t = best
    row = {k: round(1e3 * v / len(traj), 3) for k, v in t.items() if k != "setup"}
    row["total"] = round(1e3 * wall / len(traj), 3)
    return row


def _wall(scene, traj, sonar) -> float:
    """ms per ping of one run, setup excluded."""
    t = {}
    t0 = time.perf_counter()
    se.simulate(scene, traj, sonar, se.Pulse.cw(), start_time="2000-01-01", timings=t)
    return 1e3 * (time.perf_counter() - t0 - t.get("setup", 0.0)) / len(traj)


def paired(cases, rounds: int) -> dict:
    """Each case's direct, flat-surface and swell pings timed in turn, ``rounds`` times: the ratio of each round
    (the machine's drift between runs cancels within a round) and the medians."""
    out = {}
    for name, (scene, traj, sonar) in cases.items():
        z = float(traj.positions_m[:, 2].max()) + 5.0
        wet = se.Acquisition(sonar, se.Environment(surface=se.SeaSurface(z_m=z)))
        wavy = se.Acquisition(sonar, se.Environment(
            surface=se.SeaSurface(z_m=z, swell_height_m=0.4, swell_length_m=8.0)))
        rows = []
        for _ in range(rounds):
            d, f, w = (_wall(scene, traj, x) for x in (sonar, wet, wavy))
            rows.append((round(d, 2), round(f / d, 2), round(w / d, 2)))
        out[name] = {"rounds (direct ms, surface ratio, swell ratio)": rows,
                     "median surface ratio": float(np.median([r[1] for r in rows])),
                     "median swell ratio": float(np.median([r[2] for r in rows]))}
    return out


def main() -> int:
    flat = se.Scene().add(se.seafloor.flat((400.0, 200.0)), label="seafloor")
    line = se.Trajectory.line((-3.2, 0.0, 10.0), (3.2, 0.0, 10.0), 64)
    ship = shipwreck.shipwreck_scene(resolution_m=0.2)
    ship_pass = shipwreck.straight_pass(30, ping_rate_hz=1.0)
    cases = {"flat": (flat, line, se.Sonar(max_range_m=60.0)), "ship": (ship, ship_pass, se.Sonar())}
    se.simulate(flat, line[:2], start_time="2000-01-01")  # compile
    if "--paired" in sys.argv:
        print(json.dumps(paired(cases, int(sys.argv[sys.argv.index("--paired") + 1]))))
        return 0
    out = {}
    for name, (scene, traj, sonar) in cases.items():
        z = float(traj.positions_m[:, 2].max()) + 5.0
        wet = se.Acquisition(sonar, se.Environment(surface=se.SeaSurface(z_m=z)))
        swell = se.SeaSurface(z_m=z, swell_height_m=0.4, swell_length_m=8.0)
        wavy = se.Acquisition(sonar, se.Environment(surface=swell))
        lined = se.Acquisition(sonar, se.Environment(surface=se.SeaSurface(z_m=z, backscatter=-40.0)))
        out[name] = {"direct": _best(scene, traj, sonar), "surface": _best(scene, traj, wet)}
        out[name]["ratio"] = round(out[name]["surface"]["total"] / out[name]["direct"]["total"], 2)
        if "--line" in sys.argv:
            out[name]["line"] = _best(scene, traj, lined)
            out[name]["line_ratio"] = round(out[name]["line"]["total"] / out[name]["direct"]["total"], 2)
        if "--no-swell" not in sys.argv:
            out[name]["swell"] = _best(scene, traj, wavy)
            out[name]["swell_ratio"] = round(out[name]["swell"]["total"] / out[name]["direct"]["total"], 2)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

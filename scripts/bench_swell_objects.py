"""Ping time under a swell with and without small objects: the cost of the rays aimed at objects through the swell
(issue 34). Run it on two trees alternately for a before/after (PYTHONPATH=<tree> python <tree>/scripts/...).

    python scripts/bench_swell_objects.py            # prints {"0": ms/ping, "10": ms/ping} as JSON
    python scripts/bench_swell_objects.py --quick    # a small run (smoke test)

Scene: the default side-scan at 10 m over a flat 200 m floor under a long-crested swell (0.3 m high, 10 m long,
crests along the track, mean surface 5 m above the sonar), 0 or 10 Lambertian balls of 10 cm (seed 1) within
reach, a 64-ping line, speckle-free; best of three runs after a warm-up. Wall-clock on this machine; nothing here
is asserted by the tests.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import trimesh

import sonar_embree as se


def scene_with(n_balls: int):
    """The floor and ``n_balls`` balls of 10 cm radius over the starboard swath."""
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    rng = np.random.default_rng(1)
    for i in range(n_balls):
        ball = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
        ball.apply_translation((rng.uniform(-10, 10), rng.uniform(-40, -8), rng.uniform(0.1, 4)))
        scene.add(ball, label=f"ball#{i}", material=se.Material(backscatter_db=-10.0))
    return scene


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="8 pings, one run (smoke test)")
    args = p.parse_args(argv)
    sea = se.SeaSurface(z_m=15.0, swell_height_m=0.3, swell_length_m=10.0, swell_direction_deg=90.0)
    sonar = se.Acquisition(se.Sonar(max_range_m=45.0), se.Environment(surface=sea))
    n, repeat = (8, 1) if args.quick else (64, 3)
    traj = se.Trajectory.line((-5, 0, 10), (5, 0, 10), n)
    out = {}
    for n_balls in (0, 10):
        scene = scene_with(n_balls)
        se.simulate(scene, traj[:4], sonar, speckle=False)          # compile and warm up
        best = []
        for _ in range(repeat):
            t = time.perf_counter()
            se.simulate(scene, traj, sonar, speckle=False)
            best.append(time.perf_counter() - t)
        out[str(n_balls)] = round(1e3 * min(best) / n, 3)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

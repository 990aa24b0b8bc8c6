"""Coherent speckle with a device's own chirp against a CW pulse of the same resolution (issue 35, item 4).

    python scripts/bench_chirp.py            # prints a Markdown table row per pulse (ms per ping)
    python scripts/bench_chirp.py --quick    # a small run (smoke test)

Scene: the EdgeTech 4125 preset at 400 kHz (75 m range, 20° tilt) at 10 m over a flat 300 m floor, a 40-ping
line, coherent baseband speckle, best of three runs after a warm-up. Pulses: the preset's chirp (LFM 32 kHz,
2 ms) with the matched filter, the same chirp without it, and a CW pulse of the chirp's resolution (1/B =
31.25 µs). Wall-clock on this machine; nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import time

import sonar_embree as se


def ms_per_ping(scene, traj, sonar, pulse, matched_filter: bool, repeat: int) -> float:
    """Best wall time per ping of ``repeat`` runs after a warm-up, ms."""
    se.simulate(scene, traj[:2], sonar, pulse, speckle=True, matched_filter=matched_filter)
    best = []
    for _ in range(repeat):
        t = time.perf_counter()
        se.simulate(scene, traj, sonar, pulse, speckle=True, matched_filter=matched_filter)
        best.append(time.perf_counter() - t)
    return 1e3 * min(best) / len(traj)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="8 pings, one run")
    args = p.parse_args(argv)
    n, repeat = (8, 1) if args.quick else (40, 3)
    scene = se.Scene().add(se.seafloor.flat((300.0, 300.0)), label="seafloor")
    sonar = se.Sonar.preset("edgetech-4125-400")
    traj = se.Trajectory.line((0, 0, 10), (4, 0, 10), n)
    chirp = se.Pulse.preset("edgetech-4125-400")
    cw = se.Pulse.cw(duration_s=1.0 / chirp.bandwidth_hz)
    rows = [("preset chirp, compressed", chirp, True), ("preset chirp, not compressed", chirp, False),
            (f"CW {1e6 * cw.duration_s:.2f} µs (same resolution)", cw, False)]
    print("| pulse | ms/ping |\n|---|---:|")
    for name, pulse, mf in rows:
        print(f"| {name} | {ms_per_ping(scene, traj, sonar, pulse, mf, repeat):.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

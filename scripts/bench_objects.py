"""Ping time against the number of small objects, and the error the aimed rays buy (issue 34).

    python scripts/bench_objects.py                 # prints a Markdown section for docs/benchmarks.md
    python scripts/bench_objects.py --quick         # a small run (smoke test)
    python scripts/bench_objects.py --sweep 25      # N random cables against their quadrature (hard cases)

Scene: the default side-scan at 10 m over a flat 200 m floor, N Lambertian balls (radius 5 cm, 320 triangles
each) scattered over the swath (|y| 5–45 m, x over the line, 0.05–5 m above the floor, seed 0), a line of pings
2 cm apart, speckle-free, quality 1. For N = 0, 1, 10, 100, 1000: ms per ping and rays per ping with the aimed
rays (default) and without (``FanSettings(aim_objects=False)``: the fan alone). Error: one extra 5 cm ball 38 m
out and 5 m over the floor, its echo energy per ping against the quadrature of tests/analytic.py
(``sphere_quadrature``) over the pings within −20 dB of its peak: the largest error and the pings where it is
dark. Slender objects: the same for N cables (2 cm × 4 m, random headings, resting on the floor over the swath),
and the error of a 2 cm × 6 m cable across the track 20 m out against the quadrature over its lit side
(``cylinder_quadrature``). ``--sweep N``: N random closed cylinders (1–15 m long, 0.5–10 cm radius, any heading,
rising 0–30° from the floor, 8–40 m to either side; seed 0), each against its quadrature over the pings within
−10 dB of its peak: the worst and median of their largest errors. Wall-clock on this machine; nothing here is
asserted by the tests.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np
import trimesh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(ROOT, "tests"), os.path.join(ROOT, "tests", "propagation")]  # the reference, the probe

import analytic  # noqa: E402
from test_objects_seen import _pings_over, ball_energy  # noqa: E402

import sonar_embree as se  # noqa: E402

H, MU_DB, A, DX = 10.0, -10.0, 0.05, 0.02
REF = (0.0, -38.0, 5.0)  # the reference ball's centre


def scene_with(n_objects: int, line_m: float, seed: int = 0):
    """The floor, the reference ball and ``n_objects`` more balls over the swath."""
    rng = np.random.default_rng(seed)
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    ball = trimesh.creation.icosphere(subdivisions=2, radius=A)
    ref = ball.copy()
    ref.apply_translation(REF)
    scene.add(ref, label="ball", material=se.Material(backscatter_db=MU_DB))
    for i in range(n_objects):
        m = ball.copy()
        y = rng.uniform(5.0, 45.0) * rng.choice([-1.0, 1.0])
        m.apply_translation((rng.uniform(-line_m / 2, line_m / 2), y, rng.uniform(A, 5.0)))
        scene.add(m, label=f"ball#{i}", material=se.Material(backscatter_db=MU_DB))
    return scene


def cable(length_m, heading_rad, centre):
    """A 2 cm cable (64 sides) ``length_m`` long, horizontal at ``heading_rad`` from x, centred at ``centre``."""
    m = trimesh.creation.cylinder(radius=0.01, height=length_m, sections=64)
    m.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], [math.cos(heading_rad), math.sin(heading_rad), 0]))
    return m.apply_translation(centre)


def cable_scene(n_objects: int, line_m: float, seed: int = 0):
    """The floor, the reference cable (6 m across the track, 20 m to starboard) and ``n_objects`` 4 m cables."""
    rng = np.random.default_rng(seed)
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    scene.add(cable(6.0, math.pi / 2, (0.0, -20.0, 0.011)), label="cable", material=se.Material(backscatter_db=MU_DB))
    for i in range(n_objects):
        y = rng.uniform(5.0, 45.0) * rng.choice([-1.0, 1.0])
        c = cable(4.0, rng.uniform(0, math.pi), (rng.uniform(-line_m / 2, line_m / 2), y, 0.011))
        scene.add(c, label=f"cable#{i}", material=se.Material(backscatter_db=MU_DB))
    return scene


def cable_error(traj):
    """(largest |error| dB over the pings within −10 dB, dark pings there, pings there) of the reference cable."""
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    got = ball_energy(cable_scene(0, 1.0), traj, label="cable")
    ref = analytic.cylinder_quadrature(0.01, 6.0, (0.0, -20.0, 0.011), (0.0, 1.0, 0.0), traj.positions_m,
                                       se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, analytic.sidescan_gamma)
    inside = ref >= 0.1 * ref.max()
    dark = int(np.sum(got[inside] <= 0.0))
    err = 10 * np.log10(np.maximum(got[inside], 1e-30) / ref[inside])
    return float(np.abs(err[got[inside] > 0]).max()) if dark < inside.sum() else np.inf, dark, int(inside.sum())


def sweep_case(rng):
    """One random cable of the sweep: its largest |error| dB over the pings within −10 dB of its peak."""
    length, rho = rng.uniform(1.0, 15.0), 10 ** rng.uniform(math.log10(0.005), -1.0)
    head, tilt = rng.uniform(0.0, math.pi), rng.uniform(0.0, math.radians(30.0))
    y = rng.uniform(8.0, 40.0) * rng.choice([-1.0, 1.0])
    axis = np.array([math.cos(head) * math.cos(tilt), math.sin(head) * math.cos(tilt), math.sin(tilt)])
    centre = (0.0, y, rho + 0.002 + 0.5 * length * axis[2])
    m = trimesh.creation.cylinder(radius=rho, height=length, sections=48)
    m.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], axis))
    scene = se.Scene().add(se.seafloor.flat((150.0, 150.0)), label="seafloor").add(
        m.apply_translation(centre), label="cable", material=se.Material(backscatter_db=MU_DB))
    every = _pings_over(y, 1.0)
    traj = se.Trajectory(every.positions_m[::4], every.heading_deg[::4])
    alpha = se.Acquisition.of(se.Sonar().for_pulse(se.Pulse.cw())).alpha_db_per_m
    ref = analytic.cylinder_quadrature(rho, length, centre, axis, traj.positions_m, alpha, MU_DB,
                                       analytic.sidescan_gamma, n_t=max(1000, int(length / 0.005)), n_phi=96)
    got = ball_energy(scene, traj, label="cable")
    keep = ref >= 0.1 * ref.max()
    return float(np.abs(10 * np.log10(np.maximum(got[keep], 1e-300) / ref[keep])).max())


def sweep(n: int, seed: int = 0) -> str:
    """The line of ``--sweep``: worst and median largest error of ``n`` random cables, and how many exceed 1 dB."""
    rng = np.random.default_rng(seed)
    errors = np.array([sweep_case(rng) for _ in range(n)])
    return (f"{n} random cables (seed {seed}): largest errors worst {errors.max():.2f} dB, median "
            f"{np.median(errors):.2f} dB, {int(np.sum(errors > 1.0))} over 1 dB.")


def timed(scene, traj, aim: bool, repeat: int = 2):
    """(best ms per ping, rays per ping) of a speckle-free simulate()."""
    best, rays = np.inf, 0.0
    for _ in range(repeat):
        t = {}
        t0 = time.perf_counter()
        rec = se.simulate(scene, traj, fan=se.FanSettings(aim_objects=aim), timings=t)
        best = min(best, (time.perf_counter() - t0 - t.get("setup", 0.0)) / len(traj))
        rays = rec.attrs["rays_per_ping"]
    return 1e3 * best, rays


def error_of(scene, traj, aim: bool):
    """(largest |error| dB over the pings within −20 dB, dark pings there, pings there) of the reference ball."""
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    got = ball_energy(scene, traj, aim=aim)
    ref = analytic.sphere_quadrature(A, REF, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, n=120)
    inside = ref >= 0.01 * ref.max()
    dark = int(np.sum(got[inside] <= 0.0))
    err = 10 * np.log10(np.maximum(got[inside], 1e-30) / ref[inside])
    return float(np.abs(err[got[inside] > 0]).max()) if dark < inside.sum() else np.inf, dark, int(inside.sum())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="fewer pings and objects (smoke test)")
    p.add_argument("--sweep", type=int, default=0, help="only the sweep of N random cables against their quadrature")
    args = p.parse_args(argv)
    if args.sweep:
        print(sweep(args.sweep))
        return 0
    counts = (0, 1, 10) if args.quick else (0, 1, 10, 100, 1000)
    n_pings = 11 if args.quick else 101
    half = DX * (n_pings // 2)
    traj = se.Trajectory.line((-half, 0.0, H), (half, 0.0, H), n_pings)
    se.simulate(scene_with(1, 2 * half), traj[:2])  # compile the kernels outside the timings
    lines = ["| objects | ms/ping, aimed | rays/ping, aimed | ms/ping, fan only | rays/ping, fan only |",
             "|---:|---:|---:|---:|---:|"]
    for n in counts:
        scene = scene_with(n, 2 * half)
        (ta, ra), (tf, rf) = timed(scene, traj, True), timed(scene, traj, False)
        lines.append(f"| {n} | {ta:.2f} | {ra:.0f} | {tf:.2f} | {rf:.0f} |")
        print(lines[-1], file=sys.stderr)
    floor = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    tfloor, rfloor = timed(floor, traj, True)
    long = se.Trajectory.line((-1.3, 0.0, H), (1.3, 0.0, H), 131)
    err = {aim: error_of(scene_with(0, 2.6), long, aim) for aim in (True, False)}
    out = list(lines)
    out += ["", f"The floor alone (no object to aim at): {tfloor:.2f} ms/ping, {rfloor:.0f} rays/ping.", "",
            "Error bought (the reference ball, 131 pings every 2 cm, pings within −20 dB of its peak):", "",
            "| rays | max error dB | dark pings |", "|---|---:|---:|"]
    for aim, name in ((True, "aimed + fan"), (False, "fan only")):
        e, dark, n_in = err[aim]
        out.append(f"| {name} | {e:.2f} | {dark} of {n_in} |")
    print("\n".join(out + [""] + cables(counts[:-1] if len(counts) > 3 else counts, traj, 2 * half)))
    return 0


def cables(counts, traj, line_m):
    """The slender objects' section: ms and rays per ping against the number of cables, the reference's error."""
    out = ["| cables | ms/ping, aimed | rays/ping, aimed |", "|---:|---:|---:|"]
    for n in counts:
        t, r = timed(cable_scene(n, line_m), traj, True)
        out.append(f"| {n} | {t:.2f} | {r:.0f} |")
        print(out[-1], file=sys.stderr)
    e, dark, n_in = cable_error(se.Trajectory.line((-0.9, 0.0, H), (0.9, 0.0, H), 31))
    return out + ["", f"The 6 m cable, 31 pings every 6 cm: largest error {e:.2f} dB, dark in {dark} of the {n_in} "
                  "pings within −10 dB of its peak."]


if __name__ == "__main__":
    sys.exit(main())

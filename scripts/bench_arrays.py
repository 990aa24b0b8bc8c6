"""Receiver arrays: ping time against the number of elements, and SAS image formation's time per m² against the
error its upsampling buys (docs/benchmarks.md, "Receiver arrays").

    python scripts/bench_arrays.py                      # prints Markdown tables
    python scripts/bench_arrays.py --pings 2 --runs 1 --elements 1 2 8 16 --no-image   # a quicker pass
    python scripts/bench_arrays.py --layout vertical --elements 2 16 --no-image       # stacked elements

Pings: the anchor mine on a 120 m flat floor at 10 m altitude, 100 kHz, elements 4 cm long along track (D
apart, so a ±22° element beam: every node of the lattice under it radiates), a 20 kHz LFM of 1 ms, coherent
baseband speckle, ``--pings`` pings 0.15 m apart (default 4); best of ``--runs`` (default 2). The single-channel
row is the same sonar without an array (its record is the 1-element array's, bit for bit); with two elements or
more the elements share each node's scatterers (issue 53, item 4). The error column is each element's record against
that element synthesised alone (a one-element array at its place, the per-element splat), at the mine's compressed
peak and over the record (largest over elements 0, N/2 and N − 1).
Image formation: one clutter point at 14.6 m slant range seen by 8 elements over the real aperture's footprint,
its −3 dB widths along and across track measured at 0.1 mm; the error is their largest deviation from the widths at
16× upsampling (converged: the kernel then interpolates a smooth record), and likewise the first nulls'; the time is
that of a 2 m × 2 m image at 1 cm pixels, per m². No test reads this script.
"""
import argparse
import math
import os
import sys
import time

import numpy as np
import trimesh

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree.signal.sas import record_image  # noqa: E402

F0, B, D = 100e3, 20e3, 0.04
PULSE = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.1)


def _sonar(array):
    return se.Sonar(frequency_hz=F0, length_m=D, height_m=0.02, tilt_deg=20, max_range_m=40, receive_array=array)


def _line(n, z=10.0):
    x = np.arange(n) * 0.15 - 0.075 * n
    zeros = np.zeros(n)
    return se.Trajectory(np.stack([x, zeros, np.full(n, z)], axis=1), np.full(n, 90.0), zeros, zeros, x / 1.5)


def _best(scene, traj, sonar, runs):
    """(ms per ping, of which synthesis, the record) over the best of ``runs``, after a one-ping run (compiling)."""
    se.simulate(scene, _line(1), sonar, PULSE, speckle=True, seed=0)
    best = None
    for _ in range(runs):
        t = {}
        t0 = time.perf_counter()
        rec = se.simulate(scene, traj, sonar, PULSE, speckle=True, seed=0, timings=t)
        wall = time.perf_counter() - t0 - t.get("setup", 0.0)
        if best is None or wall < best[0]:
            best = (wall, t.get("synthesis", 0.0))
    return 1e3 * best[0] / len(traj), 1e3 * best[1] / len(traj), rec


def _element_error(scene, traj, rec, n):
    """(dB, rad at the compressed peak; error energy, dB) of elements 0, n/2, n − 1 against each alone."""
    worst = np.zeros(3)
    for k in sorted({0, n // 2, n - 1}):
        alone = se.simulate(scene, traj, _sonar(se.ReceiverArray((rec.sonar.receive_array.positions_m[k],))), PULSE,
                            speckle=True, seed=0).element_data[:, :, 0]
        got = rec.element_data[:, :, k]
        pk = np.unravel_index(np.argmax(np.abs(alone)), alone.shape)
        err = (abs(20 * np.log10(abs(got[pk]) / abs(alone[pk]))), abs(np.angle(got[pk] / alone[pk])),
               10 * np.log10(np.sum(np.abs(got - alone) ** 2) / np.sum(np.abs(alone) ** 2)))
        worst = np.maximum(worst, err) if k else np.array(err)
    return worst


def _array(n, layout):
    """n elements along track D apart, or stacked vertically D apart (each then hears with its own elevation
    pattern, docs/physics.md §18a); None: no array."""
    if n is None:
        return None
    if layout == "vertical" and n > 1:
        return se.ReceiverArray.vertical(D, n)
    return se.ReceiverArray.along_track(n, D)


def pings_table(n_pings=4, runs=2, elements=(1, 2, 8, 16, 32), errors=True, layout="along") -> str:
    scene = se.Scene()
    scene.add(se.seafloor.flat((120.0, 120.0)), material=se.Material(backscatter_db=-27), label="seafloor")
    scene.add(se.assets.path("anchor_mine.obj"), material=se.Material(backscatter_db=-15))
    traj = _line(n_pings)
    rows = ["| elements per side | ms per ping | × single channel | of which synthesis | synthesis per element (ms) "
            "| element vs alone: peak dB, rad; record error energy |", "|---|---|---|---|---|---|"]
    single = None
    for n in (None,) + tuple(elements):
        ms, syn, rec = _best(scene, traj, _sonar(_array(n, layout)), runs)
        single = single or ms
        err = "" if n is None or n < 2 or not errors else "{:.4f} dB, {:.4f} rad; {:.1f} dB".format(
            *_element_error(scene, traj, rec, n))
        label = "1 (no array)" if n is None else str(n)
        rows.append(f"| {label} | {ms:.0f} | {ms / single:.2f} | {syn:.0f} | {syn / (n or 1):.1f} | {err} |")
    return "\n".join(rows)


def _point_record():
    tile = trimesh.Trimesh([[-0.5, -14.1, 0], [0.5, -14.1, 0], [0.5, -13.1, 0], [-0.5, -13.1, 0]],
                           [[0, 1, 2], [0, 2, 3]])
    scene = se.Scene().add(tile, material=se.Material(backscatter_db=-150, clutter=se.Clutter(
        density_per_m2=2.0, strength_db=-20, spread_db=0.0)), label="tile")
    from sonar_embree.propagation.clutter import clutter_field

    target = clutter_field(scene.compiled(np.zeros(3)), 7).points[0]
    rec = se.simulate(scene, _line(49, 5.0), _sonar(se.ReceiverArray.along_track(8, D)), PULSE, speckle=True, seed=7)
    return rec, target


def _widths(rec, target, sub, upsample):
    """(−3 dB width along, across; first null along, across) of the point's image, m, linearly interpolated."""
    d = np.linspace(-0.08, 0.08, 1601)
    widths, nulls = [], []
    for cut in ((1, 0, 0), (0, 1, 0)):
        x = target[0] + d if cut[0] else [target[0]]
        y = target[1] + d if cut[1] else [target[1]]
        a = np.abs(record_image(rec, x, y, target[2], pings=sub, upsample=upsample)).ravel()
        i, half = int(np.argmax(a)), a.max() / math.sqrt(2)
        r = next(j for j in range(i, d.size) if a[j] < half)
        left = next(j for j in range(i, -1, -1) if a[j] < half)
        widths.append(d[r - 1] + (a[r - 1] - half) / (a[r - 1] - a[r]) * (d[r] - d[r - 1])
                      - d[left + 1] + (a[left + 1] - half) / (a[left + 1] - a[left]) * (d[left + 1] - d[left]))
        nulls.append(d[next(j for j in range(i + 1, d.size - 1) if a[j] <= a[j + 1])] - d[i])
    return np.array(widths + nulls)


def image_table() -> str:
    rec, target = _point_record()
    nav = rec.trajectory.positions_m
    sub = np.abs(nav[:, 0] - target[0]) <= 0.5 * rec.acquisition.wavelength_m * np.linalg.norm(target - nav,
                                                                                               axis=1).min() / D
    ref = _widths(rec, target, sub, 16)
    x = np.arange(-1.0, 1.0, 0.01)
    rows = ["| upsampling | s per m² (1 cm pixels, 8 elements, {} pings) | −3 dB width error | first-null error |"
            .format(int(sub.sum())), "|---|---|---|---|"]
    for up in (1, 2, 4, 8):
        record_image(rec, x[:5], x[:5] + target[1], target[2], pings=sub, upsample=up)   # compiled
        t0 = time.perf_counter()
        record_image(rec, x, x + target[1], target[2], pings=sub, upsample=up)
        per_m2 = (time.perf_counter() - t0) / 4.0
        err = np.abs(_widths(rec, target, sub, up) - ref) / ref
        rows.append(f"| {up} | {per_m2:.3f} | {100 * err[:2].max():.1f} % | {100 * err[2:].max():.1f} % |")
    return "\n".join(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pings", type=int, default=4)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--elements", type=int, nargs="+", default=[1, 2, 8, 16, 32])
    ap.add_argument("--no-errors", action="store_true", help="skip the per-element reference runs")
    ap.add_argument("--no-image", action="store_true", help="skip the image-formation table")
    ap.add_argument("--layout", choices=("along", "vertical"), default="along",
                    help="elements along track (default) or stacked vertically, D apart")
    a = ap.parse_args()
    print(pings_table(a.pings, a.runs, tuple(a.elements), not a.no_errors, a.layout))
    if not a.no_image:
        print()
        print(image_table())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Synthetic aperture sonar images of the anchor mine and the shipwreck beside the side-scan image (issue 39).

    python scripts/sas_figure.py [-o docs/sas] [--quick]

One SAS for both scenes: 100 kHz, a 20 kHz LFM of 1 ms, a transmitter and 8 receive elements of D = 8 cm along
track per side (receive_array along_track), pings 0.3 m apart (under the array's N·D/2 = 0.32 m), coherent
baseband speckle. Each scene is imaged twice on the same ground-plane grid (z = 0, 4 cm pixels):

- left, the side-scan image of the same line: element 0's intensity, each pixel taken from the ping abeam of it at
  its slant range (the real aperture: λR/D, about 4 m along track at 20 m);
- right, the SAS image: time-domain backprojection of every ping and element (signal.sas.record_image), D/2 = 4 cm
  along track and c/(2B) = 3.75 cm across at every range, with the objects' outlines from image_masks (layover
  included) drawn over it.

Both are shown in dB, the top 40 dB below their 99.5th percentile, their intensity averaged over blocks of pixels
down to about 450 columns (a few looks: speckle finer than a display pixel would alias). Writes sas.png and
sas.json (pings, elements, pixels, the seconds each step took, and the share of each image within 10 dB of its
99.9th percentile: how far the brightest echoes spread). ``--quick``: a small window around the mine
only (for the tests).

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
F0, B, D, N_EL, SPACING, PIXEL = 100e3, 20e3, 0.08, 8, 0.3, 0.04
#: Columns of a displayed panel, about.
DISPLAY_WIDTH = 450


def _sonar(se, max_range_m):
    return se.Sonar(frequency_hz=F0, length_m=D, height_m=0.02, tilt_deg=25.0, max_range_m=max_range_m,
                    receive_array=se.ReceiverArray.along_track(N_EL, D))


def _line(se, x0, x1, altitude):
    """Pings SPACING apart along +x (heading east), at rest during each ping."""
    x = np.arange(x0, x1 + 1e-9, SPACING)
    zeros = np.zeros(x.size)
    return se.Trajectory(np.stack([x, zeros, np.full(x.size, altitude)], axis=1), np.full(x.size, 90.0), zeros,
                         zeros, x / 1.5)


def cases(se, quick: bool):
    """(name, scene, trajectory, max range, side, grid x, grid y) of each panel pair."""
    from sonar_embree.runs.demo import MINE_GROUND_RANGE_M, anchor_mine_scene
    from sonar_embree.scene.shipwreck import shipwreck_scene

    r = MINE_GROUND_RANGE_M
    half = 2.0 if quick else 4.0
    scene = _mine_patch(se, r) if quick else anchor_mine_scene()
    mine = ("anchor mine", scene, _line(se, -half - 3.0, half + 3.0, 10.0), 32.0, "starboard",
            np.arange(-half, half, PIXEL), np.arange(-r - half, -r + half, PIXEL))
    if quick:
        return [mine]
    wreck = ("shipwreck", shipwreck_scene(resolution_m=0.4), _line(se, -33.0, 31.0, 15.0), 55.0, "port",
             np.arange(-27.0, 25.0, PIXEL), np.arange(11.0, 47.0, PIXEL))
    return [mine, wreck]


def _mine_patch(se, ground_range_m):
    """The anchor mine on a 16 m × 12 m patch of the demo's floor (its relief and backscatter) around it: the quick
    figure's window and the mine's shadow lie within it, and every lattice node under the elements' 11° beams
    radiates into every element (the floor beyond the patch would only add pings' worth of time, not pixels)."""
    from sonar_embree.runs.demo import anchor_mine_objects

    scene = se.Scene().add(se.seafloor.perlin(size_m=(16.0, 12.0), resolution_m=0.5, relief_m=0.3, feature_m=30.0,
                                              center_m=(0.0, -ground_range_m)),
                           material=se.Material(backscatter_db=-27.0), label="seafloor")
    for label, mesh, mat in anchor_mine_objects():
        scene.add(mesh, material=mat, label=label)
    return scene


def side_scan_on_grid(rec, x, y, channel):
    """Element 0's intensity (the record's channel) on the ground-plane grid: each pixel from the ping nearest it
    along track, at the sample of its slant range."""
    pos = rec.trajectory.positions_m
    ping = np.clip(np.searchsorted(pos[:, 0], x), 0, len(pos) - 1)            # (nx,)
    xx, yy = np.meshgrid(x, y)
    p = pos[ping][None, :, :]
    rho = np.sqrt((xx - p[..., 0]) ** 2 + (yy - p[..., 1]) ** 2 + p[..., 2] ** 2)
    n = np.clip(np.rint(2 * rho / rec.acquisition.sound_speed_m_s * rec.sonar.sample_rate_hz).astype(int), 0,
                rec.data.shape[2] - 1)
    return rec.channel(channel)[np.broadcast_to(ping[None, :], n.shape), n]


def looks(intensity, mask=None, width=DISPLAY_WIDTH):
    """The image brought to about ``width`` columns for display: intensity averaged over k × k blocks (k looks
    each way; speckle finer than a display pixel would alias) and the mask by the blocks' largest value."""
    k = max(1, int(np.ceil(intensity.shape[1] / width)))
    ny, nx = (intensity.shape[0] // k) * k, (intensity.shape[1] // k) * k
    blocks = intensity[:ny, :nx].reshape(ny // k, k, nx // k, k)
    small = None if mask is None else mask[:ny, :nx].reshape(ny // k, k, nx // k, k).max(axis=(1, 3))
    return blocks.mean(axis=(1, 3)), small


def bright_fraction(intensity, within_db=10.0) -> float:
    """The share of the image within ``within_db`` of its 99.9th percentile: how far the brightest echoes spread
    (a sharp image concentrates them)."""
    top = np.percentile(intensity, 99.9)
    return round(float(np.mean(intensity >= top * 10 ** (-within_db / 10))), 4)


def grey(intensity, outline=None, window_db=40.0):
    """dB of ``intensity`` as 8-bit grey (top ``window_db`` below the 99.5th percentile), north up; ``outline``: a
    mask whose edge pixels are drawn in amber."""
    with np.errstate(divide="ignore"):
        lev = 10 * np.log10(intensity)
    top = np.percentile(lev[np.isfinite(lev)], 99.5)
    img = (255 * np.clip((lev - top + window_db) / window_db, 0, 1)).astype(np.uint8)
    if outline is not None:
        inside = outline >= 0
        edge = inside & ~(np.roll(inside, 1, 0) & np.roll(inside, -1, 0) & np.roll(inside, 1, 1)
                          & np.roll(inside, -1, 1))
        img = np.stack([img] * 3, axis=-1)
        img[edge] = (255, 200, 0)
    return img[::-1]                                                   # rows: north (largest y) first


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "sas"), help="output folder")
    p.add_argument("--quick", action="store_true", help="the mine only, on a floor patch, a 4 m window (tests)")
    args = p.parse_args(argv)
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write
    from sonar_embree.signal.sas import image_masks, record_image

    os.makedirs(args.output, exist_ok=True)
    images, titles, info = [], [], {}
    for name, scene, traj, max_r, side, x, y in cases(se, args.quick):
        t0 = time.perf_counter()
        rec = se.simulate(scene, traj, _sonar(se, max_r), se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.1),
                          speckle=True, seed=1, start_time="2000-01-01")
        t1 = time.perf_counter()
        sas = np.abs(record_image(rec, x, y, 0.0, channel=side)) ** 2
        t2 = time.perf_counter()
        mask, _ = image_masks(scene, rec, x, y, 0.0, channel=side, spacing_m=PIXEL)
        real = side_scan_on_grid(rec, x, y, side)
        images += [grey(looks(real)[0]), grey(*looks(sas, mask))]
        titles += [f"{name}: side-scan (real aperture)", f"{name}: SAS, objects outlined"]
        info[name] = {"pings": len(traj), "elements_per_side": N_EL, "pixels": int(x.size * y.size),
                      "simulate_s": round(t1 - t0, 1), "image_s": round(t2 - t1, 1),
                      "masks_s": round(time.perf_counter() - t2, 1),
                      "bright_fraction": {"side_scan": bright_fraction(real), "sas": bright_fraction(sas)}}
    shape = images[0].shape[:2]
    images = [np.stack([im] * 3, axis=-1) if im.ndim == 2 else im for im in images]
    assert all(im.shape[:2] == shape for im in images[:2])
    plotting.mosaic_png(images, titles, os.path.join(args.output, "sas.png"))
    text = json.dumps(info, indent=1) + "\n"
    atomic_write(os.path.join(args.output, "sas.json"), lambda tmp: open(tmp, "w").write(text))
    for n in ("sas.png", "sas.json"):
        print(os.path.join(args.output, n))
    return 0


if __name__ == "__main__":
    sys.exit(main())

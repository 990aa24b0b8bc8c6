"""A mechanically scanning imaging sonar's scan: the usual polar display, still and moving.

    python scripts/msis_figure.py -o docs/msis [--pings 200]

The shipped config asset:msis_harbour.toml (700 kHz, 1.8° × 30° fan beam, 20 m range, one turn of the head in
200 pings of 1.8°, speckle) over the paper's anchor-mine scene, rendered twice: with the vehicle still, and
moving at 0.2 m/s during the turn. polar.png shows both scans in the usual MSIS display (each ping drawn along
its bearing around the first ping's position; display TVG R³, 30 dB): under motion the scan no longer closes,
the display's distortion that MSIS users know. scan.json holds the rays per ping and the pings per second.

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree.runs import runconfig  # noqa: E402
from sonar_embree.sonars.msis import polar_image  # noqa: E402


def _render(cfg, traj):
    t0 = time.perf_counter()
    rec = se.simulate(cfg.scene, traj, cfg.sonar, cfg.pulse, chain=cfg.chain, start_time="2026-05-01T12:00:00Z")
    return rec, time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-o", "--output", default=os.path.join("docs", "msis"))
    p.add_argument("--pings", type=int, default=200)
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = runconfig.load_run_config("asset:msis_harbour.toml")
    moving = cfg.trajectory[:args.pings]
    still = dataclasses.replace(moving, positions_m=np.repeat(moving.positions_m[:1], len(moving), axis=0),
                                velocity_m_s=None)
    os.makedirs(args.output, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2), constrained_layout=True)
    stats = {}
    for ax, (name, traj) in zip(axes, (("still", still), ("moving at 0.2 m/s", moving))):
        rec, secs = _render(cfg, traj)
        img, ext = polar_image(rec, pixel_m=0.05)
        x0, y0 = rec.trajectory.positions_m[0, :2]
        n = img.shape[0]
        r = np.hypot(*np.meshgrid((np.arange(n) + 0.5 - n / 2) * 0.05, (np.arange(n) + 0.5 - n / 2) * 0.05))
        with np.errstate(divide="ignore"):             # a shadow (zero) is black; NaN only outside the scan
            db = 10 * np.log10(img * r ** 3)
        top = np.nanpercentile(db[np.isfinite(db)], 99.9)
        db = np.where(np.isnan(img), np.nan, np.maximum(db, top - 30))
        ax.imshow(db, extent=(ext[0] - x0, ext[1] - x0, ext[2] - y0, ext[3] - y0), cmap="copper", vmin=top - 30,
                  vmax=top)
        ax.plot(traj.positions_m[:, 0] - x0, traj.positions_m[:, 1] - y0, "c-", lw=1.5)
        ax.set_title(f"MSIS, one turn, {name}")
        ax.set_xlabel("east, m")
        stats[name] = {"rays_per_ping": rec.attrs["rays_per_ping"], "pings_per_s": round(len(traj) / secs, 1)}
    axes[0].set_ylabel("north, m")
    fig.savefig(os.path.join(args.output, "polar.png"), dpi=110)
    with open(os.path.join(args.output, "scan.json"), "w") as fh:
        json.dump(stats, fh, indent=2)
    print(json.dumps(stats))
    return 0


if __name__ == "__main__":
    sys.exit(main())

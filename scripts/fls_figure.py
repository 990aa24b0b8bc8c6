"""A forward-looking multibeam sonar's view: the usual fan display, speckle-free and speckled.

    python scripts/fls_figure.py -o docs/fls

The shipped config asset:fls_harbour.toml (900 kHz, 128-element line array, 256 beams over 130° × 20°, 30 m
range, quality 0.5) approaching the paper's anchor-mine scene, one ping from 19 m before the mine, rendered
without and with speckle. fan.png shows both in the usual fan display (the sonar at the bottom centre, forward
up; display TVG R², 40 dB); fls.json holds the rays per ping and the frames per second of each.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree.runs import runconfig  # noqa: E402
from sonar_embree.sonars.forward_looking import fan_image  # noqa: E402
from sonar_embree.sonars.msis import display_grey  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-o", "--output", default=os.path.join("docs", "fls"))
    args = p.parse_args(argv)
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    cfg = runconfig.load_run_config("asset:fls_harbour.toml")
    traj = cfg.trajectory[len(cfg.trajectory) // 2:len(cfg.trajectory) // 2 + 1]
    os.makedirs(args.output, exist_ok=True)
    panels, info = [], {}
    for speckle in (False, True):
        chain = se.SignalChain(speckle=speckle, seed=1)
        t0 = time.perf_counter()
        rec = se.simulate(cfg.scene, traj, cfg.sonar, cfg.pulse, chain=chain, fan=cfg.fan,
                          start_time="2026-05-01T12:00:00Z")
        name = "speckled" if speckle else "expected intensity"
        info[name] = {"seconds": round(time.perf_counter() - t0, 2), "rays_per_ping": rec.attrs["rays_per_ping"]}
        img, (left, right, near, far) = fan_image(rec, 0, pixel_m=0.05)
        y = np.linspace(far, near, img.shape[0])[:, None]
        x = np.linspace(left, right, img.shape[1])[None, :]
        panels.append(display_grey(img, x ** 2 + y ** 2, 40.0))
    plotting.mosaic_png(panels, list(info), os.path.join(args.output, "fan.png"), columns=2)
    text = json.dumps(info, indent=1) + "\n"
    atomic_write(os.path.join(args.output, "fls.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("fan.png", "fls.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The anchor-mine scene in every simulation mode of the paper (Woock & Beyerer, Fig. 5–7).

    python scripts/paper_modes.py [-o docs/paper_modes] [--pings 160] [--max-range 36]

Writes one starboard waterfall PNG per mode (first ping at the top, slant range to
the right, display TVG and a 40 dB window, the same display for every mode), a
mosaic of all five, and the pixel-brightness histogram of the incoherent CW image:

- speckle_free.png     expected intensity, 100 µs CW (the "perfect sonar image")
- lfm_baseband.png     linear FM 20 kHz / 1 ms, complex baseband, pulse compression
- lfm_carrier.png      the same synthesised on the 1.64 MHz carrier
- cw_incoherent.png    100 µs CW on the carrier, square-law rectification + low-pass
- cw_coherent.png      100 µs CW in baseband, |analytic signal|²
- cw_incoherent_histogram.png, modes.png

Needs the plots extra (matplotlib) for the mosaic and the histogram.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

MODES = (
    ("speckle_free", "speckle-free (expected intensity)", "cw", {}),
    ("lfm_baseband", "linear FM, baseband", "lfm", {"speckle": True}),
    ("lfm_carrier", "linear FM, carrier", "lfm", {"speckle": True, "band": "carrier"}),
    ("cw_incoherent", "CW, incoherent (carrier)", "cw",
     {"speckle": True, "band": "carrier", "detection": "incoherent"}),
    ("cw_coherent", "CW, coherent (baseband)", "cw", {"speckle": True}),
)


def starboard_image(rec, r_min_m, r_max_m, dynamic_range_db=40.0, max_columns=600):
    """8-bit starboard waterfall between two slant ranges: display TVG, dB, top 0.5 % saturated."""
    from sonar_embree.signal.processing import tvg_gain
    from sonar_embree.display.waterfall import block_mean

    sel = (rec.slant_range_m >= r_min_m) & (rec.slant_range_m <= r_max_m)
    x = rec.starboard[:, sel] * tvg_gain(rec.time_s[sel], rec.acquisition.sound_speed_m_s,
                                         rec.acquisition.alpha_db_per_m)
    x = block_mean(x, int(np.ceil(x.shape[1] / max_columns)))
    ref = np.percentile(x, 99.5)
    db = 10 * np.log10(np.maximum(x, ref * 1e-12) / ref)
    return np.round(np.clip(1 + db / dynamic_range_db, 0, 1) * 255).astype(np.uint8)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "out", "paper_modes"), help="output folder")
    p.add_argument("--pings", type=int, default=160, help="pings over the 8 m track past the mine")
    p.add_argument("--max-range", type=float, default=36.0, help="recorded slant range, m")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    import imageio.v3 as iio

    import sonar_embree as se
    from sonar_embree.runs.demo import anchor_mine_scene
    from sonar_embree.display.plotting import brightness_histogram_png, mosaic_png
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    scene = anchor_mine_scene()
    traj = se.Trajectory.line(start=(-4.0, 0.0, 10.0), end=(4.0, 0.0, 10.0), n_pings=args.pings)
    sonar = se.Sonar(max_range_m=args.max_range)
    pulse = {"cw": se.Pulse.cw(100e-6, taper=0.1), "lfm": se.Pulse.lfm(20e3, 1e-3, taper=0.1)}
    images, titles = [], []
    for name, title, kind, chain in MODES:
        t0 = time.perf_counter()
        rec = se.simulate(scene, traj, sonar, pulse[kind], seed=args.seed, **chain)
        img = starboard_image(rec, 18.0, min(args.max_range, 36.0))
        path = os.path.join(args.output, f"{name}.png")
        atomic_write(path, lambda tmp, img=img: iio.imwrite(tmp, img, extension=".png"), suffix=".png")
        images.append(img)
        titles.append(title)
        print(f"{path}  ({time.perf_counter() - t0:.1f} s, {args.pings} pings)")
        if name == "cw_incoherent":
            hist = os.path.join(args.output, "cw_incoherent_histogram.png")
            brightness_histogram_png(img, hist, title="Pixel brightness, incoherent CW")
            print(hist)
    mosaic = os.path.join(args.output, "modes.png")
    mosaic_png(images, titles, mosaic, columns=3)
    print(mosaic)
    return 0


if __name__ == "__main__":
    sys.exit(main())

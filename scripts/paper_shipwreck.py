"""The paper's shipwreck figures (Woock & Beyerer, Fig. 8 and 9) on the procedural wreck.

    python scripts/paper_shipwreck.py --figure 8 -o docs/shipwreck
    python scripts/paper_shipwreck.py --figure 9 -o docs/shipwreck
    python scripts/paper_shipwreck.py -o docs/shipwreck            (both)

The wreck of sonar_embree.scene.shipwreck (56 m × 10.5 m, rolled 18°, sunk 1.2 m) on a
203 m floor, slightly rippled as in the paper's Fig. 8–9 (``--floor perlin`` for
the Fig. 1 floor), about 2.1 M triangles. 800 pings 0.1 m apart, 15 m above the
floor, 60 m range, 400 kHz (shipwreck.PAPER_PASS). Waterfalls: port mirrored on
the left, display TVG, 45 dB below the brightest 0.1 %.

Fig. 8  fig8_fm_baseband_straight.png   linear FM 20 kHz / 1 ms in baseband, pulse-compressed,
                                        speckle-free (the paper's FM baseband mode), straight pass
Fig. 9  fig9_cw_incoherent_curved.png   100 µs CW on the carrier, incoherent detection, along the
                                        slightly curved pass (an S-bend of ±2.5 m, heading ±10.6°)
        fig9_straight_vs_curved.png     the same mode and seed on the straight and the curved pass
        fig9_tracks.png                 plan view of both passes over the wreck

``--records`` also writes each record with its labels (``<name>.npz``). Needs the
plots extra (matplotlib) for the comparison and the plan view. Takes about 1 min
for both figures on 2 cores.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Waterfall display of every figure (keywords of waterfall_image).
DISPLAY = {"dynamic_range_db": 45.0, "tvg": True, "reference_percentile": 99.9, "max_columns": 600}
FM_BASEBAND = ("lfm", {})
CW_INCOHERENT = ("cw", {"speckle": True, "band": "carrier", "detection": "incoherent"})


def passes(n_pings: int, track_m: float):
    """Straight and curved passes of ``n_pings`` over ``track_m`` metres (PAPER_PASS otherwise)."""
    from sonar_embree import shipwreck

    kw = dict(shipwreck.PAPER_PASS, n_pings=n_pings)
    kw["ping_rate_hz"] = (n_pings - 1) * kw["speed_m_s"] / track_m
    return shipwreck.straight_pass(**kw), shipwreck.curved_pass(**kw)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "out", "shipwreck"), help="output folder")
    p.add_argument("--figure", choices=("8", "9", "all"), default="all", help="which figure (default: both)")
    p.add_argument("--floor", choices=("ripples", "perlin"), default="ripples",
                   help="rippled floor of Fig. 8-9 (default) or the Perlin floor of Fig. 1")
    p.add_argument("--pings", type=int, default=800, help="pings per pass (default 800)")
    p.add_argument("--track-m", type=float, default=79.9, help="length of each pass, m (default 79.9)")
    p.add_argument("--floor-size", type=float, default=203.0, help="side of the square floor, m (default 203)")
    p.add_argument("--max-range", type=float, default=None, help="recorded slant range, m (default 60)")
    p.add_argument("--seed", type=int, default=0, help="speckle seed")
    p.add_argument("--records", action="store_true", help="also write each record with labels as .npz")
    args = p.parse_args(argv)
    if args.pings < 2 or not args.track_m > 0 or not args.floor_size > 0:
        p.error("--pings must be >= 2, --track-m and --floor-size > 0")

    import imageio.v3 as iio
    import numpy as np
    from scipy.spatial import ConvexHull

    import sonar_embree as se
    from sonar_embree import shipwreck
    from sonar_embree.display.plotting import mosaic_png, plan_view_png
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    t0 = time.perf_counter()
    scene = shipwreck.shipwreck_scene(floor=args.floor, size_m=args.floor_size)
    sonar = se.Sonar(max_range_m=args.max_range or shipwreck.PAPER_MAX_RANGE_M)
    pulses = {"lfm": se.Pulse.lfm(20e3, 1e-3, taper=0.1), "cw": se.Pulse.cw(100e-6, taper=0.1)}
    straight, curved = passes(args.pings, args.track_m)
    print(f"scene: {scene.n_faces} triangles on a {args.floor} floor ({time.perf_counter() - t0:.1f} s)")

    def render(name, traj, mode, png=True):
        t = time.perf_counter()
        kind, chain = mode
        rec = se.simulate(scene, traj, sonar, pulses[kind], seed=args.seed, labels=args.records, **chain)
        img = rec.waterfall(**DISPLAY)
        path = os.path.join(args.output, name)
        if png:
            atomic_write(path + ".png", lambda tmp: iio.imwrite(tmp, img, extension=".png"), suffix=".png")
        if args.records:
            rec.save(path + ".npz")
        print(f"{path}{'.png' if png else ''}  ({time.perf_counter() - t:.1f} s, {traj.n_pings} pings)")
        return img

    if args.figure in ("8", "all"):
        render("fig8_fm_baseband_straight", straight, FM_BASEBAND)
    if args.figure in ("9", "all"):
        bent = render("fig9_cw_incoherent_curved", curved, CW_INCOHERENT)
        flat = render("fig9_cw_incoherent_straight", straight, CW_INCOHERENT, png=False)  # comparison only
        both = os.path.join(args.output, "fig9_straight_vs_curved.png")
        mosaic_png([flat, bent], ["straight pass", "slightly curved pass (S-bend ±2.5 m)"], both, columns=2)
        print(both)
        hull = next(o for o in scene.objects if o.label == "wreck").vertices[:, :2]
        outline = hull[ConvexHull(hull).vertices]
        tracks = os.path.join(args.output, "fig9_tracks.png")
        plan_view_png({"straight pass": straight.positions_m[:, :2], "curved pass": curved.positions_m[:, :2]},
                      {"wreck (footprint)": np.vstack([outline, outline[:1]])}, tracks,
                      title="Plan view: port looks to +y, the wreck to port")
        print(tracks)
    return 0


if __name__ == "__main__":
    sys.exit(main())

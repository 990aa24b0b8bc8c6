"""A survey's XTF as a reader draws it from the stored codes: the device's TVG beside the AGC it replaced (issue 50).

    python scripts/survey_xtf_figure.py -o docs/survey [--seconds 40]

A ship's GPS log (time, latitude, longitude) crosses a synthetic DEM (scripts/survey_from_dem.py's: two mounds and
a ridge, 40 m deep); `sonar-embree survey` runs it through the C-MAX CM2 preset at 325 kHz, 50 m range, the
towfish flown 8 m above the seabed (--altitude-m), once with the preset's receiver (a 30 log R + 2αR TVG from just
before the first bottom return, its level set so the median seabed sits at a quarter of full scale) and once with
the AGC the survey used before. Each line.xtf is read back with pyxtf and drawn as a viewer draws it: the codes
linearly over full scale, port mirrored on the left, no processing of ours.

- xtf_waterfalls.png  left: the AGC (the water column as bright as the seabed); right: the TVG
- xtf.json            per receiver: the median code of the water column before the first return and of the
                      seabed after it, their ratio in dB, the share of clipped codes

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "scripts"))

from survey_from_dem import CRS, X0, Y0, synthetic_dem  # noqa: E402

PRESET, RANGE_M, ALTITUDE_M = "cmax-cm2-325", 50.0, 8.0


def gps_log(path, seconds: int) -> None:
    """A 1 Hz log eastwards across the DEM's middle at 2 m/s: time, latitude, longitude (a ship's GPS)."""
    import pyproj

    x = X0 + 200.0 + 2.0 * np.arange(seconds + 1)
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(x, np.full(x.size, Y0 - 160))
    t0 = dt.datetime(2026, 5, 1, 9, 0, tzinfo=dt.timezone.utc)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("time,latitude,longitude\n")
        for k, (a, o) in enumerate(zip(lat, lon)):
            fh.write(f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(a)!r},{float(o)!r}\n")


def read_codes(path):
    """(pings, 2·samples) the codes as a reader has them (port far range first, then starboard), the altitude
    (pings,), the range of each sample per side (samples,) and the full scale."""
    import pyxtf

    header, packets = pyxtf.xtf_read(path)
    pings = packets[pyxtf.XTFHeaderType.sonar]
    img = np.stack([np.hstack([p.data[0], p.data[1]]) for p in pings]).astype(float)
    n = img.shape[1] // 2
    r = (np.arange(n) + 0.5) * pings[0].ping_chan_headers[1].SlantRange / n
    top = 2.0 ** (8 * header.ChanInfo[0].BytesPerSample) - 1
    return img, np.array([p.SensorPrimaryAltitude for p in pings]), r, top


def measure(img, alt, r, top) -> dict:
    stb = img[:, img.shape[1] // 2:]
    water, floor = r[None, :] < 0.8 * alt[:, None], r[None, :] > 1.2 * alt[:, None]
    w, s = float(np.median(stb[water])), float(np.median(stb[floor]))
    return {"water_column_code": w, "seabed_code": s, "contrast_db": 20 * np.log10(s / max(w, 0.5)),
            "clipped_share": float(np.mean(img >= top))}


def run(out: str, seconds: int) -> dict:
    import shutil
    import tempfile

    os.makedirs(out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="sonar-embree-xtf-figure-")
    try:
        return _run_in(work, out, seconds)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _run_in(work: str, out: str, seconds: int) -> dict:
    from sonar_embree.runs import survey as S

    dem = synthetic_dem(os.path.join(work, "dem.tif"))
    gps_log(os.path.join(work, "gps.csv"), seconds)
    results, images = {}, {}
    for name in ("agc", "tvg"):
        S.run_survey(dem, [os.path.join(work, "gps.csv")], os.path.join(work, name), PRESET, range_m=RANGE_M,
                     altitude_m=ALTITUDE_M, progress=False, pixel_m=1.0, gain=name)
        img, alt, r, top = read_codes(os.path.join(work, name, "line_00", "line.xtf"))
        results[name], images[name] = measure(img, alt, r, top), (img, top)
    _figure(out, images)
    with open(os.path.join(out, "xtf.json"), "w", encoding="utf-8") as fh:
        json.dump(results, fh, indent=2)
    return results


def _figure(out, images) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, (name, title) in zip(axes, (("agc", "AGC (the survey before): codes / full scale"),
                                         ("tvg", "the device's TVG (now): codes / full scale"))):
        img, top = images[name]
        ax.imshow(img / top, cmap="gray", vmin=0, vmax=0.5, aspect="auto", interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("sample (port far range … nadir | nadir … starboard far range)")
        ax.set_ylabel("ping")
    fig.suptitle(f"survey line.xtf read with pyxtf, {PRESET}, {RANGE_M:g} m range, {ALTITUDE_M:g} m altitude",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "xtf_waterfalls.png"), dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "survey"))
    p.add_argument("--seconds", type=int, default=40, help="length of the GPS log, s")
    args = p.parse_args(argv)
    res = run(args.output, args.seconds)
    for name, r in res.items():
        print(f"{name}: water column {r['water_column_code']:.0f}, seabed {r['seabed_code']:.0f}, "
              f"{r['contrast_db']:.1f} dB, clipped {100 * r['clipped_share']:.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A DEM to a planned, streamed survey: XTF + Zarr per line, a GeoTIFF mosaic and its bathymetry truth.

    python scripts/survey_from_dem.py -o out/survey                       # a synthetic DEM made here
    python scripts/survey_from_dem.py -o out/survey --figure docs/survey/survey.png   # + docs/guide/surveys.md's figure
    python scripts/survey_from_dem.py -o out/survey --dem my_dem.tif      # your own GeoTIFF (projected CRS, m)

Steps: the DEM (by default a 480 m × 320 m synthetic GeoTIFF at 1 m in UTM 32N, 40 m deep: smooth relief, two
mounds and a ridge, written by this script as dem.tif) becomes the seafloor (se.seafloor.from_dem); parallel
lines are planned over it with 20 % swath overlap (se.planning.plan_lines, inset by the range so that every
swath stays over the DEM); each line is flown 10 m above the DEM's median depth at 2 m/s and streamed with
ground-truth labels to lines/line_KK.zarr and lines/line_KK.xtf (latitude/longitude navigation); the lines are
mosaicked from the stores at 0.5 m (mosaic.tif: intensity, placed seafloor height) and the DEM resampled onto
the same grid (truth.tif). survey.png shows the truth, the mosaic (dB) and the placed heights with the lines;
survey.json lists the files and the placed heights' error against the truth.

--quick shrinks everything (a smoke test). Needs matplotlib (the plots extra) for survey.png.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree.io.geotiff import write_grid  # noqa: E402

CRS, X0, Y0 = "EPSG:32632", 532000.0, 6017400.0                    # upper-left corner of the synthetic DEM


def synthetic_dem(path, size_m=(480.0, 320.0), pixel_m=1.0) -> str:
    """A smooth seabed around −40 m with two mounds and a ridge, north-up GeoTIFF in UTM 32N."""
    nx, ny = int(size_m[0] / pixel_m), int(size_m[1] / pixel_m)
    x = (np.arange(nx) + 0.5) * pixel_m
    y = (np.arange(ny) + 0.5) * pixel_m                            # metres south of the top edge
    xx, yy = np.meshgrid(x, y)
    z = -40.0 + 1.5 * se.seafloor.perlin_noise((ny, nx), (3, 4), seed=7)
    for cx, cy, h, s in ((0.3, 0.5, 6.0, 12.0), (0.7, 0.68, 4.0, 8.0)):       # between the planned lines
        z += h * np.exp(-0.5 * ((xx - cx * size_m[0]) ** 2 + (yy - cy * size_m[1]) ** 2) / s ** 2)
    z += 2.5 * np.exp(-0.5 * ((yy - 0.2 * size_m[1]) - 0.3 * (xx - 0.5 * size_m[0])) ** 2 / 4.0 ** 2)
    write_grid(path, z, X0, Y0, pixel_m, CRS)
    return path


def _lines(mesh, range_m, quick):
    lo, hi = mesh.bounds[0, :2] + range_m + 5.0, mesh.bounds[1, :2] - range_m - 5.0
    if quick:
        hi = np.minimum(hi, lo + [40.0, 2 * range_m])
    poly = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
    return se.planning.plan_lines(poly, range_m, overlap=0.2, direction_deg=0.0, run_in_m=0.0)


def survey(out, dem=None, quick=False) -> dict:
    os.makedirs(os.path.join(out, "lines"), exist_ok=True)
    dem = dem or synthetic_dem(os.path.join(out, "dem.tif"), *(((120.0, 100.0), 2.0) if quick else ()))
    floor = se.seafloor.from_dem(dem)
    scene = se.Scene().add(floor, label="seafloor")
    range_m = 20.0 if quick else 40.0
    z = float(np.median(floor.vertices[:, 2])) + 10.0
    lines = _lines(floor, range_m, quick)
    trajs = se.planning.line_trajectories(lines, z, speed_m_s=2.0, ping_rate_hz=5.0, crs=scene.crs,
                                          start_time="2026-05-01T08:00:00Z")
    sonar = se.Sonar(max_range_m=range_m)
    stores = []
    for k, traj in enumerate(trajs):
        base = os.path.join(out, "lines", f"line_{k:02d}")
        stores.append(se.stream.render_line(scene, traj, base + ".zarr", sonar, block_pings=256, labels=True,
                                            xtf_path=base + ".xtf"))
    grid = se.mosaic.mosaic(stores, pixel_m=2.0 if quick else 0.5)
    grid.to_geotiff(os.path.join(out, "mosaic.tif"))
    truth = se.mosaic.write_truth(os.path.join(out, "truth.tif"), scene, grid)
    both = np.isfinite(grid.height_m) & np.isfinite(truth)
    err = grid.height_m[both] - truth[both]
    summary = {"dem": os.path.relpath(dem, out) if dem.startswith(out) else dem, "crs": scene.crs,
               "lines": len(trajs), "pings": int(sum(len(t) for t in trajs)),
               "stores": [os.path.relpath(s, out) for s in stores], "mosaic": "mosaic.tif", "truth": "truth.tif",
               "placed_height_error_m": {"median": float(np.median(err)), "p95_abs": float(np.percentile(
                   np.abs(err), 95))}}
    _figure(out, grid, truth, trajs)
    with open(os.path.join(out, "survey.json"), "w") as fh:
        json.dump(summary, fh, indent=2)
    return summary


def _figure(out, grid, truth, trajs) -> None:
    try:
        import matplotlib
    except ImportError:
        return
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ny, nx = grid.count.shape
    e0, n0 = grid.x0_m, grid.y0_m - ny * grid.pixel_m              # axes in metres from the south-west corner
    ext = (0.0, nx * grid.pixel_m, 0.0, ny * grid.pixel_m)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    db = 10 * np.log10(np.where(grid.intensity > 0, grid.intensity, np.nan))
    lo = np.nanpercentile(db, 2) if np.isfinite(db).any() else 0.0
    for ax, img, title, kw in ((axes[0], truth, "truth: DEM on the mosaic grid (m)", dict(cmap="viridis")),
                               (axes[1], db, "mosaic intensity (dB, unit source)",
                                dict(cmap="gray", vmin=lo, vmax=lo + 50)),
                               (axes[2], grid.height_m, "placed seafloor height (m)", dict(cmap="viridis"))):
        im = ax.imshow(img, extent=ext, **kw)
        fig.colorbar(im, ax=ax, shrink=0.8)
        ax.set_title(title)
        ax.set_xlabel(f"easting − {e0:.0f} m ({grid.crs})")
        for t in trajs:
            ax.plot(t.positions_m[:, 0] - e0, t.positions_m[:, 1] - n0, "r-", lw=0.6)
    axes[0].set_ylabel(f"northing − {n0:.0f} m")
    fig.savefig(os.path.join(out, "survey.png"), dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-o", "--output", default=os.path.join("out", "survey"))
    p.add_argument("--dem", help="a GeoTIFF DEM in a projected CRS (default: a synthetic one)")
    p.add_argument("--quick", action="store_true", help="a small DEM and short lines (smoke test)")
    p.add_argument("--figure", help="also copy survey.png here")
    args = p.parse_args(argv)
    print(json.dumps(survey(args.output, args.dem, args.quick), indent=2))
    if args.figure:
        import shutil

        os.makedirs(os.path.dirname(os.path.abspath(args.figure)), exist_ok=True)
        shutil.copyfile(os.path.join(args.output, "survey.png"), args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A DEM of 50 M triangles under a 5 km line: time to the first ping and peak memory (docs/benchmarks.md).

    python scripts/bench_big_dem.py                    # 5121 × 5121 pixels at 1 m (52 M triangles), 5 km line
    python scripts/bench_big_dem.py --pixels 1001      # smaller

A synthetic GeoTIFF (smooth fractal relief around −40 m, UTM 32N) is written to a temporary folder, then a line
across its middle (10 m above the seabed, 50 m range, a ping every metre) is streamed from se.TiledDEM to Zarr
(no XTF). Prints one JSON line: triangles of the DEM, seconds to write it, seconds from opening it to the end of
the first block of pings, total seconds, pings/s, tiles meshed, and the peak resident memory (MB, ru_maxrss) of
the rendering alone (the DEM is written by a child process). No test reads it.
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))


def write_dem(path: str, n: int) -> None:
    """The synthetic DEM, row band by row band (memory of a band, not of the raster)."""
    import rasterio
    from rasterio.transform import Affine
    from rasterio.windows import Window

    profile = dict(driver="GTiff", width=n, height=n, count=1, dtype="float32", crs="EPSG:32632", tiled=True,
                   blockxsize=256, blockysize=256, transform=Affine(1.0, 0.0, 500000.0, 0.0, -1.0, 6020000.0))
    x = np.arange(n, dtype=np.float64)
    with rasterio.open(path, "w", **profile) as dst:
        for r0 in range(0, n, 256):
            y = np.arange(r0, min(r0 + 256, n), dtype=np.float64)[:, None]
            z = (-40.0 + 2.0 * np.sin(x / 173.0) * np.cos(y / 211.0) + 0.5 * np.sin(x / 17.0 + y / 23.0)
                 + 0.1 * np.sin(x / 2.3) * np.sin(y / 3.1))
            dst.write(z.astype(np.float32)[None], window=Window(0, r0, n, y.shape[0]))


def render(path: str, n: int) -> dict:
    import sonar_embree as se

    t0 = time.perf_counter()
    dem = se.TiledDEM(path, tile_px=256)
    mid = 6020000.0 - 0.5 * n
    length = min(5000.0, n - 120.0)
    line = se.Trajectory.line((500060.0, mid, -30.0), (500060.0 + length, mid, -30.0), int(length) + 1)
    sonar = se.Sonar(max_range_m=50.0)
    first = {}
    sim = sys.modules["sonar_embree.simulate"]
    real = sim.simulate

    def timed(*a, **k):
        rec = real(*a, **k)
        first.setdefault("s", time.perf_counter() - t0)
        return rec

    sim.simulate = timed
    tmp = tempfile.mkdtemp(prefix="bench_big_dem-")
    try:
        se.stream.render_line(dem, line, os.path.join(tmp, "line.zarr"), sonar, block_pings=256,
                              start_time="2026-05-01T12:00:00Z")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    wall = time.perf_counter() - t0
    return {"pings": len(line), "first_block_s": round(first["s"], 2), "total_s": round(wall, 1),
            "pings_per_s": round(len(line) / wall, 1), "tiles_meshed_kept": len(dem._tiles),
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pixels", type=int, default=5121)
    p.add_argument("--render", help=argparse.SUPPRESS)               # child: render this DEM
    args = p.parse_args(argv)
    if args.render:
        print(json.dumps(render(args.render, args.pixels)))
        return 0
    tmp = tempfile.mkdtemp(prefix="bench_big_dem-")
    try:
        path = os.path.join(tmp, "dem.tif")
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); "
                        f"import bench_big_dem as b; b.write_dem({path!r}, {args.pixels})"], check=True)
        written = time.perf_counter() - t
        out = subprocess.run([sys.executable, __file__, "--pixels", str(args.pixels), "--render", path], check=True,
                             capture_output=True, text=True).stdout.strip().splitlines()[-1]
        result = {"triangles": 2 * (args.pixels - 1) ** 2, "dem_write_s": round(written, 1), **json.loads(out)}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())

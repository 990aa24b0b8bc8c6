"""A 100 000-ping line streamed from a tiled DEM with labels: resident memory over the line (docs/benchmarks.md).

    python scripts/bench_tiled_stream.py                  # 100 000 pings, 10 km over a 10 100 × 200-pixel DEM
    python scripts/bench_tiled_stream.py --pings 5000     # shorter

A synthetic GeoTIFF (1 m pixels, smooth relief around −40 m, UTM 32N) is written to a temporary folder (by a
child process, so its memory is not counted); then a line along it, 10 m above the seabed, 30 m range, a ping
every 0.1 m, is streamed by se.stream.render_line from se.TiledDEM (256-pixel tiles, the default cache of 64)
into a Zarr store and an XTF file, with ground-truth labels, in blocks of 1 000 pings. A thread samples the
process's resident memory (VmRSS) every 0.5 s. Prints one JSON line: pings, seconds, pings/s, the peak resident
memory (MB, ru_maxrss), the resident memory when 10 %, 20 %, … 100 % of the pings were done, and the sizes of
the store and the XTF. No test reads it.
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_stream import _size  # noqa: E402  (the same store/file size)

X0, Y0 = 500000.0, 6020000.0


def write_dem(path: str, nx: int, ny: int) -> None:
    import numpy as np
    import rasterio
    from rasterio.transform import Affine

    x = np.arange(nx, dtype=np.float64)[None, :]
    y = np.arange(ny, dtype=np.float64)[:, None]
    z = -40.0 + 2.0 * np.sin(x / 173.0) * np.cos(y / 61.0) + 0.5 * np.sin(x / 17.0 + y / 23.0)
    with rasterio.open(path, "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float32", crs="EPSG:32632",
                       tiled=True, blockxsize=256, blockysize=256,
                       transform=Affine(1.0, 0.0, X0, 0.0, -1.0, Y0)) as dst:
        dst.write(z.astype(np.float32), 1)


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


class _Sampler(threading.Thread):
    """Resident memory every ``period`` s, with the time of each sample."""

    def __init__(self, period=0.5):
        super().__init__(daemon=True)
        self.period, self.samples, self.stop = period, [], threading.Event()

    def run(self):
        while not self.stop.is_set():
            self.samples.append((time.perf_counter(), _rss_mb()))
            self.stop.wait(self.period)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pings", type=int, default=100_000)
    p.add_argument("--block", type=int, default=1000)
    p.add_argument("--cache-tiles", type=int, default=64, help="TiledDEM's tile cache (default 64)")
    args = p.parse_args(argv)
    spacing = 0.1
    length = spacing * (args.pings - 1)
    nx, ny = int(length) + 100, 200
    tmp = tempfile.mkdtemp(prefix="bench_tiled_stream-")
    try:
        dem = os.path.join(tmp, "dem.tif")
        subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); "
                        f"import bench_tiled_stream as b; b.write_dem({dem!r}, {nx}, {ny})"], check=True)
        import sonar_embree as se

        tiles = se.TiledDEM(dem, tile_px=256, cache_tiles=args.cache_tiles)
        yc = Y0 - 0.5 * ny
        line = se.Trajectory.line((X0 + 50.0, yc, -30.0), (X0 + 50.0 + length, yc, -30.0), args.pings,
                                  speed_m_s=2.5)
        sonar = se.Sonar(max_range_m=30.0)
        store, xtf = os.path.join(tmp, "line.zarr"), os.path.join(tmp, "line.xtf")
        marks = []
        real_write = se.stream._write_block

        def counted(path, rec, a, progress, xtf_path):
            real_write(path, rec, a, progress, xtf_path)
            marks.append((progress["pings_done"], time.perf_counter()))

        se.stream._write_block = counted
        sampler = _Sampler()
        sampler.start()
        t0 = time.perf_counter()
        se.stream.render_line(tiles, line, store, sonar, block_pings=args.block, xtf_path=xtf, xtf_scale=1.0,
                              labels=True, start_time="2026-05-01T12:00:00Z")
        wall = time.perf_counter() - t0
        sampler.stop.set()
        sampler.join()
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        by_share = {}
        for share in range(10, 101, 10):
            done_t = next(t for n, t in marks if n >= share / 100.0 * args.pings)
            upto = [mb for t, mb in sampler.samples if t <= done_t] or [_rss_mb()]
            by_share[f"{share}%"] = round(max(upto), 0)
        out = {"pings": args.pings, "block_pings": args.block, "cache_tiles": args.cache_tiles, "dem_pixels": [nx, ny], "labels": True,
               "seconds": round(wall, 1), "pings_per_s": round(args.pings / wall, 1),
               "peak_rss_mb": round(peak_mb, 1), "max_rss_mb_by_share_of_pings": by_share,
               "tiles_kept": len(tiles._tiles), "zarr_mb": round(_size(store) / 2**20, 1),
               "xtf_mb": round(_size(xtf) / 2**20, 1)}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

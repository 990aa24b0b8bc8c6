"""Streaming a long line: peak memory and speed (docs/benchmarks.md, issue 17).

    python scripts/bench_stream.py                 # 100 000 pings at 50 m range over a flat floor
    python scripts/bench_stream.py --pings 5000    # shorter

The line is streamed to a Zarr store and an XTF file in a temporary folder (removed afterwards) by
se.stream.render_line; then its first 1 000 pings are simulated in memory and compared bit for bit with the
store. Prints one JSON line: pings, seconds, pings/s, peak resident memory (MB, the process's ru_maxrss), the
store's and the XTF's size, and whether the first pings are equal. No test reads it.
"""
import argparse
import json
import os
import resource
import shutil
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402


def _size(path) -> int:
    if os.path.isfile(path):
        return os.path.getsize(path)
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(path) for f in fs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pings", type=int, default=100_000)
    p.add_argument("--block", type=int, default=1000)
    args = p.parse_args(argv)
    spacing = 0.2                                                   # m between pings (2 m/s at 10 Hz)
    length = spacing * (args.pings - 1)
    scene = se.Scene().add(se.seafloor.flat((length + 200.0, 200.0), center_m=(0.5 * length, 0.0)), label="seafloor")
    line = se.Trajectory.line((0.0, 0.0, 10.0), (length, 0.0, 10.0), args.pings, speed_m_s=2.0)
    sonar = se.Sonar(max_range_m=50.0)
    tmp = tempfile.mkdtemp(prefix="bench_stream-")
    try:
        store, xtf = os.path.join(tmp, "line.zarr"), os.path.join(tmp, "line.xtf")
        t0 = time.perf_counter()
        se.stream.render_line(scene, line, store, sonar, block_pings=args.block, xtf_path=xtf, xtf_scale=1.0,
                              start_time="2026-05-01T12:00:00Z")
        wall = time.perf_counter() - t0
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        import xarray as xr

        first = min(1000, args.pings)
        rec = se.simulate(scene, line[:first], sonar, start_time="2026-05-01T12:00:00Z")
        ds = xr.open_zarr(store)
        equal = all(np.array_equal(ds[ch][:first].values, getattr(rec, ch)) for ch in ("port", "starboard"))
        out = {"pings": args.pings, "block_pings": args.block, "seconds": round(wall, 1),
               "pings_per_s": round(args.pings / wall, 1), "peak_rss_mb": round(peak_mb, 1),
               "zarr_mb": round(_size(store) / 2**20, 1), "xtf_mb": round(_size(xtf) / 2**20, 1),
               "first_pings_equal_in_memory": bool(equal)}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

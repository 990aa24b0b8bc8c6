"""One line on every core: pings per second of a streamed line against its worker processes (docs/benchmarks.md).

    python scripts/bench_scale.py                 # prints one JSON line
    python scripts/bench_scale.py --pings 512     # a shorter line

A line over a 2 M-triangle height field (the default side-scan, 40 m range) streamed by ``render_line`` with
``block_pings`` 64: in this process with one Numba thread (``numba.set_num_threads(1)``), in this process with
every thread, and on 1, 2, … worker processes of a LocalCluster (one Numba thread each), speckle-free and
coherent (CW baseband speckle). Wall time of the whole call (the cluster's start included) and pings per second;
the stores are checked to hold the same bits. With ``--steady``, also the rate a line adds once running (a run of
n/3 pings subtracted from one of n, on one cluster): what the workers give a long line, without the one-off
start, shipping of the scene and BVH builds. No test reads it.
"""
import argparse
import contextlib
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import numpy as np  # noqa: E402

import sonar_embree as se  # noqa: E402
from sonar_embree import kernels  # noqa: E402


def _line(n):
    scene = se.Scene().add(se.seafloor.perlin((200.0, 200.0), resolution_m=0.2, seed=1), label="seafloor")
    return scene, se.Trajectory.line((-60.0, 0.0, 8.0), (60.0, 0.0, 8.0), n)


def _run(scene, traj, out, how, coherent):
    kw = dict(speckle=True, seed=1) if coherent else {}
    t = time.perf_counter()
    se.stream.render_line(scene, traj, out, se.Sonar(max_range_m=40.0), block_pings=64, start_time="2000-01-01",
                          **how, **kw)
    return time.perf_counter() - t


def _steady(scene, traj, tmp, mode, coherent, workers):
    """Pings per second a line adds once running: (t(n) − t(n/3)) over the 2n/3 pings between, the cluster started
    once for both and the scene shipped, compiled and its BVH built in each call (so those cancel)."""
    from sonar_embree.survey.cluster import client_for

    n = len(traj)
    with client_for(workers=workers, what="bench") if workers > 1 else contextlib.nullcontext() as client:
        how = {"client": client} if workers > 1 else {"workers": 1}
        secs = [_run(scene, traj[:k], os.path.join(tmp, f"steady-{mode}-{workers}-{k}.zarr"), how, coherent)
                for k in (n // 3, n)]
    return round((n - n // 3) / (secs[1] - secs[0]), 1)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pings", type=int, default=1024)
    p.add_argument("--workers", type=int, nargs="*", default=[1, 2])
    p.add_argument("--steady", action="store_true", help="also the steady rate of 1 thread and of the workers")
    args = p.parse_args()
    scene, traj = _line(args.pings)
    out, stores = {"cpus": os.cpu_count(), "pings": args.pings}, {}
    with tempfile.TemporaryDirectory() as tmp:
        _run(scene, traj[:64], os.path.join(tmp, "warm.zarr"), {"workers": 1}, True)      # compile here
        for coherent in (False, True):
            mode = "coherent" if coherent else "speckle_free"
            row = {}
            threads = kernels.num_threads()
            for label, how in [("1 thread", {"workers": 1}), (f"{threads} threads", {"workers": 1})] + [
                    (f"{w} workers", {"workers": w}) for w in args.workers if w > 1]:
                kernels.set_num_threads(1 if label == "1 thread" else threads)
                path = os.path.join(tmp, f"{mode}-{label.replace(' ', '_')}.zarr")
                secs = _run(scene, traj, path, how, coherent)
                row[label] = round(args.pings / secs, 1)
                stores[path] = np.asarray(se.Record.load(path).data)
            if args.steady:
                kernels.set_num_threads(1)
                row["steady, 1 thread"] = _steady(scene, traj, tmp, mode, coherent, 1)
                kernels.set_num_threads(threads)
                for w in (w for w in args.workers if w > 1):
                    row[f"steady, {w} workers"] = _steady(scene, traj, tmp, mode, coherent, w)
            kernels.set_num_threads(threads)
            out[mode] = row
            same = [np.array_equal(a, next(iter(stores.values()))) for a in stores.values()]
            out[f"{mode} same bits"] = all(same)
            stores.clear()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

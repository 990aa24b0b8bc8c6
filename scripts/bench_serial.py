"""The serial share of a single-thread ping: time in the Numba kernels and in Embree against the rest (Python and
NumPy between them), issue 37's measure of what one process cannot spread over cores (docs/benchmarks.md).

    python scripts/bench_serial.py          # prints one JSON line (run with one thread: set here)

Cases as scripts/bench_stages.py: the flat floor (64 and 192 pings over the same 6.4 m) and the shipwreck pass
(30 and 90 pings over the same 60 m), quality 1, speckle-free, and the shipwreck with coherent CW baseband
speckle; profiled runs after a warm-up, best of three. Kernel time is the own time (cProfile's tottime) of every
Numba dispatcher of the package, Embree's that of the caster's functions (embreex's compiled ``run`` inside
them); "serial" is the rest of the wall time. Per-ping figures are the long run's less the short run's over the
pings it adds: what a ping costs in a long line, the run's set-up and finishing excluded (those are reported
apart, "serial per run", ms). Profiling adds a little to the serial part. No test reads it.
"""
import cProfile
import importlib
import json
import os
import pstats
import sys
import time

os.environ["NUMBA_NUM_THREADS"] = "1"       # before numba loads: one thread, the ping as one core runs it
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree import shipwreck  # noqa: E402

ROOT = os.path.realpath(os.path.dirname(se.__file__))
#: embreex's ``run`` is compiled Cython, which cProfile does not see: its time is the own time of the caster's
#: functions that call it.
EMBREE = os.path.join(ROOT, "raycast", "embree.py")


def _is_kernel(path: str, name: str) -> bool:
    """Whether the profiled function is a Numba dispatcher of the package (it has ``py_func``)."""
    path = os.path.realpath(path)
    if not path.startswith(ROOT):
        return False
    module = "sonar_embree." + os.path.relpath(path, ROOT)[:-3].replace(os.sep, ".").replace(".__init__", "")
    try:
        return hasattr(getattr(importlib.import_module(module), name, None), "py_func")
    except ImportError:
        return False


def _profile(scene, traj, **kw):
    """(wall, kernel, Embree) seconds of one profiled simulate() call."""
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    se.simulate(scene, traj, start_time="2000-01-01", **kw)
    prof.disable()
    wall = time.perf_counter() - t0
    kernel = embree = 0.0
    for (path, _, name), (_, _, tottime, _, _) in pstats.Stats(prof).stats.items():
        if os.path.realpath(path) == EMBREE:
            embree += tottime
        elif _is_kernel(path, name):
            kernel += tottime
    return wall, kernel, embree


def _shares(scene, short_traj, long_traj, repeat=3, **kw):
    """Per-ping figures as the difference of a long run and a short one over the same ground (best of ``repeat``
    each): what each added ping costs, without the run's set-up and finishing (reported as "per run", ms)."""
    se.simulate(scene, short_traj[:2], start_time="2000-01-01", **kw)
    n, n_long = len(short_traj), len(long_traj)
    short = min((_profile(scene, short_traj, **kw) for _ in range(repeat)), key=lambda t: t[0])
    long = min((_profile(scene, long_traj, **kw) for _ in range(repeat)), key=lambda t: t[0])
    wall, kernel, embree = ((b - a) / (n_long - n) for a, b in zip(short, long))
    serial = wall - kernel - embree
    per_run = (short[0] - short[1] - short[2]) - n * serial
    return {"ms/ping": round(1e3 * wall, 2), "kernels": round(1e3 * kernel, 2), "embree": round(1e3 * embree, 2),
            "serial": round(1e3 * serial, 2), "serial share": round(serial / wall, 3),
            "serial per run (ms)": round(1e3 * per_run, 1)}


def main() -> int:
    flat = se.Scene().add(se.seafloor.flat((400.0, 200.0)), label="seafloor")
    lines = [se.Trajectory.line((-3.2, 0.0, 10.0), (3.2, 0.0, 10.0), n) for n in (64, 192)]
    ship = shipwreck.shipwreck_scene(resolution_m=0.2)
    passes = [shipwreck.straight_pass(30 * k, ping_rate_hz=1.0 * k) for k in (1, 3)]
    out = {"threads": se.kernels.num_threads(), "flat": _shares(flat, *lines), "ship": _shares(ship, *passes),
           "ship coherent": _shares(ship, *passes, speckle=True, seed=1)}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

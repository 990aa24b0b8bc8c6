"""The serial share of a single-thread ping: time in the Numba kernels and in Embree against the rest (Python and
NumPy between them), issue 37's measure of what one process cannot spread over cores (docs/benchmarks.md).

    python scripts/bench_serial.py          # prints one JSON line (run with one thread: set here)

Cases as scripts/bench_stages.py: the flat floor (64 pings) and the shipwreck pass (30 pings), quality 1,
speckle-free, and the shipwreck with coherent CW baseband speckle; one profiled run each after a warm-up. Kernel
time is the own time (cProfile's tottime) of every Numba dispatcher of the package, Embree's that of the caster's
functions (embreex's compiled ``run`` inside them); "serial" is the rest of the wall time, in ms per ping and as a
share. No test reads it.
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


def _shares(scene, traj, **kw):
    se.simulate(scene, traj[:2], start_time="2000-01-01", **kw)
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
    n = len(traj)
    serial = wall - kernel - embree
    return {"ms/ping": round(1e3 * wall / n, 2), "kernels": round(1e3 * kernel / n, 2),
            "embree": round(1e3 * embree / n, 2), "serial": round(1e3 * serial / n, 2),
            "serial share": round(serial / wall, 3)}


def main() -> int:
    flat = se.Scene().add(se.seafloor.flat((400.0, 200.0)), label="seafloor")
    line = se.Trajectory.line((-3.2, 0.0, 10.0), (3.2, 0.0, 10.0), 64)
    ship, ship_pass = shipwreck.shipwreck_scene(resolution_m=0.2), shipwreck.straight_pass(30, ping_rate_hz=1.0)
    out = {"threads": se.kernels.num_threads(), "flat": _shares(flat, line), "ship": _shares(ship, ship_pass),
           "ship coherent": _shares(ship, ship_pass, speckle=True, seed=1)}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

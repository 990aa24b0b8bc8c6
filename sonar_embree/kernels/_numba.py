"""The Numba set-up every kernel module shares: the only module that imports numba."""
from __future__ import annotations

import os

# GNU OpenMP threads spin after each parallel region and steal the cores Embree's threads
# need next (measured: ~30 % slower casting on 2 cores); let them sleep unless the user chose.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numba import njit, prange  # noqa: E402,F401 (re-exported)
from numba.extending import register_jitable  # noqa: E402,F401 (re-exported)


# Helpers that take arrays and are called per ray, node or scatterer are marked inline='always': a call with
# array arguments costs reference counting on the arrays' shared header, which the threads contend for
# (measured: the curved-ray chord kernel 176 → 110 ns per ray, speckle synthesis 15.7 → 11.2 ms per
# shipwreck ping, same bits). Scalar helpers stay plain calls (inlining everything triples cold compiles).

# Kernels take named groups of arrays (kernels/args.py). One caution, measured with numba 0.68: a parallel kernel
# (arc_land) given its output arrays in namedtuples wrote some of them and silently not others, by field access as
# by unpacking, while the same code run as Python was right; the kernels' naive twins in the tests caught it, and
# arc_land keeps positional arguments. A kernel moved to named groups is checked against its twin and the
# shipped records' bits before it lands.

#: The float64 refit of a hit: the range from the hit triangle's plane replaces Embree's float32
#: distance unless the ray is within this cosine of the plane or the two differ by more than
#: REFIT_REL_TOL·(1 m + distance) (then the plane is not the one hit: keep Embree's).
REFIT_MIN_COS = 1e-6
REFIT_REL_TOL = 1e-3


#: The ``layout`` argument of the kernels that also take each ray's own layout (fan_echoes, mixed_legs, arc_start,
#: arc_echoes) when the rays are the fan's: no rows. Always passed: an array default argument would make Numba
#: compile the kernel again in every process (its on-disk cache cannot key an array default).
NO_LAYOUT = np.zeros((0, 5))


def cuda_module():
    """``numba.cuda``, loaded on first use (the GPU caster only): the simulator where ``NUMBA_ENABLE_CUDASIM=1``."""
    from numba import cuda

    return cuda


def num_threads() -> int:
    """Threads Numba's parallel kernels use (``NUMBA_NUM_THREADS``)."""
    return int(numba.get_num_threads())


def max_threads() -> int:
    """The most threads Numba's kernels may run on in this process (``NUMBA_NUM_THREADS``)."""
    return int(numba.config.NUMBA_NUM_THREADS)


def set_num_threads(n: int) -> None:
    """Run Numba's parallel kernels on ``n`` threads from now on (at most ``NUMBA_NUM_THREADS``)."""
    numba.set_num_threads(int(n))

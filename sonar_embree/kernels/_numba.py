"""The Numba set-up every kernel module shares: the only module that imports numba."""
from __future__ import annotations

import os

# GNU OpenMP threads spin after each parallel region and steal the cores Embree's threads
# need next (measured: ~30 % slower casting on 2 cores); let them sleep unless the user chose.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
from numba import njit, prange  # noqa: E402,F401 (re-exported)


#: The float64 refit of a hit: the range from the hit triangle's plane replaces Embree's float32
#: distance unless the ray is within this cosine of the plane or the two differ by more than
#: REFIT_REL_TOL·(1 m + distance) (then the plane is not the one hit: keep Embree's).
REFIT_MIN_COS = 1e-6
REFIT_REL_TOL = 1e-3


def num_threads() -> int:
    """Threads Numba's parallel kernels use (``NUMBA_NUM_THREADS``)."""
    return int(numba.get_num_threads())

"""Working arrays kept from block to block by a front end (curved rays, sea-surface paths).

On this kind of machine first-touch page faults of fresh arrays cost more than the arithmetic done in them
(measured: the curved-ray hit kernel 2× slower, the one-bounce legs kernel 1.5× slower on fresh memory), so
the per-block temporaries of a front end live in one :class:`Buffers`. Arrays it hands out are overwritten
by the next block: nothing backed by them may outlive the block.
"""
from __future__ import annotations

import numpy as np


class Buffers:
    """Working arrays kept from block to block: in the marching, first-touch page faults of fresh arrays
    cost more than the arithmetic (measured: the hit kernel 2× slower on fresh memory)."""

    def __init__(self):
        self._kept = {}

    def take(self, name: str, shape, dtype=np.float64) -> np.ndarray:
        """An uninitialised C-contiguous array of ``shape`` backed by the kept buffer ``name``."""
        size = int(np.prod(shape))
        buf = self._kept.get(name)
        if buf is None or buf.size < size:
            buf = np.empty(size + size // 4, dtype=dtype)  # headroom for the next, slightly larger block
            self._kept[name] = buf
        return buf[:size].reshape(shape)

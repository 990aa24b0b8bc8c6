"""The side-scan sonar type: two channels (port, starboard), one rectangular membrane each.

Its body-frame fan and ray budget are :mod:`sonar_embree.fan` (docs/physics.md §7),
its per-direction gain the baffled membrane of :mod:`sonar_embree.beam` (§2). It turns
a block of poses into :class:`~sonar_embree.echoes.Echoes` and, for ground truth,
keeps the block's fan (:class:`~sonar_embree.fan.BlockEchoes`).
"""
from __future__ import annotations

import numpy as np

from ..config import FanSettings, Sonar
from ..echoes import Echoes
from ..fan import BlockEchoes, FanPlan, cast_block
from ..processing import absorption_np_per_m


class SideScanFrontEnd:
    """Poses → echoes for a :class:`~sonar_embree.config.Sonar` (side-scan)."""

    channels = ("port", "starboard")
    supports_labels = True

    def __init__(self, sonar: Sonar, fan: FanSettings):
        self.sonar = sonar
        self.plan = FanPlan.build(sonar, fan)
        self.two_way_np_per_m = absorption_np_per_m(sonar.alpha_db_per_m)

    def cast(self, caster, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float, want_points: bool,
             want_ids: bool, clock: dict):
        """Echoes of a block of pings, and the block's fan (for ground truth).

        Parameters
        ----------
        caster : Caster
        rot : (pings, 3, 3) float64
            Body-to-world rotations.
        pos_local : (pings, 3) float64
            Sonar positions in the scene's local frame, m.
        max_range_m : float
            Farthest slant range searched, m.
        want_points, want_ids : bool
            Fill ``Echoes.point_m`` (speckle) and ``Echoes.object_id`` (ground truth).
        clock : dict
            Timings, as for :func:`~sonar_embree.fan.cast_block`.
        """
        blk = cast_block(caster, self.plan, rot, pos_local, self.two_way_np_per_m, max_range_m,
                         2.0 / self.sonar.sound_speed_m_s, want_points=want_points, timings=clock,
                         frequency_hz=self.sonar.frequency_hz)
        return echoes_of(blk, caster.compiled.face_object if want_ids else None), blk


def echoes_of(blk: BlockEchoes, face_object: np.ndarray | None = None) -> Echoes:
    """The echo contract of a side-scan block (travel times 2R/c of straight rays, made by the fan's kernel)."""
    ids = np.zeros(0, dtype=np.int32)
    if face_object is not None:
        ids = np.where((blk.prim >= 0) & (blk.weight > 0), face_object[np.maximum(blk.prim, 0)], -1).astype(np.int32)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, blk.weight, blk.point_m, ids)

"""One prepared run (issue 51, item 4): a run builds its state once, by name; runs share it only through a RunCache
handed to each; a line's blocks share one; the bits do not depend on it."""
import numpy as np
import pytest
import trimesh
import xarray as xr

import sonar_embree as se
from sonar_embree.raycast import EmbreeCaster

from conftest import flat_scene


class CountingCaster(EmbreeCaster):
    """Embree, counting how many casters (BVHs) are built."""

    built = 0

    def __init__(self, compiled):
        type(self).built += 1
        super().__init__(compiled)


@pytest.fixture
def counting():
    CountingCaster.built = 0
    return CountingCaster


def _scene():
    return flat_scene().add(trimesh.creation.box((1.0, 1.0, 1.0)), label="box")


TRAJ = se.Trajectory.line((-2.0, 6.0, 8.0), (2.0, 6.0, 8.0), 6)
KW = dict(start_time="2026-01-01", speckle=True, seed=2, labels=True)


def test_runs_share_a_scenes_bvh_only_through_a_cache(counting):
    """Three runs over one scene with labels build two casters each (the scene's and its seafloor's), six in all;
    with a RunCache the three build two; the records and labels are the same bits either way."""
    scene, sonar = _scene(), se.Sonar(max_range_m=20.0)
    alone = [se.simulate(scene, TRAJ, sonar, caster=counting, **KW) for _ in range(3)]
    without = counting.built
    counting.built = 0
    cache = se.RunCache()
    shared = [se.simulate(scene, TRAJ, sonar, caster=counting, cache=cache, **KW) for _ in range(3)]
    assert without == 3 * counting.built and counting.built == 2         # the scene's and its seafloor's
    for a, b in zip(alone, shared):
        np.testing.assert_array_equal(a.data, b.data)
        np.testing.assert_array_equal(a.labels.kind, b.labels.kind)
    assert alone[0].data.max() > 0


def test_a_lines_blocks_build_its_bvh_once(tmp_path, counting):
    """render_line hands its blocks one RunCache: four blocks, one BVH, the bits of one simulate call."""
    scene, sonar = _scene(), se.Sonar(max_range_m=20.0)
    line = se.Trajectory.line((-2.0, 6.0, 8.0), (2.0, 6.0, 8.0), 16)
    se.stream.render_line(scene, line, tmp_path / "l.zarr", sonar, block_pings=4, caster=counting,
                          start_time="2026-01-01", seed=2, speckle=True)
    assert counting.built == 1
    one = se.simulate(scene, line, sonar, start_time="2026-01-01", seed=2, speckle=True)
    np.testing.assert_array_equal(xr.open_zarr(tmp_path / "l.zarr")["starboard"].values, one.starboard)


def test_a_cache_keeps_only_its_most_recent_scenes(counting):
    """RunCache(scenes=1): a second scene pushes the first out, so coming back to it builds again."""
    a, b, sonar = _scene(), flat_scene(), se.Sonar(max_range_m=20.0)
    cache = se.RunCache(scenes=1)
    for scene in (a, a, b, a):
        se.simulate(scene, TRAJ, sonar, caster=counting, cache=cache, start_time="2026-01-01")
    assert counting.built == 3


def test_lines_share_a_cache_handed_to_them(tmp_path, counting):
    """render_line(cache=...): two lines over one scene build its BVH once (a survey hands its lines one)."""
    scene, sonar, cache = _scene(), se.Sonar(max_range_m=20.0), se.RunCache()
    for i, y in enumerate((6.0, 7.0)):
        line = se.Trajectory.line((-2.0, y, 8.0), (2.0, y, 8.0), 8)
        se.stream.render_line(scene, line, tmp_path / f"l{i}.zarr", sonar, block_pings=4, caster=counting,
                              start_time="2026-01-01", cache=cache)
    assert counting.built == 1
    with pytest.raises(se.ConfigError, match="render_line: cache must be a sonar_embree.RunCache"):
        se.stream.render_line(scene, line, tmp_path / "x.zarr", sonar, cache={})

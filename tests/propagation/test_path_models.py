"""Path models (issue 51, item 1, first step): a front end composes the paths the medium makes, chosen once in
:func:`sonar_embree.propagation.paths.path_models`, and a new path effect is one class. The records these models make
are the same bits as before they existed (checked when they were introduced; docs/benchmarks.md)."""
import dataclasses

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree import sonars
from sonar_embree.propagation import paths

PROFILE = se.SoundSpeedProfile.linear(1500.0, 0.05, surface_z_m=20.0)


@pytest.mark.parametrize("env, direct, surface", [
    (se.Environment(), paths.Direct, ()),
    (se.Environment(surface=se.SeaSurface(z_m=20.0)), paths.Direct, (paths.FlatSurface,)),
    (se.Environment(surface=se.SeaSurface(z_m=20.0, swell_height_m=0.5)), paths.Direct, (paths.Swell,)),
    (se.Environment(surface=se.SeaSurface(z_m=20.0, wind_speed_m_s=8.0, backscatter=-30.0)), paths.Direct,
     (paths.FlatSurface, paths.SurfaceLine)),
    (se.Environment(sound_speed=PROFILE), paths.Refracted, ()),
    (se.Environment(sound_speed=PROFILE, surface=se.SeaSurface(z_m=20.0)), paths.Refracted,
     (paths.RefractedFlatSurface,)),
], ids=["plain", "flat", "swell", "flat+line", "profile", "profile+flat"])
def test_the_medium_picks_the_path_models_once(env, direct, surface):
    got_direct, got_surface = paths.path_models(env)
    assert type(got_direct) is direct and tuple(type(m) for m in got_surface) == surface
    front = sonars.front_end(se.Acquisition(se.Sonar(max_range_m=30.0), env).for_pulse(se.Pulse.cw()), se.FanSettings())
    assert type(front.direct_path) is direct and tuple(type(m) for m in front.surface_paths) == surface


@dataclasses.dataclass(frozen=True)
class BounceLoss:
    """A new path effect in one class: a constant amplitude factor ``g`` per surface bounce on the paths of
    ``inner`` (its one-bounce echoes × g, two-bounce × g²; the direct ones kept)."""

    inner: object
    g: float

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        parts, aimed = self.inner.contributions(front, run, blk, direct, rot, pos_local, max_range_m, ids,
                                                want_points, clock, rx_shift)
        scaled = [p._replace(echoes=dataclasses.replace(p.echoes, weight=p.echoes.weight * self.g ** p.path))
                  for p in parts]
        return scaled, aimed


PATH_MODELS = paths.path_models


def _record(monkeypatch, g):
    def with_loss(env):
        direct, surface = PATH_MODELS(env)
        return direct, tuple(BounceLoss(m, g) for m in surface)

    monkeypatch.setattr(paths, "path_models", with_loss)
    scene = se.Scene().add(se.seafloor.flat((160.0, 160.0)), material=se.Material(backscatter_db=-27.0),
                           label="seafloor")
    traj = se.Trajectory.line((-1, 0, 8), (1, 0, 8), 3)
    env = se.Environment(surface=se.SeaSurface(z_m=11.0))                # 3 m over the sonar
    rec = se.simulate(scene, traj, se.Acquisition(se.Sonar(max_range_m=60.0, tilt_deg=10.0), env), se.Pulse.cw(),
                      speckle=False,
                      labels=False, start_time="2026-01-01")
    return rec.data


def test_a_constant_loss_per_bounce_is_one_class(monkeypatch):
    """Speckle-free, the record is linear in the echoes' weights: R(g) = D + g·M + g²·I (direct, one bounce, two
    bounces). Three losses give D, M and I; a fourth must be their sum with g and g², and the surface paths must be
    really there (M and I far from zero, in the samples the surface paths reach)."""
    d, r1, rh = (_record(monkeypatch, g) for g in (0.0, 1.0, 0.5))
    i = 2.0 * (r1 - d) - 4.0 * (rh - d)
    m = (r1 - d) - i
    q = _record(monkeypatch, 0.25)
    np.testing.assert_allclose(q, d + 0.25 * m + 0.0625 * i, rtol=1e-9, atol=1e-12 * np.abs(r1).max())
    assert np.abs(m).max() > 1e-3 * np.abs(d).max() and np.abs(i).max() > 1e-4 * np.abs(d).max()

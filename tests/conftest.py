import os
import sys

import numpy as np
import pytest
import trimesh

sys.path.insert(0, os.path.dirname(__file__))

import sonar_embree as se  # noqa: E402

H = 10.0  # sonar altitude of the reference cases, m


def flat_scene(**material):
    return se.Scene().add(se.seafloor.flat(size_m=(400, 200), z_m=0.0),
                          material=se.Material(**material), label="seafloor")


def line_along_x(n_pings=3, z=H, length=2.0):
    """Pings heading +x (starboard towards −y) at altitude z."""
    return se.Trajectory.line(start=(-length / 2, 0.0, z), end=(length / 2, 0.0, z), n_pings=n_pings)


def box(extents, center):
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(center)
    return m


@pytest.fixture(scope="session")
def flat_record():
    """Default sonar, 100 µs rectangular CW, flat floor 10 m below, speckle-free."""
    return se.simulate(flat_scene(), line_along_x(), se.Sonar(), se.Pulse.cw(duration_s=100e-6, taper=0.0),
                       speckle=False, seed=0)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)

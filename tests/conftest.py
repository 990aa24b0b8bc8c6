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
    """Pings heading +x (starboard towards −y) at altitude z, stop-and-hop (the model of the closed forms)."""
    return se.Trajectory.line(start=(-length / 2, 0.0, z), end=(length / 2, 0.0, z), n_pings=n_pings).stop_and_hop()


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


def facing_plate(slant_range_m=20.0, size_m=0.3, altitude_m=H, tilt_deg=20.0):
    """A square plate on the starboard boresight of a sonar at (0, 0, altitude) heading +x, facing it."""
    d = np.radians(tilt_deg)
    look = np.array([0.0, -np.cos(d), -np.sin(d)])
    centre = np.array([0.0, 0.0, altitude_m]) + slant_range_m * look
    a = np.array([1.0, 0.0, 0.0])
    b = np.cross(look, a)
    s = size_m / 2
    v = np.array([centre - a * s - b * s, centre + a * s - b * s, centre + a * s + b * s, centre - a * s + b * s])
    m = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    if np.dot(m.face_normals[0], look) > 0:
        m.invert()
    return m


def decoy_above(traj, height_m=5.0):
    """A 0.2 m cube ``height_m`` above the first ping: within range of the sonar (so a scene whose surfaces
    all lie beyond the window is not refused as "nothing in range") but behind every side-scan beam."""
    return box((0.2, 0.2, 0.2), traj.positions_m[0] + np.array([0.0, 0.0, height_m]))

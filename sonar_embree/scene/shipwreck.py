"""A procedural shipwreck scene like the paper's Fig. 1 (Woock & Beyerer §4.2).

A patrol-boat-like hull, about 56 m × 10.5 m with a deckhouse, rolled and sunk
into a 203 m Perlin-noise seafloor of ~0.1 m relief (about 2 M triangles at the
default 0.2 m floor resolution), or into a slightly rippled floor. Everything is
deterministic: the same arguments give the same triangles.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from . import seafloor
from ..config import Material
from ..errors import ConfigError
from .meshes import Scene, write_obj
from ..trajectory import Trajectory

HULL_LENGTH_M = 56.0
HULL_BEAM_M = 10.5
#: Default placement: centre (x, y) in m, heading of the bow (deg, clockwise from north), roll (deg), sunk depth (m).
WRECK_POSE = {"center_m": (0.0, 30.0), "heading_deg": 60.0, "roll_deg": 18.0, "pitch_deg": 2.0, "sink_m": 1.2}
#: The survey of the paper's Fig. 8 and 9 (scripts/paper_shipwreck.py, sonar_embree/assets/configs/shipwreck_*.toml):
#: 800 pings 0.1 m apart (1 m/s at 10 Hz) over 80 m, 15 m above the floor; the deckhouse rises
#: to about 8 m and the mast to 12 m, so most shadows run past the 60 m range.
PAPER_PASS = {"n_pings": 800, "altitude_m": 15.0, "ping_rate_hz": 10.0, "speed_m_s": 1.0}
PAPER_MAX_RANGE_M = 60.0


def hull(length_m: float = HULL_LENGTH_M, beam_m: float = HULL_BEAM_M, depth_m: float = 5.5,
         stations: int = 120, section_points: int = 24) -> trimesh.Trimesh:
    """A closed, watertight hull with a deckhouse, keel at z = 0, bow towards +x.

    Sections are V-shaped at the bow, rounder aft (half-breadth y = b(x)·(z/D)^p(x));
    the deck closes the hull at z = D; a deckhouse of 0.3 L × 0.55 B × 3.2 m and a
    mast-like block stand on it.
    """
    if not (length_m > 0 and beam_m > 0 and depth_m > 0 and stations >= 8 and section_points >= 4):
        raise ConfigError("hull needs positive length_m, beam_m, depth_m, stations >= 8, section_points >= 4")
    u = np.linspace(0.0, 1.0, stations)                  # stern (0) … bow (1)
    x = (u - 0.5) * length_m
    bow = np.cos(0.5 * np.pi * np.clip(u - 0.6, 0.0, 0.4) / 0.4) ** 0.8  # the forward 40 % narrows to the stem
    half = 0.5 * beam_m * np.where(u < 0.6, 1.0 - 0.15 * ((0.6 - u) / 0.6) ** 2, bow)
    half = np.maximum(half, 1e-3 * beam_m)
    power = 0.35 + 0.45 * u                              # fuller sections aft, V at the bow
    keel = depth_m * 0.35 * np.clip((u - 0.8) / 0.2, 0.0, 1.0) ** 2   # the forefoot rises to the bow
    t = np.linspace(-1.0, 1.0, 2 * section_points + 1)  # port deck edge … keel … starboard deck edge
    zz = keel[:, None] + (depth_m - keel[:, None]) * np.abs(t)[None, :]
    frac = np.abs(t)[None, :] ** (1.0 / power[:, None])
    yy = np.sign(t)[None, :] * half[:, None] * frac
    xx = np.broadcast_to(x[:, None], zz.shape)
    verts = np.stack([xx, yy, zz], axis=-1).reshape(-1, 3)
    ns, nt = zz.shape
    idx = np.arange(ns * nt).reshape(ns, nt)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    # deck: one strip between the two deck edges of every station pair; transoms close both ends
    p, s = idx[:, 0], idx[:, -1]
    faces += [np.stack([p[:-1], s[:-1], s[1:]], -1), np.stack([p[:-1], s[1:], p[1:]], -1)]
    for end, flip in ((idx[0], False), (idx[-1], True)):
        fan = np.stack([np.full(nt - 2, end[0]), end[1:-1], end[2:]], -1)
        faces.append(fan[:, ::-1] if flip else fan)
    body = trimesh.Trimesh(verts, np.concatenate(faces), process=True)
    if body.volume < 0:  # outward normals without trimesh.repair (which needs networkx)
        body.invert()
    house = trimesh.creation.box(extents=(0.3 * length_m, 0.55 * beam_m, 3.2))
    house.apply_translation((0.05 * length_m, 0.0, depth_m + 1.6))
    mast = trimesh.creation.box(extents=(1.2, 1.2, 5.0))
    mast.apply_translation((0.12 * length_m, 0.0, depth_m + 3.2 + 2.5))
    return trimesh.util.concatenate([body, house, mast])


def wreck(pose: dict | None = None, **hull_kw) -> trimesh.Trimesh:
    """The hull rolled, pitched, turned to its heading and sunk ``sink_m`` below z = 0 (world metres)."""
    p = {**WRECK_POSE, **(pose or {})}
    m = hull(**hull_kw)
    m.apply_translation((0.0, 0.0, -0.5 * m.bounds[1, 2]))
    rot = trimesh.transformations.euler_matrix(math.radians(p["roll_deg"]), math.radians(p["pitch_deg"]),
                                               math.radians(90.0 - p["heading_deg"]), "sxyz")
    m.apply_transform(rot)
    m.apply_translation((p["center_m"][0], p["center_m"][1], -m.bounds[0, 2] - p["sink_m"]))
    return m


def write_wreck_obj(path, pose: dict | None = None) -> None:
    """Write the posed wreck (no floor) as an OBJ with one object ``wreck`` (world metres, z up)."""
    write_obj(path, [("wreck", wreck(pose))],
              "sonar_embree procedural shipwreck (Woock & Beyerer Fig. 1-like patrol boat), metres, z up,\n"
              "posed as shipwreck.WRECK_POSE; written by scripts/make_assets.py")


def shipwreck_scene(floor: str = "perlin", size_m: float = 203.0, resolution_m: float = 0.2, seed: int = 0,
                    pose: dict | None = None) -> Scene:
    """The wreck on a ``size_m`` square seafloor, ``floor`` ∈ {"perlin", "ripples"}.

    Perlin: 0.1 m relief, 20 m features (2.06 M triangles at 0.2 m). Ripples: 0.8 m
    wavelength, 5 cm high on 0.1 m Perlin relief (resolution at most 0.2 m).
    """
    if floor == "perlin":
        f = seafloor.perlin((size_m, size_m), resolution_m=resolution_m, relief_m=0.1, seed=seed)
    elif floor == "ripples":
        f = seafloor.ripples((size_m, size_m), resolution_m=resolution_m, wavelength_m=0.8, height_m=0.05,
                             relief_m=0.1, crest_heading_deg=30.0, seed=seed)
    else:
        raise ConfigError(f"shipwreck_scene: floor must be 'perlin' or 'ripples', got {floor!r}")
    scene = Scene().add(f, label="seafloor", material=Material(-27.0))
    return scene.add(wreck(pose), label="wreck", material=Material(-15.0))


def straight_pass(n_pings: int = 1000, altitude_m: float = 12.0, ping_rate_hz: float = 10.0, speed_m_s: float = 2.0,
                  offset_m: float = 0.0) -> Trajectory:
    """A straight line along +x past the wreck (which lies to port at the default pose)."""
    half = 0.5 * (n_pings - 1) * speed_m_s / ping_rate_hz
    return Trajectory.line((-half, offset_m, altitude_m), (half, offset_m, altitude_m), n_pings,
                           speed_m_s=speed_m_s)


def curved_waypoints(length_m: float, altitude_m: float = 12.0, bend_m: float = 2.5,
                     offset_m: float = 0.0) -> np.ndarray:
    """Waypoints (5, 3) in m of a gentle S-bend along +x: lateral offsets 0, +bend, 0, −bend, 0 (y, m)."""
    x = np.linspace(-0.5 * length_m, 0.5 * length_m, 5)
    y = offset_m + bend_m * np.array([0.0, 1.0, 0.0, -1.0, 0.0])
    return np.column_stack([x, y, np.full(5, float(altitude_m))])


def curved_pass(n_pings: int = 1000, altitude_m: float = 12.0, ping_rate_hz: float = 10.0, speed_m_s: float = 2.0,
                offset_m: float = 0.0, bend_m: float = 2.5) -> Trajectory:
    """A slightly curved pass past the wreck (the paper's Fig. 9): an S-bend through
    :func:`curved_waypoints` (± ``bend_m`` across track: the heading swings ±4.3° over the
    default 200 m, ±10.6° over the 80 m of :data:`PAPER_PASS`), ``n_pings`` evenly spaced
    in arc length like :func:`straight_pass`.
    """
    length = (n_pings - 1) * speed_m_s / ping_rate_hz
    return Trajectory.through_waypoints(curved_waypoints(length, altitude_m, bend_m, offset_m), n_pings,
                                        speed_m_s=speed_m_s)

"""The embedded default scene: the paper's anchor mine (Woock & Beyerer §4.1).

A simplistic moored mine: a cube sinker on the seafloor and three spheres above
it (two small mooring floats and the mine body), passed by a sonar whose main lobe
points roughly at the mooring.
"""
from __future__ import annotations

import trimesh

from ..config import Material, Pulse, Sonar
from ..scene import Scene, seafloor, write_obj
from ..trajectory import Trajectory

#: Waterfall display of the demo: display-only TVG, 35 dB below the brightest 0.01 % (the objects),
#: so the floor is grey and the shadows show.
DEMO_PNG = {"max_columns": 540}  # the display defaults (waterfall.DISPLAY_DEFAULTS), narrower

#: Where the demo's local frame lies on the Earth (latitude, longitude; the Kiel Bight, 20 m of water): its XTF
#: carries latitude/longitude (record attribute ``geo_origin_deg``, :func:`sonar_embree.io.xtf.geographic`).
DEMO_ORIGIN_DEG = (54.45, 10.30)

#: Object positions (m): sinker cube edge 1 m; spheres (centre, radius).
MINE_GROUND_RANGE_M = 24.0
SINKER = {"center": (0.0, -MINE_GROUND_RANGE_M, 0.5), "edge": 1.0}
SPHERES = (("float_low", (0.0, -MINE_GROUND_RANGE_M, 2.0), 0.25),
           ("float_high", (0.0, -MINE_GROUND_RANGE_M, 3.2), 0.25),
           ("mine", (0.0, -MINE_GROUND_RANGE_M, 4.8), 0.6))


def anchor_mine_objects():
    """(label, trimesh.Trimesh, Material) of the mine's parts, world metres."""
    cube = trimesh.creation.box(extents=(SINKER["edge"],) * 3)
    cube.apply_translation(SINKER["center"])
    out = [("sinker", cube, Material(backscatter_db=-15.0))]
    for label, centre, radius in SPHERES:
        s = trimesh.creation.icosphere(subdivisions=4, radius=radius)
        s.apply_translation(centre)
        out.append((label, s, Material(backscatter_db=-15.0)))
    return out


def anchor_mine_scene(seed: int = 0) -> Scene:
    """The anchor-mine scene on a gently undulating (Perlin, 0.3 m) sandy floor."""
    scene = Scene()
    scene.add(seafloor.perlin(size_m=(120.0, 120.0), resolution_m=0.5, relief_m=0.3, feature_m=30.0,
                              seed=seed), material=Material(backscatter_db=-27.0), label="seafloor")
    for label, mesh, mat in anchor_mine_objects():
        scene.add(mesh, material=mat, label=label)
    return scene


#: The demo's speed, m/s: slow enough that its pings are 2R/c apart at least (R = 40 m).
DEMO_SPEED_M_S = 1.5


def anchor_mine_setup(n_pings: int = 240):
    """Scene, straight trajectory at 10 m altitude and 1.5 m/s (3 knots: 240 pings 67 ms apart, more than the
    53 ms the echoes of 40 m take), default sonar and 100 µs CW pulse."""
    traj = Trajectory.line(start=(-12.0, 0.0, 10.0), end=(12.0, 0.0, 10.0), n_pings=n_pings, speed_m_s=DEMO_SPEED_M_S)
    return anchor_mine_scene(), traj, Sonar(max_range_m=40.0), Pulse.cw(duration_s=100e-6, taper=0.1)


def write_anchor_mine_obj(path) -> None:
    """Write the mine (without seafloor) as a multi-object OBJ, one named object per part."""
    write_obj(path, [(label, mesh) for label, mesh, _ in anchor_mine_objects()],
              "sonar_embree anchor-mine test scene (Woock & Beyerer 4.1), metres, z up\n"
              "written by scripts/make_assets.py (sonar_embree.runs.demo.write_anchor_mine_obj)")


def write_moored_mine_obj(path) -> None:
    """Write the mine moved so its sinker stands on the origin (for placing instances: ``moored_mine.obj``)."""
    shift = (-SINKER["center"][0], -SINKER["center"][1], 0.0)
    parts = []
    for label, mesh, _ in anchor_mine_objects():
        m = mesh.copy()
        m.apply_translation(shift)
        parts.append((label, m))
    write_obj(path, parts, "sonar_embree moored mine: the anchor-mine parts with the sinker on the origin, "
              "metres, z up\nwritten by scripts/make_assets.py (sonar_embree.runs.demo.write_moored_mine_obj)")

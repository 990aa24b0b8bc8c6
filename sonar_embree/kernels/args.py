"""Named groups of a kernel's arguments (namedtuples of arrays and numbers, which Numba passes and caches as it
does arrays): a kernel reads ``fan.s``, ``out.weight``, … instead of its 20th positional argument.

Each group is what one stage hands the next; a kernel unpacks the fields it reads at its top.
"""
from __future__ import annotations

from collections import namedtuple

#: A block's fan: azimuth direction cosines s (n_az,) and their spacing ds (float, or per line), the elevation
#: rays' cos β, sin β and cell width dβ (n,), and the rows' first rays el_start (rows + 1,).
Fan = namedtuple("Fan", "s ds cos_beta sin_beta dbeta el_start")
#: A block's poses: body-to-world rotations rot (pings, 3, 3), sonar positions pos (pings, 3, m, local frame),
#: motion during the ping rx_shift (pings,) (δ = 2·v_fwd/c).
Poses = namedtuple("Poses", "rot pos rx_shift")
#: The scene's arrays in its local frame: vertices (v, 3) float64, faces (f, 3) int32, face_normals (f, 3),
#: face_two_sided (f,) bool.
SceneArrays = namedtuple("SceneArrays", "vertices faces face_normals face_two_sided")
#: What a hit's weight needs: the beam (k·lx/2, k·ly/2, tilt rad, 0), two-way absorption (Np/m), the near-field
#: range bound and range window (m), the cap on |dR/dβ| (m/rad) and the two-way time per metre 2/c (s/m) or, for
#: curved rays, the one-way time window t_max (s) and the sonar's sound speed c_nom (m/s).
Weighting = namedtuple("Weighting", "beam two_way_np_per_m min_range_m max_range_m slope_cap_m_rad time_per_m")
ArcWeighting = namedtuple("ArcWeighting", "beam two_way_np_per_m min_range_m t_max slope_cap_m_rad c_nom")
#: A kernel's echo outputs, one row per ray: range (m), travel time (s), travel-time extent (s), weight, cos θi,
#: and the hit points (n, 3) (or (0, 3): not wanted).
EchoOut = namedtuple("EchoOut", "range time extent weight cos points")


def scene_arrays(compiled) -> SceneArrays:
    """The :data:`SceneArrays` of a compiled scene."""
    return SceneArrays(compiled.vertices, compiled.faces, compiled.face_normals, compiled.face_two_sided)

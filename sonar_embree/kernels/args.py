"""Named groups of a kernel's arguments (namedtuples of arrays and numbers, which Numba passes and caches as it
does arrays): a kernel reads ``fan.s``, ``out.weight``, … instead of its 20th positional argument.

Each group is what one stage hands the next; a kernel unpacks the fields it reads at its top.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

#: A block's fan: azimuth direction cosines s (n_az,) and their spacing ds (float, or per line), the elevation
#: rays' cos β, sin β and cell width dβ (n,), and the rows' first rays el_start (rows + 1,).
Fan = namedtuple("Fan", "s ds cos_beta sin_beta dbeta el_start")
#: A block's poses: body-to-world rotations rot (pings, 3, 3), sonar positions pos (pings, 3, m, local frame),
#: motion during the ping rx_shift (pings,) (δ = 2·v_fwd/c).
Poses = namedtuple("Poses", "rot pos rx_shift")
#: The scene's arrays in its local frame: vertices (v, 3) float64, faces (f, 3) int32, face_normals (f, 3),
#: face_two_sided (f,) bool.
SceneArrays = namedtuple("SceneArrays", "vertices faces face_normals face_two_sided")
#: What a sea-surface path's weight needs (the beam's gains come after its kernel): two-way absorption (Np/m), the
#: near-field range bound and range window (m), the cap on |dR/dβ| (m/rad) and the two-way time per metre 2/c (s/m).
Weighting = namedtuple("Weighting", "two_way_np_per_m min_range_m max_range_m slope_cap_m_rad time_per_m")
#: What a direct hit's weight needs (its beam is applied after the kernel): the baffle's tilt (rad), then as
#: :data:`Weighting`; for curved rays the one-way time window t_max (s) and the sonar's sound speed c_nom (m/s)
#: in place of the range window and 2/c.
DirectWeighting = namedtuple("DirectWeighting",
                             "tilt_rad two_way_np_per_m min_range_m max_range_m slope_cap_m_rad time_per_m")
ArcWeighting = namedtuple("ArcWeighting", "tilt_rad two_way_np_per_m min_range_m t_max slope_cap_m_rad c_nom")
#: A block's direct hits, aligned with its rays: slant range (n,) (m, inf: none), hit points (n, 3) (local frame,
#: m) and triangles (n,) int32.
Hits = namedtuple("Hits", "range point prim")
#: The one-bounce paths' surface and law: the surface height z_s (local, m), k·h_w, Lambert's μ per object (or
#: empty: σ left to the caller), face_object (f,) int32, and whether to write the bistatic azimuth and the legs.
Bistatic = namedtuple("Bistatic", "z_s wave_kh mu_obj face_object want_phi want_legs")
#: The one-bounce outputs, one row per ray: time, extent, weight, cos θi, cos θs, φ (n,), v (n, 3), leg1 (n,),
#: u2 (n, 3), leg2 (n,).
MixedOut = namedtuple("MixedOut", "time extent weight cos_i cos_s phi v leg1 u2 leg2")
#: The legs to check for blocking: hit points (n, 3) and sonar positions (pings, 3) (local frame, m), whether legs
#: start at the sonar, their unit directions (n, 3) and lengths (n,) (m), the echoes' weights (n,) and triangles
#: (n,) or (0,) int32, whether an echo's own height field seen from above is passed over, the offset from each end.
Legs = namedtuple("Legs", "point pos from_sonar dir length weight prim free_own eps")
#: Boxes that hold the scene: lo, hi (k, 3) (local frame, m), the height-field object of each (k,) int32 (−1: none)
#: and its steepest slope (k,) (tan).
Boxes = namedtuple("Boxes", "lo hi obj slope")
#: The legs to cast: each leg's span start, end (n,) (m), and the cast legs' indices (n,) int64, origins and
#: directions (n, 3) float32 and lengths (n,) float32.
LegOut = namedtuple("LegOut", "start end idx org dir length")
#: A block's echoes for speckle: row offsets (channels·pings + 1,), hit points (n, 3) (local frame, m), the local
#: frame's world origin (3,), each echo's weight, two-way travel time (s) and its extent (s) (n,), and the rows'
#: along-track strips: each row's forward axis times the fan's line spacing (rows, 3) (world, rad; (0, 3): none),
#: its along-track two-way pattern and that pattern's receive factor alone (rows, n_tab) on s = s0 + k·step, s0 and
#: step (propagation.echoes.AlongTrack), and which echoes lie on them (n,) bool ((0,): all), then the receive
#: pattern across track for receivers off the reference's along-track line (the four fields of :data:`Across`;
#: default: none) (kernels.speckle_block).
SpeckleEchoes = namedtuple("SpeckleEchoes", "ray_start points origin weights times extents axis gain gain_rx s0 step "
                                            "on_strip side across v0 v_step")
#: The receive pattern across track, for receiver arrays whose elements lie off the reference receiver's along-track
#: line (docs/physics.md §18a): each row's unit across axis v̂ (rows, 3) (world; (0, 3): none), the pattern's across
#: factor as an amplitude |Γ(v)| (n,) on v = v0 + k·v_step, v0 and v_step. (Flat in SpeckleEchoes: a parallel
#: kernel's arguments may not nest tuples.)
Across = namedtuple("Across", "side across v0 v_step")
#: No receive pattern across track: the elements take the reference receiver's.
NO_ACROSS = Across(np.zeros((0, 3)), np.zeros(2), -1.0, 2.0)
SpeckleEchoes.__new__.__defaults__ = tuple(NO_ACROSS)
#: Each ping's transmitting position (pings, 3) and receiving positions (pings, channels·receivers, 3) (world, m),
#: the receivers' velocity (pings, 3), the receiver the echoes' times were made for (pings, 3) and the travel time
#: per metre of path (1/c; 0: the receivers' own delays ignored), see kernels.speckle_block.
PathEnds = namedtuple("PathEnds", "tx rx vel_rx rx_ref time_per_m")
#: The frozen scatterer lattice: seed (int), spacing (m), acoustic wavelength (m), scatterers per node.
Lattice = namedtuple("Lattice", "seed cell_m wavelength_m n_sub")
#: A waveform table (as for kernels.splat_table: table, its first sample's offset, its rate per output sample), the
#: output samples per second of travel time and extra carrier cycles per second.
Waveform = namedtuple("Waveform", "table table_start table_rate rate_hz phase_cycles_per_s")
#: Speckle's hash tables, node lists and last-cell caches (kernels.gather_nodes), one per thread task.
NodeTables = namedtuple("NodeTables", "slots epochs nodes node_key caches")
#: Rays' footprints on a surface, for labels: range (n,) (m), extent (n,) (m), object (n,) int32, point (n, 3)
#: (local frame, m) and the unit direction of the footprint's line (n, 3).
Footprints = namedtuple("Footprints", "range extent object point dir")
#: Per-sample labels: kind (rows, n_s) int8, object_id and shadow_of (rows, n_s) int32, height and ground (rows,
#: n_s) float32.
LabelOut = namedtuple("LabelOut", "kind object_id shadow_of height ground")
#: A curved fan's direct hits for the surface's paths: point (n, 3) (local, m), triangle (n,) int32, unit direction of
#: arrival (n, 3), path length (n,) float32 (m), two-way time and extent (n,) (s), lit (n,) bool.
CurvedHits = namedtuple("CurvedHits", "point prim arrival path time extent lit")
#: Each ray's cell dβ (n,) (rad) and its row (n,) int64 (2·ping + side).
Launch = namedtuple("Launch", "dbeta row")
#: A profile as the eigenray kernels read it: knots from depth 0 (m), speeds (m/s), and the surface's local z (m).
Medium = namedtuple("Medium", "z c z_s")
#: What a curved one-bounce echo's weight needs (the beam's gains come after it): two-way absorption (Np/m), the
#: fan's ds, R_min (m), k·h_w, and whether to write the bistatic azimuth.
MixedWeighting = namedtuple("MixedWeighting", "two_way_np_per_m ds min_range_m wave_kh want_phi")
#: A swell's bounced rays (kernels.swell_paths): each row's entries ``up_start`` (rows + 1,) into ``up`` (m,) (the image
#: fan's ray of each entry) and the image fan's rows of rays ``ray_start`` (rows + 1,); per entry the launch direction
#: u, surface point p and mirrored direction ur (m, 3) float64; per image-fan ray the surface distance t1 (n,)
#: float32 (m) and facet prim_s (n,) int32; per entry the scene triangle prim (m,) int32 (−1: none), its distance
#: t2 (m,) float32 (m) from the bounced ray's origin and ``seen`` (m,) (> 0: S → P clear); the surface mesh's normals
#: (f_s, 3) and the bounced rays' origin offset eps (m) along ur.
Bounce = namedtuple("Bounce", "up_start up ray_start u p ur t1 prim_s prim t2 seen surface_normals eps")
#: The swell's paths, one row per entry: X (m, 3) (local, m); one bounce w1, time1, ext1; two bounces w2, time2, ext2;
#: cos θi, cos θs, φ (m,); the direct leg X → S: unit direction (m, 3) and length r (m,) (m).
SwellOut = namedtuple("SwellOut", "x w1 time1 ext1 w2 time2 ext2 cos_i cos_s phi leg r")
#: A kernel's echo outputs, one row per ray: range (m), travel time (s), travel-time extent (s), weight, cos θi,
#: and the hit points (n, 3) (or (0, 3): not wanted).
EchoOut = namedtuple("EchoOut", "range time extent weight cos points")


def scene_arrays(compiled) -> SceneArrays:
    """The :data:`SceneArrays` of a compiled scene."""
    return SceneArrays(compiled.vertices, compiled.faces, compiled.face_normals, compiled.face_two_sided)

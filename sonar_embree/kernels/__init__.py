"""Numba kernels, grouped by stage: array in, array out, into buffers the caller allocated.

- :mod:`.rays`: the side-scan fan (ray placement, directions, propagation per hit) — front end;
- :mod:`.aim`: the rays aimed at objects (their lattices, directions, echoes, the fan hits they replace) — front end;
- :mod:`.splat`: footprint splatting — back end, expected intensity;
- :mod:`.speckle`: the frozen scatterer lattice and its synthesis — back end, speckle;
- :mod:`.truth`: ground-truth labels of the centre line;
- :mod:`.multipath`: the one- and two-bounce surface paths of a block, and merging paths — front end;
- :mod:`.swell`: the same paths off a meshed surface, between and after its Embree casts — front end;
- :mod:`.refraction`: curved rays in a sound-speed profile, chord by chord — front end;
- :mod:`.eigenrays`: the rays from the sonar by the sea surface to a point, in a profile — front end;
- :mod:`.curved_swell`: a swell's bounced rays over a profile in closed form, and the direct legs back — front end;
- :mod:`.sas`: time-domain backprojection of receiver-array records (synthetic aperture) — image formation;
- :mod:`.args`: named groups of kernel arguments (a block's fan, its poses, the scene's arrays, the outputs).

:mod:`._numba` is the only module that imports numba (the scattering laws take ``njit`` and ``prange``
from here). Kernels read no global state (named constants only), allocate nothing but a chunk's scratch (the
plain functions ``visibility_legs`` and ``label_rows`` allocate their stages' scratch), draw no random numbers and
skip (never wrap) indices outside the buffer. Each has a naive NumPy twin in ``tests/naive.py`` or a closed-form
reference in its tests (the curved swell's: the circular arcs of a linear profile). Compiled code is cached on
disk.
"""
from . import args
from ._numba import NO_LAYOUT, REFIT_MIN_COS, REFIT_REL_TOL, max_threads, njit, num_threads, prange, set_num_threads
from .eigenrays import (EIGEN_WIDTH, M_COS_I, M_COS_S, M_EXT, M_PHI, M_T, M_U2, M_W, M_XUP, MIX_WIDTH, curved_mixed,
                        surface_eigenrays, surface_reach)
from .curved_swell import direct_eigenrays, swell_bounce, swell_tubes, swell_up_legs
from .multipath import count_lit, merge_lit, mixed_legs, two_bounce, visibility_legs
from .refraction import (HIT_WIDTH, RAY_WIDTH, S_L, STATE_WIDTH, arc_advance, arc_chord, arc_echoes, arc_land,
                         arc_start, arc_start_at)
from .bvh import (DeviceBvh, cuda_available, lbvh_boxes, lbvh_children, morton_codes, traverse_cpu)
from .rays import (BEAM_GAUSS, BEAM_SINC, _sinc, beam_cosines, beam_factor, factor_rows, cos_sin,
                   elevation_density, fan_echoes, fan_rays, place_rows, probe_rays, sinc_rows, weigh_fan,
                   weigh_lines, weigh_pairs, weigh_rays, launch_body)
from .sas import backproject
from .speckle import CACHE_WIDTH, NODE_WIDTH, frozen_scatterers, gather_nodes, speckle_block, speckle_block_shared
from .splat import splat_rows, splat_table
from .swell import (G_HB, G_HS, G_NB, G_NS, G_S0, G_B0, G_STRIP, GLINT_WIDTH, glint_rays, swell_glints, swell_launch,
                    swell_paths, swell_surface_hits)
from .truth import label_rows

__all__ = ["direct_eigenrays", "swell_bounce", "swell_tubes", "swell_up_legs", "arc_start_at", "backproject", "DeviceBvh", "cuda_available", "lbvh_boxes", "lbvh_children", "morton_codes", "traverse_cpu", "EIGEN_WIDTH", "M_COS_I", "M_COS_S", "M_EXT", "M_PHI", "M_T", "M_U2", "M_W", "M_XUP", "MIX_WIDTH", "curved_mixed", "surface_eigenrays", "surface_reach", "NO_LAYOUT", "HIT_WIDTH", "RAY_WIDTH", "S_L", "STATE_WIDTH", "arc_advance", "arc_chord", "arc_echoes", "arc_land", "arc_start", "CACHE_WIDTH", "NODE_WIDTH", "REFIT_MIN_COS", "REFIT_REL_TOL", "cos_sin", "elevation_density", "fan_echoes", "fan_rays",
           "frozen_scatterers", "gather_nodes", "label_rows", "count_lit", "merge_lit", "mixed_legs", "two_bounce", "visibility_legs", "njit", "max_threads", "num_threads", "set_num_threads", "place_rows", "probe_rays", "prange", "speckle_block", "speckle_block_shared", "splat_rows",
           "splat_table", "G_HB", "G_HS", "G_NB", "G_NS", "G_S0", "G_B0", "G_STRIP", "GLINT_WIDTH", "glint_rays",
           "swell_glints", "swell_launch", "swell_paths", "swell_surface_hits", "_sinc", "sinc_rows",
           "beam_cosines", "weigh_lines", "weigh_fan", "weigh_rays", "weigh_pairs", "launch_body",
           "BEAM_SINC", "BEAM_GAUSS",
           "beam_factor", "factor_rows"]

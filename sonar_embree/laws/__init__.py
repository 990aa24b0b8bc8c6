"""Scattering laws, backscatter maps and texture: the surface's response (docs/physics.md §10).

A law is a frozen dataclass with

- ``sigma(cos_i, cos_s, phi_rad)``: the bistatic cross-section in NumPy (θ from the
  surface normal, φ the scattered direction's azimuth away from the backscatter
  direction: φ = 0 and θs = θi is monostatic);
- ``params(data)``: the numbers its scalar σ reads, per object (at most :data:`MAX_PARAMS`;
  longer data, such as a table, go into the shared list ``data``);
- a scalar Numba ``*_sigma(params, o, cos_i, data)`` in its module: σ(θi, θi, 0)/cos θi at one hit (the ray's
  footprint dA = R²dΩ/cos θi is folded in analytically), registered in :data:`.driver.KINDS`; one driver
  (:func:`.driver.law_weights`) multiplies each echo weight by it (or adds it to a factor, for composite laws).

Laws add (``Lambert(-30) + Kirchhoff(0.5, 0.1)`` is a :class:`Composite`). On top of the
law, an object may carry a backscatter map (:mod:`.maps`: dB per face, per vertex or
from an image through UV coordinates) and its material a K-distribution texture
(:mod:`.texture`). :func:`apply_laws` (called by each sonar type's front end) runs the driver
once per term (one pass for a scene without composite laws, whatever its laws), and the map and texture
kernels only for a scene that has them.
"""
from __future__ import annotations


from .apl_uw import AplUw
from .chapman_harris import ChapmanHarris
from .clutter import Clutter
from .composite import Composite, Summable
from .kirchhoff import Kirchhoff
from .lambert import Lambert
from .small_slope import SmallSlope
from .table import MAX_PARAMS, LawTable, apply_laws, law_table
from .tabulated import Tabulated
from .texture import KTexture

#: The laws by the name a TOML ``scattering = { kind = "…", … }`` table gives.
LAWS = {"lambert": Lambert, "kirchhoff": Kirchhoff, "tabulated": Tabulated, "chapman-harris": ChapmanHarris,
        "apl-uw": AplUw, "small-slope": SmallSlope}

__all__ = ["AplUw", "ChapmanHarris", "Clutter", "Composite", "KTexture", "Kirchhoff", "LAWS", "Lambert", "LawTable", "MAX_PARAMS", "SmallSlope", "Summable",
           "Tabulated",
           "apply_laws", "law_table"]

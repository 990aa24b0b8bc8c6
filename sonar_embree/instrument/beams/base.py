"""The beam protocol: what a front end asks of a beam (:mod:`sonar_embree.instrument.beams`)."""
from __future__ import annotations

import math

import numpy as np


class Beam:
    """The beam protocol (a frozen dataclass, built from its one-way −3 dB full width and the wavelength, or for a
    side-scan from its aperture).

    Directions are unit vectors in the beam's frame: ``u_fwd`` along the aperture's first axis (along track),
    ``u_side`` along its second (across: in the side-scan's elevation plane, perpendicular to the boresight) and
    ``u_down`` along the boresight; the baffle leaves nothing where ``u_down`` ≤ 0.

    Attributes
    ----------
    first_null_rad : float
        The widest angle from the axis of the main lobe's edge (its first null, or for a pattern without nulls the
        angle a membrane of the same −3 dB width has its null at), rad: the modelled cone reaches a few of these.
    area_m2 : float
        The aperture's area, m² (directivity index, speckle cell).
    separable : bool
        Whether b = along(u_fwd)·across(u_side) in front of the baffle (rectangular apertures, Gaussian beams): a
        side-scan's beam must be, so that its fan, planned per azimuth line, weighs each line once.
    """

    first_null_rad: float
    area_m2: float
    wavelength_m: float
    separable = False
    #: (kind, q_along, q_across) of a separable beam whose one-way factors are f(q·x) of a form the kernels know
    #: (:data:`sonar_embree.kernels.BEAM_SINC`, ``BEAM_GAUSS``): the beam stages (:mod:`sonar_embree.propagation.gain`)
    #: then evaluate it in one kernel pass. None: they take :meth:`along` and :meth:`across` in NumPy (slower, the
    #: same physics); no path kernel weighs a beam itself.
    kernel_form = None

    def one_way(self, u_fwd, u_side, u_down) -> np.ndarray:
        """b of unit directions (n,) each, 0 behind the baffle (u_down ≤ 0)."""
        return np.where(np.asarray(u_down) > 0.0, self.along(u_fwd) * self.across(u_side), 0.0)

    def along(self, u) -> np.ndarray:
        """A separable beam's one-way factor along its first axis (u = u_fwd)."""
        raise NotImplementedError(f"{type(self).__name__} is not separable")

    def across(self, v) -> np.ndarray:
        """A separable beam's one-way factor along its second axis (v = u_side)."""
        raise NotImplementedError(f"{type(self).__name__} is not separable")

    def null_lines(self, u) -> np.ndarray:
        """Which along-track direction cosines ``u`` lie on a null of :meth:`along` (lines a fan leaves out: they
        weigh nothing); none for a pattern without nulls."""
        return np.zeros(np.shape(u), dtype=bool)

    @property
    def directivity_index_db(self) -> float:
        """DI = 10·log10(4π·A/λ²) of a large baffled aperture of area A, dB (Kinsler et al., §8.9; Urick, ch. 3): the
        fallback of a beam without its own pattern integral (the piston and the square have theirs)."""
        return 10.0 * math.log10(4.0 * math.pi * self.area_m2 / self.wavelength_m ** 2)

    @property
    def speckle_cell_m(self) -> float:
        """The speckle lattice's default spacing, m: half the aperture's width, √A/2 (a square's half side; the
        circular piston takes its radius)."""
        return 0.5 * math.sqrt(self.area_m2)

"""Receiver arrays: a side-scan's transmitter with N receive elements per side (docs/physics.md §18a).

Every element hears the same frozen scatterers (so speckle is coherent across the elements) along its own
bistatic path: transmitter at ping time → scatterer → element, where the element is when the echo arrives
(motion during the ping), with travel time τ_k = (|X − p_tx| + |X − p_k|)/c and carrier phase −2π·f0·τ_k. Each
element is a copy of the side's receiving membrane and hears with its pattern along its own direction to the
scatterer (along track always; across track too where the element lies off the transmitter's along-track line;
docs/physics.md §18a). Two layouts have constructors:

- :meth:`ReceiverArray.vertical`: an interferometric side-scan's receivers stacked across the face (the
  phase difference of two of them gives the angle of arrival, :mod:`sonar_embree.signal.interferometry`);
- :meth:`ReceiverArray.along_track`: a synthetic-aperture sonar's line of elements along track
  (:mod:`sonar_embree.signal.sas`).

Positions are in the side's own frame, metres from the transmitter's phase centre: ``forward`` along the vehicle's
forward axis, ``outward`` towards the side the channel looks to (starboard for starboard, port for port) and ``up``
against gravity in the vehicle's frame. Sources: the bistatic delay and the phase-difference geometry are those of
Lurton, *An Introduction to Underwater Acoustics*, 2nd ed., Springer, 2010, §8.3 (interferometric sonars), and
Hayes and Gough, "Synthetic aperture sonar: a review of current status", IEEE J. Oceanic Eng. 34(3), 2009 (the
SAS geometry: transmitter, receive array, displaced phase centres).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_number, from_table

#: Most elements per side (the record holds a complex series per element, side and ping).
MAX_ELEMENTS = 256
#: Farthest element from the transmitter, m (a towfish or AUV is a few metres long).
MAX_OFFSET_M = 10.0


@dataclass(frozen=True)
class ReceiverArray:
    """N receive elements per side at fixed offsets from the transmitter.

    Parameters
    ----------
    positions_m : sequence of (forward, outward, up) triples
        Each element's phase centre in the side's frame, m (see the module's notes); element 0 is the record's
        reference channel (its intensity is ``Record.data``'s).
    """

    positions_m: tuple = ((0.0, 0.0, 0.0),)

    def __post_init__(self):
        try:
            p = np.asarray(self.positions_m, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"ReceiverArray.positions_m must be (forward, outward, up) triples in m, got "
                              f"{self.positions_m!r}") from None
        if p.ndim != 2 or p.shape[1] != 3 or not 1 <= p.shape[0] <= MAX_ELEMENTS:
            raise ConfigError(f"ReceiverArray.positions_m must hold 1 to {MAX_ELEMENTS} (forward, outward, up) "
                              f"triples, got shape {p.shape}")
        if not np.isfinite(p).all() or np.abs(p).max() > MAX_OFFSET_M:
            raise ConfigError(f"ReceiverArray.positions_m must be finite and within {MAX_OFFSET_M:g} m of the "
                              f"transmitter, got {self.positions_m!r}")
        object.__setattr__(self, "positions_m", tuple(tuple(float(v) for v in row) for row in p))

    @classmethod
    def vertical(cls, baseline_m: float, n_elements: int = 2) -> "ReceiverArray":
        """An interferometer: ``n_elements`` receivers one above the other, ``baseline_m`` apart (m), the lowest at
        the transmitter."""
        check_number("ReceiverArray.vertical", "baseline_m", baseline_m, positive=True)
        _check_count("ReceiverArray.vertical", n_elements, 2)
        return cls(tuple((0.0, 0.0, k * float(baseline_m)) for k in range(n_elements)))

    @classmethod
    def along_track(cls, n_elements: int, spacing_m: float) -> "ReceiverArray":
        """A synthetic-aperture array: ``n_elements`` receivers along track, ``spacing_m`` apart (m), centred on the
        transmitter; element 0 is the foremost."""
        check_number("ReceiverArray.along_track", "spacing_m", spacing_m, positive=True)
        _check_count("ReceiverArray.along_track", n_elements, 1)
        mid = 0.5 * (n_elements - 1)
        return cls(tuple(((mid - k) * float(spacing_m), 0.0, 0.0) for k in range(n_elements)))

    @property
    def n_elements(self) -> int:
        return len(self.positions_m)

    def body_offsets(self, side: float) -> np.ndarray:
        """(elements, 3) offsets in the body frame (forward, starboard, down), m, for ``side`` −1 (port) or +1
        (starboard)."""
        p = np.asarray(self.positions_m)
        return np.stack([p[:, 0], side * p[:, 1], -p[:, 2]], axis=1)

    def world_positions(self, rot: np.ndarray, pos_world: np.ndarray) -> np.ndarray:
        """Every element's position per ping, port's then starboard's: (pings, 2·elements, 3) world m, from the
        transducer's body-to-world rotations ``rot`` (pings, 3, 3) and the transmitter's positions (pings, 3)."""
        body = np.concatenate([self.body_offsets(-1.0), self.body_offsets(1.0)])   # (2·elements, 3)
        return np.ascontiguousarray(pos_world[:, None, :] + np.einsum("pij,kj->pki", rot, body))


def _check_count(where: str, n, lo: int) -> None:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not lo <= n <= MAX_ELEMENTS:
        raise ConfigError(f"{where}: n_elements must be an integer in [{lo}, {MAX_ELEMENTS}], got {n!r}")


#: The layouts a table may name with ``kind``, and their constructors' keys.
KINDS = {"vertical": ("baseline_m", "n_elements"), "along_track": ("n_elements", "spacing_m")}


def receive_array_of(value):
    """A ReceiverArray from itself, None or a dict (TOML ``receive_array = {…}``, a record's metadata): either
    ``{positions_m = [[forward, outward, up], …]}`` or a layout, ``{kind = "vertical", baseline_m = …,
    n_elements = 2}`` or ``{kind = "along_track", n_elements = …, spacing_m = …}``."""
    if value is None or isinstance(value, ReceiverArray):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"Sonar.receive_array must be a sonar_embree.ReceiverArray or None, got {value!r}")
    if "kind" not in value:
        return from_table(ReceiverArray, value, "Sonar.receive_array")
    kind = value["kind"]
    if kind not in KINDS:
        raise ConfigError(f"Sonar.receive_array: unknown kind {kind!r}; one of {', '.join(KINDS)}")
    unknown = sorted(set(value) - {"kind", *KINDS[kind]})
    if unknown:
        raise ConfigError(f"Sonar.receive_array: unknown key {unknown[0]!r} for kind {kind!r}; one of "
                          f"{', '.join(KINDS[kind])}")
    return getattr(ReceiverArray, kind)(**{k: v for k, v in value.items() if k != "kind"})


__all__ = ["KINDS", "MAX_ELEMENTS", "MAX_OFFSET_M", "ReceiverArray", "receive_array_of"]

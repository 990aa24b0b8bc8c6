"""What :func:`~sonar_embree.simulate` asks of a sonar type's front end: the protocol, with its defaults.

A front end turns a block of poses into :class:`~sonar_embree.propagation.echoes.Echoes`. Every front end
derives from :class:`FrontEnd`, so each optional part of the protocol has one declared default and no stage
needs to ask whether a front end has it.
"""
from __future__ import annotations

import numpy as np


class FrontEnd:
    """The front-end protocol and its defaults (a sonar type overrides what it has).

    Attributes
    ----------
    channels : tuple of str
        The record's channels, in order.
    supports_labels : bool
        Whether ground truth can be made for it (:mod:`sonar_embree.signal.truth`).
    aims : bool
        Whether rays are aimed at the scene's objects besides the fan's (:mod:`sonar_embree.propagation.aim`).
    n_synth_channels : int or None
        Channels the back end synthesises when they differ from the record's (a beamformer's inputs: one per
        azimuth line); None: the record's channels.
    beam_power : (channels, n_synth_channels) ndarray or None
        A beamformer's power weights from synthesised channels to the record's (ground truth's object echoes
        are formed with them); None: no beamformer.
    """

    channels: tuple = ()
    supports_labels = False
    aims = False
    n_synth_channels: int | None = None
    beam_power: np.ndarray | None = None

    def cast(self, run, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float, want_points: bool,
             want_ids: bool, clock: dict, rx_shift: np.ndarray | None = None):
        """(Echoes of a block of pings, the block's fan or None) of the run ``run``
        (:class:`~sonar_embree.propagation.prepared.PreparedRun`); see :meth:`SideScanFrontEnd.cast`."""
        raise NotImplementedError(f"{type(self).__name__}.cast")

    def aim_plan(self, compiled):
        """The objects of ``compiled`` to aim rays at (an :class:`~sonar_embree.propagation.aim.AimPlan`), made
        once per run; None (default): the type aims at none."""
        return None

    @property
    def synth_channels(self) -> int:
        """Channels the back end synthesises per ping."""
        return len(self.channels) if self.n_synth_channels is None else self.n_synth_channels

    @property
    def beamforms(self) -> bool:
        """Whether the record's channels are beams formed from the synthesised channels (:meth:`beamform`)."""
        return self.beam_power is not None

    def receivers(self, rot: np.ndarray, pos_world: np.ndarray) -> np.ndarray | None:
        """Each synthesised channel's receiving position per ping, (pings, synth channels, 3) world m, for a
        receiver array (:class:`~sonar_embree.instrument.array.ReceiverArray`); None (default): every channel
        receives at the transmitter."""
        return None

    def mount(self, rot: np.ndarray, pings: np.ndarray) -> np.ndarray:
        """Body-to-world rotations of the transducer at ping indices ``pings`` from the vehicle's ``rot``
        (pings, 3, 3); default: mounted on the vehicle's axes, ``rot`` itself."""
        return rot

    def label_lines(self, plan):
        """(sides, azimuth lines) of each channel's label line in the block's fan ``plan``; None: the
        side-scan's centre lines (:func:`~sonar_embree.signal.truth.label_block`)."""
        return None

    def beamform(self, intensity: np.ndarray, cplx: np.ndarray | None, noise):
        """Beams from the synthesised channels (only where :attr:`beamforms`)."""
        raise NotImplementedError(f"{type(self).__name__} forms no beams")

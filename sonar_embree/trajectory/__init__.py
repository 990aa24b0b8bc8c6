"""Vehicle trajectories: time-stamped poses (docs/physics.md §1).

World axes: x east, y north, z up (m). Heading in degrees clockwise from north
(+y), pitch positive nose up, roll positive starboard down; attitude composes as
heading, then pitch, then roll (intrinsic z-y-x). Body axes: forward, starboard, down.
"""
from __future__ import annotations

import csv
import dataclasses
import logging
import math
import os
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_number, iso_utc  # noqa: F401 (iso_utc re-exported: its old home)
from ..io.files import atomic_write
from .motion import interpolate_poses
from .motion import jitter
from .motion import layback_positions
from .motion import track_heading_deg

# World (east, north, up) from aerospace NED (north, east, down).
_ENU_FROM_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

log = logging.getLogger(__name__)

VELOCITY_COLUMNS = ("vx_m_s", "vy_m_s", "vz_m_s")
CSV_COLUMNS = ("time_s", "x_m", "y_m", "z_m", "heading_deg", "pitch_deg", "roll_deg") + VELOCITY_COLUMNS
#: Columns of a navigation log in geographic coordinates and real time (:meth:`Trajectory.from_csv`).
GEO_CSV_COLUMNS = ("time", "lat_deg", "lon_deg", "depth_m")
#: Other names navigation logs give their columns (lower case, as read), and the column each stands for.
CSV_ALIASES = {"latitude": "lat_deg", "lat": "lat_deg", "latitude_deg": "lat_deg",
               "longitude": "lon_deg", "lon": "lon_deg", "long": "lon_deg", "lng": "lon_deg", "longitude_deg": "lon_deg",
               "depth": "depth_m", "heading": "heading_deg", "hdg": "heading_deg", "pitch": "pitch_deg",
               "roll": "roll_deg", "timestamp": "time", "datetime": "time", "utc": "time", "date_time": "time",
               "easting": "x_m", "northing": "y_m", "x": "x_m", "y": "y_m", "z": "z_m", "t": "time_s",
               "seconds": "time_s"}
#: Speed (m/s) above which a CSV trajectory's time stamps look like a unit slip: towfish and AUVs fly below 5 m/s.
IMPLAUSIBLE_SPEED_M_S = 30.0
#: Mean speed over ground (m/s) below which a moving log's time stamps look like a unit slip the other way
#: (milliseconds typed as seconds): survey vehicles make way at 0.5–5 m/s.
SLOW_SPEED_M_S = 0.05


def body_to_world(heading_deg, pitch_deg, roll_deg):
    """Rotation matrices taking body (forward, starboard, down) vectors to world (x, y, z).

    Parameters
    ----------
    heading_deg, pitch_deg, roll_deg : (n,) float
        Attitude angles in degrees.

    Returns
    -------
    (n, 3, 3) float
        ``R[i] @ v_body`` is ``v`` in world axes; columns are the body axes.
    """
    h, p, r = (np.radians(np.asarray(a, dtype=np.float64)) for a in (heading_deg, pitch_deg, roll_deg))
    ch, sh, cp, sp, cr, sr = np.cos(h), np.sin(h), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    n = h.shape[0]
    m = np.empty((n, 3, 3))
    # Standard aerospace R_nb = Rz(h) Ry(p) Rx(r) in NED.
    m[:, 0, 0] = ch * cp
    m[:, 0, 1] = ch * sp * sr - sh * cr
    m[:, 0, 2] = ch * sp * cr + sh * sr
    m[:, 1, 0] = sh * cp
    m[:, 1, 1] = sh * sp * sr + ch * cr
    m[:, 1, 2] = sh * sp * cr - ch * sr
    m[:, 2, 0] = -sp
    m[:, 2, 1] = cp * sr
    m[:, 2, 2] = cp * cr
    return np.einsum("ij,njk->nik", _ENU_FROM_NED, m)


def _fix_times(value, times_s: np.ndarray) -> np.ndarray:
    """``fix_times_s`` checked against the ping times: one per ping, none after its ping, never decreasing."""
    fix = _as_float_array("fix_times_s", value, times_s.size)
    if np.any(fix > times_s + 1e-9) or np.any(np.diff(fix) < 0.0):
        raise ConfigError("Trajectory.fix_times_s must not decrease and no fix may come after its ping")
    return fix


def _check_n_pings(where: str, n_pings) -> None:
    if isinstance(n_pings, bool) or not isinstance(n_pings, (int, np.integer)) or n_pings < 1:
        raise ConfigError(f"Trajectory.{where} n_pings must be an integer >= 1, got {n_pings!r}")


def _as_float_array(name, value, n=None):
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"Trajectory.{name} must be numeric, got {value!r}") from None
    if n is not None:
        if a.ndim == 0:
            a = np.full(n, float(a))
        if a.shape != (n,):
            raise ConfigError(f"Trajectory.{name} must have shape ({n},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"Trajectory.{name} contains NaN or inf")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses of the sonar at each ping.

    Parameters
    ----------
    positions_m : (n, 3) float
        Transducer positions in world metres (x east, y north, z up).
    heading_deg : (n,) float or float
        Heading, degrees clockwise from north.
    pitch_deg, roll_deg : (n,) float or float
        Pitch (nose up +) and roll (starboard down +) in degrees.
    times_s : (n,) float or None
        Ping times in s, strictly increasing; ``None`` means one ping per second.
    velocity_m_s : (n, 3) float or None
        The vehicle's velocity at each ping, world m/s, when known (:meth:`survey`, :meth:`line` and
        :meth:`through_waypoints` set it from their speed): then the sonar moves during each ping
        (docs/physics.md §16). ``None`` (a bare or CSV trajectory): stop-and-hop.
    crs : int or str or None
        The projected CRS of the positions (an EPSG code or a CRS string, metres; :mod:`sonar_embree.io.geo`),
        stored as "EPSG:…"; ``None``: local metres.
    start_time : datetime or str or None
        The UTC time of ``times_s`` = 0 (ISO 8601), when known (navigation logs): :func:`~sonar_embree.simulate`
        takes it as the record's start time unless given one.
    ship_positions_m : (n, 3) float or None
        Where the ship (its GPS antenna) is at each ping when the sonar is towed behind it (:meth:`with_layback`),
        world m; ``None``: the sonar is where the navigation is (hull mount, AUV). XTF writes it as the Ship
        coordinates.
    fix_times_s : (n,) float or None
        The time (s, this trajectory's clock) of the navigation fix each ping's logged position comes from: the
        last fix of the log at or before the ping (:meth:`resampled` sets it from a log's own times). A device
        logs that fix's time and position until the next fix comes (XTF FixTime; :mod:`sonar_embree.io.xtf`),
        while the sonar itself moves on. ``None``: every ping is its own fix.
    """

    positions_m: np.ndarray
    heading_deg: np.ndarray = 0.0
    pitch_deg: np.ndarray = 0.0
    roll_deg: np.ndarray = 0.0
    times_s: np.ndarray | None = None
    velocity_m_s: np.ndarray | None = None
    crs: str | None = None
    start_time: str | None = None
    ship_positions_m: np.ndarray | None = None
    fix_times_s: np.ndarray | None = None

    def __post_init__(self):
        pos = _as_float_array("positions_m", self.positions_m)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ConfigError(f"Trajectory.positions_m must have shape (n, 3), got {pos.shape}")
        n = pos.shape[0]
        if n < 1:
            raise ConfigError("Trajectory needs at least one pose, got 0")
        object.__setattr__(self, "positions_m", pos)
        for name in ("heading_deg", "pitch_deg", "roll_deg"):
            object.__setattr__(self, name, _as_float_array(name, getattr(self, name), n))
        for name in ("pitch_deg", "roll_deg"):
            if np.any(np.abs(getattr(self, name)) >= 90.0):
                raise ConfigError(f"Trajectory.{name} must lie in (-90, 90) degrees")
        t = np.arange(n, dtype=np.float64) if self.times_s is None else self.times_s
        t = _as_float_array("times_s", t, n)
        if n > 1 and np.any(np.diff(t) <= 0):
            raise ConfigError("Trajectory.times_s must be strictly increasing")
        object.__setattr__(self, "times_s", t)
        if self.velocity_m_s is not None:
            v = _as_float_array("velocity_m_s", self.velocity_m_s)
            if v.shape != (n, 3):
                raise ConfigError(f"Trajectory.velocity_m_s must have shape ({n}, 3), got {v.shape}")
            object.__setattr__(self, "velocity_m_s", v)
        if self.ship_positions_m is not None:
            ship = _as_float_array("ship_positions_m", self.ship_positions_m)
            if ship.shape != (n, 3):
                raise ConfigError(f"Trajectory.ship_positions_m must have shape ({n}, 3), got {ship.shape}")
            object.__setattr__(self, "ship_positions_m", ship)
        if self.fix_times_s is not None:
            object.__setattr__(self, "fix_times_s", _fix_times(self.fix_times_s, t))
        if self.crs is not None:
            from ..io.geo import crs_name

            object.__setattr__(self, "crs", crs_name(self.crs))
        if self.start_time is not None:
            object.__setattr__(self, "start_time", iso_utc(self.start_time))

    def __len__(self) -> int:
        return self.positions_m.shape[0]

    def __repr__(self) -> str:
        """A summary (pings, span, times, CRS), not every array: a long line prints in one line."""
        lo, hi = self.positions_m.min(axis=0), self.positions_m.max(axis=0)
        span = ", ".join(f"{a:.6g}…{b:.6g}" for a, b in zip(lo, hi))
        extra = [f"crs={self.crs}"] if self.crs else []
        extra += [f"start_time={self.start_time}"] if self.start_time else []
        extra += ["moving during the ping"] if self.velocity_m_s is not None else []
        extra += ["towed (ship positions)"] if self.ship_positions_m is not None else []
        extra += ["navigation fixes held between pings"] if self.fix_times_s is not None else []
        t = self.times_s
        return (f"Trajectory({len(self)} pings, x/y/z {span} m, t {t[0]:.6g}…{t[-1]:.6g} s"
                + "".join(", " + e for e in extra) + ")")

    def __getitem__(self, index) -> "Trajectory":
        """The poses of a slice of pings (``traj[a:b]``), as a trajectory; times are kept."""
        if not isinstance(index, slice):
            raise ConfigError(f"Trajectory takes slices of pings (traj[a:b]), got {index!r}")
        idx = np.arange(len(self))[index]
        if idx.size == 0:
            raise ConfigError(f"Trajectory slice {index} selects no ping of {len(self)}")
        return Trajectory(self.positions_m[idx], self.heading_deg[idx], self.pitch_deg[idx], self.roll_deg[idx],
                          self.times_s[idx], None if self.velocity_m_s is None else self.velocity_m_s[idx],
                          self.crs, self.start_time,
                          None if self.ship_positions_m is None else self.ship_positions_m[idx],
                          None if self.fix_times_s is None else self.fix_times_s[idx])

    @classmethod
    def concatenate(cls, parts) -> "Trajectory":
        """Consecutive pieces of one trajectory, joined."""
        parts = list(parts)
        if len({(p.crs, p.start_time) for p in parts}) > 1:
            raise ConfigError("Trajectory.concatenate: the pieces differ in CRS or start time")
        def joined(name):
            return (np.concatenate([getattr(p, name) for p in parts])
                    if all(getattr(p, name) is not None for p in parts) else None)

        return cls(*(joined(k) for k in ("positions_m", "heading_deg", "pitch_deg", "roll_deg", "times_s",
                                         "velocity_m_s")), parts[0].crs, parts[0].start_time,
                   joined("ship_positions_m"), joined("fix_times_s"))

    def __eq__(self, other) -> bool:
        if not isinstance(other, Trajectory):
            return NotImplemented
        return (self.crs, self.start_time) == (other.crs, other.start_time) and all(
            np.array_equal(getattr(self, k), getattr(other, k))
            for k in ("positions_m", "heading_deg", "pitch_deg", "roll_deg", "times_s", "velocity_m_s",
                      "ship_positions_m", "fix_times_s"))

    @property
    def n_pings(self) -> int:
        return len(self)

    def rotations(self) -> np.ndarray:
        """Body-to-world rotation per ping, (n, 3, 3)."""
        return body_to_world(self.heading_deg, self.pitch_deg, self.roll_deg)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def line(cls, start, end, n_pings: int, *, speed_m_s: float = 2.0, pitch_deg=0.0,
             roll_deg=0.0, heading_deg=None) -> "Trajectory":
        """Evenly spaced pings on the straight line from ``start`` to ``end`` (m).

        The heading follows the line (90° for a line along +x) unless given;
        ping times and the velocity (motion during the ping, docs/physics.md §16) follow from ``speed_m_s``.
        """
        _check_n_pings("line", n_pings)
        if not (isinstance(speed_m_s, (int, float)) and math.isfinite(speed_m_s) and speed_m_s > 0):
            raise ConfigError(f"Trajectory.line speed_m_s must be > 0, got {speed_m_s!r}")
        a = _as_float_array("line start", start)
        b = _as_float_array("line end", end)
        if a.shape != (3,) or b.shape != (3,):
            raise ConfigError("Trajectory.line start and end must be (x, y, z) triples")
        d = b - a
        if heading_deg is None:
            if math.hypot(d[0], d[1]) == 0.0:
                if n_pings > 1:
                    raise ConfigError("Trajectory.line: start and end have the same x, y; give heading_deg")
                heading_deg = 0.0
            else:
                heading_deg = math.degrees(math.atan2(d[0], d[1])) % 360.0
        u = np.linspace(0.0, 1.0, n_pings)
        pos = a[None, :] + u[:, None] * d[None, :]
        length = float(np.linalg.norm(d))
        times = u * length / speed_m_s
        velocity = None  # known only when the line has a length: the vehicle moves at speed_m_s along it
        if length > 0.0:
            velocity = np.broadcast_to(d / length * speed_m_s, pos.shape)
        elif n_pings > 1:
            times = np.arange(n_pings, dtype=np.float64)
        return cls(pos, heading_deg, pitch_deg, roll_deg, times, velocity)

    @classmethod
    def through_waypoints(cls, waypoints_m, n_pings: int, *, speed_m_s: float = 2.0,
                          pitch_deg=0.0, roll_deg=0.0) -> "Trajectory":
        """A smooth path through ``waypoints_m`` ((m, 3), m ≥ 2) sampled evenly in arc length.

        A cubic spline in chord-length parameter (straight for two waypoints); the
        heading follows the horizontal tangent, the velocity is ``speed_m_s`` along the tangent.
        """
        _check_n_pings("through_waypoints", n_pings)
        length, sample = _path(waypoints_m, "through_waypoints", 20 * n_pings)
        s = np.linspace(0.0, length, n_pings)
        pos, heading, tangent = sample(s, True)
        if n_pings == 1:
            return cls(pos, heading, pitch_deg, roll_deg, None)
        return cls(pos, heading, pitch_deg, roll_deg, s / speed_m_s, speed_m_s * tangent)

    @classmethod
    def survey(cls, waypoints_m, speed_m_s: float, ping_rate_hz: float | None = None, *, sonar=None,
               pitch_deg=0.0, roll_deg=0.0, crs=None, start_time=None,
               sound_speed_m_s: float = 1500.0) -> "Trajectory":
        """Pings timed by a ping rate along a path flown at a speed (docs/physics.md §16).

        The path is that of :meth:`through_waypoints`; ping k is at arc length k·v/PRF and time k/PRF, so the
        path's length and the speed set the number of pings. ``ping_rate_hz`` None: back to back, one ping
        every 2·R_max/c of ``sonar``; a rate faster than that is refused (the next ping would transmit
        before the last echo of this one is in).

        Parameters
        ----------
        waypoints_m : (m, 3) float
            The path, world m.
        speed_m_s : float
            Speed over the path, m/s.
        ping_rate_hz : float or None
            Pings per second.
        sonar : Sonar, EchoSounder, MSIS or ForwardLooking, optional
            Its range window limits (and by default sets) the ping rate, at ``sound_speed_m_s``.
        sound_speed_m_s : float
            The water's speed of sound c, m/s (default: the default :class:`~sonar_embree.Environment`'s).
        crs, start_time : optional
            The waypoints' projected CRS and the UTC time of the first ping, kept on the trajectory (as in
            the constructor).
        """
        if not (isinstance(speed_m_s, (int, float)) and math.isfinite(speed_m_s) and 0 < speed_m_s <= 50):
            raise ConfigError(f"Trajectory.survey speed_m_s must be in (0, 50] m/s, got {speed_m_s!r}")
        check_number("Trajectory.survey", "sound_speed_m_s", sound_speed_m_s, positive=True)
        prf = _ping_rate(ping_rate_hz, sonar, sound_speed_m_s)
        length, sample = _path(waypoints_m, "survey", 2000)
        n = int(math.floor(length * prf / speed_m_s * (1 + 1e-12))) + 1
        if n > 50_000_000:
            raise ConfigError(f"Trajectory.survey: {n} pings; split the path or lower the ping rate")
        t = np.arange(n) / prf
        pos, heading, tangent = sample(t * speed_m_s, True)
        return cls(pos, heading, pitch_deg, roll_deg, t if n > 1 else None, speed_m_s * tangent, crs, start_time)

    def with_motion(self, motion, seed: int = 0) -> "Trajectory":
        """This trajectory with the attitude and heave jitter of ``motion`` (:class:`~sonar_embree.Motion`)
        added at its ping times, frozen by ``seed``."""
        d = jitter(motion, self.times_s, seed)
        pos = self.positions_m.copy()
        pos[:, 2] += d["heave_m"]
        return dataclasses.replace(self, positions_m=pos, heading_deg=(self.heading_deg + d["yaw_deg"]) % 360.0,
                                   pitch_deg=self.pitch_deg + d["pitch_deg"], roll_deg=self.roll_deg + d["roll_deg"])

    def stop_and_hop(self) -> "Trajectory":
        """This trajectory without its velocity: the sonar stands still during each ping (the paper's model and
        the closed forms of docs/physics.md §3; motion during the ping, §16, switched off)."""
        return dataclasses.replace(self, velocity_m_s=None)

    def at_times(self, times_s) -> "Trajectory":
        """The poses at ``times_s`` (s on this trajectory's clock, strictly increasing, within its first and last
        time), interpolated as :func:`~sonar_embree.trajectory.motion.interpolate_poses` does (positions by PCHIP
        through the fixes, heading along the shorter turn, the rest linearly); the CRS and start time are kept. At the
        trajectory's own times the poses are its own."""
        t = _as_float_array("times_s", times_s)
        if t.ndim != 1 or t.size < 1:
            raise ConfigError(f"Trajectory.at_times: times_s must be a non-empty 1-D array, got shape {t.shape}")
        lo, hi = self.times_s[0], self.times_s[-1]
        if t[0] < lo - 1e-9 or t[-1] > hi + 1e-9:
            raise ConfigError(f"Trajectory.at_times: times {t[0]:g}…{t[-1]:g} s reach outside the trajectory's "
                              f"{lo:g}…{hi:g} s")

        t = np.clip(t, lo, hi)
        pos, heading, pitch, roll, vel = interpolate_poses(self.times_s, self.positions_m, self.heading_deg,
                                                           self.pitch_deg, self.roll_deg, self.velocity_m_s, t)
        ship = None
        if self.ship_positions_m is not None:
            ship = interpolate_poses(self.times_s, self.ship_positions_m, self.heading_deg, self.pitch_deg,
                                     self.roll_deg, None, t)[0]
        return Trajectory(pos, heading, pitch, roll, t, vel, self.crs, self.start_time, ship)

    def resampled(self, ping_rate_hz: float) -> "Trajectory":
        """The poses at a ping rate (Hz) from the first time to the last: pings at t₀ + k/rate, interpolated as
        :meth:`at_times` does. A navigation log's fixes (often 1 Hz) become the device's pings; each ping's
        :attr:`fix_times_s` is the time of the last fix at or before it (a log whose fixes come no slower than the
        pings: each ping its own fix)."""
        check_number("Trajectory.resampled", "ping_rate_hz", ping_rate_hz, positive=True, hi=1e4)
        span = float(self.times_s[-1] - self.times_s[0])
        n = int(math.floor(span * ping_rate_hz * (1 + 1e-12))) + 1
        if n > 50_000_000:
            raise ConfigError(f"Trajectory.resampled: {n} pings; lower the ping rate or split the log")
        pings = self.at_times(self.times_s[0] + np.arange(n) / float(ping_rate_hz))
        last = self.times_s[np.searchsorted(self.times_s, pings.times_s + 1e-9, side="right") - 1]
        held = pings.times_s if np.median(np.diff(self.times_s)) <= 1.0 / float(ping_rate_hz) else last
        return dataclasses.replace(pings, fix_times_s=held)

    def with_layback(self, layback_m: float | None = None, *, cable_out_m: float | None = None,
                     tow_point_z_m: float = 0.0) -> "Trajectory":
        """The sonar towed behind the navigation: this trajectory's positions become the ship's
        (:attr:`ship_positions_m`, at the tow point's height) and the sonar follows the ship's track ``layback_m``
        behind along it
        (:func:`~sonar_embree.trajectory.motion.layback_positions`), at this trajectory's heights, heading along the
        track.

        Give ``layback_m`` (horizontal distance, m) or ``cable_out_m``: a straight cable from a tow point at
        height ``tow_point_z_m`` (world m; default 0, the sea surface of a DEM's vertical datum) to the sonar,
        layback = √(cable² − Δz²) per ping (no catenary: a taut cable, the simplest layback model).
        """
        if (layback_m is None) == (cable_out_m is None):
            raise ConfigError("Trajectory.with_layback: give layback_m or cable_out_m (one of them)")
        if layback_m is not None:
            check_number("Trajectory.with_layback", "layback_m", layback_m, nonneg=True, hi=1e4)
            back = float(layback_m)
        else:
            check_number("Trajectory.with_layback", "cable_out_m", cable_out_m, positive=True, hi=1e4)
            check_number("Trajectory.with_layback", "tow_point_z_m", tow_point_z_m)
            dz = np.abs(tow_point_z_m - self.positions_m[:, 2])
            if np.any(dz > cable_out_m):
                raise ConfigError(f"Trajectory.with_layback: cable_out_m={cable_out_m:g} is shorter than the sonar's "
                                  f"depth below the tow point ({dz.max():.4g} m)")
            back = np.sqrt(cable_out_m ** 2 - dz ** 2)

        pos, heading = layback_positions(self.positions_m, back)
        ship = self.positions_m.copy() if self.ship_positions_m is None else self.ship_positions_m
        ship[:, 2] = tow_point_z_m if self.ship_positions_m is None else ship[:, 2]     # the tow point
        vel = self.velocity_m_s
        if vel is not None:                           # the ship's speed, along the sonar's own track
            speed, h = np.hypot(vel[:, 0], vel[:, 1]), np.radians(heading)
            vel = np.stack([speed * np.sin(h), speed * np.cos(h), vel[:, 2]], axis=1)
        return dataclasses.replace(self, positions_m=pos, heading_deg=heading, velocity_m_s=vel,
                                   ship_positions_m=ship)

    def forward_speed_m_s(self, rotations: np.ndarray | None = None) -> np.ndarray:
        """(n,) the velocity's component along each ping's forward axis, m/s (zeros when unknown); ``rotations``
        (n, 3, 3): the transducer's body frames when they are not the vehicle's (an MSIS head's)."""
        if self.velocity_m_s is None:
            return np.zeros(len(self))
        rot = self.rotations() if rotations is None else rotations
        return np.einsum("ij,ij->i", self.velocity_m_s, rot[:, :, 0])

    @classmethod
    def from_csv(cls, path, crs=None, depth_m: float | None = None) -> "Trajectory":
        """Read a trajectory from CSV with a header row.

        Columns (any order): the position as ``x_m, y_m`` (world metres, in ``crs`` when given) or as
        ``lat_deg, lon_deg`` (WGS 84, projected into ``crs``; default the UTM zone of the first fix,
        :func:`sonar_embree.io.geo.utm_crs`), and its height as ``z_m`` (up) or ``depth_m`` (down from z = 0, the
        vertical datum of a DEM); ``heading_deg`` (without it: the track's heading over ground,
        :func:`~sonar_embree.trajectory.motion.track_heading_deg`, with a one-line notice), ``pitch_deg``, ``roll_deg``
        (default 0); the ping times as
        ``time_s`` (s) or ``time`` (ISO 8601, e.g. 2026-05-01T12:00:00.25Z: ``times_s`` from the first, which
        becomes ``start_time``); the velocity ``vx_m_s, vy_m_s, vz_m_s`` (all three or none). Common other names
        are taken too (:data:`CSV_ALIASES`: ``latitude``, ``lon``, ``depth``, ``heading``, ``timestamp``, …, any
        case). A log without a height column (a ship's GPS) takes ``depth_m``, a constant depth below z = 0 (m).
        Without velocity
        columns but with times, the velocity is the positions' time derivative (second-order differences,
        ends included), so the sonar moves during each ping (docs/physics.md §16); without times it stops for
        each ping. A speed above :data:`IMPLAUSIBLE_SPEED_M_S`, or a mean below :data:`SLOW_SPEED_M_S`, is warned
        about (time stamps not in seconds?).
        """
        path = os.fspath(path)
        header, rows = _csv_rows(path)
        if depth_m is not None:
            check_number("Trajectory.from_csv", "depth_m", depth_m)
            if "z_m" in header or "depth_m" in header:
                raise ConfigError(f"{path}: the log has a height column; give depth_m only for a log without one")
            header, rows = header + ["depth_m"], [r + [repr(float(depth_m))] for r in rows]
        col = _csv_columns(path, header, rows)
        try:
            xyz, crs = _csv_position(col, crs)
            times, start = _csv_times(col)
            heading = col.get("heading_deg")
            if heading is None and xyz.shape[0] > 1:
                heading = track_heading_deg(xyz, np.arange(xyz.shape[0], dtype=float) if times is None else times)
                log.warning("%s: no heading_deg column: the sonar's heading follows the track over ground", path)
            traj = cls(xyz, 0.0 if heading is None else heading, col.get("pitch_deg", 0.0),
                       col.get("roll_deg", 0.0), times, None, crs, start)
            v = _csv_velocity(col, traj, path)
            return traj if v is None else dataclasses.replace(traj, velocity_m_s=v)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None

    @classmethod
    def from_xtf(cls, path, crs=None, keep=None) -> "Trajectory":
        """The poses of an XTF file's sonar pings (pyxtf reads it; :func:`sonar_embree.io.xtf.read_navigation`).

        Latitude/longitude navigation (NavUnits 3) is projected into ``crs`` (default: the UTM zone of the first
        ping), its true headings turned into grid headings there (:func:`sonar_embree.io.geo.grid_heading_deg`);
        metres are taken as world x and y (in ``crs`` when given). Positions held between navigation fixes (as
        devices log them) are rebuilt into the continuous track (:func:`sonar_embree.io.xtf.continuous_track`), each
        ping's fix time kept as :attr:`fix_times_s`. z = −SensorDepth (depth below the sea
        surface at z = 0), attitude from the Sensor fields, ``times_s`` from the first ping's time, which becomes
        ``start_time``. The velocity is not read (stop-and-hop unless set from the times, as for CSV). ``keep``
        ((pings,) bool) takes only those pings, before the projection (pings without a fix left out).
        """
        from ..io.geo import from_lonlat, grid_heading_deg, utm_crs
        from ..io.xtf import NAV_UNITS_LATLON, continuous_track, read_navigation

        nav = read_navigation(path)
        if keep is not None:
            nav = {k: (np.asarray(v)[keep] if k not in ("nav_units", "fix_times") else v) for k, v in nav.items()}
            nav["fix_times"] = None if nav["fix_times"] is None else list(np.asarray(nav["fix_times"])[keep])
        x, y, heading = nav["x"], nav["y"], nav["heading_deg"] % 360.0
        try:
            if nav["nav_units"] == NAV_UNITS_LATLON:
                crs = crs if crs is not None else utm_crs(float(x[0]), float(y[0]))
                x, y = from_lonlat(crs, x, y)
                heading = grid_heading_deg(crs, x, y, heading)          # XTF headings are true headings
            t = np.array([(w - nav["times"][0]).total_seconds() for w in nav["times"]])
            fix = (None if nav["fix_times"] is None
                   else np.array([(w - nav["times"][0]).total_seconds() for w in nav["fix_times"]]))
            x, y = continuous_track(t, x, y, fix)
            fix = None if fix is None or np.any(fix > t + 1e-9) or np.any(np.diff(fix) < 0) else fix
            return cls(np.stack([x, y, -nav["depth_m"]], axis=1), heading, nav["pitch_deg"],
                       nav["roll_deg"], t, None, crs, nav["times"][0].isoformat(), fix_times_s=fix)
        except ConfigError as exc:
            raise ConfigError(f"{os.fspath(path)}: {exc}") from None

    def to_csv(self, path) -> None:
        """Write the trajectory as CSV with the columns of :meth:`from_csv` (atomic): a trajectory with a CRS
        as ``lat_deg, lon_deg`` (WGS 84), one with a start time with ISO 8601 ``time`` stamps, so that
        :meth:`from_csv` (given the same ``crs`` unless it is the first fix's UTM zone) reads it back."""
        names = list(CSV_COLUMNS if self.velocity_m_s is not None else CSV_COLUMNS[:-len(VELOCITY_COLUMNS)])
        cols = [self.times_s, self.positions_m, self.heading_deg, self.pitch_deg, self.roll_deg]
        data = np.column_stack(cols + ([self.velocity_m_s] if self.velocity_m_s is not None else []))
        text = [[f"{v:.17g}" for v in row] for row in data]
        if self.crs is not None:
            from ..io.geo import to_lonlat

            lon, lat = to_lonlat(self.crs, self.positions_m[:, 0], self.positions_m[:, 1])
            names[1:3] = ["lat_deg", "lon_deg"]
            for row, a, o in zip(text, lat, lon):
                row[1:3] = [f"{a:.17g}", f"{o:.17g}"]
        if self.start_time is not None:
            import datetime as dt

            t0 = dt.datetime.fromisoformat(self.start_time)
            names[0] = "time"
            for row, t in zip(text, self.times_s):
                row[0] = (t0 + dt.timedelta(seconds=float(t))).isoformat()

        def write(tmp):
            with open(tmp, "w", newline="") as fh:
                fh.write(",".join(names) + "\n" + "".join(",".join(row) + "\n" for row in text))

        atomic_write(path, write, suffix=".csv")


def _csv_rows(path: str):
    """(header, data rows) of a CSV file, blank rows dropped."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read trajectory CSV ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a UTF-8 text file (byte 0x{exc.object[exc.start]:02x} at offset "
                          f"{exc.start}); save the trajectory CSV as UTF-8") from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise ConfigError(f"{path}: empty trajectory CSV")
    return _canonical_header(path, [c.strip() for c in rows[0]]), rows[1:]


def csv_header(path) -> list:
    """The column names of a trajectory CSV as :meth:`Trajectory.from_csv` reads them (aliases resolved)."""
    return _csv_rows(os.fspath(path))[0]


def _canonical_header(path: str, header: list) -> list:
    """The header with known column names as they are and common other names (:data:`CSV_ALIASES`, any case) as
    the columns they stand for; two columns standing for one is a one-line error."""
    known = CSV_COLUMNS + GEO_CSV_COLUMNS
    out = [c if c in known else CSV_ALIASES.get(c.lower(), c.lower() if c.lower() in known else c) for c in header]
    for name in set(out):
        if out.count(name) > 1:
            both = [h for h, o in zip(header, out) if o == name]
            raise ConfigError(f"{path}: columns {both[0]!r} and {both[1]!r} both give {name!r}; keep one")
    return out


def _csv_columns(path: str, header, rows) -> dict:
    """The CSV's columns by name: float64 arrays, the ISO ``time`` column as strings."""
    unknown = [c for c in header if c not in CSV_COLUMNS + GEO_CSV_COLUMNS]
    if unknown:
        raise ConfigError(f"{path}: unknown trajectory column {unknown[0]!r} (allowed: "
                          f"{', '.join(CSV_COLUMNS + GEO_CSV_COLUMNS)})")
    for pair in (("x_m", "lat_deg"), ("y_m", "lon_deg"), ("z_m", "depth_m"), ("time_s", "time")):
        if all(c in header for c in pair):
            raise ConfigError(f"{path}: give {pair[0]!r} or {pair[1]!r}, not both")
    for req in (("x_m", "lat_deg"), ("y_m", "lon_deg"), ("z_m", "depth_m")):
        if not any(c in header for c in req):
            hint = ("; a ship's log without one takes a depth (survey: --depth-m D or --altitude-m H)"
                    if req[0] == "z_m" else "")
            raise ConfigError(f"{path}: trajectory CSV lacks column {req[0]!r} (or {req[1]!r}){hint}")
    if not rows:
        raise ConfigError(f"{path}: trajectory needs at least one pose, got 0")
    if any(len(r) != len(header) for r in rows):
        raise ConfigError(f"{path}: every trajectory row needs {len(header)} values")
    col = {}
    for i, name in enumerate(header):
        cells = [r[i].strip() for r in rows]
        if name == "time":
            col[name] = cells
            continue
        try:
            col[name] = np.array([float(c) for c in cells], dtype=np.float64)
        except ValueError as exc:
            raise ConfigError(f"{path}: non-numeric trajectory value in column {name!r} ({exc})") from None
    return col


def _csv_position(col: dict, crs):
    """((n, 3) positions in metres, CRS or None) from x/y or lat/lon columns and z or depth."""
    z = col["z_m"] if "z_m" in col else -col["depth_m"]
    if "lat_deg" not in col:
        return np.stack([col["x_m"], col["y_m"], z], axis=1), crs
    from ..io.geo import from_lonlat, utm_crs

    crs = crs if crs is not None else utm_crs(float(col["lon_deg"][0]), float(col["lat_deg"][0]))
    x, y = from_lonlat(crs, col["lon_deg"], col["lat_deg"])
    return np.stack([x, y, z], axis=1), crs


def _csv_times(col: dict):
    """(times_s or None, start time or None) from a ``time_s`` or an ISO 8601 ``time`` column."""
    if "time" not in col:
        return col.get("time_s"), None
    import datetime as dt

    stamps = [dt.datetime.fromisoformat(iso_utc(t)) for t in col["time"]]
    return np.array([(t - stamps[0]).total_seconds() for t in stamps]), stamps[0].isoformat()


def _csv_velocity(col: dict, traj: "Trajectory", path: str):
    """(n, 3) velocity of a CSV trajectory, m/s: its columns, else d(position)/dt where times are given, else None."""
    given = [c for c in VELOCITY_COLUMNS if c in col]
    if given and len(given) < len(VELOCITY_COLUMNS):
        raise ConfigError(f"velocity needs all of {', '.join(VELOCITY_COLUMNS)}; got only {', '.join(given)}")
    if given:
        return np.stack([col[c] for c in VELOCITY_COLUMNS], axis=1)
    if ("time_s" not in col and "time" not in col) or len(traj) < 2:
        return None
    v = np.gradient(traj.positions_m, traj.times_s, axis=0, edge_order=2 if len(traj) > 2 else 1)
    fastest = float(np.linalg.norm(v, axis=1).max())
    if fastest > IMPLAUSIBLE_SPEED_M_S:
        log.warning("%s: the vehicle moves at up to %.3g m/s between its time stamps; is time_s in seconds?",
                    path, fastest)
    way = float(np.sum(np.linalg.norm(np.diff(traj.positions_m, axis=0), axis=1)))
    span = float(traj.times_s[-1] - traj.times_s[0])
    if way > 0.0 and span > 0.0 and way / span < SLOW_SPEED_M_S:
        log.warning("%s: the vehicle makes %.3g m/s on average (%.3g m in %.4g s); are the times in seconds, not "
                    "milliseconds?", path, way / span, way, span)
    return v


def _ping_rate(ping_rate_hz, sonar, c: float) -> float:
    """The survey's ping rate: the given one (checked against the sonar's window at sound speed ``c``) or back to
    back."""
    limit = None if sonar is None else c / (2.0 * sonar.max_range_m)
    if ping_rate_hz is None:
        if limit is None:
            raise ConfigError("Trajectory.survey: give ping_rate_hz or the sonar (back to back at 2 R_max / c)")
        return limit
    if isinstance(ping_rate_hz, bool) or not isinstance(ping_rate_hz, (int, float)) or not 0 < ping_rate_hz < 1e4:
        raise ConfigError(f"Trajectory.survey ping_rate_hz must be in (0, 1e4) Hz, got {ping_rate_hz!r}")
    if limit is not None and ping_rate_hz > limit * (1 + 1e-12):
        raise ConfigError(f"Trajectory.survey: ping_rate_hz={ping_rate_hz:g} is faster than the sonar's "
                          f"{limit:.4g} Hz (2 x max_range_m / c): pings would overlap")
    return float(ping_rate_hz)


def _path(waypoints_m, where: str, n_dense: int):
    """(length m, sample(s[, tangent]) → (positions (k, 3), headings (k,) deg[, unit tangents (k, 3)])) of the path
    through ``waypoints_m``."""
    from scipy.interpolate import CubicSpline

    w = _as_float_array("waypoints_m", waypoints_m)
    if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 2:
        raise ConfigError(f"Trajectory.{where} needs (m>=2, 3) waypoints, got {w.shape}")
    chord = np.linalg.norm(np.diff(w, axis=0), axis=1)
    if np.any(chord == 0.0):
        raise ConfigError(f"Trajectory.{where}: two consecutive waypoints coincide")
    u = np.concatenate(([0.0], np.cumsum(chord)))
    if w.shape[0] == 2:  # straight: arc length is the parameter
        def straight(s, tangent=False):
            pos = w[0] + (np.asarray(s) / u[-1])[:, None] * (w[1] - w[0])
            d = w[1] - w[0]
            heading = np.full(pos.shape[0], math.degrees(math.atan2(d[0], d[1])) % 360.0)
            return (pos, heading, np.broadcast_to(d / u[-1], pos.shape)) if tangent else (pos, heading)
        return float(u[-1]), straight
    spline = CubicSpline(u, w, bc_type="natural")
    dense_u = np.linspace(0.0, u[-1], max(2000, n_dense))
    dense = spline(dense_u)
    arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))))

    def curved(s, tangent=False):
        pu = np.interp(s, arc, dense_u)
        tan = spline(pu, 1)
        heading = np.degrees(np.arctan2(tan[:, 0], tan[:, 1])) % 360.0
        unit = tan / np.linalg.norm(tan, axis=1)[:, None]
        return (spline(pu), heading, unit) if tangent else (spline(pu), heading)
    return float(arc[-1]), curved

"""The same floor with straight rays and in two sound-speed profiles: refraction in the waterfall and in one ping.

    python scripts/refraction_figure.py [-o docs/refraction] [--pings 120]

A 100 kHz side-scan sonar 20 m deep, 15 m above a flat fine-sand floor with a steel box 80 m out, 200 m
range, speckle-free:

- waterfalls.png  straight rays (c = 1500 m/s throughout), an upward-refracting layer (c grows 1.5 m/s per m
                  below the sonar: rays bend up, the floor ends in a shadow zone) and a downward-refracting
                  thermocline (c falls 1.5 m/s per m: rays bend down), on one grey scale (display TVG, 50 dB)
- ping.png        one starboard ping of each against the apparent range ct/2 (c the sonar's 1500 m/s), with
                  the upward profile's shadow edge from the closed-form ray map marked
- refraction.json that shadow edge: the record's last lit sample against the arrival time of the limiting
                  ray (the one that grazes the floor, cos θ0 = c_sonar / c_floor), from
                  :meth:`SoundSpeedProfile.trace_down`; the echo ends a pulse length after it

Near the shadow edge the floor is seen at grazing incidence and the footprints reach their cap (as for
straight rays at grazing range): the last 20 m before the edge, 50 dB below the near floor, are combed.

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEPTH, H, GRAD, C = 20.0, 15.0, 1.5, 1500.0


def _scene(se):
    import trimesh

    box = trimesh.creation.box(extents=(3.0, 3.0, 2.0))
    box.apply_translation((0.0, -80.0, 1.0))
    return (se.Scene().add(se.seafloor.flat((400.0, 500.0)), label="seafloor",
                           material=se.Material(scattering=se.sediments.FINE_SAND))
            .add(box, label="box", material=se.Material(scattering=se.sediments.STEEL)))


def profiles(se):
    """{name: profile or None}: c = C at the sonar, gradient ±GRAD below it (depth 0 at z = H + DEPTH)."""
    def linear(g):
        return se.SoundSpeedProfile.linear(C - g * DEPTH, g, depth_m=60.0, surface_z_m=H + DEPTH)
    return {"straight rays (c = 1500 m/s)": None, f"upward refraction (+{GRAD:g} /s)": linear(GRAD),
            f"downward refraction (−{GRAD:g} /s)": linear(-GRAD)}


def records(se, pings):
    """{name: Record} of the same pass in each profile."""
    traj = se.Trajectory.line((-0.5 * pings / 2, 0.0, H), (0.5 * pings / 2, 0.0, H), pings)
    out = {}
    for name, profile in profiles(se).items():
        sonar = se.Acquisition(se.Sonar(frequency_hz=100e3, length_m=0.76, height_m=0.015, max_range_m=200.0,
                                        tilt_deg=10.0,
                         sample_rate_hz=10e3), se.Environment(sound_speed=profile))
        out[name] = se.simulate(_scene(se), traj, sonar, se.Pulse.cw(duration_s=200e-6), start_time="2000-01-01")
    return out


def shadow_edge(se, recs) -> dict:
    """The upward profile's last lit sample (starboard, middle ping) against the limiting ray's arrival."""
    name, rec = list(recs.items())[1]
    profile = profiles(se)[name]
    c_floor = profile.speed_at(DEPTH + H)
    theta = np.arccos(C / c_floor) * (1 + 1e-9)                 # grazes the floor: its farthest reach
    _, _, t = profile.trace_down(DEPTH, [theta], DEPTH + H)
    row = rec.starboard[rec.n_pings // 2]
    lit = np.flatnonzero(row > 0.0)
    return {"last_lit_s": float(rec.time_s[lit[-1]]), "limiting_ray_s": float(2 * t[0]),
            "pulse_s": float(rec.pulse.duration_s), "sample_s": float(rec.time_s[1] - rec.time_s[0])}


def ping_panel(recs, edge):
    """One starboard ping of every record in dB against ct/2, with the closed-form shadow edge."""
    first = next(iter(recs.values()))
    i = first.n_pings // 2
    with np.errstate(divide="ignore"):
        lines = [(name, 10 * np.log10(rec.starboard[i])) for name, rec in recs.items()]
    top = max(np.nanmax(y[np.isfinite(y)]) for _, y in lines)
    return {"x": first.slant_range_m, "lines": lines, "xlabel": "apparent range ct/2 (m), c = 1500 m/s",
            "ylabel": "intensity (dB, unit source)", "ylim": (top - 70, top + 5), "title": "middle ping, starboard",
            "vlines": [(0.5 * C * edge["limiting_ray_s"], "shadow edge (ray map)")]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "refraction"), help="output folder")
    p.add_argument("--pings", type=int, default=120, help="pings per waterfall (0.5 m apart)")
    args = p.parse_args(argv)
    if args.pings < 2:
        p.error(f"--pings must be at least 2, got {args.pings}")
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from multipath_figure import _images  # the same common grey scale (display TVG, 50 dB)
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    recs = records(se, args.pings)
    edge = shadow_edge(se, recs)
    plotting.mosaic_png(_images(recs), list(recs), os.path.join(args.output, "waterfalls.png"), columns=3)
    plotting.line_panels_png([ping_panel(recs, edge)], os.path.join(args.output, "ping.png"))
    text = json.dumps(edge, indent=1) + "\n"
    atomic_write(os.path.join(args.output, "refraction.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("waterfalls.png", "ping.png", "refraction.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

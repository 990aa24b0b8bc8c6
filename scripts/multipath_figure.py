"""The same floor with and without a sea surface: multipath images in the waterfall and in one ping.

    python scripts/multipath_figure.py [-o docs/multipath] [--pings 200]

- waterfalls.png  a box on a flat fine-sand floor in shallow water (6 m altitude, surface 3 m above the
                  sonar, 30 m range, a broad 10°-tilted beam that reaches the surface), speckle-free:
                  without a surface, with a flat one, with a rough one (h_w = 0.5 mm) and under a swell
                  (meshed, one Embree reflection per ray), and a flat surface with its own backscatter (the
                  surface line, a Lambert −40 dB level), on one common grey scale (display TVG, 50 dB)
- ping.png        one starboard ping of each against slant range ct/2, with the surface line (d), one-bounce
                  (h + d) and two-bounce (h + 2d) onsets marked
- multipath.json  the first sample where the surface record departs from the direct one, against the
                  one-bounce onset (2h + 2d)/c (later by the angle the baffle hides straight up)

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
H, D = 6.0, 3.0


def _scene(se):
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 1.5))
    box.apply_translation((0.0, -15.0, 0.75))
    return (se.Scene().add(se.seafloor.flat((200.0, 120.0)), label="seafloor",
                           material=se.Material(scattering=se.sediments.FINE_SAND))
            .add(box, label="box", material=se.Material(scattering=se.sediments.STEEL)))


def records(se, pings):
    """{name: Record} without a surface, with a flat one and with a rough one."""
    traj = se.Trajectory.line((-0.1 * pings / 2, 0.0, H), (0.1 * pings / 2, 0.0, H), pings)
    surfaces = {"no surface": None, f"flat surface {D:g} m above": se.SeaSurface(z_m=H + D),
                "rough surface (h_w = 0.5 mm)": se.SeaSurface(z_m=H + D, rms_wave_height_m=0.5e-3),
                "swell (H = 0.4 m, Λ = 8 m, along track)": se.SeaSurface(z_m=H + D, swell_height_m=0.4,
                                                                        swell_length_m=8.0),
                "flat surface and its surface line (−40 dB)": se.SeaSurface(z_m=H + D, backscatter=-40.0)}
    out = {}
    for name, surf in surfaces.items():
        sonar = se.Acquisition(se.Sonar(max_range_m=30.0, tilt_deg=10.0, height_m=0.0019), se.Environment(surface=surf))
        out[name] = se.simulate(_scene(se), traj, sonar, se.Pulse.cw(), start_time="2000-01-01")
    return out


def _images(recs, span_db=50.0, columns=300):
    from sonar_embree.signal.processing import tvg_gain
    from sonar_embree.display.waterfall import block_mean

    dbs = []
    for rec in recs.values():
        g = tvg_gain(rec.time_s, rec.acquisition.sound_speed_m_s, rec.acquisition.alpha_db_per_m)
        block = max(rec.time_s.size // columns, 1)
        port, stbd = (block_mean(x * g, block) for x in (rec.port, rec.starboard))
        with np.errstate(divide="ignore"):
            dbs.append(10 * np.log10(np.concatenate([port[:, ::-1], stbd], axis=1)))
    white = max(np.percentile(d[np.isfinite(d)], 99.5) for d in dbs)
    return [(255 * np.clip((d - (white - span_db)) / span_db, 0, 1)).astype(np.uint8) for d in dbs]


def ping_panel(recs):
    """One starboard ping of every record in dB against ct/2, with the onsets marked."""
    first = next(iter(recs.values()))
    i = first.n_pings // 2
    with np.errstate(divide="ignore"):
        lines = [(name, 10 * np.log10(rec.starboard[i])) for name, rec in recs.items()]
    top = max(np.nanmax(y[np.isfinite(y)]) for _, y in lines)
    xlabel = "ct/2 (m): surface line d, floor h, one bounce h + d, two bounces h + 2d"
    return {"x": first.slant_range_m, "lines": lines, "xlabel": xlabel, "ylabel": "intensity (dB, unit source)",
            "ylim": (top - 60, top + 5), "title": "middle ping, starboard",
            "vlines": [(D, "d"), (H, "h"), (H + D, "h + d"), (H + 2 * D, "h + 2d")]}


def onset(recs) -> dict:
    """First sample where the flat-surface record departs from the direct one, and the geometry's onset."""
    direct, flat = (np.asarray(list(recs.values())[k].starboard).mean(axis=0) for k in (0, 1))
    t = list(recs.values())[0].time_s
    k = int(np.flatnonzero(flat - direct > 1e-9 * direct.max())[0])
    c = list(recs.values())[0].acquisition.sound_speed_m_s
    return {"first_multipath_s": float(t[k]), "one_bounce_onset_s": (2 * H + 2 * D) / c, "sample_s": float(t[1] - t[0])}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "multipath"), help="output folder")
    p.add_argument("--pings", type=int, default=200, help="pings per waterfall (0.1 m apart)")
    args = p.parse_args(argv)
    if args.pings < 2:
        p.error(f"--pings must be at least 2, got {args.pings}")
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    recs = records(se, args.pings)
    plotting.mosaic_png(_images(recs), list(recs), os.path.join(args.output, "waterfalls.png"), columns=2)
    plotting.line_panels_png([ping_panel(recs)], os.path.join(args.output, "ping.png"))
    text = json.dumps(onset(recs), indent=1) + "\n"
    atomic_write(os.path.join(args.output, "multipath.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("waterfalls.png", "ping.png", "multipath.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The physics behind the images: the beam pattern (like the paper's Fig. 3) and one ping's time series.

    python scripts/physics_plots.py [-o docs/physics]

- beam_pattern.png   one-way Γ² and two-way Γ⁴ (dB) of the default 400 kHz membrane
                     (190 mm × 3.8 mm, docs/physics.md §2) along track and in elevation,
                     with the −3 dB beamwidths and first nulls marked
- ping.png           one starboard ping over the anchor-mine scene: expected intensity
                     (speckle-free) and one coherent-speckle realisation, in dB, with
                     the first bottom return 2h/c and the objects' echoes

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def beam_panels(se):
    from sonar_embree.instrument import beam

    s = se.Sonar()
    k, lam = se.Acquisition.of(s).wavenumber_rad_m, se.Acquisition.of(s).wavelength_m
    panels = []
    for name, size, span in (("along track", s.length_m, 4.0), ("elevation (about the tilted boresight)",
                                                                   s.height_m, 90.0)):
        ang = np.linspace(-span, span, 4001)
        u = np.sin(np.radians(ang))
        g = beam.directivity(u if size == s.length_m else np.zeros_like(u),
                             u if size != s.length_m else np.zeros_like(u), np.cos(np.radians(ang)), k,
                             s.length_m, s.height_m)
        with np.errstate(divide="ignore"):
            one, two = 20 * np.log10(np.abs(g)), 40 * np.log10(np.abs(g))
        bw = beam.beamwidth_deg(size, lam)
        null = math.degrees(beam.first_null_rad(size, lam))
        panels.append({"x": ang, "lines": [("one way, Γ²", one), ("two way, Γ⁴", two)],
                       "xlabel": "angle from boresight (°)", "ylabel": "dB", "ylim": (-60, 3),
                       "title": f"{name}: −3 dB width {bw:.2f}° (one way)",
                       "vlines": [(-bw / 2, ""), (bw / 2, f"±{bw / 2:.2f}°"), (null, f"null {null:.2f}°")]})
    return panels


def ping_panels(se, pings):
    from sonar_embree.runs.demo import anchor_mine_setup

    scene, traj, sonar, pulse = anchor_mine_setup(n_pings=pings)
    i = pings // 2
    one = traj[i:i + 1]
    clean = se.simulate(scene, one, sonar, pulse)
    noisy = se.simulate(scene, one, sonar, pulse, speckle=True, seed=1)
    r = clean.slant_range_m
    with np.errstate(divide="ignore"):
        db = [10 * np.log10(x.starboard[0]) for x in (clean, noisy)]
    top = np.nanmax(db[0][np.isfinite(db[0])])
    h = float(clean.altitude_m[0])
    return [{"x": clean.time_s * 1e3, "lines": [("coherent speckle, seed 1", db[1]), ("speckle-free (expected)", db[0])],
             "xlabel": "time after transmission (ms)", "ylabel": "intensity (dB, unit source)",
             "ylim": (top - 70, top + 8), "title": "one starboard ping over the anchor-mine scene",
             "vlines": [(2 * h / se.Acquisition.of(sonar).sound_speed_m_s * 1e3,
                         f"first bottom return 2h/c (h = {h:.1f} m)")],
             "legend_low": True},
            {"x": r, "lines": [("speckle-free", db[0])], "xlabel": "slant range (m)", "ylabel": "dB",
             "ylim": (top - 70, top + 8), "title": "the same ping against slant range R = ct/2"}]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "physics"), help="output folder")
    p.add_argument("--pings", type=int, default=240, help="pings of the demo pass (the middle one is shown)")
    args = p.parse_args(argv)
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from sonar_embree.display import plotting

    os.makedirs(args.output, exist_ok=True)
    plotting.line_panels_png(beam_panels(se), os.path.join(args.output, "beam_pattern.png"),
                             "Rectangular-membrane beam pattern, 400 kHz, 190 mm × 3.8 mm")
    plotting.line_panels_png(ping_panels(se, args.pings), os.path.join(args.output, "ping.png"))
    for name in ("beam_pattern.png", "ping.png"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

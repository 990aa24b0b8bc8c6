"""Seafloors that look like real data: one scene over each sediment preset, a textured floor, and σ(θ).

    python scripts/seafloor_gallery.py [-o docs/seafloors] [--pings 300]

- presets.png   the same scene (a steel box and a concrete pipe on a flat floor, 10 m altitude,
                coherent speckle, 400 kHz) over mud, sandy mud, fine sand, coarse sand, gravel and rock
                (the bare names: each class's physical model, issue 52), then fine sand with K texture
                (ν = 1, L = 1 m) and a patchwork of three sediments; one common grey scale (display TVG,
                50 dB), so the brightness between panels is the sediments' backscatter difference, not a
                per-image stretch. Where two classes' σ lie within 1 dB over the waterfall's grazing
                angles, the physics makes them look alike, and gallery.json says so (``look_alike``)
- sigma.png     σ(θ) measured from speckle-free flat-floor records against each preset's curve
- migration.png each bare name's σ(θ) at 400 kHz now (its physical model) and before issue 52 (the
                Lambert + Kirchhoff preset, kept as "lambert-kirchhoff <name>")
- gallery.json  the largest |measured − curve| (dB) per preset from 15° to 75° grazing, the median
                displayed level (dB) of each waterfall, each floor's mean σ over 15°–45° (dB) and the
                pairs of floors within 1 dB of each other there

σ is measured as the record over the preset divided by the record over a Lambert floor of μ = 1 under the same
sonar, path and pulse, times that floor's cos²θ: spreading, absorption, beam and footprint cancel in the ratio.
Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLOORS = ("mud", "sandy mud", "fine sand", "coarse sand", "gravel", "rock")
ALTITUDE_M = 10.0


def _targets(se):
    """A steel box to starboard and a concrete pipe to port, lying on the floor (z = 0)."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 1.2, 1.0))
    box.apply_translation((0.0, -18.0, 0.5))
    pipe = trimesh.creation.cylinder(radius=0.5, height=6.0, sections=48)
    pipe.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, (0, 1, 0)))
    pipe.apply_transform(trimesh.transformations.rotation_matrix(math.radians(30), (0, 0, 1)))
    pipe.apply_translation((0.0, 22.0, 0.5))
    return [(box, se.Material(scattering=se.sediments.STEEL), "steel box"),
            (pipe, se.Material(scattering=se.sediments.CONCRETE), "concrete pipe")]


def _scene(se, floor):
    """The gallery scene over ``floor``: a preset name, ("texture", name) or ("patches", names)."""
    scene = se.Scene()
    if isinstance(floor, tuple) and floor[0] == "patches":
        grid = se.seafloor.from_heights(np.zeros((161, 161)), spacing_m=0.5, origin_m=(-40.0, -40.0))
        scene.add_sediments(grid, {n: se.sediments.preset(n) for n in floor[1]}, patch_m=12.0, seed=3)
    else:
        name, texture = (floor[1], se.KTexture(shape=1.0, correlation_m=1.0, seed=5)) if isinstance(
            floor, tuple) else (floor, None)
        scene.add(se.seafloor.flat((80.0, 80.0)), label="seafloor",
                  material=se.Material(scattering=se.sediments.preset(name), texture=texture))
    for mesh, material, label in _targets(se):
        scene.add(mesh, material=material, label=label)
    return scene


def _db_image(rec, white_db, span_db=50.0, columns=400):
    """Both channels (port mirrored left) in ground range and dB after display TVG, on a common scale: uint8."""
    from sonar_embree.signal.processing import tvg_gain
    from sonar_embree.display.waterfall import block_mean, to_ground_range

    g = tvg_gain(rec.time_s, rec.acquisition.sound_speed_m_s, rec.acquisition.alpha_db_per_m)
    block = max(rec.time_s.size // (2 * columns), 1)  # average in intensity, then place on the ground
    r = block_mean(rec.slant_range_m[None, :], block)[0]
    sides = [to_ground_range(block_mean(x * g, block), r, rec.altitude_m, columns)[1]
             for x in (rec.port, rec.starboard)]
    with np.errstate(divide="ignore"):
        db = 10 * np.log10(np.concatenate([sides[0][:, ::-1], sides[1]], axis=1))
    return (255 * np.clip((db - (white_db - span_db)) / span_db, 0, 1)).astype(np.uint8), db


def preset_panels(se, pings):
    """Waterfalls of the gallery scene over every floor, on one grey scale; (images, titles, median dB of each)."""
    sonar = se.Sonar(max_range_m=30.0)
    traj = se.Trajectory.line((-0.1 * pings / 2, 0.0, ALTITUDE_M), (0.1 * pings / 2, 0.0, ALTITUDE_M), pings)
    floors = list(FLOORS) + [("texture", "fine sand"), ("patches", ("mud", "fine sand", "gravel"))]
    titles = list(FLOORS) + ["fine sand, K texture ν = 1, L = 1 m", "patches: mud, fine sand, gravel"]
    records = [se.simulate(_scene(se, f), traj, sonar, se.Pulse.cw(), speckle=True, seed=1,
                           start_time="2000-01-01") for f in floors]
    dbs = [_db_image(r, 0.0)[1] for r in records]
    white = max(np.percentile(d[np.isfinite(d)], 99.5) for d in dbs)
    medians = {t: float(np.median(d[np.isfinite(d)])) for t, d in zip(titles, dbs)}
    return [_db_image(r, white)[0] for r in records], titles, medians


def measured_sigma(se):
    """σ(grazing) of each preset measured from records (see the module docstring): grazing (°), {name: dB}."""
    sonar = se.Sonar(tilt_deg=50.0, height_m=0.0015, max_range_m=40.0, sample_rate_hz=200e3)
    pulse = se.Pulse.cw(duration_s=20e-6, taper=0.0)
    line = se.Trajectory.line((-0.05, 0.0, ALTITUDE_M), (0.05, 0.0, ALTITUDE_M), 2)

    def record(material):
        scene = se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=material, label="seafloor")
        return se.simulate(scene, line, sonar, pulse, start_time="2000-01-01")

    ref = record(se.Material(backscatter_db=0.0))
    acq = se.Acquisition.of(sonar)
    centre = ref.slant_range_m - acq.sound_speed_m_s * pulse.duration_s / 4   # middle of each range cell
    ok = centre > ALTITUDE_M * 1.001
    grazing = np.degrees(np.arcsin(ALTITUDE_M / centre[ok]))
    base = ref.starboard.mean(axis=0)[ok]
    out = {}
    for name in FLOORS + ("concrete", "steel"):
        rec = record(se.Material(scattering=se.sediments.preset(name)))
        with np.errstate(divide="ignore", invalid="ignore"):
            out[name] = 10 * np.log10(rec.starboard.mean(axis=0)[ok] / base * np.sin(np.radians(grazing)) ** 2)
    return grazing, out, acq.frequency_hz


def curve_db(se, name, grazing_deg, frequency_hz):
    """10·log10 σ(θ, θ) of the preset ``name`` at the carrier (a physical model is taken at it)."""
    s = np.sin(np.radians(grazing_deg))
    return 10 * np.log10(se.sediments.preset(name).at_frequency(frequency_hz).sigma(s, s))


def look_alike(se, frequency_hz):
    """Each floor's mean σ over 15°–45° grazing (dB; the waterfalls' floor) and the pairs within 1 dB there."""
    g = np.linspace(15.0, 45.0, 31)
    mean = {n: float(10 * np.log10(np.mean(10 ** (curve_db(se, n, g, frequency_hz) / 10)))) for n in FLOORS}
    pairs = [[a, b] for i, a in enumerate(FLOORS) for b in FLOORS[i + 1:] if abs(mean[a] - mean[b]) < 1.0]
    return mean, pairs


def migration_panels(se, frequency_hz):
    """Each bare name's σ(θ) now (its physical model, solid) and before issue 52 (Lambert + Kirchhoff, dashed)."""
    g = np.linspace(2.0, 88.0, 173)
    panels = []
    for names, title in ((FLOORS[:3], "mud, sandy mud, fine sand"), (FLOORS[3:], "coarse sand, gravel, rock")):
        lines = []
        for k, name in enumerate(names):
            lines += [(f"{name}: now", curve_db(se, name, g, frequency_hz), f"C{k}-"),
                      (f"{name}: before", curve_db(se, f"lambert-kirchhoff {name}", g, frequency_hz), f"C{k}--")]
        panels.append({"x": g, "lines": lines, "xlabel": "grazing angle (°)", "title": title, "ylim": (-70, 10),
                       "ylabel": f"10 log σ at {frequency_hz / 1e3:g} kHz (dB)"})
    return panels


def sigma_panels(se, grazing, measured, frequency_hz):
    """Measured σ (dots) against each preset's closed-form curve (line); and the errors (dB) from 15° to 75°."""
    pick = np.flatnonzero(np.isfinite(grazing))[::25]
    band = (grazing[pick] >= 15) & (grazing[pick] <= 75)
    panels, errors = [], {}
    for names, title in ((FLOORS[:3], "mud to fine sand"), (FLOORS[3:], "coarse sand to rock"),
                         (("concrete", "steel"), "man-made surfaces")):
        lines = []
        for k, name in enumerate(names):
            curve = curve_db(se, name, grazing[pick], frequency_hz)
            lines += [(f"{name}: curve", curve, f"C{k}-"), (f"{name}: measured", measured[name][pick], f"C{k}.")]
            errors[name] = float(np.max(np.abs(measured[name][pick][band] - curve[band])))
        panels.append({"x": grazing[pick], "lines": lines, "xlabel": "grazing angle (°)",
                       "ylabel": "backscatter strength 10 log σ (dB)", "title": title, "ylim": (-60, 25)})
    return panels, errors


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "seafloors"), help="output folder")
    p.add_argument("--pings", type=int, default=300, help="pings per waterfall (0.1 m apart)")
    args = p.parse_args(argv)
    if args.pings < 2:
        p.error(f"--pings must be at least 2, got {args.pings}")
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    images, titles, medians = preset_panels(se, args.pings)
    plotting.mosaic_png(images, titles, os.path.join(args.output, "presets.png"), columns=4)
    grazing, measured, f = measured_sigma(se)
    panels, errors = sigma_panels(se, grazing, measured, f)
    plotting.line_panels_png(panels, os.path.join(args.output, "sigma.png"),
                             "σ(θ) measured from speckle-free flat-floor records (dots) against each preset's curve")
    plotting.line_panels_png(migration_panels(se, f), os.path.join(args.output, "migration.png"),
                             "the bare sediment names: their physical models now, Lambert + Kirchhoff before")
    mean, pairs = look_alike(se, f)
    text = json.dumps({"sigma_error_db": errors, "floor_median_db": medians, "floor_sigma_15_45_db": mean,
                       "look_alike": pairs}, indent=1) + "\n"
    atomic_write(os.path.join(args.output, "gallery.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("presets.png", "sigma.png", "migration.png", "gallery.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The same scene as a unit-source intensity image and as a device records it (issue 16).

    python scripts/device_figure.py [-o docs/device] [--length 40]

A survey line past a steel box and a concrete pipe on fine sand, flown at 2 m/s with back-to-back pings by an
EdgeTech 4125 at 400 kHz (the `edgetech-4125-400` preset: its beamwidths, tilt, CHIRP and source level) at
75 m range, 10 m above the floor:

- waterfalls.png  left: the unit-source expected intensity of the stop-and-hop line (display TVG, 50 dB grey
                  scale, the figure every earlier gallery entry shows); right: the 16-bit samples a device
                  stores: source level 210 dB, sea-state noise (8 m/s wind), frozen speckle, attitude and heave
                  jitter (yaw 0.5°, roll 1°, heave 5 cm, 2 s correlation), motion during the ping, and a
                  receiver with −180 dB re 1 V/µPa, a 30 log R + 2αR TVG and a 16-bit ADC, shown linearly as
                  codes / 2^16 (no display processing)
- device.json     what the device record holds: dtype, the share of clipped samples, the median code in the
                  water column before the first bottom echo (noise, not zero) and in the unit-source record

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
H, PRESET = 10.0, "edgetech-4125-400"


def _scene(se):
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 1.5))
    box.apply_translation((0.0, -30.0, 0.75))
    pipe = trimesh.creation.cylinder(radius=0.5, height=12.0)
    pipe.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0.0, 1.0, 0.0)))
    pipe.apply_translation((6.0, 45.0, 0.5))
    return (se.Scene().add(se.seafloor.flat((300.0, 300.0)), label="seafloor",
                           material=se.Material(scattering=se.sediments.FINE_SAND))
            .add(box, label="box", material=se.Material(scattering=se.sediments.STEEL))
            .add(pipe, label="pipe", material=se.Material(scattering=se.sediments.CONCRETE)))


def records(se, length_m):
    """(unit-source Record, device Record) of the same line."""
    unit_sonar = se.Sonar.preset(PRESET, source_level_db=None)
    rx = se.Receiver(sensitivity_db=-180.0, gain=se.TVG(g0_db=40.0, k=30), adc_bits=16, full_scale_v=1.0)
    windy = se.Environment(noise=se.AmbientNoise(wind_speed_m_s=8.0))
    device_sonar = se.Acquisition(se.Sonar.preset(PRESET, receiver=rx), windy)
    path = [(-0.5 * length_m, 0.0, H), (0.5 * length_m, 0.0, H)]
    line = se.Trajectory.survey(path, speed_m_s=2.0, sonar=device_sonar)
    still = se.Trajectory(line.positions_m, line.heading_deg, line.pitch_deg, line.roll_deg, line.times_s)
    wobbly = line.with_motion(se.Motion(yaw_rms_deg=0.5, roll_rms_deg=1.0, heave_rms_m=0.05, correlation_s=2.0),
                              seed=4)
    pulse = se.Pulse.preset(PRESET)
    unit = se.simulate(_scene(se), still, unit_sonar, pulse, start_time="2000-01-01")
    device = se.simulate(_scene(se), wobbly, device_sonar, pulse, speckle=True, seed=4, start_time="2000-01-01")
    return unit, device


def device_image(rec, columns=300):
    """The device's codes as it stores them, port mirrored, block means across track, 8-bit linear."""
    from sonar_embree.display.waterfall import block_mean

    block = max(rec.time_s.size // columns, 1)
    full = float(2 ** rec.sonar.receiver.adc_bits - 1)
    port, stbd = (block_mean(rec.samples[:, i].astype(float), block) for i in (0, 1))
    return (255 * np.clip(np.concatenate([port[:, ::-1], stbd], axis=1) / full, 0, 1)).astype(np.uint8)


def summary(unit, device) -> dict:
    """The device record's content in numbers (see the module docstring)."""
    water = device.slant_range_m < 0.9 * H
    full = 2 ** device.sonar.receiver.adc_bits - 1
    return {"dtype": str(device.samples.dtype), "clipped_share": float(np.mean(device.samples == full)),
            "median_code_water_column": float(np.median(device.samples[:, :, water])),
            "median_unit_source_water_column": float(np.median(unit.data[:, :, unit.slant_range_m < 0.9 * H])),
            "pings": int(device.n_pings), "ping_rate_hz": float(1.0 / np.diff(device.trajectory.times_s)[0])}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "device"), help="output folder")
    p.add_argument("--length", type=float, default=40.0, help="line length, m (pings every 0.2 m)")
    args = p.parse_args(argv)
    if not args.length > 0.2:
        p.error(f"--length must exceed one ping spacing (0.2 m), got {args.length}")
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from multipath_figure import _images  # the gallery's common display grey scale
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    unit, device = records(se, args.length)
    plotting.mosaic_png([_images({"unit": unit})[0], device_image(device)],
                        ["unit source, expected intensity (display TVG)",
                         "device: 16-bit codes (SL, noise, speckle, jitter, 30 log R TVG)"],
                        os.path.join(args.output, "waterfalls.png"))
    text = json.dumps(summary(unit, device), indent=1) + "\n"
    atomic_write(os.path.join(args.output, "device.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("waterfalls.png", "device.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

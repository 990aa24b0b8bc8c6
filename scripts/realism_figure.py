"""A real-looking line beside today's default one (issue 38).

    python scripts/realism_figure.py [-o docs/realism] [--length 40]

A 600 kHz side-scan, 30 m range, 8 m above the floor, pings every 0.15 m, both lines with speckle, a 210 dB
source level and sea noise (8 m/s wind), stored by the same kind of receiver (−180 dB re 1 V/µPa, 30 log R TVG
from 20 dB, 16 bits):

- waterfalls.png  left, today's defaults: a flat fine-sand floor of the Lambert + Kirchhoff preset, white noise
                  over the whole sample band, every sample kept. Right, the realism of issue 38:
                  - a seabed of sand waves (8 m, 0.3 m high, asymmetric), a trawl mark, a scour around a
                    boulder field, a rock outcrop;
                  - the APL-UW fine sand;
                  - shell clutter (40 per m², −45 dB, 6 dB spread);
                  - the receiver's 25 kHz band-pass;
                  - a TVG that starts at 2 m and stops at 60 dB;
                  - 8-bit logarithmic codes, decimated by the maximum to 1024 samples per side.
                  Both are shown in dB of the amplitude their codes stand for, the top 50 dB.
- realism.json    per line: the scintillation index per range band, the level's spread, the lag-2 correlation
                  along range (the measures of ``sonar-embree replay``)

Needs matplotlib (the plots extra).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
H, F0, RANGE, SAMPLES = 8.0, 600e3, 30.0, 1024


def _sonar(se, realistic):
    gain = se.TVG(g0_db=20.0, k=30, start_range_m=2.0, max_gain_db=60.0) if realistic else se.TVG(g0_db=20.0, k=30)
    rx = (se.Receiver(sensitivity_db=-180.0, gain=gain, adc_bits=8, encoding="log", log_range_db=60.0,
                      bandwidth_hz=25e3) if realistic else se.Receiver(sensitivity_db=-180.0, gain=gain))
    sonar = se.Sonar.from_beamwidths(0.5, 50.0, frequency_hz=F0, tilt_deg=15.0, max_range_m=RANGE,
                                     source_level_db=210.0, receiver=rx)
    return se.Acquisition(sonar, se.Environment(noise=se.AmbientNoise(wind_speed_m_s=8.0)))


def _scenes(se, length_m):
    today = se.Scene().add(se.seafloor.flat((length_m + 80.0, 80.0)), label="seafloor",
                           material=se.Material(scattering=se.sediments.FINE_SAND))
    sand = se.Material(scattering=se.sediments.preset("apl-uw fine sand"),
                       clutter=se.Clutter(40.0, strength_db=-45.0, spread_db=6.0))
    half = 0.5 * length_m
    real = se.features.seabed(
        (length_m + 40.0, 70.0), 0.1,
        bedforms=dict(wavelength_m=8.0, height_m=0.3, crest_heading_deg=20.0, asymmetry=0.75),
        trawl_marks=[dict(start_m=(-half - 20, -25.0), end_m=(half + 20, -8.0), depth_m=0.2, width_m=1.0,
                          separation_m=3.0)],
        scours=[dict(centre_m=(0.3 * half, 18.0), radius_m=3.0, depth_m=0.3)],
        outcrops=[dict(centre_m=(-0.5 * half, 22.0), size_m=(10.0, 6.0), height_m=0.8)],
        boulder_field=dict(density_per_m2=0.01, d_min_m=0.4, d_max_m=2.0), materials={"seafloor": sand,
                                                                                   "sand_wave": sand})
    return today, real


def records(se, length_m):
    """(today's Record, the realistic Record) of the same line."""
    line = se.Trajectory.line((-0.5 * length_m, 0.0, H), (0.5 * length_m, 0.0, H), int(round(length_m / 0.15)) + 1)
    pulse = se.Pulse.cw(duration_s=50e-6)
    today, real = _scenes(se, length_m)
    a = se.simulate(today, line, _sonar(se, False), pulse, speckle=True, seed=3, start_time="2000-01-01")
    b = se.simulate(real, line, _sonar(se, True), pulse, speckle=True, seed=3, start_time="2000-01-01")
    return a, b


def stored(rec, n=SAMPLES):
    """The codes per side as stored: decimated by the maximum to ``n`` samples (pings, 2, n)."""
    from sonar_embree.io.xtf import decimate

    return np.stack([decimate(rec.samples[:, ch], n, "max") for ch in (0, 1)], axis=1)


def amplitude(codes, rx):
    """Volts at the ADC from the codes: linear steps, or the logarithmic encoding's inverse (code 0 → 0)."""
    c = codes.astype(float)
    if rx.encoding == "linear":
        return c * rx.step_v
    top = 2 ** rx.adc_bits - 1
    return np.where(c > 0, rx.full_scale_v * 10 ** ((c / top * rx.log_range_db - rx.log_range_db) / 20), 0.0)


def image(codes, rx, window_db=50.0):
    """Port mirrored beside starboard in dB of the stored amplitude, the top ``window_db`` below the 99.5th
    percentile as 8-bit grey: both lines on one footing, whatever their encoding."""
    a = amplitude(np.concatenate([codes[:, 0, ::-1], codes[:, 1]], axis=1), rx)
    with np.errstate(divide="ignore"):
        lev = 20 * np.log10(a)
    top = np.percentile(lev[np.isfinite(lev)], 99.5)
    return (255 * np.clip((lev - top + window_db) / window_db, 0, 1)).astype(np.uint8)


def stats(codes, rx) -> dict:
    """Per range band of the floor: scintillation index of the stored intensity (amplitude², each range column
    divided by its mean), the level's spread (dB) and the lag-2 correlation along range."""
    r = np.linspace(0.0, RANGE, codes.shape[2])
    out = {"bands_m": [], "scintillation_index": [], "level_spread_db": [], "range_lag2_correlation": []}
    for lo, hi in ((10.0, 15.0), (15.0, 22.0), (22.0, 29.0)):
        cols = (r >= lo) & (r < hi)
        i = amplitude(codes[:, :, cols], rx).reshape(-1, cols.sum()) ** 2
        norm = i / np.maximum(i.mean(axis=0), 1e-300)
        z = (norm - norm.mean(axis=0)) / np.maximum(norm.std(axis=0), 1e-300)
        lev = 10 * np.log10(np.maximum(norm, 1e-6))
        out["bands_m"].append([lo, hi])
        out["scintillation_index"].append(float(norm.var()))
        out["level_spread_db"].append(float(np.std(lev)))
        out["range_lag2_correlation"].append(float(np.mean(z[:, :-2] * z[:, 2:])))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "realism"), help="output folder")
    p.add_argument("--length", type=float, default=40.0, help="line length, m (pings every 0.15 m)")
    args = p.parse_args(argv)
    if not args.length >= 1.0:
        p.error(f"--length must be at least 1 m, got {args.length}")
    sys.path.insert(0, ROOT)
    import sonar_embree as se
    from sonar_embree.display import plotting
    from sonar_embree.io.files import atomic_write

    os.makedirs(args.output, exist_ok=True)
    today, real = records(se, args.length)
    a, b = stored(today), stored(real)
    rx_a, rx_b = today.sonar.receiver, real.sonar.receiver
    plotting.mosaic_png([image(a, rx_a), image(b, rx_b)],
                        ["today: flat preset sand, white noise", "issue 38: features, APL-UW, clutter, device"],
                        os.path.join(args.output, "waterfalls.png"))
    text = json.dumps({"today": stats(a, rx_a), "realistic": stats(b, rx_b)}, indent=1) + "\n"
    atomic_write(os.path.join(args.output, "realism.json"), lambda tmp: open(tmp, "w").write(text))
    for name in ("waterfalls.png", "realism.json"):
        print(os.path.join(args.output, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())

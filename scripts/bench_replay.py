"""`replay --fit --fit-beam --fit-pulse` of a 500-ping 600 kHz line: wall time, and the report's level against
grazing (docs/benchmarks.md, "replay --fit --fit-beam on a 500-ping line"; issue 52).

    python scripts/bench_replay.py            # 500 pings; prints one JSON line
    python scripts/bench_replay.py --pings 60 # a quick look

The line is the project's own record made with known settings: a 600 kHz side-scan 30 m range, membrane 40° wide
(one way, −3 dB) tilted 10° down, over APL-UW fine sand, altitude 2.5–4.5 m, roll swinging ±3°, speckle, a 50 µs
pulse, +12 dB, written as a device does (1024 samples a side, each the largest of its run). The replay fits the
class (the default four), the gain, the elevation pattern and the pulse on runs of pings across the altitudes, then
replays every ping. Reported: wall time of the whole command, the fitted tilt, width, class, gain and pulse, and the
RMS of recorded
minus replayed level against grazing angle over 5°–80° (bins with floor in both), all bins and the bins within
15 dB of the record's highest. No test reads the numbers.
"""
import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree.instrument.beam import membrane_size_for_beamwidth  # noqa: E402
from sonar_embree.survey import replay as R  # noqa: E402

F0, TILT_DEG, WIDTH_DEG, GAIN_DB, ROLL_DEG, SEDIMENT = 600e3, 10.0, 40.0, 12.0, 3.0, "apl-uw fine sand"


def make_line(path, n):
    """The hidden line, written to ``path``."""
    ly = membrane_size_for_beamwidth(math.radians(WIDTH_DEG), 1500.0 / F0)
    scene = se.Scene().add(se.seafloor.flat((800.0, 400.0)), material=se.Material(
        scattering=se.sediments.preset(SEDIMENT)), label="seafloor")
    k = np.arange(n)
    pos = np.stack([-0.5 * 0.3 * n + 0.3 * k, np.zeros(n), 3.5 - np.cos(2 * np.pi * k / max(n, 2))], axis=1)
    traj = se.Trajectory(pos, 90.0, 0.0, ROLL_DEG * np.sin(2 * np.pi * k / 17.0), 0.15 * k)
    rec = se.simulate(scene, traj, se.Sonar(frequency_hz=F0, max_range_m=30.0, tilt_deg=TILT_DEG, height_m=ly),
                      se.Pulse.cw(duration_s=50e-6), speckle=True, seed=4, start_time="2026-05-01T12:00:00Z")
    se.Record(rec.data * 10 ** (GAIN_DB / 10), rec.time_s, rec.trajectory, rec.sonar, rec.pulse, rec.altitude_m,
              rec.attrs).to_xtf(path, scale=1.0, samples_per_channel=1024)


def rms(report, depth_db=None):
    real, sim = (np.array(report[k]["level_vs_grazing_db"], float) for k in ("recorded", "simulated"))
    g = np.array(report["recorded"]["grazing_deg"])
    keep = np.isfinite(real) & np.isfinite(sim) & (g >= 5.0) & (g <= 80.0)
    if depth_db is not None:
        keep &= real >= np.nanmax(real[keep]) - depth_db
    return round(float(np.sqrt(np.mean((real[keep] - sim[keep]) ** 2))), 2), int(keep.sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pings", type=int, default=500)
    args = ap.parse_args(argv)
    work = tempfile.mkdtemp()
    line = os.path.join(work, "line.xtf")
    make_line(line, args.pings)
    t0 = time.perf_counter()
    rep = R.replay(line, os.path.join(work, "out"), fit_classes=R.FIT_CLASSES, fit_beam=True, fit_pulse=True, seed=3,
                 progress=True)
    wall = time.perf_counter() - t0
    beam = rep["fit"]["elevation"]
    print(json.dumps({"pings": args.pings, "wall_s": round(wall, 1), "class": rep["fit"]["sediment"],
                      "gain_db": round(rep["gain_offset_db"], 2), "tilt_deg": beam["tilt_deg"],
                      "width_deg": beam["vertical_beamwidth_deg"], "pulse_us": round(rep["fit"]["pulse_s"] * 1e6, 1),
                      "correlation_errors": rep["fit"]["correlation_errors"], "rms_5_80_db": rms(rep),
                      "rms_5_80_within_15_db": rms(rep, R.FIT_ELEVATION_DEPTH_DB)}), flush=True)


if __name__ == "__main__":
    main()

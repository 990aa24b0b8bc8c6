"""Cost of refraction (curved rays in a sound-speed profile) against the straight-ray ping (docs/benchmarks.md).

    python scripts/bench_refraction.py            # prints one JSON line
    python scripts/bench_refraction.py --paired 5 # the ratio only: 5 rounds of straight and curved in turn, one
                                                  # process; each round's ratio and the median

Cases: the flat floor (10 m altitude, 60 m range) and the shipwreck pass, each with straight rays and in a linear
profile (gradient 0.5 s⁻¹, the sonar 20 m deep), and in the profile under a flat surface (its paths along curved
rays, docs/physics.md §12b) and under a swell (H = 0.4 m, Λ = 8 m: curved rays off its facets, §13c);
speckle-free. ms per ping, best of three, the stage times, and the rounds of chords the curved rays took. No test
reads it.
"""
import dataclasses
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import sonar_embree as se  # noqa: E402
from sonar_embree import shipwreck  # noqa: E402
from bench_multipath import _best, _wall  # noqa: E402  (ms per stage and ping, best of three: one definition)


def main() -> int:
    flat = se.Scene().add(se.seafloor.flat((400.0, 200.0)), label="seafloor")
    line = se.Trajectory.line((-3.2, 0.0, 10.0), (3.2, 0.0, 10.0), 64)
    ship = shipwreck.shipwreck_scene(resolution_m=0.2)
    ship_pass = shipwreck.straight_pass(30, ping_rate_hz=1.0)
    cases = {"flat": (flat, line, se.Sonar(max_range_m=60.0)), "ship": (ship, ship_pass, se.Sonar())}
    se.simulate(flat, line[:2], start_time="2000-01-01")  # compile
    out = {}
    for name, (scene, traj, sonar) in cases.items():
        z = float(traj.positions_m[:, 2].max()) + 20.0
        profile = se.SoundSpeedProfile.linear(se.Acquisition.of(sonar).sound_speed_m_s - 0.5 * 20.0, 0.5, surface_z_m=z)
        bent = se.Acquisition(sonar, se.Environment(sound_speed=profile))
        se.simulate(scene, traj[:2], bent, start_time="2000-01-01")  # compile the curved path
        if "--paired" in sys.argv:
            rounds = []
            for _ in range(int(sys.argv[sys.argv.index("--paired") + 1])):
                d, b = _wall(scene, traj, sonar), _wall(scene, traj, bent)
                rounds.append((round(d, 2), round(b / d, 2)))
            out[name] = {"rounds (straight ms, ratio)": rounds,
                         "median ratio": float(sorted(r[1] for r in rounds)[len(rounds) // 2])}
            continue
        wet = se.Acquisition(sonar, se.Environment(sound_speed=profile,
                                                                    surface=se.SeaSurface(z_m=z)))
        swell = se.Acquisition(sonar, se.Environment(sound_speed=profile, surface=se.SeaSurface(
            z_m=z, swell_height_m=0.4, swell_length_m=8.0)))
        se.simulate(scene, traj[:2], wet, start_time="2000-01-01")  # compile the surface's curved paths
        se.simulate(scene, traj[:2], swell, start_time="2000-01-01")
        out[name] = {"straight": _best(scene, traj, sonar), "profile": _best(scene, traj, bent),
                     "profile_surface": _best(scene, traj, wet), "profile_swell": _best(scene, traj, swell)}
        for k in ("profile", "profile_surface", "profile_swell"):
            out[name][f"ratio {k}"] = round(out[name][k]["total"] / out[name]["straight"]["total"], 2)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

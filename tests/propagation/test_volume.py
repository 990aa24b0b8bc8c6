"""Water-column volume reverberation (docs/physics.md §14b) against Urick's closed form, with the equivalent beam
angle Ψ = ∫Γ⁴dΩ and the floor's cut of it computed here by brute spherical quadrature."""
import math

import numpy as np
import pytest
import trimesh

import analytic
import sonar_embree as se
from sonar_embree.errors import ConfigError

SV, TAU, LX, LY, LAM, TILT = -70.0, 100e-6, 0.19, 0.0038, 1500.0 / 400e3, 20.0


def _gamma4(u, v, w):
    return analytic.membrane_pattern(LX, LY, LAM)(u, v) ** 4


def _record(scene, traj, **kw):
    sonar = se.Acquisition(se.Sonar(max_range_m=30.0), se.Environment(volume_backscatter_db=SV, noise=None))
    return se.simulate(scene, traj, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01", **kw)


def _urick(rec, psi):
    """σ_v·Ψ·∫dR'/R'² over the shell the rect pulse covers at each sample, R − cτ/2 … R (Urick's σ_v·Ψ·(cτ/2)/R²
    for R ≫ cτ/2), times the two-way absorption at the shell's middle."""
    r, half = rec.slant_range_m, 750.0 * TAU
    a2 = 2 * rec.acquisition.alpha_db_per_m * math.log(10) / 10
    with np.errstate(divide="ignore", invalid="ignore"):
        return 10 ** (SV / 10) * psi * (1 / (r - half) - 1 / r) * np.exp(-a2 * (r - half / 2))


@pytest.mark.parametrize("speckle", [False, True])
def test_an_open_water_column_gives_uricks_volume_reverberation(speckle):
    plate = trimesh.creation.box((1.0, 1.0, 0.1))
    plate.apply_translation((-20.0, 0.0, 100.0))                            # in range, but nothing below the sonar
    rec = _record(se.Scene().add(plate), se.Trajectory.line((0, 0, 100.0), (1, 0, 100.0), 60),
                  **({"speckle": True, "seed": 2} if speckle else {}))
    psi = analytic.hemisphere_integral(_gamma4)
    r = rec.slant_range_m
    sel = (r > 5) & (r < 25)
    for side in (rec.port, rec.starboard):
        ratio = side[:, sel] / _urick(rec, psi)[sel]                          # pings × samples
        if speckle:                                                           # pooled: 60 pings × 1067 samples
            assert 10 * np.log10(ratio.mean()) == pytest.approx(0.0, abs=0.2)
            metre = ratio.reshape(ratio.shape[0], 11, -1).mean(axis=(0, 2))   # about 2 m bands
            assert np.max(np.abs(10 * np.log10(metre))) < 0.5
        else:
            assert np.max(np.abs(10 * np.log10(ratio.mean(axis=0)))) < 0.05


def test_the_floor_cuts_the_column_as_its_directions_meet_it():
    """Over a level floor 10 m down, at range R only the directions whose downward cosine is below 10/R still hold
    water: Ψ_open(R) by quadrature of the pattern with that mask, the record within 0.2 dB."""
    h = 10.0
    floor = se.seafloor.flat((200.0, 200.0))
    rec = _record(se.Scene().add(floor, material=se.Material(backscatter_db=-200.0)),
                  se.Trajectory.line((0, 0, h), (1, 0, h), 3))
    d = math.radians(TILT)
    for r_m in (12.0, 16.0, 22.0, 28.0):
        open_psi = analytic.hemisphere_integral(lambda u, v, w: _gamma4(u, v, w) * (r_m * (v * math.cos(d) +
                                                                                          w * math.sin(d)) < h))
        k = int(np.argmin(np.abs(rec.slant_range_m - r_m)))
        got = rec.starboard[:, k].mean()
        assert 10 * np.log10(got / _urick(rec, open_psi)[k]) == pytest.approx(0.0, abs=0.2), r_m
    assert open_psi < 0.6 * analytic.hemisphere_integral(_gamma4)            # at 28 m the floor cuts nearly half


def test_bad_values_and_other_sonar_types_are_refused():
    with pytest.raises(ConfigError, match="volume_backscatter_db"):
        se.Environment(volume_backscatter_db=5.0)
    es = se.Acquisition(se.EchoSounder(max_range_m=10.0), se.Environment(volume_backscatter_db=-70.0))
    scene = se.Scene().add(se.seafloor.flat((20.0, 20.0)))
    with pytest.raises(ConfigError, match="side-scan Sonar, not EchoSounder"):
        se.simulate(scene, se.Trajectory.line((0, 0, 5.0), (1, 0, 5.0), 2), es, se.Pulse.cw(),
                    start_time="2000-01-01")

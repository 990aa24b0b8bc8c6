"""The medium's seam: Environment, its absorption models and the TOML [environment] table (docs/physics.md §3)."""

import copy
import dataclasses
import json
import pickle

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree import runconfig, sonars
from sonar_embree.environment import ABSORPTION_MODELS
from sonar_embree.environment.ainslie_mccolm import ainslie_mccolm_db_per_m
from sonar_embree.environment.francois_garrison import francois_garrison_db_per_m
from sonar_embree.config import LEGACY_MEDIUM_KEYS, split_medium

import analytic
from conftest import flat_scene, write_anchor_config as _write


@pytest.mark.parametrize("t_c", [-2.0, 4.0, 10.0, 15.0, 22.0])
@pytest.mark.parametrize("f_hz", [1e3, 10e3, 100e3, 400e3, 900e3])
@pytest.mark.parametrize("depth_m", [0.0, 500.0])
def test_ainslie_mccolm_within_10_percent_of_francois_garrison(t_c, f_hz, depth_m):
    """The second absorption model against the first, over its published validity (docs/physics.md §3)."""
    am = ainslie_mccolm_db_per_m(f_hz, t_c, 35.0, depth_m, 8.0)
    fg = francois_garrison_db_per_m(f_hz, t_c, 35.0, depth_m, 8.0)
    assert abs(am / fg - 1.0) < 0.10, (am, fg)


def test_ainslie_mccolm_matches_its_independent_twin():
    for f, t, s, d, ph in [(400e3, 10, 35, 0, 8), (50e3, 4, 30, 2000, 7.7), (900e3, 20, 34, 100, 8.2)]:
        assert ainslie_mccolm_db_per_m(f, t, s, d, ph) * 1e3 == pytest.approx(
            analytic.ainslie_mccolm_db_per_km(f, t, s, d, ph), rel=1e-12)
    assert ainslie_mccolm_db_per_m(400e3) == pytest.approx(0.1011, abs=1e-4)


def test_environment_chooses_the_model_and_the_override_wins():
    fg, am = se.Environment(), se.Environment(absorption_model="ainslie-mccolm")
    assert fg.alpha_db_per_m(400e3) == francois_garrison_db_per_m(400e3)
    assert am.alpha_db_per_m(400e3) == ainslie_mccolm_db_per_m(400e3)
    assert se.Environment(absorption_model="ainslie-mccolm", absorption_db_per_m=0.05).alpha_db_per_m(400e3) == 0.05
    assert set(ABSORPTION_MODELS) == {"francois-garrison", "ainslie-mccolm"}
    with pytest.raises(se.ConfigError, match="Environment.absorption_model.*'thorp'"):
        se.Environment(absorption_model="thorp")
    with pytest.raises(se.ConfigError, match="Environment.sound_speed_m_s"):
        se.Environment(sound_speed_m_s=-1.0)


def test_the_medium_is_a_run_input_and_the_acquisition_resolves_c_lambda_alpha_once():
    """Issue 51, item 3: no sonar type has an environment field; an Acquisition pairs a sonar with its medium and
    holds c, λ = c/f0, k = 2π f0/c and α(f0) as fields made on construction."""
    env = se.Environment(sound_speed_m_s=1480.0, temperature_c=4.0)
    for cls in sonars.SONAR_TYPES:
        assert "environment" not in {f.name for f in dataclasses.fields(cls)}, cls
        with pytest.raises(TypeError, match="environment"):
            cls(environment=env)
    acq = se.Acquisition(se.Sonar(), env)
    assert acq.sound_speed_m_s == 1480.0 and acq.wavelength_m == pytest.approx(1480.0 / 400e3)
    assert acq.wavenumber_rad_m == pytest.approx(2 * np.pi * 400e3 / 1480.0)
    assert acq.alpha_db_per_m == env.alpha_db_per_m(400e3) and acq.frequency_hz == 400e3   # the sonar's, read through
    assert {"sound_speed_m_s", "wavelength_m", "wavenumber_rad_m", "alpha_db_per_m"} <= set(vars(acq))
    assert pickle.loads(pickle.dumps(acq)) == acq and copy.deepcopy(acq) == acq
    with pytest.raises(AttributeError):
        acq.no_such_field
    # the beam follows the water: the same membrane is narrower in slower water (λ smaller)
    assert acq.directivity_index_db > se.Acquisition(se.Sonar()).directivity_index_db
    for key in LEGACY_MEDIUM_KEYS:       # the medium's keys are the environment's, not the instrument's
        with pytest.raises(TypeError, match=key):
            se.Sonar(**{key: 1.0})
    with pytest.raises(se.ConfigError, match="give the medium once"):
        se.simulate(flat_scene(), se.Trajectory.line((0, 0, 10), (1, 0, 10), 2), acq, environment=se.Environment())
    with pytest.raises(se.ConfigError, match="Acquisition.environment"):
        se.Acquisition(se.Sonar(), "sea")


def test_old_toml_medium_keys_in_sonar_are_mapped_with_a_deprecation_warning(tmp_path):
    cfg = tmp_path / "old.toml"
    cfg.write_text('[sonar]\nmax_range_m = 20.0\nsound_speed_m_s = 1480.0\ntemperature_c = 4.0\n'
                   '[trajectory]\nkind = "line"\nstart = [0, 0, 10]\nend = [1, 0, 10]\nn_pings = 2\n'
                   '[[objects]]\nseafloor = "flat"\nsize_m = [40, 40]\nlabel = "seafloor"\n'
                   '[objects.material]\nlaw = { kind = "lambert", backscatter_db = -20.0 }\n')
    with pytest.warns(FutureWarning) as caught:
        run = runconfig.load_run_config(cfg)
    said = [str(w.message) for w in caught]
    assert any("sound_speed_m_s, temperature_c belong in [environment]" in m for m in said), said
    assert any("'law' is now called 'scattering'" in m for m in said), said
    assert run.environment == se.Environment(sound_speed_m_s=1480.0, temperature_c=4.0)
    assert run.scene.compiled(np.zeros(3)).laws[0] == se.laws.Lambert(-20.0)


def test_a_record_saved_with_the_medium_in_its_sonar_table_loads():
    meta = {"frequency_hz": 400e3, "max_range_m": 20.0, "sound_speed_m_s": 1480.0}
    table, env = split_medium(meta, "Sonar")
    sonar = se.Sonar(**table)
    assert env.sound_speed_m_s == 1480.0 and sonar.max_range_m == 20.0
    nested = {"frequency_hz": 400e3, "environment": {"sound_speed_m_s": 1490.0}}   # the medium inside the sonar
    assert split_medium(nested, "Sonar") == ({"frequency_hz": 400e3}, se.Environment(sound_speed_m_s=1490.0))


def test_a_file_written_before_the_medium_left_the_sonar_loads_with_its_medium(tmp_path):
    """The previous file layout (the environment nested in the sonar's table, no top-level one) loads with that
    medium, so its slant ranges (c·t/2) are the ones it was simulated with."""
    water = se.Environment(sound_speed_m_s=1480.0, surface=se.SeaSurface(z_m=30.0))
    rec = se.simulate(flat_scene(), se.Trajectory.line((0, 0, 10), (0.2, 0, 10), 2), se.Sonar(max_range_m=20.0),
                      environment=water, start_time="2000-01-01")
    rec.save(tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz") as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["meta"]))
    meta["sonar"]["environment"] = meta.pop("environment")              # as the files before this change hold it
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **arrays)
    old = se.Record.load(tmp_path / "old.npz")
    assert old.environment == water and old.sonar == rec.sonar
    np.testing.assert_array_equal(old.slant_range_m, 0.5 * 1480.0 * rec.time_s)


def test_simulate_uses_the_environment_given():
    traj = se.Trajectory.line((0, 0, 10), (0.2, 0, 10), 2)
    sonar = se.Sonar(max_range_m=20.0)
    warm = se.Environment(temperature_c=20.0)
    scene = flat_scene()
    a = se.simulate(scene, traj, sonar, environment=warm, start_time="2000-01-01")
    b = se.simulate(scene, traj, se.Acquisition(se.Sonar(max_range_m=20.0), warm), start_time="2000-01-01")
    c = se.simulate(scene, traj, sonar, start_time="2000-01-01")
    assert a.environment == warm and a.attrs["alpha_db_per_m"] == warm.alpha_db_per_m(400e3)
    assert np.array_equal(a.port, b.port)
    # warmer water absorbs more at 400 kHz: 2·Δα·R dB less at slant range R (docs/physics.md eq. 1)
    r = a.slant_range_m
    k = np.argmin(np.abs(r - 18.0))
    d_alpha = warm.alpha_db_per_m(400e3) - se.Environment().alpha_db_per_m(400e3)
    ratio_db = 10 * np.log10(a.port[:, k] / c.port[:, k])
    assert ratio_db == pytest.approx(-2 * d_alpha * r[k], abs=0.02)
    with pytest.raises(se.ConfigError, match="simulate: environment"):
        se.simulate(scene, traj, sonar, environment={"temperature_c": 4})




def test_toml_environment_table_and_old_sonar_keys(tmp_path):
    cfg = runconfig.load_run_config(_write(tmp_path, env="temperature_c = 4.0\nabsorption_model = \"ainslie-mccolm\"\n"))
    assert cfg.environment.temperature_c == 4.0
    assert cfg.environment.absorption_model == "ainslie-mccolm"
    old = runconfig.load_run_config(_write(tmp_path, sonar_extra="temperature_c = 4.0\n"))
    assert old.environment.temperature_c == 4.0
    with pytest.raises(se.ConfigError, match="'temperature_c' is given in both"):
        runconfig.load_run_config(_write(tmp_path, sonar_extra="temperature_c = 4.0\n", env="temperature_c = 5.0\n"))
    with pytest.raises(se.ConfigError, match="unknown key 'salinity' in \\[environment\\]"):
        runconfig.load_run_config(_write(tmp_path, env="salinity = 35.0\n"))


def test_toml_sea_surface(tmp_path):
    cfg = runconfig.load_run_config(_write(tmp_path, env="surface = { z_m = 30.0, rms_wave_height_m = 0.001 }\n"))
    assert cfg.environment.surface == se.SeaSurface(z_m=30.0, rms_wave_height_m=0.001)
    with pytest.raises(se.ConfigError, match="unknown key 'height' in Environment.surface|Environment.surface: "
                                             "unknown key 'height'"):
        runconfig.load_run_config(_write(tmp_path, env="surface = { z_m = 30.0, height = 1.0 }\n"))

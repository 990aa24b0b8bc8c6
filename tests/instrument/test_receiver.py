"""The receive chain (docs/physics.md §15): sensitivity, TVG / AGC and the ADC, against the formulas written here.

    v = 10^(S/20)·√I (V rms, I in µPa²),  TVG: v·10^((G0 + k log10 max(R, 1) + 2αR)/20),  R = c t / 2,
    code = clip(rint(v/Δ), 0, 2^b − 1),  Δ = V_fs/(2^b − 1);  rounding error variance Δ²/12 (Widrow & Kollár).
"""
import numpy as np
import pytest

import sonar_embree as se


def _scene(target=False):
    scene = se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=se.Material(backscatter_db=-27.0),
                           label="seafloor")
    if target:
        import trimesh

        box = trimesh.creation.box((1.0, 1.0, 1.0))
        box.apply_translation((0.0, 20.0, 0.5))
        scene.add(box, material=se.Material(backscatter_db=0.0), label="block")
    return scene


def _record(receiver, target=False, pings=3, **kw):
    sonar = se.Sonar(max_range_m=35.0, source_level_db=210.0, receiver=receiver, **kw)
    return se.simulate(_scene(target), se.Trajectory.line((-0.2, 0, 10.0), (0.2, 0, 10.0), pings), sonar,
                       se.Pulse.cw(), start_time="2000-01-01")


def _codes(rec, s_db, g0, k, bits, vfs):
    r = np.maximum(rec.slant_range_m, 1.0)
    g = g0 + k * np.log10(r) + 2 * rec.acquisition.alpha_db_per_m * r
    v = 10 ** (s_db / 20) * np.sqrt(rec.data) * 10 ** (g / 20)
    return np.clip(np.rint(v / (vfs / (2 ** bits - 1))), 0, 2 ** bits - 1), v


def test_quantisation_error_of_a_ramp_has_variance_delta_squared_over_12():
    rx = se.Receiver(adc_bits=10, full_scale_v=2.0)
    ramp = np.linspace(0.0, 2.0, 1_000_003)[:-1]
    delta = 2.0 / (2 ** 10 - 1)
    err = rx.digitise(ramp).astype(float) * delta - ramp
    assert np.var(err) == pytest.approx(delta ** 2 / 12, rel=0.05)
    assert np.abs(err).max() <= delta / 2 + 1e-12 and rx.digitise(ramp).dtype == np.uint16
    assert se.Receiver(adc_bits=8).digitise(np.array([0.5])).dtype == np.uint8


def test_samples_follow_sensitivity_tvg_and_adc():
    """The record's samples equal the chain applied to its own µPa² intensities, for k = 20, 30 and 40."""
    for k, g0 in ((20, 60.0), (30, 45.0), (40, 25.0)):
        rx = se.Receiver(sensitivity_db=-195.0, gain=se.TVG(g0_db=g0, k=k), adc_bits=12, full_scale_v=1.5)
        rec = _record(rx)
        want, _ = _codes(rec, -195.0, g0, k, 12, 1.5)
        np.testing.assert_array_equal(rec.samples, want)
        assert rec.samples.dtype == np.uint16 and np.mean(rec.samples == 4095) < 0.2 and rec.samples.max() > 100


def test_a_bright_target_clips_at_full_scale():
    rx = se.Receiver(sensitivity_db=-170.0, gain=se.TVG(g0_db=40.0, k=30), adc_bits=16, full_scale_v=1.0)
    rec = _record(rx, target=True)
    _, volts = _codes(rec, -170.0, 40.0, 30, 16, 1.0)
    over = volts > 1.0
    assert over[:, 1].any() and np.all(rec.samples[over] == 65535)           # the block, starboard
    assert np.all(rec.samples[~over] < 65535) and np.any(rec.samples[~over] > 1000)


def test_agc_holds_the_moving_rms_at_its_target():
    """AGC: the gained signal's RMS over the window is target·V_fs wherever the floor is lit (speckle-free)."""
    rx = se.Receiver(gain=se.AGC(window_s=2e-3, target=0.3), adc_bits=16)
    rec = _record(rx)
    fs = rec.sonar.sample_rate_hz
    floor = (rec.slant_range_m > 14.0) & (rec.slant_range_m < 33.0)
    n = int(round(2e-3 * fs))
    x = rec.samples[:, 1].astype(float) * (1.0 / 65535)
    rms = np.sqrt(np.convolve(x[0] ** 2, np.ones(n) / n, mode="same"))
    np.testing.assert_allclose(rms[floor], 0.3, rtol=0.05)


def test_receiver_errors_and_toml(tmp_path):
    with pytest.raises(se.ConfigError, match="receiver needs source_level_db"):
        se.Sonar(receiver=se.Receiver())
    for bad, needle in ((dict(adc_bits=17), "adc_bits"), (dict(adc_bits=True), "adc_bits"),
                        (dict(full_scale_v=0.0), "full_scale_v"), (dict(gain={"kind": "tvg", "k": 35}), "TVG.k"),
                        (dict(gain={"kind": "boost"}), "kind"), (dict(gain={"k": 30, "slope": 1}), "'slope'")):
        with pytest.raises(se.ConfigError, match=needle):
            se.Receiver(**bad)
    from conftest import write_anchor_config as _write

    from sonar_embree import runconfig

    cfg = runconfig.load_run_config(_write(tmp_path, sonar_extra=(
        "source_level_db = 210.0\nreceiver = { sensitivity_db = -175.0, adc_bits = 8, "
        "gain = { kind = \"tvg\", k = 40, g0_db = 10.0 } }\n")))
    assert cfg.sonar.receiver == se.Receiver(sensitivity_db=-175.0, adc_bits=8, gain=se.TVG(g0_db=10.0, k=40))
    with pytest.raises(se.ConfigError, match="'bits'"):
        runconfig.load_run_config(_write(tmp_path, sonar_extra="source_level_db = 210.0\nreceiver = { bits = 8 }\n"))


def test_samples_survive_files_and_xtf_holds_them_as_a_device_would(tmp_path):
    """npz round trip, the dataset's *_samples variables, and pyxtf reading uint16 codes with the gain codes."""
    import pyxtf

    rx = se.Receiver(gain=se.TVG(g0_db=30.0, k=40), adc_bits=16, full_scale_v=2.5)
    rec = _record(rx)
    rec.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz")
    np.testing.assert_array_equal(back.samples, rec.samples)
    assert back.samples.dtype == np.uint16 and back.sonar == rec.sonar
    ds = rec.to_xarray()
    np.testing.assert_array_equal(ds["starboard_samples"].values, rec.samples[:, 1])
    assert ds.attrs["receiver.gain.k"] == 40 and ds.attrs["receiver.gain.kind"] == "tvg"
    rec.to_xtf(tmp_path / "r.xtf")
    fh, packets = pyxtf.xtf_read(str(tmp_path / "r.xtf"))
    ping = packets[pyxtf.XTFHeaderType.sonar][1]
    np.testing.assert_array_equal(ping.data[1], rec.samples[1, 1])
    np.testing.assert_array_equal(ping.data[0], rec.samples[1, 0, ::-1])           # port from far range in
    assert ping.data[1].dtype == np.uint16 and fh.sonar_info[0].VoltScale == pytest.approx(2.5)
    assert ping.ping_chan_headers[1].GainCode == 40 and ping.ping_chan_headers[1].InitialGainCode == 30
    rec.to_xtf(tmp_path / "f.xtf", samples=False)
    _, floats = pyxtf.xtf_read(str(tmp_path / "f.xtf"))
    assert floats[pyxtf.XTFHeaderType.sonar][1].data[1].dtype == np.float32


def test_a_tvg_that_overflows_is_refused_before_any_ping(monkeypatch):
    """Issue 33, finding 6: 100 dB/m absorption made the receiver's TVG overflow into an all-65535 record with
    numpy's warning only (the chain's tvg=True refused the same set-up); now refused, in one line, before any ray."""
    import sys

    sim_module = __import__("importlib").import_module("sonar_embree.simulate")

    sonar = se.Acquisition(se.Sonar(max_range_m=45.0, source_level_db=210.0,
                     receiver=se.Receiver(gain=se.TVG(k=30))), se.Environment(absorption_db_per_m=100.0))
    cast = []
    monkeypatch.setattr(sim_module._Run, "setup", lambda *a, **k: cast.append(1))
    with pytest.raises(se.ConfigError, match=r"Receiver TVG: the gain reaches 9\d\d\d dB at max_range_m = 45 m "
                                             r"with 100 dB/m absorption, beyond float64"):
        se.simulate(_scene(), se.Trajectory.line((-0.2, 0, 10.0), (0.2, 0, 10.0), 3), sonar)
    assert cast == []
    ok = se.Acquisition(se.Sonar(max_range_m=45.0, source_level_db=210.0,
                  receiver=se.Receiver(gain=se.TVG(k=30, absorption=False))), se.Environment(absorption_db_per_m=100.0))
    se.Receiver(gain=ok.receiver.gain).gain.check_range(45.0, 100.0)      # without the 2αR term: fine


def test_agc_does_not_stretch_round_off_into_codes():
    """Issue 33, finding 6: AGC on a record whose largest value is 1e-187 µPa² (no noise, nothing lit) gave
    72 non-zero codes; the amplifier's gain is bounded (max_gain_db), so such a record stays at code 0, while a
    lit floor still reaches its target (test_agc_holds_the_moving_rms_at_its_target)."""
    rx = se.Receiver(gain=se.AGC(window_s=2e-3, target=0.3), adc_bits=16)
    sonar = se.Sonar(max_range_m=40.0, source_level_db=210.0, receiver=rx).for_pulse(se.Pulse.cw())
    tiny = np.full((2, 2, 500), 2e-187)
    tiny[:, :, ::7] = 0.0
    assert rx.samples(tiny, np.arange(500) / sonar.sample_rate_hz, se.Acquisition.of(sonar)).max() == 0
    # the bound itself: 160 dB on 1 µPa² at −180 dB re 1 V/µPa is 1e-9 V × 1e8 = 0.1 V
    one = rx.samples(np.ones((1, 1, 500)), np.arange(500) / sonar.sample_rate_hz, se.Acquisition.of(sonar))
    np.testing.assert_allclose(one[0, 0, 250], round(0.1 / rx.step_v), atol=1)


@pytest.mark.parametrize("value", ["no", "false", 1, None])
def test_bool_keys_take_only_booleans(value, tmp_path):
    """Issue 33, finding 7: TVG(absorption="no") was taken as true (a non-empty string); every bool-like key
    takes only True or False."""
    with pytest.raises(se.ConfigError, match=r"TVG.absorption must be True or False"):
        se.TVG(absorption=value)
    with pytest.raises(se.ConfigError, match=r"simulate.labels must be True or False"):
        se.simulate(_scene(), se.Trajectory.line((-0.2, 0, 10.0), (0.2, 0, 10.0), 3), se.Sonar(max_range_m=20.0), labels=value)
    if value is not None:                                               # None: the default, by label
        with pytest.raises(se.ConfigError, match=r"Scene.add.seafloor must be True, False or None"):
            se.Scene().add(se.seafloor.flat((10.0, 10.0)), label="floor", seafloor=value)
    from conftest import write_anchor_config as _write

    from sonar_embree import runconfig

    if isinstance(value, str):
        with pytest.raises(se.ConfigError, match=r"TVG.absorption must be True or False"):
            runconfig.load_run_config(_write(tmp_path, sonar_extra=(
                f"source_level_db = 210.0\nreceiver = {{ gain = {{ kind = \"tvg\", absorption = \"{value}\" }} }}\n")))


def test_a_device_record_is_drawn_from_its_codes():
    """Issue 50: a waterfall of a record with a receiver is what a viewer draws from its stored codes (code², no
    display TVG), not the floats: the water column before the first return is black, as in the XTF."""
    import dataclasses

    from sonar_embree.display.waterfall import waterfall_image

    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    rx = se.devices.device("cmax-cm2-325").receiver(g0_db=-20.0, start_range_m=9.0)
    sonar = se.Sonar.preset("cmax-cm2-325", max_range_m=25.0, receiver=rx)
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, 10), (1, 0, 10), 12), sonar, se.Pulse.preset("cmax-cm2-325"),
                      start_time="2000-01-01")
    assert rec.samples is not None and rec.samples.max() > 0
    as_floats = dataclasses.replace(rec, data=rec.samples.astype(float) ** 2, samples=None)
    img = waterfall_image(rec, max_columns=None)
    np.testing.assert_array_equal(img, waterfall_image(as_floats, max_columns=None, tvg=False))
    n = rec.data.shape[2]
    water = rec.slant_range_m < 9.0                                    # before the first return at 10 m
    assert np.all(img[:, n:][:, water] == 0) and img[:, n:][:, ~water].mean() > 50

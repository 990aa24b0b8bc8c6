"""The signal chain (docs/physics.md §5): bands, detection, matched filter, noise, TVG, options."""
import numpy as np
import pytest

import analytic
import sonar_embree as se
from conftest import H, box, facing_plate, flat_scene, line_along_x
from sonar_embree.signal import processing, pulses


def _rel_rms(a, b):
    return np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2))


@pytest.fixture(scope="module")
def scene_with_box():
    return flat_scene().add(box((1.0, 1.0, 1.0), (0.0, -15.0, 0.5)), label="box")


@pytest.mark.parametrize("pulse", [se.Pulse.cw(), se.Pulse.lfm(bandwidth_hz=15e3, duration_s=0.5e-3)],
                         ids=["cw", "lfm"])
def test_baseband_and_carrier_agree(scene_with_box, pulse):
    sonar = se.Sonar(max_range_m=30.0)
    traj = line_along_x(n_pings=2)
    bb = se.simulate(scene_with_box, traj, sonar, pulse, speckle=True, seed=5)
    ca = se.simulate(scene_with_box, traj, sonar, pulse, speckle=True, seed=5, band="carrier")
    assert ca.attrs["carrier_rate_hz"] >= 4 * 400e3
    for side in ("port", "starboard"):
        assert _rel_rms(getattr(ca, side), getattr(bb, side)) < 0.02
    if not pulse.is_fm:
        inc = se.simulate(scene_with_box, traj, sonar, pulse, speckle=True, seed=5, band="carrier",
                          detection="incoherent")
        for side in ("port", "starboard"):
            assert _rel_rms(getattr(inc, side), getattr(bb, side)) < 0.02


def test_a_rectangular_pulse_is_where_bands_differ(scene_with_box):
    # Documented limit: a rectangle's edges are resolved only at the carrier rate.
    sonar = se.Sonar(max_range_m=30.0)
    rect = se.Pulse.cw(taper=0.0)
    bb = se.simulate(scene_with_box, line_along_x(n_pings=1), sonar, rect, speckle=True)
    ca = se.simulate(scene_with_box, line_along_x(n_pings=1), sonar, rect, speckle=True, band="carrier")
    assert 0.02 < _rel_rms(ca.starboard, bb.starboard) < 0.15


def test_detectors_on_a_steady_tone():
    fc, f0 = 1.6e6, 400e3
    t = np.arange(40000) / fc
    amp = 0.7 * np.exp(0.4j)
    x = (amp * np.exp(2j * np.pi * f0 * t)).real
    coherent = np.abs(processing.analytic_baseband(x, f0, fc)) ** 2
    incoherent = processing.square_law(x, f0, fc)
    mid = slice(5000, 35000)
    # (1e-3: the FFT Hilbert transform of a tone cut off at both ends has 1/t tails)
    np.testing.assert_allclose(coherent[mid], abs(amp) ** 2, rtol=1e-3)
    np.testing.assert_allclose(incoherent[mid], abs(amp) ** 2, rtol=1e-4)   # not −3.01 dB
    np.testing.assert_allclose(processing.analytic_baseband(x, f0, fc)[mid], amp, rtol=1e-3)


def _half_power_width(x):
    k = int(np.argmax(x))
    half = x[k] / 2
    i = k
    while x[i] > half:
        i -= 1
    left = i + (half - x[i]) / (x[i + 1] - x[i])
    j = k
    while x[j] > half:
        j += 1
    right = j - 1 + (x[j - 1] - half) / (x[j - 1] - x[j])
    return right - left


@pytest.fixture(scope="module")
def plate_scene():
    return se.Scene().add(facing_plate(20.0), label="plate")


def _still(n=1):
    return se.Trajectory(np.tile([[0.0, 0.0, H]], (n, 1)), heading_deg=np.full(n, 90.0))


@pytest.mark.parametrize("speckle", [False, True])
def test_lfm_compressed_peak_position_and_width(plate_scene, speckle):
    b, fs = 20e3, 200e3
    sonar = se.Sonar(max_range_m=30.0, sample_rate_hz=fs)
    rec = se.simulate(plate_scene, _still(), sonar, se.Pulse.lfm(b, 1e-3, taper=0.0), speckle=speckle)
    assert rec.attrs["matched_filter"] is True                      # default on for FM
    x = rec.starboard[0]
    assert abs(rec.time_s[np.argmax(x)] - 2 * 20.0 / 1500.0) <= 1 / fs
    width_s = _half_power_width(x) / fs
    assert width_s == pytest.approx(0.88 / b, rel=0.15)
    # uncompressed, the same echo lasts the whole pulse
    raw = se.simulate(plate_scene, _still(), sonar, se.Pulse.lfm(b, 1e-3, taper=0.0), speckle=speckle,
                      matched_filter=False).starboard[0]
    assert _half_power_width(raw) / fs == pytest.approx(1e-3, rel=0.05)


def test_tapered_lfm_widens_the_compressed_peak(plate_scene):
    b, fs = 20e3, 200e3
    sonar = se.Sonar(max_range_m=30.0, sample_rate_hz=fs)
    rec = se.simulate(plate_scene, _still(), sonar, se.Pulse.lfm(b, 1e-3, taper=0.1))
    assert _half_power_width(rec.starboard[0]) / fs == pytest.approx(1.03 / b, rel=0.1)  # docs/physics.md §5


def test_pulse_compression_gains_b_tau_in_peak_to_noise(plate_scene):
    b, tau, fs = 20e3, 1e-3, 40e3
    # 2R/c on the sample grid, so the sampled peak is the true peak
    scene = se.Scene().add(facing_plate(20.0625), label="plate")
    sonar = se.Sonar(max_range_m=30.0, sample_rate_hz=fs)
    pulse = se.Pulse.lfm(b, tau, taper=0.0)
    kw = dict(speckle=True, seed=2, speckle_cell_m=sonar.length_m / 2)  # one lattice for raw and compressed
    raw = se.simulate(scene, _still(), sonar, pulse, matched_filter=False, **kw).starboard[0]
    echo = raw[raw > 0.5 * raw.max()]
    a2 = np.median(echo)                                              # |A|², the uncompressed echo
    assert echo.size == pytest.approx(tau * fs, abs=2)
    n0 = a2 / b                                                       # in-band input SNR = 1 (0 dB)
    n0_db = 10 * np.log10(n0)
    noisy_raw = se.simulate(scene, _still(4), sonar, pulse, matched_filter=False, noise_db_per_hz=n0_db, **kw)
    quiet = noisy_raw.time_s < 0.02                                   # before the echo: noise only
    assert noisy_raw.starboard[:, quiet].mean() == pytest.approx(n0 * fs, rel=0.05)  # N0·fs per sample
    peak = se.simulate(scene, _still(), sonar, pulse, **kw).starboard[0].max()
    noisy = se.simulate(scene, _still(4), sonar, pulse, noise_db_per_hz=n0_db, **kw)
    noise_out = noisy.starboard[:, quiet].mean()
    gain_db = 10 * np.log10((peak / noise_out) / (a2 / (n0 * b)))
    assert gain_db == pytest.approx(10 * np.log10(b * tau), abs=1.0)
    # the noise is drawn per ping from the seed: reproducible, different between pings
    again = se.simulate(scene, _still(4), sonar, pulse, noise_db_per_hz=n0_db, **kw)
    assert np.array_equal(again.starboard, noisy.starboard)
    assert not np.array_equal(noisy.starboard[0], noisy.starboard[1])
    # speckle-free mode adds the noise's mean intensity
    mean_mode = se.simulate(scene, _still(), sonar, pulse, noise_db_per_hz=n0_db)
    assert mean_mode.starboard[0, quiet] == pytest.approx(n0 / tau, rel=1e-6)


def test_exp_chirp_with_equal_frequencies_gives_the_cw_record(scene_with_box):
    sonar = se.Sonar(max_range_m=25.0)
    traj = line_along_x(n_pings=2)
    for kw in ({}, {"speckle": True, "seed": 4}):
        cw = se.simulate(scene_with_box, traj, sonar, se.Pulse.cw(150e-6, 0.2), **kw)
        ex = se.simulate(scene_with_box, traj, sonar, se.Pulse.exp_chirp(400e3, 400e3, 150e-6, 0.2), **kw)
        assert np.array_equal(cw.starboard, ex.starboard) and np.array_equal(cw.port, ex.port)


def test_perfect_tvg_flat_floor_follows_the_closed_form():
    sonar = se.Acquisition(se.Sonar(), se.Environment(absorption_db_per_m=0.096))
    rec = se.simulate(flat_scene(), line_along_x(n_pings=1), sonar, se.Pulse.cw(100e-6, taper=0.0), tvg=True)
    r = rec.slant_range_m
    band = (r > 14.0) & (r < 49.0)
    expected = analytic.tvg_flat_floor(r[band] - 0.0375)               # the cell's centre
    err_db = 10 * np.log10(rec.starboard[0, band] / expected)
    assert np.max(np.abs(err_db)) < 0.5
    assert rec.attrs["tvg"] is True


def test_lowpass_after_detection_smooths_speckle(scene_with_box):
    sonar = se.Sonar(max_range_m=30.0)
    kw = dict(speckle=True, seed=1)
    sharp = se.simulate(flat_scene(), line_along_x(n_pings=1), sonar, **kw).starboard[0]
    smooth = se.simulate(flat_scene(), line_along_x(n_pings=1), sonar, lowpass_hz=2e3, **kw).starboard[0]
    band = slice(1000, 2000)
    assert np.std(np.diff(smooth[band])) < 0.3 * np.std(np.diff(sharp[band]))
    assert smooth[band].mean() == pytest.approx(sharp[band].mean(), rel=0.05)


def test_processing_helpers():
    fs = 40e3
    pulse = se.Pulse.lfm(10e3, 1e-3, taper=0.0)
    rep = pulses.replica(pulse, 400e3, fs)
    x = np.zeros(400, dtype=complex)
    x[123:123 + rep.size] = 2.0 * rep
    y = processing.matched_filter(x[None], rep)[0]
    assert np.argmax(np.abs(y)) == 123 and abs(y[123]) == pytest.approx(2.0)
    ones = np.ones((2, 500))
    np.testing.assert_allclose(processing.lowpass(ones, 5e3, fs)[:, 100:400], 1.0, rtol=1e-6)
    assert processing.tvg_gain(np.array([2 * 30 / 1500]), 1500, 0.1)[0] == pytest.approx(30 ** 4 * 10 ** 0.6)


@pytest.mark.parametrize("kwargs, needle", [
    ({"band": "carrier"}, "speckle=False"),
    ({"detection": "incoherent", "speckle": True}, "band='carrier'"),
    ({"speckle": True, "band": "carrier", "detection": "incoherent", "matched_filter": True}, "phase"),
    ({"band": "radio"}, "SignalChain.band"),
    ({"speckle": "yes"}, "SignalChain.speckle"),
    ({"seed": -1}, "seed"),
    ({"lowpass_hz": 30e3}, "lowpass_hz"),
    ({"speckle_cell_m": 0.0}, "speckle_cell_m"),
])
def test_invalid_chains_fail_before_any_work(kwargs, needle):
    with pytest.raises(se.ConfigError, match=needle):
        se.simulate(flat_scene(), line_along_x(n_pings=1), **kwargs)


def test_fm_checks_against_the_sonar():
    lfm = se.Pulse.lfm(bandwidth_hz=60e3)
    with pytest.raises(se.ConfigError, match="sample_rate_hz"):  # an explicit rate too low for the sweep
        se.simulate(flat_scene(), line_along_x(n_pings=1), se.Sonar(sample_rate_hz=40e3), lfm)
    with pytest.raises(se.ConfigError, match="compression"):
        se.simulate(flat_scene(), line_along_x(n_pings=1), se.Sonar(), se.Pulse.lfm(20e3), speckle=True,
                    band="carrier", detection="incoherent")


def test_run_config_and_cli_flags_set_the_chain(tmp_path, capsys):
    from sonar_embree.runs.cli import main
    from sonar_embree.runs.runconfig import load_run_config

    cfg = tmp_path / "run.toml"
    cfg.write_text("""
[sonar]
max_range_m = 20.0
[pulse]
kind = "lfm"
bandwidth_hz = 15000.0
duration_s = 0.0005
[simulation]
speckle = true
band = "baseband"
tvg = true
seed = 9
[trajectory]
start = [0.0, 0.0, 10.0]
end = [0.2, 0.0, 10.0]
n_pings = 2
[[objects]]
seafloor = "flat"
size_m = [60.0, 60.0]
""")
    run = load_run_config(cfg)
    assert run.chain == se.SignalChain(speckle=True, tvg=True, seed=9)
    assert run.pulse == se.Pulse.lfm(15e3, 5e-4, taper=0.1)
    assert main([f"render", str(cfg), "-o", str(tmp_path / "a"), "--no-progress", "--seed", "3",
                 "--no-tvg"]) == 0
    rec = se.Record.load(tmp_path / "a" / "record.npz")
    assert rec.attrs["seed"] == 3 and rec.attrs["tvg"] is False and rec.attrs["matched_filter"] is True
    assert rec.pulse == run.pulse and rec.attrs["mode"] == "speckle"
    bad = tmp_path / "bad.toml"
    bad.write_text(cfg.read_text().replace('band = "baseband"', 'band = "carrier"\ndetection = "incoherent"'))
    assert main(["render", str(bad), "-o", str(tmp_path / "b"), "--no-progress"]) == 2
    assert "compression" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("speckle", [False, True])
def test_compressed_record_is_not_darkened_at_the_end_of_the_window(speckle):
    # The matched filter at the end of the window needs echoes from up to cτ/2 beyond it:
    # they are synthesised, so the last samples match a longer window's (truncating
    # the correlation would darken the last 0.75 m by many dB). With speckle, 16 pings 2 m apart: the two
    # windows' ray fans differ, so one ping's 20-sample ratio scatters by ±0.04 (seeds 3 … 22); 16 pings, ±0.01.
    pulse = se.Pulse.lfm(15e3, 1e-3)
    traj = line_along_x(n_pings=16 if speckle else 1, length=30.0)
    short = se.simulate(flat_scene(), traj, se.Sonar(max_range_m=25.0), pulse, speckle=speckle, seed=3)
    long = se.simulate(flat_scene(), traj, se.Sonar(max_range_m=30.0), pulse, speckle=speckle, seed=3)
    n = short.time_s.size
    tail = slice(n - 20, n)                                   # the last 0.375 m
    ratio = short.starboard[:, tail].mean() / long.starboard[:, tail].mean()
    assert ratio == pytest.approx(1.0, abs=0.03 if speckle else 1e-3)


def test_sample_rate_follows_the_pulse_unless_given():
    """fs = max(4/τ, 4·max|f − f0|): 4 samples per CW pulse, 2B for a centred LFM, 4× the offset of an
    off-centre exponential chirp; an explicit rate is kept."""
    base = se.Sonar()
    assert base.sample_rate_hz is None
    with pytest.raises(se.ConfigError, match="for_pulse"):
        _ = se.Acquisition.of(base).n_samples
    assert base.for_pulse(se.Pulse.cw(100e-6)).sample_rate_hz == 40e3
    assert base.for_pulse(se.Pulse.cw(250e-6)).sample_rate_hz == 16e3
    assert base.for_pulse(se.Pulse.lfm(60e3, duration_s=2e-3)).sample_rate_hz == 120e3
    assert base.for_pulse(se.Pulse.exp_chirp(390e3, 430e3)).sample_rate_hz == 120e3
    assert se.Sonar(sample_rate_hz=25e3).for_pulse(se.Pulse.cw()).sample_rate_hz == 25e3
    rec = se.simulate(flat_scene(), line_along_x(n_pings=1), base, se.Pulse.lfm(60e3))
    assert rec.sonar.sample_rate_hz == 120e3 and rec.attrs["matched_filter"]
    assert rec.port.shape[1] == rec.acquisition.n_samples

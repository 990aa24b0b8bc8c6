"""The same physics verdicts on every scanning sonar type (issue: other scanning sonars): speckle statistics,
the scattering law's scale, absorption, a sea surface's multipath, refraction in a sound-speed profile, the
source level and the receiver's codes, each checked against its closed form, parametrised over the side-scan, the
MSIS (whose ping is the side-scan's fan on a head), the forward-looking sonar (the side-scan's fan turned forward,
its azimuth lines beamformed) and the echo sounder (rings of rays about its down axis, curved in a profile), with
its circular and its square piston.
"""
import dataclasses

import numpy as np
import pytest

import sonar_embree as se

H = 10.0


def _floor(mu_db=-20.0):
    return se.Scene().add(se.seafloor.flat((300.0, 300.0)), material=se.Material(backscatter_db=mu_db),
                          label="seafloor")


def _case(kind, n=40, **kw):
    """(sonar, trajectory): independent pings over the floor (side-scan: 2 m apart; MSIS: a still head turning
    9° per ping, its beam on new floor each ping; forward-looking: 6 m apart)."""
    if kind == "sidescan":
        return (se.Sonar(max_range_m=30.0, **kw),
                se.Trajectory.line((-40.0, 0.0, H), (40.0, 0.0, H), n).stop_and_hop())
    if kind.startswith("echosounder"):  # a 30° beam (its cone reaches 89°); twice the pings (one channel), 1 m apart
        beam = "square" if kind.endswith("square") else "piston"
        return (se.EchoSounder(beamwidth_deg=30.0, max_range_m=30.0, beam=beam, **kw),
                se.Trajectory.line((-40.0, 0.0, H), (40.0, 0.0, H), 2 * n).stop_and_hop())
    if kind == "forward_looking":  # a small array (32 elements, 33 beams over 60°); a third of the pings, 6 m apart
        n = max(2, n // 3)
        return (se.ForwardLooking(n_elements=32, n_beams=33, field_of_view_deg=60.0, max_range_m=30.0, **kw),
                se.Trajectory.line((-40.0, 0.0, H), (-40.0 + 6.0 * (n - 1), 0.0, H), n).stop_and_hop())
    return (se.MSIS(step_deg=9.0, max_range_m=30.0, **kw),
            se.Trajectory(np.tile([[0.0, 0.0, H]], (n, 1)), times_s=np.arange(float(n))))


KINDS = ["sidescan", "msis", "forward_looking", "echosounder", "echosounder_square"]
#: The sea surface's paths leave or reach the sonar upwards: a down-looking baffled piston has no gain there, so a
#: surface changes nothing of the echo sounder's record (docs/physics.md §11).
LOOKS_UP = {"sidescan", "msis", "forward_looking"}


@pytest.mark.parametrize("kind", KINDS)
def test_speckle_is_fully_developed(kind):
    sonar, traj = _case(kind)
    expected = se.simulate(_floor(), traj, sonar)
    speckled = se.simulate(_floor(), traj, sonar, speckle=True, seed=3)
    band = (expected.slant_range_m > 12.0) & (expected.slant_range_m < 28.0)
    ratio = speckled.data[:, :, band] / expected.data[:, :, band]
    assert ratio.size > 20_000
    assert abs(ratio.mean() - 1) < 0.05 and abs(ratio.std() / ratio.mean() - 1) < 0.1   # exponential: contrast 1


@pytest.mark.parametrize("kind", KINDS)
def test_law_scale_and_absorption(kind):
    """A Lambert floor 10 dB weaker gives the record × 0.1; absorption α (dB/m) takes 2αR off each sample."""
    sonar, traj = _case(kind, n=3)
    quiet = se.Acquisition(sonar, se.Environment(absorption_db_per_m=0.0))
    lossy = se.Acquisition(sonar, se.Environment(absorption_db_per_m=0.2))
    base = se.simulate(_floor(), traj, quiet)
    weak = se.simulate(_floor(-30.0), traj, quiet)
    lit = base.data > 1e-6 * base.data.max()
    np.testing.assert_allclose(weak.data[lit], 0.1 * base.data[lit], rtol=1e-9)
    damped = se.simulate(_floor(), traj, lossy)
    r = base.slant_range_m[None, None, :] * np.ones_like(base.data)
    loss_db = 10 * np.log10(damped.data[lit] / base.data[lit])
    c_tau = 0.5 * base.acquisition.sound_speed_m_s * base.pulse.duration_s          # ranges within a sample's pulse
    assert np.all(np.abs(loss_db + 2 * 0.2 * r[lit]) <= 2 * 0.2 * c_tau + 1e-6)


@pytest.mark.parametrize("kind", KINDS)
def test_sea_surface_adds_multipath_only_after_its_onset(kind):
    """A flat surface 4 m above the sonar: nothing changes before the one-bounce onset (2h + 2d)/c, energy is
    added after it (never taken away: the paths add in power)."""
    sonar, traj = _case(kind, n=3)
    wet = se.Acquisition(sonar, se.Environment(surface=se.SeaSurface(z_m=H + 4.0)))
    dry, moist = se.simulate(_floor(), traj, sonar), se.simulate(_floor(), traj, wet)
    if kind not in LOOKS_UP:
        np.testing.assert_array_equal(moist.data, dry.data)
        return
    assert_surface_verdict(dry, moist, 4.0, 5e-3)


def assert_surface_verdict(dry, moist, above_m, min_share):
    """A surface ``above_m`` over the sonar changed nothing of ``dry`` before the one-bounce onset (2h + 2d)/c and
    only added energy after it, at least ``min_share`` of the dry record's there."""
    sonar = dry.sonar
    onset = (2 * H + 2 * above_m) / se.Acquisition.of(sonar).sound_speed_m_s
    before = dry.time_s < onset - sonar.for_pulse(dry.pulse).sample_rate_hz ** -1
    np.testing.assert_allclose(moist.data[:, :, before], dry.data[:, :, before], rtol=1e-9, atol=0)
    after = dry.time_s > onset + dry.pulse.duration_s
    added = moist.data[:, :, after] - dry.data[:, :, after]
    assert np.all(added >= -1e-12 * dry.data.max()) and added.sum() > min_share * dry.data[:, :, after].sum()


@pytest.mark.parametrize("kind", KINDS)
def test_source_level_scales_the_record(kind):
    """With a source level SL and a silent sea, the record is the unit-source record × 10^(SL/10) (µPa²)."""
    sonar, traj = _case(kind, n=2)
    loud = se.Acquisition(dataclasses.replace(sonar, source_level_db=210.0), se.Environment(noise=None))
    unit, db = se.simulate(_floor(), traj, sonar), se.simulate(_floor(), traj, loud)
    np.testing.assert_allclose(db.data, unit.data * 10 ** 21.0, rtol=1e-9, atol=0)
    assert db.attrs["intensity_unit"] == "uPa^2"


@pytest.mark.parametrize("kind", KINDS)
def test_sound_speed_profile_bends_the_rays_and_a_uniform_one_does_not(kind):
    """A uniform profile is the homogeneous ocean bit for bit; in a gradient g = +0.5 s⁻¹ (1500 m/s at the sonar,
    faster below) the first echo, from straight below, arrives at 2/g·ln(c_floor/c_sonar) (the vertical ray's
    closed form), 4 samples of 5 µs earlier than 2h/c, within one sample."""
    sonar, traj = _case(kind, n=3, sample_rate_hz=200e3)
    straight = se.simulate(_floor(), traj, sonar)
    flat = se.SoundSpeedProfile(depth_m=[0.0, 100.0], speed_m_s=[1500.0, 1500.0], surface_z_m=H + 20.0)
    same = se.simulate(_floor(), traj, sonar, environment=se.Environment(sound_speed=flat))
    np.testing.assert_array_equal(same.data, straight.data)
    grad = se.SoundSpeedProfile(depth_m=[0.0, 100.0], speed_m_s=[1490.0, 1540.0], surface_z_m=H + 20.0)
    bent = se.simulate(_floor(), traj, sonar, environment=se.Environment(sound_speed=grad, sound_speed_m_s=1500.0))
    t = straight.time_s
    first = t[np.flatnonzero(bent.data.max(axis=(0, 1)) > 1e-6 * bent.data.max())[0]]
    want = 2.0 / 0.5 * np.log((1500.0 + 0.5 * H) / 1500.0)
    assert abs(first - want) <= t[1] and want < 2 * H / 1500.0 - 3 * t[1]


@pytest.mark.parametrize("kind", KINDS)
def test_a_surface_over_a_profile_adds_multipath_only_after_its_curved_onset(kind):
    """A flat surface 4 m above the sonar over a gradient g = +0.5 s⁻¹ (1500 m/s at the sonar): the record equals the
    profile's alone before the one-bounce onset, the vertical rays' times ln(c_b/c_a)/g down to the floor, up to the
    surface and down to the floor (docs/physics.md §12b), and gains energy after it, never loses any."""
    sonar, traj = _case(kind, n=3, sample_rate_hz=200e3)
    grad = se.SoundSpeedProfile(depth_m=[0.0, 100.0], speed_m_s=[1498.0, 1548.0], surface_z_m=H + 4.0)
    base = se.Environment(sound_speed=grad, sound_speed_m_s=1500.0)
    dry = se.simulate(_floor(), traj, sonar, environment=base)
    moist = se.simulate(_floor(), traj, sonar, environment=dataclasses.replace(base,
                                                                               surface=se.SeaSurface(z_m=H + 4.0)))
    if kind not in LOOKS_UP:
        np.testing.assert_array_equal(moist.data, dry.data)
        assert dry.data.max() > 0
        return
    c_sonar, c_floor, c_top = 1500.0, 1500.0 + 0.5 * H, 1498.0
    onset = (np.log(c_floor / c_sonar) + np.log(c_sonar / c_top) + np.log(c_floor / c_top)) / 0.5
    t = dry.time_s
    before = t < onset - t[1]
    np.testing.assert_array_equal(moist.data[:, :, before], dry.data[:, :, before])
    after = t > onset + dry.pulse.duration_s
    added = moist.data[:, :, after] - dry.data[:, :, after]
    assert np.all(added >= -1e-12 * dry.data.max()) and added.sum() > 5e-3 * dry.data[:, :, after].sum()
    first = t[np.flatnonzero((moist.data - dry.data).max(axis=(0, 1)) > 0)[0]]
    assert first >= onset - t[1]


@pytest.mark.parametrize("kind", KINDS)
def test_receiver_codes_follow_the_level(kind):
    """With a receiver (sensitivity, TVG, 12-bit ADC) every record carries integer codes within the ADC's range,
    and a source 10 dB louder never lowers a code and raises their sum."""
    rx = se.Receiver(adc_bits=12)
    sonar, traj = _case(kind, n=2, source_level_db=190.0, receiver=rx)
    quiet = se.simulate(_floor(), traj, sonar)
    loud = se.simulate(_floor(), traj, dataclasses.replace(sonar, source_level_db=200.0))
    assert quiet.samples is not None and quiet.samples.shape == quiet.data.shape
    assert quiet.samples.max() <= 4095 and np.all(loud.samples.astype(int) >= quiet.samples.astype(int))
    assert loud.samples.sum() > quiet.samples.sum()

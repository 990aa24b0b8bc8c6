"""The APL-UW bottom backscattering model (docs/physics.md §10b) against its equations written here in scalar complex
arithmetic, and recovered from a flat-floor record as the other laws are (tests/laws/test_law_recovery.py).

What the equations here are: TR 9407's Kirchhoff-roughness, small-roughness-perturbation and sediment-volume cross
sections and its grain-size regressions (as the Navy's CASS codes them, routine gsiz2des), joined as
(σ_kr⁻² + σ_pr⁻²)^(−1/2) (Williams and Jackson 1998). TR 9407's own join, an average of the perturbation term over
the large-scale slopes, is not here: its text could not be read for this work (issue 38's closing note)."""
import cmath
import logging
import math

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.errors import ConfigError
from sonar_embree.laws.apl_uw import AplUw, apl_class

from test_law_recovery import _recovered_sigma
from test_sediments import _apl_rho_nu


def _handbook_params(mz):
    """(ρ, ν, δ, w2 [cm⁴], γ, σ2) at mean grain size Mz (φ): TR 9407's regressions (as CASS codes them)."""
    rho, nu = _apl_rho_nu(mz)
    kp = (0.4556 if mz < 0 else 0.4556 + 0.0245 * mz if mz < 2.6 else 0.1978 + 0.1245 * mz if mz < 4.5
          else 8.0399 - 2.5228 * mz + 0.20098 * mz ** 2 if mz < 6 else 0.9431 - 0.2041 * mz + 0.0117 * mz ** 2)
    delta = kp * nu * 1528.0 * math.log(10) / (40000 * math.pi)      # dB/(m kHz) → Im k / Re k
    h = (2.03846 - 0.26923 * mz) / (1 + 0.076923 * mz) if mz < 5 else 0.5
    return rho, nu, delta, 0.00207 * h * h, 3.25, 0.002 if mz < 5.5 else 0.001


def _handbook_sigma_db(mz, f, grazing_deg, c=1500.0):
    """σ_b = (σ_kr⁻² + σ_pr⁻²)^(−1/2) + σ_v at one angle, written term by term."""
    rho, nu, delta, w2, gam, s2 = _handbook_params(mz)
    k, th = 2 * math.pi * f / c, math.radians(grazing_deg)
    kap = complex(1, delta) / nu
    p = cmath.sqrt(kap * kap - math.cos(th) ** 2)
    refl = (rho * math.sin(th) - p) / (rho * math.sin(th) + p)
    w = w2 * 1e-8 / 0.01 ** gam                                       # W(K) = w / K^γ in m⁴, K in rad/m
    al = gam / 2 - 1
    ch2 = 2 * math.pi * w * math.gamma(2 - al) * 2 ** (-2 * al) / (al * (1 - al) * math.gamma(1 + al))
    qc = ch2 * 2 ** (1 - 2 * al) * k ** (2 - 2 * al)
    a = (8 * al ** 2 * math.gamma((1 + al) / (2 * al))
         / (math.gamma(0.5) * math.gamma(1 / al) * math.gamma(1 / (2 * al)))) ** (2 * al)
    b = a ** ((1 + al) / (2 * al)) * math.gamma(1 / al) / (2 * al)
    r90 = abs((rho - kap) / (rho + kap)) ** 2
    s_kr = b * qc * r90 / (8 * math.pi * (math.cos(th) ** (4 * al) + a * qc ** 2 * math.sin(th) ** 4)
                           ** ((1 + al) / (2 * al)))
    y = ((rho - 1) ** 2 * math.cos(th) ** 2 + rho ** 2 - kap ** 2) / (rho * math.sin(th) + p) ** 2
    s_pr = 4 * k ** 4 * math.sin(th) ** 4 * abs(y) ** 2 * w / (2 * k * math.cos(th)) ** gam if th < math.pi / 2 \
        else math.inf
    s_r = (s_kr ** -2 + s_pr ** -2) ** -0.5
    s_v = 5 * delta * s2 * abs(1 - refl ** 2) ** 2 * math.sin(th) ** 2 / (math.log(10) * abs(p) ** 2 * p.imag)
    return 10 * math.log10(s_r + s_v)


CLASSES = {"coarse sand": 0.5, "fine sand": 2.5, "coarse silt": 4.5, "fine silt": 6.5, "clay": 9.0}
ANGLES = [3, 7, 12, 20, 30, 45, 60, 75, 85, 89.5, 90]


@pytest.mark.parametrize("name", sorted(CLASSES))
@pytest.mark.parametrize("frequency_hz", [30e3, 100e3])
def test_each_class_matches_the_handbooks_equations_within_half_a_db(name, frequency_hz):
    law = apl_class(name)
    got = law.backscatter_strength_db(np.array(ANGLES, float), frequency_hz)
    want = [_handbook_sigma_db(CLASSES[name], frequency_hz, g) for g in ANGLES]
    assert np.max(np.abs(got - want)) < 0.5, (got, want)
    assert np.max(np.abs(got - want)) < 1e-6                          # the same equations: round-off only


def test_the_model_falls_faster_than_lambert_at_low_grazing_and_sand_is_louder_than_mud_there():
    """The measured shape the model was brought in for (issue 38): from 30° to 6° grazing a sand falls by more
    than Lambert's 10·log10(sin²30°/sin²6°) = 13.6 dB; at 20° coarse sand is above clay."""
    sand = apl_class("fine sand").backscatter_strength_db(np.array([6.0, 30.0]), 100e3)
    assert sand[1] - sand[0] > 10 * math.log10(math.sin(math.radians(30)) ** 2 / math.sin(math.radians(6)) ** 2)
    at20 = [apl_class(n).backscatter_strength_db(np.array([20.0]), 100e3)[0] for n in ("coarse sand", "clay")]
    assert at20[0] > at20[1]


@pytest.mark.parametrize("name", ["coarse sand", "fine sand", "clay"])
def test_the_carriers_table_is_within_five_hundredths_of_a_db_of_the_model(name):
    law = apl_class(name)
    table = law.at_frequency(100e3)
    g = np.linspace(0.2, 90.0, 4001)
    err = table.backscatter_strength_db(g) - law.backscatter_strength_db(g, 100e3)
    assert np.max(np.abs(err)) < 0.05, g[np.argmax(np.abs(err))]


def test_sigma_is_recovered_from_a_flat_floor_record():
    """A speckle-free flat-floor record at 400 kHz gives back the model's σ(θ) within 0.3 dB from 15° to the nadir
    lobe (the handbook's σ at the sonar's carrier, computed here)."""
    sigma, cos_i, grazing = _recovered_sigma({"scattering": se.laws.AplUw.from_grain_size(2.5)})
    want = np.array([_handbook_sigma_db(2.5, 400e3, g) for g in grazing])
    band = grazing >= 15
    err = 10 * np.log10(sigma[band]) - want[band]
    assert band.sum() > 20 and np.max(np.abs(err)) < 0.3, np.max(np.abs(err))


def test_a_carrier_outside_the_handbooks_range_warns_once(caplog):
    with caplog.at_level(logging.WARNING, logger="sonar_embree.checks"):
        AplUw.from_grain_size(1.0).at_frequency(455e3)
    assert any("10–100 kHz" in r.message and "455 kHz" in r.message for r in caplog.records)


def test_bad_values_are_one_line_errors_naming_them():
    with pytest.raises(ConfigError, match="mean_grain_size_phi"):
        AplUw.from_grain_size(12.0)
    with pytest.raises(ConfigError, match="loss_parameter"):
        AplUw.from_grain_size(2.0, loss_parameter=-0.1)
    with pytest.raises(ConfigError, match="unknown APL-UW sediment class 'sandd'"):
        apl_class("sandd")
    with pytest.raises(ConfigError, match="at_frequency"):
        apl_class("clay").sigma(0.5, 0.5)


def test_toml_names_and_tables_select_the_model(tmp_path):
    from sonar_embree.runs.runconfig import parse_law
    assert parse_law("apl-uw medium sand", "x.toml", "material") == AplUw.from_grain_size(1.5)
    assert parse_law({"kind": "apl-uw", "sediment": "clay"}, "x.toml", "m") == AplUw.from_grain_size(9.0)
    law = parse_law({"kind": "apl-uw", "mean_grain_size_phi": 3.0, "volume_parameter": 0.004}, "x.toml", "m")
    assert law.volume_parameter == 0.004 and law.density_ratio == pytest.approx(_handbook_params(3.0)[0])
    with pytest.raises(ConfigError, match="x.toml"):
        parse_law({"kind": "apl-uw", "sediment": "clay", "bogus": 1}, "x.toml", "m")
    assert parse_law("lambert-kirchhoff fine sand", "x.toml", "m") == se.laws.sediments.FINE_SAND  # kept by name
    assert parse_law("mud", "x.toml", "m") == AplUw.from_grain_size(8.0)             # a bare name: the model

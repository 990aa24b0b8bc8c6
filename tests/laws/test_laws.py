"""The scattering-law seam (docs/physics.md §10): Lambert and Kirchhoff against closed forms and twins."""
import numpy as np
import pytest

import analytic
import naive
import sonar_embree as se
from conftest import flat_scene, line_along_x
from sonar_embree.laws import Kirchhoff, Lambert, Tabulated, law_table
from sonar_embree.laws.driver import law_weights


def test_the_law_driver_matches_the_naive_twins_of_every_law_in_one_pass(rng):
    """Two objects of each law; one pass of the driver gives each hit its own object's law, multiplying or adding;
    other hits, misses and zero weights are untouched."""
    laws = [Lambert(-20.0), Kirchhoff(0.6, 0.2), Tabulated((5, 30, 60, 85), (-40, -30, -22, -5)), Lambert(-30.0),
            Kirchhoff(-0.3, 0.05), Tabulated((10, 80), (-35, -15))]
    t = law_table(laws)
    assert t.kinds == (Lambert, Kirchhoff, Tabulated) and list(t.term_law[0]) == [0, 1, 2, 0, 1, 2]
    n, n_faces = 5000, 40
    face_object = rng.integers(0, 6, n_faces).astype(np.int32)
    prim = rng.integers(-1, n_faces, n).astype(np.int32)
    cos_i = rng.uniform(1e-9, 1.0, n)
    weight = rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) > 0.1)
    factor = np.ones(n)
    for law, kind in enumerate(["lambert", "kirchhoff", "tabulated"]):
        factor *= naive.law_weights(prim, cos_i, face_object, t.term_law[0], law, t.term_params[0], weight, kind,
                                    t.data)
    got = weight.copy()
    law_weights(prim, cos_i, face_object, t.term_law[0], t.kind_of, t.term_params[0], t.data, got, got, False)
    np.testing.assert_allclose(got, weight * factor, rtol=1e-11, atol=1e-300)  # subnormals aside
    other = (prim < 0) | (weight == 0)
    np.testing.assert_array_equal(got[other], weight[other])
    for law in range(3):                                      # every law changed its own hits
        own = ~other & (t.term_law[0][face_object[np.maximum(prim, 0)]] == law)
        assert own.sum() > 100 and not np.array_equal(got[own], weight[own])
    added = np.full(n, 0.5)
    law_weights(prim, cos_i, face_object, t.term_law[0], t.kind_of, t.term_params[0], t.data, weight, added, True)
    np.testing.assert_allclose(added, np.where(other, 0.5, 0.5 + factor), rtol=1e-11, atol=1e-300)


def test_a_law_without_a_scalar_sigma_is_refused_naming_it():
    class Phong(se.laws.Lambert):
        pass

    with pytest.raises(se.ConfigError, match="scattering law Phong has no scalar sigma"):
        law_table([Phong(-20.0)])


def test_kirchhoff_closed_forms():
    law = Kirchhoff(0.5, 0.15)
    theta = np.radians(np.linspace(0, 85, 30))
    c = np.cos(theta)
    np.testing.assert_allclose(law.sigma(c, c, 0.0), analytic.kirchhoff_monostatic(theta, 0.5, 0.15), rtol=1e-12)
    assert law.sigma(1.0, 1.0) == pytest.approx(0.25 / (8 * np.pi * 0.15 ** 2), rel=1e-12)  # σ_K(0) = R0²/(8π s²)
    # the specular direction (φ = π, θs = θi): the facets facing the bisector are level, σ = σ_K(0) at every θi
    np.testing.assert_allclose(law.sigma(c[:-1], c[:-1], np.pi), 0.25 / (8 * np.pi * 0.15 ** 2), rtol=1e-9)
    # reciprocity σ(θi, θs, φ) = σ(θs, θi, φ)
    a, b, phi = np.cos(0.3), np.cos(0.9), 0.7
    assert law.sigma(a, b, phi) == pytest.approx(law.sigma(b, a, phi), rel=1e-12)
    assert law.sigma(-0.2, 0.5) == 0.0 and Kirchhoff(0.5, 0.15).sigma(np.cos(np.radians(89.99)), 1e-4) >= 0
    assert Kirchhoff.from_impedances(1.9, 1.1).reflection_coefficient == pytest.approx((2.09 - 1) / (2.09 + 1))
    with pytest.raises(se.ConfigError, match="Kirchhoff.slope_rms"):
        Kirchhoff(0.5, 0.0)


def test_lambert_law_is_the_default_and_bistatic():
    assert se.Material().law == Lambert(-27.0) and se.Material(backscatter_db=-15.0).law == Lambert(-15.0)
    assert se.Material(scattering=Lambert(-12.0)).backscatter_db == -12.0
    law = Lambert(-20.0)
    assert law.sigma(0.5, 0.8, 1.0) == pytest.approx(0.01 * 0.5 * 0.8)
    with pytest.raises(se.ConfigError, match="backscatter_db or scattering"):
        se.Material(backscatter_db=-15.0, scattering=Kirchhoff())
    with pytest.raises(se.ConfigError, match="Material.scattering"):
        se.Material(scattering="sand")


def test_laws_say_whether_sigma_depends_on_the_bistatic_azimuth():
    """The multipath front end computes φ (an arccos per echo) only for a scene with a law that reads it: each
    declaration is checked against the law's own σ at two azimuths."""
    ci, cs = np.array([0.9, 0.5]), np.array([0.8, 0.6])
    table = Tabulated((0.0, 45.0, 90.0), (-40.0, -30.0, -20.0))
    kirchhoff = Kirchhoff(0.5, 0.1)
    for law in (Lambert(-30.0), table, kirchhoff, Lambert(-30.0) + table, Lambert(-30.0) + kirchhoff):
        depends = not np.array_equal(law.sigma(ci, cs, 0.0), law.sigma(ci, cs, 0.7))
        assert law.uses_azimuth == depends, law


def test_kirchhoff_flat_floor_against_quadrature():
    """A Kirchhoff floor simulated speckle-free against eq. (2) with σ_K (docs/physics.md §3, §10)."""
    r0, s = 0.5, 0.5
    rec = se.simulate(flat_scene(scattering=Kirchhoff(r0, s)), line_along_x(), se.Sonar(),
                      se.Pulse.cw(duration_s=100e-6, taper=0.0), start_time="2000-01-01")
    r = rec.slant_range_m
    band = (r >= 11.0) & (r <= 40.0)  # beyond, σ_K < −200 dB and the reference's cumulative sum cancels to 0
    want = analytic.flat_floor_expected_intensity(r[band], sigma=lambda c: analytic.kirchhoff_monostatic(
        np.arccos(c), r0, s))
    for channel in (rec.starboard, rec.port):
        err_db = 10 * np.log10(channel.mean(axis=0)[band] / want)
        assert np.max(np.abs(err_db)) < 0.2, np.max(np.abs(err_db))
    lam = 10 * np.log10(analytic.flat_floor_expected_intensity(np.array([11.0, 40.0])))
    kir = 10 * np.log10(analytic.flat_floor_expected_intensity(np.array([11.0, 40.0]), sigma=lambda c: (
        analytic.kirchhoff_monostatic(np.arccos(c), r0, s))))
    assert kir[0] - lam[0] > 10 and kir[1] < lam[1]  # the specular lobe near nadir, darker far out


def test_toml_material_law(tmp_path):
    from sonar_embree import runconfig

    with pytest.warns(FutureWarning, match="'law' is now called 'scattering'"):
        mat = runconfig.parse_material({"law": {"kind": "kirchhoff", "reflection_coefficient": 0.6, "slope_rms": 0.2}},
                                       "x.toml", "object #1")
    assert mat.law == Kirchhoff(0.6, 0.2)
    with pytest.raises(se.ConfigError, match="x.toml: object #1 material law must be a sediment name or a table"), \
            pytest.warns(FutureWarning):
        runconfig.parse_material({"law": {"kind": "phong"}}, "x.toml", "object #1")
    with pytest.raises(se.ConfigError, match="unknown key 'slope' in object #1 material law"), \
            pytest.warns(FutureWarning):
        runconfig.parse_material({"law": {"kind": "kirchhoff", "slope": 0.2}}, "x.toml", "object #1")

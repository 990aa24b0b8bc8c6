"""K-distribution texture (docs/physics.md §10): the field against Gamma(ν), its kernel against a NumPy twin,
and the scintillation index 1 + 2/ν of a speckled, textured flat floor (Jakeman & Pusey 1976)."""
import math

import numpy as np
import pytest
from scipy import stats
from scipy.special import gammaincinv, ndtr

import sonar_embree as se
from sonar_embree.laws.texture import KTexture, TextureTable, texture_weights

M64 = (1 << 64) - 1


def _mix(h):
    h ^= h >> 30
    h = (h * 0xBF58476D1CE4E5B9) & M64
    h ^= h >> 27
    h = (h * 0x94D049BB133111EB) & M64
    return h ^ (h >> 31)


def _normal(i, j, k, seed):
    """splitmix64 of (seed, i, j, k), Box–Muller: the lattice's frozen normal, in Python integers."""
    h = _mix((seed + 0x9E3779B97F4A7C15) & M64)
    for n in (i, j, k):
        h = _mix(h ^ (n & 0xFFFFFFFFFFFF))
    g = _mix(h ^ 0xD1B54A32D192ED03)
    u1 = ((h >> 11) + 0.5) * 2.0 ** -53
    u2 = (g >> 11) * 2.0 ** -53
    return math.sqrt(-2 * math.log(u1)) * math.cos(2 * math.pi * u2)


def _naive_g(p, inv_l, seed, nu):
    """G at world point p: trilinear over the 8 nodes, renormalised, then the exact Gamma(ν, 1/ν) quantile."""
    x = np.asarray(p) * inv_l
    f = np.floor(x)
    t = x - f
    acc = norm = 0.0
    for c in range(8):
        d = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
        w = np.prod(np.where(d == 1, t, 1 - t))
        if w:
            acc += w * _normal(*(int(v) for v in f + d), seed)
            norm += w * w
    return gammaincinv(nu, ndtr(acc / math.sqrt(norm))) / nu


def test_texture_kernel_matches_its_twin(rng):
    tex = KTexture(shape=2.0, correlation_m=1.5, seed=7)
    scene = se.Scene().add(se.seafloor.flat(size_m=(40, 40)), label="seafloor", material=se.Material(texture=tex))
    scene.add(se.seafloor.flat(size_m=(10, 10), z_m=3.0), label="plain")
    c = scene.compiled(origin_m=(3.0, -2.0, 0.0))
    table = TextureTable.build([tex, None])
    n = 400
    prim = rng.integers(-1, 4, n).astype(np.int32)
    pts = rng.uniform(-20, 20, (n, 3))
    pts[:, 2] = np.where(prim >= 2, 3.0, 0.0)
    w = rng.uniform(0.5, 1, n)
    got = w.copy()
    texture_weights(prim, pts, c.origin_m, c.face_object, table.tex_index, table.tex_inv_l, table.tex_seed,
                    table.tables, got)
    on = (prim >= 0) & (c.face_object[np.maximum(prim, 0)] == 0)
    want = np.array([_naive_g(p + c.origin_m, 1 / 1.5, 7, 2.0) if k else 1.0 for p, k in zip(pts, on)])
    np.testing.assert_allclose(got / w, want, rtol=2e-4)   # the quantile table against the exact quantile
    assert on.sum() > 100 and np.all(got[~on] == w[~on])


@pytest.mark.parametrize("nu", [0.5, 1.0, 3.0, 10.0])
def test_field_is_gamma_and_correlated_over_l(nu):
    """1.6 M points over 400 L × 400 L: Gamma(ν, mean 1) marginal; correlated within L, not beyond 2 L."""
    tex = KTexture(shape=nu, correlation_m=2.0, seed=3)
    table = TextureTable.build([tex])
    x, y = np.meshgrid(np.arange(0, 800, 0.625), np.arange(0, 800, 0.625))
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)

    def g(p):
        out = np.ones(len(p))
        texture_weights(np.zeros(len(p), np.int32), p, np.zeros(3), np.zeros(1, np.int32), table.tex_index,
                        table.tex_inv_l, table.tex_seed, table.tables, out)
        return out

    v = g(pts)
    assert v.mean() == pytest.approx(1.0, abs=0.01) and v.var() == pytest.approx(1 / nu, rel=0.05)
    assert stats.kstest(v[::97], stats.gamma(nu, scale=1 / nu).cdf).statistic < 0.02
    near = g(pts + [0.1, 0.0, 0.0])
    far = g(pts + [4.3, 3.1, 0.0])
    assert np.corrcoef(v, near)[0, 1] > 0.9 and abs(np.corrcoef(v, far)[0, 1]) < 0.02


def test_texture_errors_and_infinite_shape():
    with pytest.raises(se.ConfigError, match="KTexture.shape must be a number > 0"):
        KTexture(shape=0.0)
    with pytest.raises(se.ConfigError, match="KTexture.correlation_m"):
        KTexture(correlation_m=math.inf)
    with pytest.raises(se.ConfigError, match="Material.texture"):
        se.Material(texture=3.0)
    assert TextureTable.build([KTexture(shape=math.inf), None]) is None


def test_infinite_shape_keeps_the_rayleigh_bits():
    traj = se.Trajectory.line((0, 0, 10), (1, 0, 10), 3)
    recs = [se.simulate(se.Scene().add(se.seafloor.flat(), label="seafloor", material=m), traj,
                        se.Sonar(max_range_m=30.0), speckle=True, seed=4, start_time="2000-01-01")
            for m in (se.Material(), se.Material(texture=KTexture(shape=math.inf)))]
    assert np.array_equal(recs[0].data, recs[1].data)


SONAR = se.Sonar(length_m=2.0, max_range_m=50.0)     # 0.1° beam: 3.75 cm along track at 20 m
PULSE = se.Pulse.cw(duration_s=20e-6, taper=0.0)      # 1.5 cm in range
L = 0.4                                               # ≥ 10 resolution cells


def _ratio(material, speckle, n_pings):
    traj = se.Trajectory.line((0, 0, 10), (0.4 * n_pings, 0, 10), n_pings)
    rec = se.simulate(se.Scene().add(se.seafloor.flat(), label="seafloor", material=material), traj, SONAR, PULSE,
                      speckle=speckle, seed=3, start_time="2000-01-01")
    return rec


@pytest.fixture(scope="module")
def k_floor():
    n = 90
    expected = _ratio(se.Material(), False, n)
    band = (expected.slant_range_m > 14) & (expected.slant_range_m < 49)

    def ratio(rec):
        with np.errstate(invalid="ignore"):   # 0/0 in the water column, outside the band
            return (rec.data / expected.data)[:, :, band]

    return ratio, n, ratio(_ratio(se.Material(), True, n))


@pytest.mark.parametrize("nu", [1.0, 3.0, 10.0])
def test_k_texture_scintillation_index_and_mean(k_floor, nu):
    ratio, n, rayleigh = k_floor
    x = ratio(_ratio(se.Material(texture=KTexture(shape=nu, correlation_m=L)), True, n))
    si = (x ** 2).mean() / x.mean() ** 2 - 1
    assert si == pytest.approx(1 + 2 / nu, rel=0.10), si
    assert abs(10 * np.log10(x.mean() / rayleigh.mean())) < 0.1
    si_rayleigh = (rayleigh ** 2).mean() / rayleigh.mean() ** 2 - 1
    assert si_rayleigh == pytest.approx(1.0, abs=0.05)

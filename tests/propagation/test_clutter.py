"""Discrete clutter (docs/physics.md §10c): the scintillation index of a flat floor's samples against the
compound-Poisson closed form SI = 1 + n⟨σ²⟩∫g²/(n⟨σ⟩∫g + ∫σ_d g)², its resolution cell's weights g (the two-way
membrane pattern, spreading, absorption and the rect pulse) integrated here over the floor, and the samples'
independence beyond the cell."""
import math

import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.errors import ConfigError

H, TAU, F0, C, MU_DB, SPREAD = 10.0, 100e-6, 400e3, 1500.0, -50.0, 4.0
BAND = (26.0, 33.0)


def _record(density, seed=3, pings=170):
    floor = se.seafloor.flat((130.0, 14.0), center_m=(0.0, 28.0))               # port side, ground 21–35 m
    clutter = se.Clutter(density, strength_db=-40.0, spread_db=SPREAD)
    scene = se.Scene().add(floor, material=se.Material(backscatter_db=MU_DB, clutter=clutter))
    traj = se.Trajectory.line((-59.0, 0, H), (59.0, 0, H), pings)               # 0.7 m apart: independent pings
    return se.simulate(scene, traj, se.Sonar(max_range_m=36.0), se.Pulse.cw(duration_s=TAU, taper=0.0),
                       speckle=True, band="baseband", detection="coherent", seed=seed, start_time="2000-01-01")


def _cell_integrals(r_end, alpha_db_m):
    """∫g, ∫g² and ∫σ_d·g over the floor for the sample at slant range r_end: g = Γ⁴·e^(−2α'R)/R⁴ on the annulus
    r_end − cτ/2 < R ≤ r_end the rect pulse covers; dA = dx·(R/y)·dR."""
    a2 = 2 * alpha_db_m * math.log(10) / 10
    x = np.linspace(-4.0, 4.0, 3201)
    r = np.linspace(r_end - C * TAU / 2, r_end, 41)
    xx, rr = np.meshgrid(x, r, indexing="ij")
    y = np.sqrt(rr ** 2 - H ** 2 - xx ** 2)
    u = np.stack([xx, y, np.full_like(xx, H)]) / rr                          # forward, outboard, down
    g = analytic.gamma_membrane(u[0], u[1], u[2]) ** 4 * np.exp(-a2 * rr) / rr ** 4
    da = rr / y
    sig_d = 10 ** (MU_DB / 10) * (H / rr) ** 2                                  # Lambert μ·sin²θg
    integ = lambda f: np.trapezoid(np.trapezoid(f * da, r, axis=1), x)
    return integ(g), integ(g * g), integ(sig_d * g)


@pytest.mark.parametrize("density", [12.0, 45.0, 180.0])
def test_scintillation_index_is_the_compound_poisson_closed_form(density):
    rec = _record(density)
    clutter = se.Clutter(density, strength_db=-40.0, spread_db=SPREAD)
    r = rec.slant_range_m
    pick = np.flatnonzero((r > BAND[0]) & (r < BAND[1]))
    i = rec.port[:, pick]
    m1, n = i.mean(axis=0), i.shape[0]                                           # per sample over the pings:
    mean_sq = m1 ** 2 - i.var(axis=0, ddof=1) / n                                # E[I]² unbiased (Ī² is not)
    measured = np.mean(np.mean(i ** 2, axis=0) / mean_sq - 1)
    si = []
    for k in pick[::10]:
        g1, g2, gd = _cell_integrals(r[k], rec.acquisition.alpha_db_per_m)
        mean_s = 10 ** (-4.0) * math.exp(0.5 * (SPREAD * math.log(10) / 10) ** 2)   # ⟨σ⟩ of the log-normal
        mom2 = mean_s ** 2 * math.exp((SPREAD * math.log(10) / 10) ** 2)             # ⟨σ²⟩
        si.append(1 + density * mom2 * g2 / (density * mean_s * g1 + gd) ** 2)
    expected = float(np.mean(si))
    assert clutter.moment_ratio == pytest.approx(mom2 / mean_s ** 2)
    assert measured == pytest.approx(expected, rel=0.10), (measured, expected)


def test_samples_are_independent_beyond_the_resolution_cell():
    rec = _record(45.0)
    r = rec.slant_range_m
    i = rec.port[:, (r > BAND[0]) & (r < BAND[1])]
    z = (i - i.mean(axis=0)) / i.std(axis=0)
    cell = int(math.ceil(TAU * rec.sonar.sample_rate_hz))                       # samples per pulse length
    for lag in (cell + 1, cell + 3, 2 * cell + 2):
        assert abs(np.mean(z[:, :-lag] * z[:, lag:])) < 0.05, lag
    assert np.mean(z[:, :-1] * z[:, 1:]) > 0.3                                   # within the cell they are not


def test_clutter_is_frozen_the_same_in_every_block_and_by_seed():
    a, b = _record(45.0, pings=12), _record(45.0, pings=12)
    np.testing.assert_array_equal(a.data, b.data)
    assert not np.array_equal(a.data, _record(45.0, seed=4, pings=12).data)


def test_bad_clutter_values_are_one_line_errors():
    with pytest.raises(ConfigError, match="Clutter.density_per_m2"):
        se.Clutter(0.0)
    with pytest.raises(ConfigError, match="Clutter.spread_db"):
        se.Clutter(10.0, spread_db=-1.0)
    with pytest.raises(ConfigError, match="Material.clutter"):
        se.Material(clutter=3.0)
    floor = se.seafloor.flat((10.0, 10.0))
    scene = se.Scene().add(floor, material=se.Material(clutter=se.Clutter(10.0)))
    with pytest.raises(ConfigError, match="side-scan Sonar, not EchoSounder"):
        se.simulate(scene, se.Trajectory.line((0, 0, 5.0), (1, 0, 5.0), 2), se.EchoSounder(max_range_m=10.0),
                    se.Pulse.cw(), start_time="2000-01-01")


def test_a_clutter_field_beyond_memory_is_refused_at_once():
    """Issue 49: 1e4 scatterers per m² over 70 m × 70 m (4.9e7, under the old per-object cap) drew for a minute and
    ran out of memory; the scene's total is capped and refused before any is drawn, with the memory it would take."""
    scene = se.Scene().add(se.seafloor.flat((70.0, 70.0)), material=se.Material(clutter=se.Clutter(1e4)))
    with pytest.raises(ConfigError, match=r"4.9e\+07 scatterers .* GB\) exceed 1e\+07"):
        se.simulate(scene, se.Trajectory.line((0, 0, 5.0), (1, 0, 5.0), 2), se.Sonar(max_range_m=10.0),
                    se.Pulse.cw(), start_time="2000-01-01")


def test_toml_material_clutter():
    from sonar_embree.runs.runconfig import parse_material
    m = parse_material({"clutter": {"density_per_m2": 20.0, "spread_db": 6.0}}, "x.toml", "[[objects]] #1")
    assert m.clutter == se.Clutter(20.0, spread_db=6.0)
    with pytest.raises(ConfigError, match="x.toml.*'dens'"):
        parse_material({"clutter": {"dens": 20.0}}, "x.toml", "[[objects]] #1")

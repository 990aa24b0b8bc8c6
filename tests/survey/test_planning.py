"""Survey planning (issue: real surveys): parallel lines over a polygon, swaths overlapping, turns excluded.

Coverage is checked by brute force: points sampled inside the polygon against their distance to the lines.
"""
import math

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.survey.planning import line_trajectories, plan_lines


def _inside(poly, pts):
    """Even-odd rule, written here."""
    x, y = pts[:, 0][:, None], pts[:, 1][:, None]
    x0, y0 = poly[:, 0][None], poly[:, 1][None]
    x1, y1 = np.roll(poly[:, 0], -1)[None], np.roll(poly[:, 1], -1)[None]
    hit = ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0 + 1e-300))
    return hit.sum(axis=1) % 2 == 1


def _distance_to_lines(pts, lines):
    d = np.full(len(pts), np.inf)
    for ln in lines:
        a, b = np.asarray(ln.start_m), np.asarray(ln.end_m)
        t = np.clip(((pts - a) @ (b - a)) / np.dot(b - a, b - a), 0, 1)
        d = np.minimum(d, np.linalg.norm(pts - (a + t[:, None] * (b - a)), axis=1))
    return d


@pytest.mark.parametrize("poly", [
    [(0, 0), (400, 0), (400, 170), (0, 170)],                           # a rectangle: lines along x
    [(0, 0), (300, 0), (300, 100), (100, 100), (100, 300), (0, 300)],   # an L: some lines cut in two
])
def test_lines_cover_the_polygon_with_the_overlap(poly):
    poly = np.asarray(poly, float)
    rng = np.random.default_rng(0)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    pts = rng.uniform(lo, hi, (20000, 2))
    pts = pts[_inside(poly, pts)]
    range_m, overlap = 50.0, 0.25
    lines = plan_lines(poly, range_m, overlap)
    assert np.all(_distance_to_lines(pts, lines) <= range_m * (1 - overlap / 2) + 1e-6)  # covered with margin
    d = np.array([ln.end_m for ln in lines]) - np.array([ln.start_m for ln in lines])
    heading = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180
    assert np.ptp(heading) < 1e-6                                          # parallel
    offsets = np.unique(np.round(np.array([ln.start_m for ln in lines]) @ [-math.sin(math.radians(heading[0])),
                                                                               math.cos(math.radians(heading[0]))], 6))
    spacing = np.diff(offsets)
    assert np.all(spacing <= 2 * range_m * (1 - overlap) + 1e-6)          # swaths overlap by at least 25 %
    width = np.ptp(poly @ [-math.sin(math.radians(heading[0])), math.cos(math.radians(heading[0]))])
    assert len(offsets) == math.ceil(width / (2 * range_m * (1 - overlap)))   # and no more lines than needed


def test_rectangle_lines_alternate_and_become_trajectories():
    poly = [(0, 0), (400, 0), (400, 170), (0, 170)]
    lines = plan_lines(poly, 50.0, 0.2)
    assert len(lines) == 3 and lines[0].start_m[0] < lines[0].end_m[0] and lines[1].start_m[0] > lines[1].end_m[0]
    assert lines[0].start_m[0] == pytest.approx(-50.0) and lines[0].end_m[0] == pytest.approx(450.0)  # run in/out
    trajs = line_trajectories(lines, -20.0, 2.0, 4.0, crs=32632, start_time="2026-05-01T12:00:00Z")
    assert [len(t) for t in trajs] == [1001, 1001, 1001]                    # a ping every 0.5 m over 500 m
    assert all(t.crs == "EPSG:32632" for t in trajs)
    np.testing.assert_allclose(np.diff(trajs[0].positions_m[:, 0]), 0.5)
    assert trajs[1].times_s[0] == pytest.approx(trajs[0].times_s[-1] + 0.25)  # the turn is skipped, time goes on
    np.testing.assert_allclose(trajs[1].heading_deg, 270.0)                 # west
    with pytest.raises(se.ConfigError, match="overlap must lie in"):
        plan_lines(poly, 50.0, 1.5)
    with pytest.raises(se.ConfigError, match="no area"):
        plan_lines([(0, 0), (1, 1), (2, 2)], 50.0)


def test_the_planner_refuses_nonsense_in_one_line():
    """Issue 33, finding 9: a negative run-in made 2 000 km lines, NaN a traceback, an infinite speed no
    trajectory, 1e9 Hz a MemoryError, a 1e7 m square at 1 m range minutes of silence, and a self-intersecting
    polygon "has no area"; each is now refused in one line, the size stated."""
    square = [(0.0, 0.0), (200.0, 0.0), (200.0, 100.0), (0.0, 100.0)]
    for kw, what in ((dict(run_in_m=-1e6), r"run_in_m must be a finite number >= 0 and <= 500"),
                     (dict(run_in_m=float("nan")), "run_in_m must be a finite number"),
                     (dict(direction_deg=float("inf")), "direction_deg must be a finite number"),
                     (dict(range_m=True), "range_m must be a finite number")):
        with pytest.raises(se.ConfigError, match=what):
            plan_lines(square, **({"range_m": 50.0} | kw))
    lines = plan_lines(square, 50.0)
    for args, what in (((float("inf"), 4.0), "speed_m_s must be a finite number > 0"),
                       ((2.0, 1e9), r"ping_rate_hz must be a finite number > 0 and <= 1000"),
                       ((2.0, float("nan")), "ping_rate_hz must be a finite"),
                       ((0.0, 4.0), "speed_m_s must be a finite number > 0")):
        with pytest.raises(se.ConfigError, match=what):
            line_trajectories(lines, -20.0, *args)
    huge = [(0.0, 0.0), (1e7, 0.0), (1e7, 1e7), (0.0, 1e7)]
    with pytest.raises(se.ConfigError, match=r"plan_lines: 1e\+07 m across at range_m = 1 m needs 6250000 lines "
                                             r"\(some 6.25e\+10 km of track\), beyond 10000"):
        plan_lines(huge, 1.0)
    long_lines = plan_lines([(0.0, 0.0), (5e5, 0.0), (5e5, 4e3), (0.0, 4e3)], 100.0)
    with pytest.raises(se.ConfigError, match=r"line_trajectories: 25 lines of 1.25\d*e\+04 km at 2 m/s and 20 Hz "
                                             r"make 12505\d{4} pings \(17\d\d h of survey\), beyond 20000000"):
        line_trajectories(long_lines, -20.0, 2.0, 20.0)
    bow_tie = [(0.0, 0.0), (100.0, 100.0), (100.0, 0.0), (0.0, 100.0)]
    with pytest.raises(se.ConfigError, match=r"the polygon's edges 0 and 2 cross \(it is self-intersecting\)"):
        plan_lines(bow_tie, 50.0)


def test_survey_size_counts_what_line_trajectories_makes():
    """The estimate is the plan's: its pings equal the trajectories' (counted independently), hours = km / v."""
    from sonar_embree.survey.planning import survey_size

    poly = [(0.0, 0.0), (300.0, 0.0), (300.0, 120.0), (150.0, 200.0), (0.0, 120.0)]
    lines = plan_lines(poly, 40.0, 0.3)
    size = survey_size(lines, 2.0, 5.0)
    trajs = line_trajectories(lines, -20.0, 2.0, 5.0)
    assert size["pings"] == sum(len(t) for t in trajs) and size["lines"] == len(trajs)
    assert size["km"] == pytest.approx(sum(math.dist(ln.start_m, ln.end_m) for ln in lines) / 1e3)
    assert size["hours"] == pytest.approx(size["km"] * 1e3 / 2.0 / 3600.0)

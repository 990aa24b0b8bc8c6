"""Survey planning (issue: real surveys): parallel lines over a polygon, swaths overlapping, turns excluded.

Coverage is checked by brute force: points sampled inside the polygon against their distance to the lines.
"""
import math

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.planning import line_trajectories, plan_lines


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

"""World geometry: distances, intersections, polygons, the corridor, the longest ladder."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from hybridteam.world import (
    corridor_with_turn,
    longest_ladder,
    point_segment_distance,
    point_segment_distances,
    points_in_polygon,
    segment_segment_distances,
    segments_intersect,
    segments_intersect_polygon,
)
from hybridteam.world.limits import critical_angle


def _brute_point_segment(p, s, samples=20001):
    t = np.linspace(0.0, 1.0, samples)
    q = s[:2] + t[:, None] * (s[2:] - s[:2])
    return np.hypot(*(q - p).T).min()


def test_point_segment_distance_matches_dense_sampling():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-10, 10, (30, 2))
    segs = rng.uniform(-10, 10, (7, 4))
    dist, closest = point_segment_distances(pts, segs)
    assert dist.shape == (30, 7) and closest.shape == (30, 7, 2)
    for i in range(30):
        for j in range(7):
            assert dist[i, j] == pytest.approx(_brute_point_segment(pts[i], segs[j]), abs=2e-3)
            assert np.hypot(*(closest[i, j] - pts[i])) == pytest.approx(dist[i, j])
    dmin, cmin = point_segment_distance(pts, segs)
    np.testing.assert_allclose(dmin, dist.min(axis=1))
    np.testing.assert_allclose(cmin, closest[np.arange(30), dist.argmin(axis=1)])


def test_point_segment_distance_simple_cases():
    walls = np.array([[0, 0, 10, 0], [0, 0, 0, 10], [5, 5, 5, 5]], dtype=float)
    d, c = point_segment_distances([[3, 4], [-3, -4], [5, 6]], walls)
    np.testing.assert_allclose(d, [[4, 3, math.hypot(2, 1)], [5, 5, math.hypot(8, 9)], [6, 5, 1]])
    np.testing.assert_allclose(c[0, 0], [3, 0])
    np.testing.assert_allclose(c[1, 1], [0, 0])  # clamped to the end point
    np.testing.assert_allclose(c[2, 2], [5, 5])  # degenerate segment is a point


def test_point_segment_distance_is_batch_independent():
    rng = np.random.default_rng(2)
    pts = rng.uniform(-100, 100, (57, 2))
    walls = corridor_with_turn().walls
    d, _ = point_segment_distances(pts, walls)
    for i in range(0, 57, 5):
        assert np.array_equal(point_segment_distances(pts[i : i + 1], walls)[0][0], d[i])


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        ([0, 0, 2, 2], [0, 2, 2, 0], True),  # proper crossing
        ([0, 0, 1, 1], [1, 1, 2, 0], True),  # shared end point
        ([0, 0, 2, 0], [1, 0, 1, 5], True),  # T: end on the interior
        ([0, 0, 2, 0], [1, 0.001, 1, 5], False),  # just short
        ([0, 0, 2, 0], [1, 0, 3, 0], True),  # collinear overlap
        ([0, 0, 1, 0], [2, 0, 3, 0], False),  # collinear, disjoint
        ([0, 0, 2, 0], [0, 1, 2, 1], False),  # parallel
    ],
)
def test_segments_intersect_cases(a, b, expected):
    assert segments_intersect([a], [b])[0, 0] == expected
    assert segments_intersect([b], [a])[0, 0] == expected


def test_segments_intersect_matches_parametric_solution():
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 10, (200, 4))
    b = rng.uniform(0, 10, (50, 4))
    got = segments_intersect(a, b)
    for i in range(200):
        for j in range(50):
            p, r = a[i, :2], a[i, 2:] - a[i, :2]
            q, s = b[j, :2], b[j, 2:] - b[j, :2]
            den = r[0] * s[1] - r[1] * s[0]
            t = ((q - p)[0] * s[1] - (q - p)[1] * s[0]) / den
            u = ((q - p)[0] * r[1] - (q - p)[1] * r[0]) / den
            assert got[i, j] == (0 <= t <= 1 and 0 <= u <= 1)


def test_segment_segment_distances():
    a = np.array([[0, 0, 10, 0], [0, 0, 2, 2]], dtype=float)
    b = np.array([[0, 3, 10, 3], [5, -1, 5, 1], [3, 0, 4, 1]], dtype=float)
    d = segment_segment_distances(a, b)
    np.testing.assert_allclose(d[0], [3, 0, 0])
    np.testing.assert_allclose(d[1], [1, math.sqrt(10), 1.5 * math.sqrt(2)])


def test_points_in_polygon_concave_and_boundary():
    ell = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    pts = [[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5], [1, 1.5], [2, 0.5], [3, 3]]
    assert points_in_polygon(pts, ell).tolist() == [True, True, True, False, True, True, False]


def test_segments_intersect_polygon():
    square = corridor_with_turn().corner
    segs = [
        [-50, 900, 300, 1300],  # crosses the square, both ends outside
        [50, 1050, 60, 1060],  # inside
        [300, 0, 300, 900],  # outside
        [200, 1200, 400, 1400],
    ]  # touches a corner
    assert segments_intersect_polygon(segs, square).tolist() == [True, True, False, True]


def test_default_corridor_is_the_papers():
    c = corridor_with_turn()
    outer = np.hypot(
        c.outer_walls[:, 2] - c.outer_walls[:, 0], c.outer_walls[:, 3] - c.outer_walls[:, 1]
    )
    inner = np.hypot(
        c.inner_walls[:, 2] - c.inner_walls[:, 0], c.inner_walls[:, 3] - c.inner_walls[:, 1]
    )
    assert outer.sum() == 2400 and inner.sum() == 2000
    assert c.width_in == c.width_out == 200 and c.turn == "right"
    x0, y0 = c.corner.min(axis=0)
    x1, y1 = c.corner.max(axis=0)
    assert (x1 - x0, y1 - y0) == (200, 200)
    np.testing.assert_array_equal(c.inner_vertex, [200, 1000])
    assert c.walls.shape == (4, 4)
    # What the views draw, and its trace form, JSON-ready.
    scene = c.describe()
    assert scene.walls == tuple(tuple(w) for w in c.walls.tolist())
    assert scene.regions[0].label == "corner" and scene.obstacles == ()
    meta = json.loads(json.dumps(scene.to_meta()))
    assert set(meta) == {"world"} and set(meta["world"]) == {"walls", "regions", "obstacles"}
    assert meta["world"]["regions"][0]["label"] == "corner" and len(meta["world"]["walls"][0]) == 4
    # Travel goes up the incoming leg, then right; the inner normals point into the walls.
    np.testing.assert_array_equal(c.direction_in, [0, 1])
    np.testing.assert_array_equal(c.direction_out, [1, 0])
    np.testing.assert_array_equal(c.inner_normals, [[1, 0], [0, -1]])


def test_corridor_points_and_left_turn():
    c = corridor_with_turn()
    np.testing.assert_allclose(
        c.corner_entry_point([0.0, 0.65, 1.0]), [[200, 1000], [70, 1000], [0, 1000]]
    )
    np.testing.assert_allclose(c.corner_exit_point(0.8), [200, 1160])
    np.testing.assert_allclose(c.leg_point("in", 70.0), [100, 70])
    np.testing.assert_allclose(c.leg_point("out", 70.0), [1130, 1100])
    left = corridor_with_turn(turn="left")
    mirror = np.array([-1.0, 1.0, -1.0, 1.0])
    np.testing.assert_allclose(left.walls, c.walls * mirror)
    np.testing.assert_allclose(left.corner_entry_point(0.65), [-70, 1000])
    # Inner normals point from the corridor into the inner walls for both turns.
    for cor in (c, left):
        mid1 = cor.leg_point("in", 500.0)
        mid2 = cor.leg_point("out", 500.0)
        for p, n in ((mid1, cor.inner_normals[0]), (mid2, cor.inner_normals[1])):
            d0, _ = point_segment_distance(p[None], cor.inner_walls)
            d1, _ = point_segment_distance((p + 10 * n)[None], cor.inner_walls)
            assert d1 < d0


def test_corridor_with_unequal_legs():
    c = corridor_with_turn(width_in=150, width_out=250, outer_leg_in=900, outer_leg_out=700)
    np.testing.assert_array_equal(c.inner_vertex, [150, 650])
    np.testing.assert_array_equal(c.corner, [[0, 650], [150, 650], [150, 900], [0, 900]])
    assert c.inner_walls[0].tolist() == [150, 0, 150, 650]
    assert c.inner_walls[1].tolist() == [150, 650, 700, 650]
    with pytest.raises(ValueError):
        corridor_with_turn(turn="up")


def _numeric_limit(wa, wb, r):
    """Shortest chord through the inner vertex between the outer walls moved in by r.

    Corridor coordinates: vertex at the origin, leg a's shifted outer wall at x = -(wa - r),
    leg b's at y = wb - r; a chord at angle phi to leg a (the y axis) meets them at the
    distances below, computed from the lines, not from the closed form.
    """

    def chord(phi):
        d = np.array([math.sin(phi), math.cos(phi)])  # direction, leg a along +y
        to_a = (wa - r) / d[0]  # back along -d to x = -(wa - r)
        to_b = (wb - r) / d[1]  # forward along +d to y = wb - r
        return to_a + to_b

    res = minimize_scalar(
        chord, bounds=(1e-6, math.pi / 2 - 1e-6), method="bounded", options={"xatol": 1e-12}
    )
    return res.fun, res.x


@pytest.mark.parametrize(
    ("wa", "wb", "r"),
    [(200, 200, 0), (200, 200, 26), (200, 200, 28), (150, 300, 20), (300, 120, 10)],
)
def test_longest_ladder_matches_numeric_minimum(wa, wb, r):
    length, phi = _numeric_limit(wa, wb, r)
    assert longest_ladder(wa, wb, r) == pytest.approx(length, rel=1e-9)
    assert critical_angle(wa, wb, r) == pytest.approx(phi, abs=1e-5)


def test_longest_ladder_equal_widths_is_two_root_two():
    assert longest_ladder(200, 200, 25) == pytest.approx(2 * math.sqrt(2) * 175)
    assert longest_ladder(200, 200, 28) == pytest.approx(486.489, abs=1e-3)
    with pytest.raises(ValueError):
        longest_ladder(200, 200, 101)


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 4), st.integers(1, 6), st.integers(0, 2**32 - 1))
def test_segment_distances_are_each_ends_own(n, m, seed):
    """segment_segment_distances casts each set's ends against the other set in one call;
    every distance must be the one :func:`point_segment_distances` gives that end alone
    (bit for bit, degenerate segments, shared and zero coordinates included)."""
    rng = np.random.default_rng(seed)
    pts = np.round(rng.uniform(-3, 3, (n + m, 4)), 1)  # shared coordinates are likely
    pts[rng.random(pts.shape) < 0.2] = 0.0
    a, b = pts[:n].copy(), pts[n:].copy()
    if seed % 3 == 0:
        a[0, 2:] = a[0, :2]  # a degenerate segment
    got = segment_segment_distances(a, b)
    ends = [
        point_segment_distances(a[:, 0:2], b)[0],
        point_segment_distances(a[:, 2:4], b)[0],
        point_segment_distances(b[:, 0:2], a)[0].T,
        point_segment_distances(b[:, 2:4], a)[0].T,
    ]
    dist = np.minimum(np.minimum(ends[0], ends[1]), np.minimum(ends[2], ends[3]))
    expected = np.where(segments_intersect(a, b), 0.0, dist)
    assert got.tobytes() == expected.tobytes()

"""Range sensors: rays against walls and disks, rings on robots, thresholds, clearance."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from hybridteam.world.geometry import point_segment_distances, rectangle
from hybridteam.world.sensors import RangeRing, cast, clearance, detect, polygon_edges

ROOM = polygon_edges(rectangle(-2.0, -1.0, 3.0, 4.0))  # x in [-2, 3], y in [-1, 4]


def ray(ox, oy, dx, dy):
    """One ray as the ``(1, 1, 2)`` origins and directions :func:`cast` takes."""
    return np.array([[[ox, oy]]], dtype=float), np.array([[[dx, dy]]], dtype=float)


def cast1(ox, oy, dx, dy, segments=None, circles=None, max_range=np.inf) -> float:
    return float(cast(*ray(ox, oy, dx, dy), segments, circles, max_range)[0, 0])


def room_reading(ox: float, oy: float, phi: float) -> float:
    """Distance from inside ROOM to its wall along heading ``phi``, by trigonometry."""
    c, s = math.cos(phi), math.sin(phi)
    tx = (3.0 - ox) / c if c > 1e-15 else (-2.0 - ox) / c if c < -1e-15 else math.inf
    ty = (4.0 - oy) / s if s > 1e-15 else (-1.0 - oy) / s if s < -1e-15 else math.inf
    return min(tx, ty)


def test_axis_beams_in_a_room_read_the_wall_distances():
    ring = RangeRing(count=4, max_range=10.0)
    assert ring.read(np.array([[0.0, 0.0, 0.0]]), ROOM).tolist() == [[3.0, 4.0, 2.0, 1.0]]
    turned = ring.read(np.array([[0.0, 0.0, math.pi / 2]]), ROOM)
    np.testing.assert_allclose(turned, [[4.0, 2.0, 1.0, 3.0]], rtol=1e-12)


def test_every_beam_of_a_mounted_ring_matches_trigonometry():
    ring = RangeRing(count=24, max_range=10.0, mount_radius=0.33, offset=0.1, name="ir")
    x, y, theta = 0.5, 0.7, 0.3
    readings = ring.read(np.array([[x, y, theta]]), ROOM)[0]
    for i, a in enumerate(ring.angles):
        phi = theta + a
        ox, oy = x + 0.33 * math.cos(phi), y + 0.33 * math.sin(phi)
        assert readings[i] == pytest.approx(room_reading(ox, oy, phi), rel=1e-12)


def test_a_beam_into_a_corner_does_not_slip_between_the_walls():
    square = polygon_edges(rectangle(0.0, 0.0, 4.0, 4.0))
    ring = RangeRing(count=4, max_range=10.0, offset=math.pi / 4)
    readings = ring.read(np.array([[2.0, 2.0, 0.0]]), square)
    np.testing.assert_allclose(readings, 2.0 * math.sqrt(2.0), rtol=1e-12)


def test_rays_parallel_to_walls():
    wall = np.array([[0.0, 1.0, 5.0, 1.0]])  # y = 1, x in [0, 5]
    assert cast1(-3.0, 0.0, 1.0, 0.0, wall) == math.inf  # parallel, off its line
    assert cast1(-3.0, 1.0, 1.0, 0.0, wall) == 3.0  # collinear: its near end
    assert cast1(8.0, 1.0, -2.0, 0.0, wall) == 3.0  # from the other side
    assert cast1(6.0, 1.0, 1.0, 0.0, wall) == math.inf  # collinear, behind
    assert cast1(2.0, 1.0, 1.0, 0.0, wall) == 0.0  # starting on it
    assert cast1(-1.0, 0.0, 1.0, 0.0, ROOM) == 4.0  # room: along two walls
    assert cast1(-2.0, 0.0, 0.0, 1.0, ROOM) == 0.0  # on a wall, along it


def test_rays_starting_on_a_segment_read_zero():
    wall = np.array([[0.0, 0.0, 2.0, 2.0]])
    assert cast1(1.0, 1.0, 1.0, 0.0, wall) == 0.0
    assert cast1(1.0, 1.0, -1.0, 0.0, wall) == 0.0
    assert cast1(0.0, 0.0, 0.0, -1.0, wall) == 0.0  # on its end point
    assert cast1(2.0, 0.0, 0.0, 1.0, wall) == pytest.approx(2.0)  # meets it at its far end


def test_zero_length_segments_are_points():
    point = np.array([[3.0, 0.0, 3.0, 0.0]])
    assert cast1(0.0, 0.0, 1.0, 0.0, point) == 3.0
    assert cast1(0.0, 0.0, 1.0, 0.1, point) == math.inf
    assert cast1(0.0, 0.0, -1.0, 0.0, point) == math.inf
    assert cast1(0.0, 0.0, 1.0, 0.0, np.zeros((0, 4))) == math.inf
    assert cast1(0.0, 0.0, 1.0, 0.0, None) == math.inf


def test_a_circle_is_hit_at_its_analytic_chord():
    # Centre 1.2 off the ray: the near intersection is 5 - sqrt(2^2 - 1.2^2) = 3.4 along it.
    assert cast1(0.0, 0.0, 1.0, 0.0, circles=[[5.0, 1.2, 2.0]]) == pytest.approx(3.4, rel=1e-14)
    assert cast1(0.0, 0.0, 1.0, 0.0, circles=[[5.0, 2.0, 2.0]]) == pytest.approx(5.0)  # tangent
    assert cast1(0.0, 0.0, 1.0, 0.0, circles=[[5.0, 2.5, 2.0]]) == math.inf
    assert cast1(0.0, 0.0, 1.0, 0.0, circles=[[-5.0, 0.0, 2.0]]) == math.inf  # behind
    assert cast1(0.0, 0.0, 1.0, 0.0, circles=[[0.5, 0.0, 2.0]]) == 0.0  # inside it
    assert cast1(0.0, 0.0, 3.0, 4.0, circles=[[6.0, 8.0, 5.0]]) == pytest.approx(5.0)
    # The nearer of a wall and a circle wins.
    assert cast1(0.0, 0.0, 1.0, 0.0, ROOM, [[2.0, 0.0, 0.5]]) == pytest.approx(1.5)
    assert cast1(0.0, 0.0, -1.0, 0.0, ROOM, [[2.0, 0.0, 0.5]]) == 2.0


def test_per_instance_circles_and_nan_rows():
    origins = np.zeros((3, 1, 2))
    directions = np.tile([1.0, 0.0], (3, 1, 1))
    circles = np.array(
        [
            [[2.0, 0.0, 1.0], [np.nan] * 3],
            [[4.0, 0.0, 1.0], [3.0, 0.0, 0.5]],
            [[np.nan] * 3, [np.nan] * 3],
        ]
    )
    out = cast(origins, directions, None, circles, max_range=10.0)
    assert out[:, 0].tolist() == [1.0, 2.5, 10.0]


def test_polygon_obstacle_is_its_edges():
    box = polygon_edges(rectangle(1.0, -0.5, 2.0, 0.5))
    assert box.shape == (4, 4)
    assert cast1(0.0, 0.0, 1.0, 0.0, box) == 1.0
    assert cast1(1.5, 0.0, 1.0, 0.0, box) == pytest.approx(0.5)  # from inside: far face


def test_readings_are_clipped_to_the_sensor_range():
    ring = RangeRing(count=8, max_range=1.0, min_range=0.15)
    far = ring.read(np.array([[0.5, 1.5, 0.0]]), ROOM)
    assert np.all(far == 1.0)
    near = ring.read(np.array([[2.9, 1.5, 0.0]]), ROOM)
    assert near[0, 0] == 0.15 and near[0, 4] == 1.0
    assert cast1(0.0, 0.0, 1.0, 0.0, ROOM, max_range=2.5) == 2.5


def test_cone_reading_is_the_minimum_over_its_sub_rays():
    half = math.radians(12.5)
    cone = RangeRing(count=1, max_range=5.0, half_angle=half, rays_per_beam=5, name="sonar")
    line = RangeRing(count=1, max_range=5.0, name="ir")
    post = [[2.0, 0.4, 0.1]]  # off the beam's axis, inside its cone
    pose = np.array([[0.0, 0.0, 0.0]])
    assert line.read(pose, None, post)[0, 0] == 5.0
    # Only the edge ray at +12.5 degrees meets the post; its chord by hand:
    ux, uy = math.cos(half), math.sin(half)
    along = 2.0 * ux + 0.4 * uy
    off = abs(-2.0 * uy + 0.4 * ux)
    assert off < 0.1
    expected = along - math.sqrt(0.1**2 - off**2)
    assert cone.read(pose, None, post)[0, 0] == pytest.approx(expected, rel=1e-12)
    # And against any world: the beam reads the minimum of its five rays cast one by one.
    ring = RangeRing(count=16, max_range=5.0, mount_radius=0.2, half_angle=half, rays_per_beam=5)
    poses = np.array([[0.3, 0.4, 0.7], [-1.0, 2.0, -2.0]])
    circles = [[1.0, 1.0, 0.3], [-1.5, 3.0, 0.2]]
    origins, directions = ring.rays(poses)
    each = cast(origins, directions, ROOM, circles, 5.0).reshape(2, 16, 5)
    np.testing.assert_array_equal(ring.read(poses, ROOM, circles), each.min(axis=2))


def test_a_batch_of_poses_equals_single_calls_bit_for_bit():
    rng = np.random.default_rng(7)
    walls = np.concatenate([ROOM, rng.uniform(-2.0, 3.0, (40, 4))])
    circles = rng.uniform(-1.0, 3.0, (257, 5, 3)) * [1.0, 1.0, 0.1]
    poses = np.column_stack(
        [rng.uniform(-2.0, 3.0, 257), rng.uniform(-1.0, 4.0, 257), rng.uniform(-7.0, 7.0, 257)]
    )
    ring = RangeRing(
        count=24,
        max_range=5.0,
        min_range=0.1,
        mount_radius=0.33,
        half_angle=math.radians(12.5),
        rays_per_beam=3,
    )
    batch = ring.read(poses, walls, circles)
    singles = np.concatenate(
        [ring.read(poses[i : i + 1], walls, circles[i : i + 1]) for i in range(len(poses))]
    )
    np.testing.assert_array_equal(batch, singles)
    gap = clearance(poses, 0.33, walls, circles)
    np.testing.assert_array_equal(
        gap, [clearance(poses[i : i + 1], 0.33, walls, circles[i : i + 1])[0] for i in range(257)]
    )


# --- property: never see through a wall, and every hit is on a wall ------------------------


def _exact_hit(o, d, seg) -> tuple[Fraction, float] | None:
    """First point of ``seg`` on the ray, exactly: ray parameter (units of |d|) and the sine
    of the angle between ray and segment (0 when parallel)."""
    ox, oy, dx, dy = map(Fraction, (*o, *d))
    ax, ay, bx, by = map(Fraction, seg)
    ex, ey, wx, wy = bx - ax, by - ay, ax - ox, ay - oy
    den = dx * ey - dy * ex
    if den != 0:
        t, s = (wx * ey - wy * ex) / den, (wx * dy - wy * dx) / den
        sine = abs(float(den)) / (
            math.hypot(float(dx), float(dy)) * math.hypot(float(ex), float(ey))
        )
        return (t, sine) if t >= 0 and 0 <= s <= 1 else None
    if wx * dy - wy * dx != 0:
        return None  # parallel, off the line
    dd = dx * dx + dy * dy
    ta, tb = (wx * dx + wy * dy) / dd, ((wx + ex) * dx + (wy + ey) * dy) / dd
    return (max(min(ta, tb), Fraction(0)), 0.0) if max(ta, tb) >= 0 else None


coord = st.one_of(
    st.integers(-5, 5).map(float), st.floats(-10.0, 10.0, allow_nan=False, allow_subnormal=False)
)
segment = st.one_of(
    st.tuples(coord, coord, coord, coord), st.tuples(coord, coord).map(lambda p: (*p, *p))
)  # zero length
direction = st.tuples(coord, coord).filter(lambda d: math.hypot(*d) > 1e-3)
aim = st.integers(0, 11)  # at a segment's end point: corners, grazing and collinear rays


@settings(max_examples=300, deadline=None)
@given(
    st.lists(segment, min_size=1, max_size=6),
    st.lists(st.tuples(coord, coord, st.one_of(direction, aim)), min_size=1, max_size=4),
)
@example([(0.0, 0.0, 0.0, 8.595081661836888e-306)], [(2.0, 5.0, 0)])  # aimed at a tiny wall
@example([(0.0, 6.411170972520673e-08, 1.0, 3.0)], [(0.0, 0.0, 1)])  # grazing its whole length
@example([(0.0, 0.0, 4.0, 0.0), (4.0, 0.0, 4.0, 4.0)], [(2.0, 2.0, 2)])  # into a corner
def test_reading_never_passes_a_wall_and_hits_lie_on_walls(segments, rays):
    segs = np.array(segments, dtype=float)
    ends = segs.reshape(-1, 2)
    rays = [
        (ox, oy, d if isinstance(d, tuple) else tuple(ends[d % len(ends)] - (ox, oy)))
        for ox, oy, d in rays
    ]
    rays = [r for r in rays if math.hypot(*r[2]) > 1e-3] or [(0.0, 0.0, (1.0, 0.0))]
    origins = np.array([[r[0], r[1]] for r in rays])[None]
    directions = np.array([r[2] for r in rays])[None]
    readings = cast(origins, directions, segs)[0]
    scale = 1.0 + max(np.abs(segs).max(), np.abs(origins).max())  # tolerances are relative
    for (ox, oy, d), reading in zip(rays, readings, strict=True):
        hits = [h for h in (_exact_hit((ox, oy), d, s) for s in segments) if h is not None]
        true, sine = min(hits, key=lambda h: (h[0], -h[1])) if hits else (math.inf, 0.0)
        true = float(true) * math.hypot(*d)
        # Where a ray grazes a wall the crossing is ill-conditioned: the rounding of the
        # inputs (~1e-16 * scale) moves it by that over the sine of the grazing angle.
        assert reading <= true + 1e-9 + (1e-14 * scale / sine if sine > 0 else 0.0)
        if math.isfinite(reading):
            n = math.hypot(*d)
            point = np.array([[ox + reading * d[0] / n, oy + reading * d[1] / n]])
            off, _ = point_segment_distances(point, segs)
            e = segs[:, 2:] - segs[:, :2]
            sines = np.abs(d[0] * e[:, 1] - d[1] * e[:, 0]) / (n * np.hypot(*e.T) + 1e-300)
            allowed = 1e-9 * scale + 1e-14 * scale / np.where(sines > 0, sines, np.inf)
            assert np.any(off[0] <= allowed)


# --- thresholds, sectors, clearance, validation -------------------------------------------


def test_detect_fires_when_selected_beams_see_closer_than_the_threshold():
    readings = np.array([[0.4, 2.0, 2.0, 2.0], [2.0, 2.0, 0.3, 2.0], [0.6, 2.0, 2.0, 2.0]])
    assert detect(readings, 0.5).tolist() == [True, True, False]
    assert detect(readings, 0.5, beams=slice(0, 2)).tolist() == [True, False, False]
    assert detect(readings, 0.5, beams=np.array([2])).tolist() == [False, True, False]
    assert detect(readings, np.array([0.3, 0.3, 0.7])).tolist() == [False, False, True]
    ring = RangeRing(count=24, max_range=0.5)
    assert ring.sector(0.0, math.pi / 4).tolist() == [0, 1, 2, 3, 21, 22, 23]
    assert ring.sector(math.pi, 0.01).tolist() == [12]


def test_front_ir_sees_a_robot_ahead():
    ir = RangeRing(count=24, max_range=0.5, mount_radius=0.33, name="ir")
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi]])
    other = [[1.0, 0.0, 0.3]]  # a robot 1 m ahead of the first: 0.37 m hull to hull
    readings = ir.read(poses, None, other)
    assert readings[0, 0] == pytest.approx(0.37)
    assert detect(readings, 0.5, ir.sector(0.0, math.pi / 4)).tolist() == [True, False]


def test_clearance_of_disks_from_walls_and_circles():
    poses = np.array([[0.0, 0.0, 1.0], [2.5, 3.0, 0.0], [0.0, 1.0, 0.0]])
    gap = clearance(poses, 0.3, ROOM, [[1.0, 1.0, 0.2]])
    np.testing.assert_allclose(gap, [0.7, 0.2, 0.5])
    assert clearance(poses[:1], np.array([1.5]), ROOM)[0] == pytest.approx(-0.5)
    assert clearance(poses, 0.3, None).tolist() == [math.inf] * 3
    per_instance = np.array([[[0.0, 0.5, 0.1]], [[np.nan] * 3], [[9.0, 9.0, 1.0]]])
    np.testing.assert_allclose(
        clearance(poses, 0.0, None, per_instance), [0.4, math.inf, math.hypot(9.0, 8.0) - 1.0]
    )


@pytest.mark.parametrize(
    "kwargs",
    [
        {"count": 0, "max_range": 1.0},
        {"count": 4, "max_range": 1.0, "min_range": 1.0},
        {"count": 4, "max_range": 1.0, "mount_radius": -0.1},
        {"count": 4, "max_range": 1.0, "half_angle": 0.2},
        {"count": 4, "max_range": 1.0, "rays_per_beam": 3},
        {"count": 4, "max_range": 1.0, "half_angle": 2.0, "rays_per_beam": 3},
    ],
)
def test_bad_rings_are_refused(kwargs):
    with pytest.raises(ValueError):
        RangeRing(**kwargs)


def test_bad_arrays_are_refused():
    with pytest.raises(ValueError, match="non-zero"):
        cast(*ray(0.0, 0.0, 0.0, 0.0), ROOM)
    with pytest.raises(ValueError, match="shape"):
        cast(np.zeros((2, 2)), np.ones((2, 2)), ROOM)
    with pytest.raises(ValueError, match="circles"):
        cast(*ray(0.0, 0.0, 1.0, 0.0), ROOM, np.zeros((2, 1, 3)))
    with pytest.raises(ValueError, match="poses"):
        RangeRing(count=4, max_range=1.0).read(np.zeros(3), ROOM)


def test_a_cast_reads_nothing_a_previous_cast_of_the_same_shape_left_behind():
    """Casts of one shape share this thread's scratch arrays: a cast after another, on a
    different scene, gives what it gives in a fresh thread (fresh scratch), bit for bit:
    walls and circles, rays that hit and rays that read the maximum range."""
    import threading

    rng = np.random.default_rng(11)

    def scene(seed: int):
        r = np.random.default_rng(seed)
        o = r.uniform(-3, 3, (4, 6, 2))
        ang = r.uniform(-np.pi, np.pi, (4, 6))
        d = np.stack([np.cos(ang), np.sin(ang)], -1)
        seg = r.uniform(-4, 4, (5, 4))
        circ = np.c_[r.uniform(-3, 3, (3, 2)), r.uniform(0.1, 1.0, 3)]
        return o, d, seg, circ

    first, second = scene(int(rng.integers(1 << 30))), scene(int(rng.integers(1 << 30)))
    cast(*first, max_range=5.0)
    after = cast(*second, max_range=5.0)
    fresh: list[np.ndarray] = []
    worker = threading.Thread(target=lambda: fresh.append(cast(*second, max_range=5.0)))
    worker.start()
    worker.join()
    np.testing.assert_array_equal(after, fresh[0])
    assert np.any(after < 5.0) and np.any(after == 5.0)  # some rays hit, some read max


@given(
    st.lists(st.integers(0, 15), min_size=1, max_size=16, unique=True),
    st.floats(-50, 50),
    st.floats(-50, 50),
    st.floats(-10, 10),
)
@settings(max_examples=100, deadline=None)
def test_the_rays_of_some_beams_are_those_beams_rays(beams, x, y, theta):
    """Casting only the beams a rule reads gives those beams' rays of the whole ring, bit
    for bit (a cone's sub-rays included, in the order the beams are given)."""
    ring = RangeRing(16, 3.0, 0.05, 0.2, 0.1, half_angle=0.2, rays_per_beam=3)
    poses = np.array([[x, y, theta], [y, x, -theta]])
    b = np.array(beams)
    rays = (b[:, None] * 3 + np.arange(3)).ravel()
    whole_o, whole_d = ring.rays(poses)
    some_o, some_d = ring.rays(poses, b)
    np.testing.assert_array_equal(some_o, whole_o[:, rays])
    np.testing.assert_array_equal(some_d, whole_d[:, rays])

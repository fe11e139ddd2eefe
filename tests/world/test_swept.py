"""Clearances and collisions over the motion between ticks, exactly (issue 48: the swept
test, :mod:`hybridteam.world.swept`).

Hand-computed cases. A unicycle at v = 1, omega = 1 from (0, 0) heading +x drives round the
unit circle about (0, 1): at time t it is at (sin t, 1 - cos t), at angle t - pi/2 about
the centre. A post at (2, 1) is nearest to that circle at (1, 1), reached at t = pi/2,
1 from the post's centre. Under a law of period 2 pi / 3 the ticks see the robot at
angles -90, 30 and 150 degrees only: (0, 0), (0.866, 1.5), (-0.866, 1.5), the nearest of
them hypot(2 - cos 30deg, 0.5) = 1.2393 from the post.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.world.swept import first_contact, holds_between_instants, least_gap, piece

PERIOD = 2 * math.pi / 3
#: the nearest tick position, (cos 30, 1 + sin 30), from the post at (2, 1)
TICK_DISTANCE = math.hypot(2 - math.cos(math.pi / 6), 1 - 1.5)

CIRCLING = """
team: circling
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 1.0}}, period: {period!r}}}}}
world:
  - use: obstacles
    with:
      circles: [[2.0, 1.0, 0.25]]
      radius: [[r, {radius}]]
      on_collision: {mode}
simulation: {{duration: 3.0}}
"""


def _circling(team_from_yaml, radius: float, mode: str = "outcome"):
    return team_from_yaml(CIRCLING.format(period=PERIOD, radius=radius, mode=mode))


def test_an_arc_passing_a_post_is_nearest_where_the_ray_from_its_centre_meets_it():
    """The first period's arc, rebuilt from its end poses: centre (0, 1), radius 1; its
    least distance to the post (2, 1) is 1 at three quarters of it (t = pi/2 of 2 pi/3),
    though both ends are farther (sqrt 5 and 1.2393)."""
    end = (math.sin(PERIOD), 1 - math.cos(PERIOD), PERIOD)
    path = piece(0.0, (0.0, 0.0, 0.0), PERIOD, end, turning=True)
    assert path is not None
    assert (path.cx, path.cy, path.radius) == pytest.approx((0.0, 1.0, 1.0), abs=1e-12)
    gap, s = least_gap(path, [(2.0, 1.0, 0.25)], [])
    assert gap == pytest.approx(1.0 - 0.25, abs=1e-12)
    assert path.time(s) == pytest.approx(math.pi / 2, abs=1e-12)
    assert TICK_DISTANCE > 1.2  # (what sampling the ends would have said)


def test_an_arc_beside_a_wall_is_nearest_where_its_tangent_runs_along_it():
    """A wall on x = 1.5 from y = 0 to 2: the arc's point with a vertical tangent, (1, 1)
    at t = pi/2, is 0.5 from it; the ends are 1.5 and 1.5 - 0.866 = 0.634 away."""
    end = (math.sin(PERIOD), 1 - math.cos(PERIOD), PERIOD)
    path = piece(0.0, (0.0, 0.0, 0.0), PERIOD, end, turning=True)
    assert path is not None
    gap, s = least_gap(path, [], [(1.5, 0.0, 1.5, 2.0)])
    assert gap == pytest.approx(0.5, abs=1e-12)
    assert path.time(s) == pytest.approx(math.pi / 2, abs=1e-12)


def test_the_first_contact_with_a_post_is_the_closed_form_root():
    """A footprint of 0.8 touches the post (0.25) when the centre is 1.05 from (2, 1):
    |p - q|^2 = 5 - 4 cos(phi) with phi = t - pi/2, so cos(phi) = (5 - 1.05^2) / 4."""
    end = (math.sin(PERIOD), 1 - math.cos(PERIOD), PERIOD)
    path = piece(0.0, (0.0, 0.0, 0.0), PERIOD, end, turning=True)
    assert path is not None
    s = first_contact(path, 0.8, [(2.0, 1.0, 0.25)], [])
    assert s is not None
    expected = math.pi / 2 - math.acos((5 - 1.05**2) / 4)
    assert path.time(s) == pytest.approx(expected, abs=1e-12)
    x, y = path.at(s)
    assert math.hypot(x - 2.0, y - 1.0) == pytest.approx(1.05, abs=1e-12)


def test_a_straight_drive_through_a_thin_wall_touches_it_at_the_quadratic_root():
    """A segment from (0, 0) to (2, 0) in 2 s and a wall on x = 1.5: a 0.1 footprint first
    touches it at x = 1.4, t = 1.4; the least gap is -0.1 (the centre crosses it)."""
    path = piece(0.0, (0.0, 0.0, 0.0), 2.0, (2.0, 0.0, 0.0), turning=False)
    assert path is not None
    wall = [(1.5, -1.0, 1.5, 1.0)]
    assert least_gap(path, [], wall)[0] == 0.0
    s = first_contact(path, 0.1, [], wall)
    assert s is not None and path.time(s) == pytest.approx(1.4, abs=1e-12)


def test_min_clearance_includes_the_nearest_approach_between_ticks(team_from_yaml):
    """Footprint 0.5: 1 - 0.25 - 0.5 = 0.25 at t = pi/2, between the ticks; the ticks
    alone see 1.2393 - 0.75 = 0.489. An ensemble of three says the same in each."""
    run = ht.simulate(_circling(team_from_yaml, 0.5))
    assert run.outcome == "ok"
    (got,) = run.diagnostics[0]["stats"]["min_clearance"]
    assert got == pytest.approx(0.25, abs=1e-12)
    ensemble = ht.simulate(_circling(team_from_yaml, 0.5), n=3)
    for i in range(3):
        assert ensemble.diagnostics[i]["stats"]["min_clearance"] == pytest.approx([0.25], abs=1e-12)


def test_a_graze_between_ticks_is_a_collision_at_its_first_contact(team_from_yaml):
    """Footprint 0.85: the disk reaches the post (1.1 from its centre) between the ticks,
    where it never overlaps (1.2393 > 1.1); the run ends at the tick 2 pi/3 with the
    contact's time, pi/2 - acos((5 - 1.1^2) / 4), and its deepest overlap by then,
    1.1 - 1 = 0.1, in the message."""
    run = ht.simulate(_circling(team_from_yaml, 0.85))
    assert run.outcome == "collision"
    assert run.diagnostics[0]["t"] == pytest.approx(PERIOD, abs=1e-12)
    assert run.message.startswith("robot 'r' hit circles[0] (its footprint overlapping it by up")
    assert "by up to 0.1 by its tick" in run.message
    contact = float(run.message.rsplit("first touching it at t=", 1)[1])
    assert contact == pytest.approx(math.pi / 2 - math.acos((5 - 1.1**2) / 4), abs=1e-12)
    (mark,) = run.meta["world"]["collisions"]
    x, y = math.sin(contact), 1 - math.cos(contact)
    assert (mark["t"], mark["x"], mark["y"]) == pytest.approx((contact, x, y), abs=1e-12)


def test_a_continuous_law_or_a_reset_of_the_pose_is_not_swept(team_from_yaml):
    """Between instants a continuous law's input changes and a reset jumps: no single arc
    joins the poses, so those robots are judged at their instants only."""
    base = """
team: kinds
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {modes}}}
"""
    held = team_from_yaml(base.format(modes="{inputs: {v: 1.0, omega: 0.5}}"))
    assert holds_between_instants(held.agents[0].root)
    sampled = team_from_yaml(base.format(modes="{inputs: {v: 'x + 1', omega: 0}, period: 0.1}"))
    assert holds_between_instants(sampled.agents[0].root)
    following = team_from_yaml(base.format(modes="{inputs: {v: 'x + 1', omega: 0}}"))
    assert not holds_between_instants(following.agents[0].root)
    jumping = team_from_yaml(
        base.format(
            modes="{inputs: {v: 1, omega: 0}, period: 0.1, "
            "transitions: [{to: Go, after: 1, do: ['x = 0']}]}"
        )
    )
    assert not holds_between_instants(jumping.agents[0].root)


def _gap_at(path, circles, segments, s: float) -> float:
    """The centre's distance to the nearest circle edge or segment at fraction ``s``."""
    x, y = path.at(s)
    out = math.inf
    for qx, qy, r in circles:
        out = min(out, math.hypot(x - qx, y - qy) - r)
    for ax, ay, bx, by in segments:
        ex, ey = bx - ax, by - ay
        u = min(1.0, max(0.0, ((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey)))
        out = min(out, math.hypot(ax + u * ex - x, ay + u * ey - y))
    return out


def test_random_pieces_agree_with_dense_samples_of_the_true_motion():
    """Arcs and segments made by the unicycle's closed form (not by :func:`piece`'s
    reconstruction), random posts and walls: the least gap is attained where it says, is
    below every one of 2001 samples, and the first contact is at the reach exactly and no
    later than the first sample within it."""
    rng = np.random.default_rng(7)
    samples = np.linspace(0.0, 1.0, 2001).tolist()
    for n in range(150):
        x0, y0, th0 = rng.normal(size=3).tolist()
        v, h = float(rng.uniform(-2, 2)), float(rng.uniform(0.05, 1.2))
        w = 0.0 if n % 3 == 0 else float(rng.uniform(-2.5, 2.5))
        if w:
            x1 = x0 + v / w * (math.sin(th0 + w * h) - math.sin(th0))
            y1 = y0 - v / w * (math.cos(th0 + w * h) - math.cos(th0))
        else:
            x1, y1 = x0 + v * h * math.cos(th0), y0 + v * h * math.sin(th0)
        path = piece(0.0, (x0, y0, th0), h, (x1, y1, th0 + w * h), turning=n % 3 != 0)
        assert path is not None
        circles = [(*(rng.normal(size=2) * 1.5).tolist(), abs(float(rng.normal())) * 0.3)]
        segments = [tuple((rng.normal(size=4) * 1.5).tolist()) for _ in range(2)]
        gap, s = least_gap(path, circles, segments)
        dense = [_gap_at(path, circles, segments, t) for t in samples]
        assert _gap_at(path, circles, segments, s) == pytest.approx(gap, abs=1e-9)
        assert gap <= min(dense) + 1e-12
        reach = 0.2
        if dense[0] > reach and min(dense) < reach:
            contact = first_contact(path, reach, circles, segments)
            assert contact is not None
            assert _gap_at(path, circles, segments, contact) == pytest.approx(reach, abs=1e-9)
            assert contact <= next(t for t, d in zip(samples, dense, strict=True) if d <= reach)


BACK_AND_FORTH = """
team: reversing
agents:
  r:
    plant: {kind: holonomic, state: {x: 0, y: 0, theta: 0}}
    initial: Out
    modes:
      Out:
        inputs: {vx: 1.0, vy: 0, omega: 0}
        period: 1.0
        transitions: [{to: Back, after: 0.5}]
      Back: {inputs: {vx: -1.0, vy: 0, omega: 0}, period: 1.0}
world:
  - use: obstacles
    with:
      circles: [[1.5, 0.0, 0.25]]
      radius: [[r, 0.25]]
simulation: {duration: 1.0}
"""


def test_an_input_changed_between_ticks_ends_a_piece_there(team_from_yaml):
    """Out at 1 m/s towards a post at x = 1.5, back from t = 0.5 (a mode entered between
    the ticks 0 and 1, where the law samples again): nearest at x = 0.5, 1 - 0.25 - 0.25
    = 0.5 from the post; both ticks find the robot at x = 0, 1.5 - 0.5 = 1.0. One arc
    through the ticks' poses would see nothing of the trip; the pieces end at instants."""
    run = ht.simulate(team_from_yaml(BACK_AND_FORTH))
    assert run.outcome == "ok"
    assert run.diagnostics[0]["stats"]["min_clearance"] == pytest.approx([0.5], abs=1e-12)

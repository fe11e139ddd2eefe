"""A payload held by two or more grasps against the static obstacles over its motion
between ticks (issue 48: the swept settled payload, :mod:`hybridteam.world.swept_settled`).

Hand-computed cases. Two robots side by side, at (0, 1) and (0, -1) heading +x, hold a
box 0.6 long (x) and 1.0 wide (y) between them by grasps at the middles of its long
sides (body points (0, 0.5) and (0, -0.5)) at their centres: the springs balance with the
box centred between them and square to them (the weighted centroid of the robot points
is (x, 0), the cross-covariance has no cross term), so driving both straight on by 2 m
translates the box: it spans x within 0.3 of s * 2, y within 0.5 of 0. A post at
(1, 0.9) of radius 0.1 faces its top edge while the box spans x = 1 (s in [0.35,
0.65]): 0.9 - 0.5 - 0.1 = 0.3 apart. A post at (1, 0.55) instead is first touched by
the top right corner (2 s + 0.3, 0.5) where its distance to the centre is 0.1:
``0.7 - 2 s = sqrt(0.1^2 - 0.05^2)``.

Two unicycles on one circle's radius, at (1, 0) and (3, 0) heading +y, turning at one rate
about the origin (v = omega r) hold a box 2.4 x 0.4 by body points (-1, 0) and (1, 0):
the box, centred at (2, 0), turns rigidly about the origin. Its farthest points, the
outer corners, are hypot(3.2, 0.2) from it, so a post at (0, 4) of radius 0.1 is
3.9 - hypot(3.2, 0.2) from the box where the outer top corner, at angle atan2(0.2, 3.2),
has turned to pi / 2.
"""

from __future__ import annotations

import math
import random
from typing import Any

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.world.carried import _point_box, _segment_box
from hybridteam.world.payload import equilibrium
from hybridteam.world.swept_settled import (
    CONTACT_TOLERANCE,
    FRACTION_TOLERANCE,
    GAP_TOLERANCE,
    SettledCarry,
    grip,
)

SIDE = math.sqrt(0.1**2 - 0.05**2)


def _side_by_side(post):
    grips = [
        grip(0.0, (0.0, y, 0.0), 1.0, (2.0, y, 0.0), False, (0.0, 0.0), (0.0, b), 1.0)
        for y, b in ((1.0, 0.5), (-1.0, -0.5))
    ]
    return SettledCarry(grips, 0.3, 0.5, [post], [])


def test_a_box_carried_side_by_side_past_a_post_is_nearest_it_where_its_edge_faces_it():
    gap, s = _side_by_side((1.0, 0.9, 0.1)).least_gap()
    assert gap == pytest.approx(0.3, abs=1e-12)
    assert 0.35 - 1e-9 <= s <= 0.65 + 1e-9


def test_a_box_carried_side_by_side_first_touches_a_post_at_its_corner():
    motion = _side_by_side((1.0, 0.55, 0.1))
    gap, s = motion.least_gap()
    assert gap == 0.0
    first = motion.first_contact(s)
    exact = (0.7 - SIDE) / 2.0
    # no contact before it, and the corner within the contact tolerance of the post: at
    # or after the fraction where hypot(0.7 - 2 s, 0.05) = 0.1 + CONTACT_TOLERANCE (less
    # the narrowest part the search splits to)
    near = (0.7 - math.sqrt((0.1 + CONTACT_TOLERANCE) ** 2 - 0.05**2)) / 2.0
    assert near - FRACTION_TOLERANCE - 1e-15 <= first <= exact + 1e-15


def _turning_together(turn):
    grips = []
    for r, b in ((1.0, -1.0), (3.0, 1.0)):
        end = (r * math.cos(turn), r * math.sin(turn), math.pi / 2 + turn)
        grips.append(grip(0.0, (r, 0.0, math.pi / 2), 1.0, end, True, (0.0, 0.0), (b, 0.0), 1.0))
    return SettledCarry(grips, 1.2, 0.2, [(0.0, 4.0, 0.1)], [])


def test_a_box_turned_by_two_carriers_about_one_centre_is_nearest_where_its_corner_passes():
    gap, s = _turning_together(2.0).least_gap()
    assert gap == pytest.approx(3.9 - math.hypot(3.2, 0.2), abs=GAP_TOLERANCE)
    assert s * 2.0 == pytest.approx(math.pi / 2 - math.atan2(0.2, 3.2), abs=1e-3)


def test_the_box_stops_short_of_the_post_then_its_ends_are_nearest():
    """Turned by 1 rad only, the corner stops at angle 1 + atan2(0.2, 3.2), short of the
    post: the least gap is at the end, by the law of cosines."""
    gap, s = _turning_together(1.0).least_gap()
    corner = math.hypot(3.2, 0.2)
    angle = math.pi / 2 - 1.0 - math.atan2(0.2, 3.2)
    expected = math.sqrt(corner**2 + 16.0 - 8.0 * corner * math.cos(angle)) - 0.1
    assert (gap, s) == (pytest.approx(expected, abs=1e-12), 1.0)


# ---------------------------------------------------------------- against dense samples
def _robot_at(pose, v, omega, turning, s):
    """The robot's pose at fraction ``s`` of a unit interval under (v, omega) held: a
    unicycle's closed form, or a holonomic base driving ``v`` (a vector) and turning."""
    x, y, th = pose
    if turning:
        if omega == 0.0:
            return x + v * s * math.cos(th), y + v * s * math.sin(th), th
        end = th + omega * s
        return (
            x + v / omega * (math.sin(end) - math.sin(th)),
            y - v / omega * (math.cos(end) - math.cos(th)),
            end,
        )
    return x + v[0] * s, y + v[1] * s, th + omega * s


def _sampled_gaps(carriers, hw, hd, circles, segments, fractions):
    """The settled box's gap at each fraction, from the robots' own closed-form motion,
    the payload's numpy equilibrium and its distances (:mod:`hybridteam.world.carried`)."""
    points, body, springs = [], [], []
    for pose, v, omega, turning, mount, b, w in carriers:
        row = []
        for s in fractions:
            x, y, th = _robot_at(pose, v, omega, turning, s)
            c, sn = math.cos(th), math.sin(th)
            row.append((x + c * mount[0] - sn * mount[1], y + sn * mount[0] + c * mount[1]))
        points.append(row)
        body.append(b)
        springs.append(w)
    eq = equilibrium(np.array(points).transpose(1, 0, 2), np.array(body), np.array(springs))
    c, sn = np.cos(eq.theta), np.sin(eq.theta)

    def local(x, y):
        return c * (x - eq.x) + sn * (y - eq.y), -sn * (x - eq.x) + c * (y - eq.y)

    m = len(fractions)
    half_w, half_d = np.full(m, hw), np.full(m, hd)
    out = np.full(m, np.inf)
    for qx, qy, r in circles:
        out = np.minimum(out, np.maximum(_point_box(*local(qx, qy), half_w, half_d) - r, 0.0))
    for ax, ay, bx, by in segments:
        out = np.minimum(out, _segment_box(*local(ax, ay), *local(bx, by), half_w, half_d))
    return out


def _random_carry(rng):
    carriers, grips = [], []
    turning = rng.random() < 0.5
    for k in range(rng.choice((2, 3))):
        pose = (rng.uniform(-1, 1), rng.uniform(-1, 1) + 1.5 * k, rng.uniform(-math.pi, math.pi))
        omega = rng.uniform(-2.5, 2.5)
        v = rng.uniform(-1.5, 1.5) if turning else (rng.uniform(-1, 1), rng.uniform(-1, 1))
        mount = (rng.uniform(-0.3, 0.5), rng.uniform(-0.3, 0.3))
        body = (rng.uniform(-0.6, 0.6), rng.uniform(-0.3, 0.3))
        spring = rng.uniform(0.5, 3.0)
        carriers.append((pose, v, omega, turning, mount, body, spring))
        end = _robot_at(pose, v, omega, turning, 1.0)
        one = grip(0.0, pose, 1.0, end, turning, mount, body, spring)
        assert one is not None
        grips.append(one)
    return carriers, grips


@pytest.mark.parametrize("seed", range(6))
def test_random_carries_agree_with_dense_samples_of_the_settled_pose(seed):
    """The certified least gap is attained (at or above the densest sampling's least, to
    rounding) and within its tolerance of the least of every sample; where it is 0, the
    first contact has no sample touching before it."""
    rng = random.Random(seed)
    fractions = np.linspace(0.0, 1.0, 4001)
    touched = cleared = 0
    for _ in range(12):
        carriers, grips = _random_carry(rng)
        hw, hd = rng.uniform(0.2, 0.8), rng.choice((0.0, rng.uniform(0.1, 0.4)))
        circles = [(rng.uniform(-2, 2), rng.uniform(-1, 4), rng.uniform(0.05, 0.4))]
        ends = (rng.uniform(-2, 2), rng.uniform(-1, 4), rng.uniform(-2, 2), rng.uniform(-1, 4))
        segments = [ends]
        motion = SettledCarry(grips, hw, hd, circles, segments)
        found = motion.least_gap()
        assert found is not None
        gap, s = found
        samples = _sampled_gaps(carriers, hw, hd, circles, segments, fractions)
        assert gap <= samples.min() + GAP_TOLERANCE + 1e-12
        if gap > 0.0:
            cleared += 1
            # attained: the gap at its fraction is what it says
            at = _sampled_gaps(carriers, hw, hd, circles, segments, [s])[0]
            assert at == pytest.approx(gap, abs=1e-12)
        else:
            touched += 1
            first = motion.first_contact(s)
            assert np.all(samples[fractions < first - 1e-9] > 0.0)
            at = _sampled_gaps(carriers, hw, hd, circles, segments, [first])[0]
            assert at <= CONTACT_TOLERANCE + 1e-12 or first == 0.0
    assert touched and cleared  # (both branches exercised)


# ---------------------------------------------------------------- in a run
SIDE_BY_SIDE = """
team: side_by_side
agents:
  a:
    plant: {{kind: unicycle, state: {{x: 0, y: 1, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0.0}}, period: 0.5}}}}
  b:
    plant: {{kind: unicycle, state: {{x: 0, y: -1, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0.0}}, period: 0.5}}}}
world:
  - use: payload
    with:
      name: box
      width: 0.2
      depth: 1.0
      grasps: [{{agent: a, point: [0.0, 0.5]}}, {{agent: b, point: [0.0, -0.5]}}]
  - use: obstacles
    with:
      circles: [[0.75, {y}, 0.05]]
simulation: {{duration: 1.5}}
"""


def test_a_box_carried_by_two_robots_counts_its_nearest_approach_between_ticks(team_from_yaml):
    """Two robots 2 m apart drive +x at 1 m/s under a period of 0.5 s with a 0.2 x 1.0 box
    between them (x within 0.1 of t, y within 0.5 of 0). A post of 0.05 at (0.75, 0.6)
    faces the box's top edge for t in [0.65, 0.85]: 0.6 - 0.5 - 0.05 = 0.05 apart. The
    ticks see the box at t = 0.5 and 1.0 only, its corner hypot(0.15, 0.1) from the post:
    0.130 (what the code before this test said)."""
    team = team_from_yaml(SIDE_BY_SIDE.format(y=0.6))
    run = ht.simulate(team)
    assert run.outcome == "ok"
    assert run.diagnostics[0]["stats"]["payload_clearance"] == pytest.approx(0.05, abs=1e-12)
    ensemble = ht.simulate(team, n=2)
    for i in range(2):
        stats = ensemble.diagnostics[i]["stats"]
        assert stats["payload_clearance"] == pytest.approx(0.05, abs=1e-12)


def test_a_box_carried_by_two_robots_through_a_post_between_ticks_collides(team_from_yaml):
    """The post at (0.75, 0.3) instead: the ticks see the box 0.15 - 0.05 = 0.1 from it on
    either side (``ok`` before this test), but its front edge x = t + 0.1 reaches the post's
    edge, x = 0.7, at t = 0.6: the run ends at the tick 1.0 with that contact time."""
    team = team_from_yaml(SIDE_BY_SIDE.format(y=0.3))
    run = ht.simulate(team)
    assert run.outcome == "collision"
    assert run.message.startswith(
        "payload 'box' hit an obstacle (by its carriers' tick at t=1), first touching"
    )
    contact = float(run.message.rsplit("at t=", 1)[1])
    assert contact == pytest.approx(0.6, abs=1e-9)
    (mark,) = run.meta["world"]["collisions"]
    assert (mark["who"], mark["x"], mark["y"]) == ("box", pytest.approx(contact), 0.0)
    ensemble = ht.simulate(team, n=2)
    assert [d["message"] for d in ensemble.diagnostics] == [run.message] * 2


ALONG_A_WALL = """
team: along_a_wall
agents:
  a:
    plant: {kind: unicycle, state: {x: 0, y: 1, theta: 0}}
    modes: {Go: {inputs: {v: 1.0, omega: 0.0}, period: 0.1}}
  b:
    plant: {kind: unicycle, state: {x: 0, y: -1, theta: 0}}
    modes: {Go: {inputs: {v: 1.0, omega: 0.0}, period: 0.1}}
world:
  - use: payload
    with:
      name: box
      width: 1.6
      depth: 1.0
      grasps: [{agent: a, point: [0.0, 0.5]}, {agent: b, point: [0.0, -0.5]}]
  - use: obstacles
    with:
      walls: [[-5, 0.85, 5, 0.85]]
simulation: {duration: 1.5}
"""


def test_a_gap_measured_at_the_carriers_ticks_restarts_the_bound(team_from_yaml, monkeypatch):
    """A 1.6 x 1.0 box carried at 1 m/s parallel to a wall 0.35 above its top edge, ticks
    every 0.1 s: its gap is 0.35 throughout. The centroid's bound is no help (the centroid
    is 0.85 from the wall, the farthest corner hypot(0.8, 0.5) = 0.943 from it), and a
    piece's points move up to about 0.2 (0.1 along, the rest the bound on turning), so a
    bound started from the last judged piece's end runs out every other piece, which was
    then judged for a contact at once (before: those from t = 0, 0.2, ..., 1.4, 8 of 15).
    The gap measured at each tick restarts it: 0.35 - 0.2 > 0, only the first piece (no
    gap measured before it) is judged for a contact while running, and the summary still
    finds 0.35."""
    from hybridteam.world import obstacles

    contacts = []
    judge = obstacles.Obstacles._judge_settled

    def counted(self: obstacles.Obstacles, *args: Any) -> float | None:
        if len(args) == 9:  # (no ``below``: judged at once, for a contact)
            contacts.append(args[3])
        return judge(self, *args)

    monkeypatch.setattr(obstacles.Obstacles, "_judge_settled", counted)
    run = ht.simulate(team_from_yaml(ALONG_A_WALL))
    assert run.outcome == "ok"
    assert run.diagnostics[0]["stats"]["payload_clearance"] == pytest.approx(0.35, abs=1e-9)
    assert contacts == [0.0]  # (the first piece: no gap measured before it)

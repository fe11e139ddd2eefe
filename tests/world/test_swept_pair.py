"""Two robots against each other over their motion between ticks (issue 48: the swept
pair test, :mod:`hybridteam.world.swept_pair`).

Hand-computed cases. Robot a drives from (0, 0) along +x at 1 m/s, robot b from (1, -1)
along +y at 1 m/s: at time t their centres are (t, 0) and (1, t - 1), sqrt(2) |1 - t|
apart, so they pass through each other at t = 1 and two disks of 0.1 touch at
t = 1 - 0.2 / sqrt(2). Under a law of period 0.8 the ticks find them sqrt(2) 0.2 = 0.283
(t = 0.8) and sqrt(2) 0.6 = 0.849 (t = 1.6) apart: never overlapping.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.world.swept import Piece, first_contact, piece, point_distance
from hybridteam.world.swept_pair import (
    CONTACT_TOLERANCE,
    GAP_TOLERANCE,
    first_touch,
    least_separation,
    may_touch,
)

#: robot a's and b's first touch, and where: the midpoint of their centres then
CONTACT = 1 - 0.2 / math.sqrt(2)

CROSSING = """
team: crossing
agents:
  a:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0}}, period: 0.8}}}}
  b:
    plant: {{kind: unicycle, state: {{x: 1.0, y: -1.0, theta: 1.5707963267948966}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0}}, period: 0.8}}}}
world:
  - use: obstacles
    with:
      radius: [[a, 0.1], [b, 0.1]]
      on_collision: {mode}
simulation: {{duration: 2.0}}
"""


def _separation(pa: Piece, pb: Piece, s: float) -> float:
    (xa, ya), (xb, yb) = pa.at(s), pb.at(s)
    return math.hypot(xa - xb, ya - yb)


def test_two_straight_drives_cross_between_ticks_at_the_quadratic_root():
    """The pieces from the ticks 0.8 to 1.6: a (0.8, 0) -> (1.6, 0), b (1, -0.2) -> (1, 0.6);
    the centres coincide at s = 1/4 (t = 1) and first come 0.2 apart at t = CONTACT."""
    pa = piece(0.8, (0.8, 0.0, 0.0), 1.6, (1.6, 0.0, 0.0), turning=True)
    pb = piece(0.8, (1.0, -0.2, math.pi / 2), 1.6, (1.0, 0.6, math.pi / 2), turning=True)
    assert pa is not None and pb is not None
    least, s = least_separation(pa, pb)
    assert least == pytest.approx(0.0, abs=1e-15)
    assert pa.time(s) == pytest.approx(1.0, abs=1e-15)
    touch = first_touch(pa, pb, 0.2, s)
    assert pa.time(touch) == pytest.approx(CONTACT, abs=1e-15)


def test_an_arc_against_a_parked_robot_is_the_arc_point_closed_form():
    """A unicycle at v = omega = 1 from (0, 0) heading +x for 2 pi / 3: the arc about
    (0, 1) of radius 1; a robot parked at (2, 1) is nearest to it 1 away at t = pi / 2
    (:func:`point_distance`, the closed form), and a 0.8 disk against a 0.25 one first
    touches where the centres are 1.05 apart, at t = pi/2 - acos((5 - 1.05^2) / 4). The
    certified answers agree within their stated tolerances (a contact tolerance of 1e-10 m
    at a closing rate of 2 sin(phi) / 1.05 = 0.43 m per radian: 2.3e-10 in t)."""
    period = 2 * math.pi / 3
    end = (math.sin(period), 1 - math.cos(period), period)
    arc = piece(0.0, (0.0, 0.0, 0.0), period, end, turning=True)
    parked = piece(0.0, (2.0, 1.0, 0.0), period, (2.0, 1.0, 0.0), turning=True)
    assert arc is not None and parked is not None and arc.radius and not parked.length
    exact, s_exact = point_distance(arc, 2.0, 1.0)
    assert (exact, arc.time(s_exact)) == pytest.approx((1.0, math.pi / 2), abs=1e-12)
    least, s = least_separation(arc, parked)
    assert exact <= least <= exact + GAP_TOLERANCE
    assert _separation(arc, parked, s) == least  # (attained)
    touch = first_touch(arc, parked, 1.05, s)
    closed = first_contact(arc, 0.8, [(2.0, 1.0, 0.25)], [])
    assert closed is not None
    expected = math.pi / 2 - math.acos((5 - 1.05**2) / 4)
    assert arc.time(closed) == pytest.approx(expected, abs=1e-12)
    assert 0.0 <= _separation(arc, parked, touch) - 1.05 <= CONTACT_TOLERANCE
    assert arc.time(touch) <= expected + 1e-12
    assert arc.time(touch) == pytest.approx(expected, abs=3e-10)


def test_two_arcs_on_one_circle_in_opposite_directions_meet_halfway():
    """Two unicycles on the unit circle about the origin at 2 rad/s for 1 s, one from angle
    0 anticlockwise, one from angle 2.5 clockwise: their angles are 2t and 2.5 - 2t, so
    they meet at t = 0.625, and their centres' chord 2 sin((2.5 - 4t) / 2) is 0.4 at
    t = (2.5 - 2 asin(0.2)) / 4. The chord closes at 4 cos(asin 0.2) = 3.9 m/s there:
    1e-10 m is 2.6e-11 in t."""
    pa = piece(0.0, (1.0, 0.0, math.pi / 2), 1.0, (math.cos(2), math.sin(2), math.pi / 2 + 2), True)
    b0 = (math.cos(2.5), math.sin(2.5), 2.5 - math.pi / 2)
    pb = piece(0.0, b0, 1.0, (math.cos(0.5), math.sin(0.5), 0.5 - math.pi / 2), True)
    assert pa is not None and pb is not None
    least, s = least_separation(pa, pb)
    assert 0.0 <= least <= GAP_TOLERANCE
    assert s == pytest.approx(0.625, abs=1e-6)  # (|D| is flat-bottomed nowhere: a V)
    touch = first_touch(pa, pb, 0.4, s)
    expected = (2.5 - 2 * math.asin(0.2)) / 4
    assert touch <= expected + 1e-15
    assert touch == pytest.approx(expected, abs=1e-10)


def _unicycle(rng: np.random.Generator, straight: bool) -> Piece:
    """A random held-input piece made by the unicycle's closed form."""
    x0, y0, th0 = rng.normal(size=3).tolist()
    v = float(rng.uniform(-2, 2))
    w = 0.0 if straight else float(rng.uniform(-2.5, 2.5))
    if w:
        x1 = x0 + v / w * (math.sin(th0 + w) - math.sin(th0))
        y1 = y0 - v / w * (math.cos(th0 + w) - math.cos(th0))
    else:
        x1, y1 = x0 + v * math.cos(th0), y0 + v * math.sin(th0)
    out = piece(0.0, (x0, y0, th0), 1.0, (x1, y1, th0 + w), turning=not straight)
    assert out is not None
    return out


def _local_minimum(pa: Piece, pb: Piece, lo: float, hi: float) -> float:
    """A golden-section search of the separation on ``[lo, hi]`` (a bracket about one
    dense sample's local minimum): the local least, to rounding."""
    ratio = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        m1, m2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        if _separation(pa, pb, m1) <= _separation(pa, pb, m2):
            hi = m2
        else:
            lo = m1
    return min(_separation(pa, pb, s) for s in (lo, hi, 0.5 * (lo + hi)))


def test_random_pairs_agree_with_dense_samples_of_the_true_motion():
    """Random arcs and segments against each other (both arcs, arc and segment, two
    segments): the least separation is attained, below every one of 2001 samples (to its
    tolerance) and within its tolerance of the samples' local minima refined by a golden
    section search; the first touch is within its tolerance of contact, and no sample
    before it is within reach. The end-gap bound that rules pairs out
    (:func:`may_touch`) never rules out a reach the pair comes within."""
    rng = np.random.default_rng(48)
    samples = np.linspace(0.0, 1.0, 2001).tolist()
    for n in range(120):
        pa = _unicycle(rng, straight=n % 3 == 0)
        pb = _unicycle(rng, straight=n % 4 == 0)
        least, s = least_separation(pa, pb)
        dense = [_separation(pa, pb, t) for t in samples]
        assert _separation(pa, pb, s) == pytest.approx(least, abs=1e-14)  # (attained)
        assert least <= min(dense) + GAP_TOLERANCE
        refined = min(
            _local_minimum(pa, pb, samples[max(k - 1, 0)], samples[min(k + 1, 2000)])
            for k in range(2001)
            if dense[k] <= dense[max(k - 1, 0)] and dense[k] <= dense[min(k + 1, 2000)]
        )
        assert least == pytest.approx(refined, abs=GAP_TOLERANCE)
        assert may_touch(dense[0], dense[-1], pa.length + pb.length, least)
        reach = 0.5 * (dense[0] + least)
        if dense[0] > reach > least:
            touch = first_touch(pa, pb, reach, s)
            rounding = 1e-14  # (a few ulps of coordinates of a few metres: the root rounded)
            over = _separation(pa, pb, touch) - reach
            assert -rounding <= over <= CONTACT_TOLERANCE + rounding
            assert all(d > reach for t, d in zip(samples, dense, strict=True) if t < touch)


def test_robots_crossing_between_ticks_collide_at_their_first_contact(team_from_yaml):
    """The crossing robots never overlap at a tick (the code before this test said ``ok``):
    the run ends at the tick t = 1.6 with the first contact's time in the message and the
    deepest overlap by then, 0.2 (the centres coincide), and the views' mark at the
    midpoint of their centres then, (CONTACT, CONTACT - 1) / 2 + (1, 0) / 2. An ensemble
    says the same in each instance (the array path)."""
    run = ht.simulate(team_from_yaml(CROSSING.format(mode="outcome")))
    assert run.outcome == "collision"
    assert run.diagnostics[0]["t"] == pytest.approx(1.6, abs=1e-12)
    assert run.message.startswith(
        "robots 'a' and 'b' collided (their footprints overlapping by up to 0.2 by the tick "
        "at t=1.6), first touching at t="
    )
    contact = float(run.message.rsplit("at t=", 1)[1])
    assert contact == pytest.approx(CONTACT, abs=1e-12)
    (mark,) = run.meta["world"]["collisions"]
    where = ((CONTACT + 1) / 2, (CONTACT - 1) / 2)
    assert (mark["who"], mark["t"]) == ("a and b", pytest.approx(CONTACT, abs=1e-12))
    assert (mark["x"], mark["y"]) == pytest.approx(where, abs=1e-12)
    ensemble = ht.simulate(team_from_yaml(CROSSING.format(mode="outcome")), n=3)
    for i in range(3):
        assert ensemble.diagnostics[i]["t"] == pytest.approx(1.6, abs=1e-12)
        assert ensemble.diagnostics[i]["message"] == run.message


def test_warn_lists_a_contact_between_ticks_and_goes_on(team_from_yaml):
    warned = ht.simulate(team_from_yaml(CROSSING.format(mode="warn")))
    assert warned.outcome == "ok" and warned.diagnostics[0]["t"] == 2.0
    (first,) = warned.diagnostics[0]["stats"]["collisions"]
    assert first.startswith("robots 'a' and 'b' collided (their footprints overlapping")
    assert float(first.rsplit("at t=", 1)[1]) == pytest.approx(CONTACT, abs=1e-12)


def test_the_first_contact_between_ticks_is_the_one_reported(team_from_yaml):
    """Robot a also reaches a wall at x = 1.5 (its disk at t = 1.4) between the same ticks
    0.8 and 1.6 as the crossing (t = 0.859): the run's message is the crossing's, the
    earlier contact, though robots against walls are judged before pairs; warn lists
    both, each at its own contact."""
    walled = CROSSING.replace("radius:", "walls: [[1.5, -0.5, 1.5, 0.5]]\n      radius:")
    run = ht.simulate(team_from_yaml(walled.format(mode="outcome")))
    assert run.outcome == "collision" and run.diagnostics[0]["t"] == pytest.approx(1.6)
    assert run.message.startswith("robots 'a' and 'b' collided")
    assert float(run.message.rsplit("at t=", 1)[1]) == pytest.approx(CONTACT, abs=1e-12)
    warned = ht.simulate(team_from_yaml(walled.format(mode="warn")))
    pair, wall = warned.diagnostics[0]["stats"]["collisions"]
    assert pair.startswith("robots 'a' and 'b'") and wall.startswith("robot 'a' hit walls[0]")
    assert float(wall.rsplit("at t=", 1)[1]) == pytest.approx(1.4, abs=1e-12)


def test_robots_turning_side_by_side_apart_are_not_bisected_to_the_tolerance(monkeypatch):
    """Two robots on concentric arcs (radii 1 and 1.5 about the origin) turning together
    by 1 rad stay 0.5 apart all along: with disks reaching 0.4 no part of the motion can
    come within reach, and the least separation is settled in a few dozen evaluations
    (bisecting the flat bottom to 1e-9 m takes some 17,000: the chord bound's error
    2.5 h^2 / 8 must fall below it, the cost when no reach is given)."""
    from hybridteam.world import swept_pair

    inner = Piece(0.0, 1.0, 1.0, 0.0, math.cos(1), math.sin(1), 0.0, 0.0, 1.0, 0.0, 1.0)
    end = (1.5 * math.cos(1), 1.5 * math.sin(1))
    outer = Piece(0.0, 1.0, 1.5, 0.0, *end, 0.0, 0.0, 1.5, 0.0, 1.0)
    calls = []
    counted = swept_pair._separation

    def counting(pa: Piece, pb: Piece, s: float) -> tuple[float, float]:
        calls.append(s)
        return counted(pa, pb, s)

    monkeypatch.setattr(swept_pair, "_separation", counting)
    least, _ = least_separation(inner, outer, 0.4)
    assert least == pytest.approx(0.5, abs=1e-15) and len(calls) < 50
    least, _ = least_separation(inner, outer)
    assert least == pytest.approx(0.5, abs=1e-15)

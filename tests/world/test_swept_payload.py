"""A payload held by one grasp against the static obstacles over its motion between ticks
(issue 48: the swept payload, :mod:`hybridteam.world.swept_payload`).

Hand-computed cases. A unicycle at v = omega = 1 from (0, 0) heading +x drives round the
unit circle about (0, 1): at time t it is at (sin t, 1 - cos t). It holds a 0.4 x 0.2 box
by one grasp at the middle of the box's back edge (body point (-0.2, 0)) at its centre;
a single grasp keeps the box's angle (0), so the box spans x in [sin t, sin t + 0.4],
y within 0.1 of 1 - cos t. A post at (1.8, 1): while |cos t| <= 0.1 the box's right edge
faces it, 1.4 - sin t away, least at t = pi/2: 0.4. Under a law of period 2 pi / 3 the
ticks see the box at t = 0 and 2 pi / 3 only: its nearest corner (sin 120deg + 0.4,
1.4) is hypot(1.4 - sin 120deg, 0.4) = 0.667 from the post.
"""

from __future__ import annotations

import math

import pytest

import hybridteam as ht
from hybridteam.world.swept import least_gap
from hybridteam.world.swept_payload import (
    carry,
    outline,
    payload_first_contact,
    payload_least_gap,
)

PERIOD = 2 * math.pi / 3
POST = (1.8, 1.0)
#: the top right corner (sin t + 0.4, 1.1 - cos t) first 0.45 from the post where
#: 2.8 sin t + 0.2 cos t = 2.97 - 0.45^2 (before |cos t| <= 0.1, where the edge faces it)
CORNER_CONTACT = math.asin((2.97 - 0.45**2) / math.hypot(2.8, 0.2)) - math.atan2(0.2, 2.8)

CARRYING = """
team: carrying
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 1.0}}, period: {period!r}}}}}
world:
  - use: payload
    with:
      name: box
      width: 0.4
      depth: 0.2
      pose: [0.2, 0.0, 0.0]
      grasps: [{{agent: r, point: [-0.2, 0.0]}}]
  - use: obstacles
    with:
      circles: [[1.8, 1.0, {radius}]]
simulation: {{duration: 3.0}}
"""


def _first_period():
    """The first period's carry and the box's outline at its start."""
    end = (math.sin(PERIOD), 1 - math.cos(PERIOD), PERIOD)
    motion = carry(0.0, (0.0, 0.0, 0.0), PERIOD, end, (0.0, 0.0), turning=True)
    assert motion is not None
    corners, edges = outline(0.2, 0.0, 0.0, 0.2, 0.1)
    return motion, corners, edges


def test_a_box_carried_round_an_arc_is_nearest_a_post_where_its_edge_faces_it():
    """Its least gap to a post of 0.25 is 0.4 - 0.25 = 0.15 at t = pi / 2; at t = 3 pi / 8
    the box has moved by the unicycle's displacement (sin t, 1 - cos t)."""
    motion, corners, edges = _first_period()
    gap, s = payload_least_gap(motion, corners, edges, [(*POST, 0.25)], [])
    assert gap == pytest.approx(0.15, abs=1e-12)
    assert motion.t0 + s * (motion.t1 - motion.t0) == pytest.approx(math.pi / 2, abs=1e-12)
    t = 3 * math.pi / 8
    x, y = motion.moving(0.2, 0.0).at(t / PERIOD)
    assert (x, y) == pytest.approx((0.2 + math.sin(t), 1 - math.cos(t)), abs=1e-12)


def test_a_box_first_touches_a_post_at_its_corner_at_the_closed_form_root():
    """A post of 0.45 reaches into the box's path: first touched by the top right corner
    at CORNER_CONTACT (1.331), before the edge could face it (cos t = 0.1 at 1.471)."""
    motion, corners, edges = _first_period()
    assert math.cos(CORNER_CONTACT) > 0.1
    circles = [(*POST, 0.45)]
    assert payload_least_gap(motion, corners, edges, circles, [])[0] == 0.0
    s = payload_first_contact(motion, corners, edges, circles, [])
    assert s is not None
    assert s * PERIOD == pytest.approx(CORNER_CONTACT, abs=1e-12)


def test_a_short_wall_reaching_into_the_path_is_met_by_an_edge_not_a_corner():
    """A holonomic base drives the box (grasped as above) along +x from (0, 0) to (2, 0)
    in 2 s; a wall from (1, -0.05) to (1, 0.05) lies between its corners' paths (y = +-0.1),
    so no corner ever touches it (0.05 away at best): the box's right edge, x = 0.4 + t,
    meets the wall's ends at t = 0.6."""
    motion = carry(0.0, (0.0, 0.0, 0.0), 2.0, (2.0, 0.0, 0.0), (0.0, 0.0), turning=False)
    assert motion is not None
    corners, edges = outline(0.2, 0.0, 0.0, 0.2, 0.1)
    wall = [(1.0, -0.05, 1.0, 0.05)]
    assert min(least_gap(motion.moving(*q), [], wall)[0] for q in corners) == pytest.approx(
        0.05, abs=1e-12
    )
    assert payload_least_gap(motion, corners, edges, [], wall)[0] == 0.0
    s = payload_first_contact(motion, corners, edges, [], wall)
    assert s is not None and 2.0 * s == pytest.approx(0.6, abs=1e-12)


def test_motions_with_no_arc_are_not_rebuilt():
    """A holonomic base turning while it translates moves an off-centre mount on no arc;
    a unicycle turning half a revolution between instants is not rebuilt (as for robots);
    a holonomic base carrying at its centre translates the payload whatever it turns."""
    assert carry(0.0, (0, 0, 0), 1.0, (1, 0, 0.5), (0.3, 0.0), turning=False) is None
    assert carry(0.0, (0, 0, 0), 1.0, (0, 2, math.pi), (0.0, 0.0), turning=True) is None
    centred = carry(0.0, (0, 0, 0), 1.0, (1, 0, 0.5), (0.0, 0.0), turning=False)
    assert centred is not None and (centred.dx, centred.dy, centred.turn) == (1, 0, 0.0)


def test_payload_clearance_includes_the_nearest_approach_between_ticks(team_from_yaml):
    """Post of 0.25: 0.15 at t = pi / 2, between the ticks (the ticks alone: 0.667 - 0.25 =
    0.417, what the code before this test said). An ensemble says the same."""
    team = team_from_yaml(CARRYING.format(period=PERIOD, radius=0.25))
    run = ht.simulate(team)
    assert run.outcome == "ok"
    assert run.diagnostics[0]["stats"]["payload_clearance"] == pytest.approx(0.15, abs=1e-12)
    ensemble = ht.simulate(team, n=3)
    for i in range(3):
        stats = ensemble.diagnostics[i]["stats"]
        assert stats["payload_clearance"] == pytest.approx(0.15, abs=1e-12)


def test_a_payload_grazing_a_post_between_ticks_collides_at_its_first_contact(team_from_yaml):
    """Post of 0.45: never touched at a tick (0.667 > 0.45; the code before this test said
    ``ok``); the run ends at the tick 2 pi / 3 with the corner's contact time, and the
    views' mark at the box's centre then, (sin t + 0.2, 1 - cos t)."""
    team = team_from_yaml(CARRYING.format(period=PERIOD, radius=0.45))
    run = ht.simulate(team)
    assert run.outcome == "collision"
    assert run.diagnostics[0]["t"] == pytest.approx(PERIOD, abs=1e-12)
    assert run.message.startswith(
        "payload 'box' hit an obstacle (by its carriers' tick at t=2.094395102), first touching"
    )
    contact = float(run.message.rsplit("at t=", 1)[1])
    assert contact == pytest.approx(CORNER_CONTACT, abs=1e-12)
    (mark,) = run.meta["world"]["collisions"]
    where = (math.sin(contact) + 0.2, 1 - math.cos(contact))
    assert (mark["who"], mark["t"]) == ("box", pytest.approx(contact, abs=1e-12))
    assert (mark["x"], mark["y"]) == pytest.approx(where, abs=1e-12)
    ensemble = ht.simulate(team, n=2)
    assert [d["message"] for d in ensemble.diagnostics] == [run.message] * 2


def _gaps_at(mount_at, s, body, theta, hw, hd, circles, segments):
    """The box's gap to the obstacles at the fractions ``s`` of the true motion, by the
    payload component's own distances (:mod:`hybridteam.world.carried`): a list."""
    import numpy as np

    from hybridteam.world.carried import _point_box, _segment_box

    m = np.array([mount_at(f) for f in s])
    c, sn = math.cos(theta), math.sin(theta)
    ox, oy = m[:, 0] - (c * body[0] - sn * body[1]), m[:, 1] - (sn * body[0] + c * body[1])

    def local(x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
        return c * (x - ox) + sn * (y - oy), -sn * (x - ox) + c * (y - oy)

    out = np.full(len(s), np.inf)
    hw, hd = np.full(len(s), hw), np.full(len(s), hd)  # (_segment_box: one per point)
    for qx, qy, r in circles:
        out = np.minimum(out, np.maximum(_point_box(*local(qx, qy), hw, hd) - r, 0.0))
    for ax, ay, bx, by in segments:
        out = np.minimum(out, _segment_box(*local(ax, ay), *local(bx, by), hw, hd))
    return out.tolist()


def test_random_carries_agree_with_dense_samples_of_the_true_motion():
    """Unicycle arcs and segments by the closed form (the mount point rotating with the
    heading), random boxes, grasps, posts and walls: the least gap is attained where it
    says, below every one of 1001 samples of the payload component's own gap, and the
    first contact has gap 0 and comes no later than the first sample touching."""
    import numpy as np

    rng = np.random.default_rng(48)
    samples = np.linspace(0.0, 1.0, 1001).tolist()
    touched = 0
    for n in range(200):
        x0, y0, th0 = rng.normal(size=3).tolist()
        v, w = float(rng.uniform(-2, 2)), 0.0 if n % 3 == 0 else float(rng.uniform(-2.5, 2.5))
        mount = tuple(rng.uniform(-0.3, 0.3, size=2).tolist())
        hw, hd = rng.uniform(0.1, 0.5, size=2).tolist()
        body = (float(rng.uniform(-hw, hw)), float(rng.uniform(-hd, hd)))
        theta = float(rng.uniform(-3, 3))

        def pose(s: float, x0=x0, y0=y0, th0=th0, v=v, w=w) -> tuple[float, float, float]:
            if w:
                return (
                    x0 + v / w * (math.sin(th0 + w * s) - math.sin(th0)),
                    y0 - v / w * (math.cos(th0 + w * s) - math.cos(th0)),
                    th0 + w * s,
                )
            return x0 + v * s * math.cos(th0), y0 + v * s * math.sin(th0), th0

        def mount_at(s: float, pose=pose, mount=mount) -> tuple[float, float]:
            x, y, th = pose(s)
            c, sn = math.cos(th), math.sin(th)
            return x + c * mount[0] - sn * mount[1], y + sn * mount[0] + c * mount[1]

        motion = carry(0.0, pose(0.0), 1.0, pose(1.0), mount, turning=n % 3 != 0)
        assert motion is not None
        c, sn = math.cos(theta), math.sin(theta)
        ox = motion.mx - (c * body[0] - sn * body[1])
        oy = motion.my - (sn * body[0] + c * body[1])
        corners, edges = outline(ox, oy, theta, hw, hd)
        circles = [(*(rng.normal(size=2) * 1.5).tolist(), abs(float(rng.normal())) * 0.3)]
        segments = [tuple((rng.normal(size=4) * 1.5).tolist()) for _ in range(2)]
        gap, s = payload_least_gap(motion, corners, edges, circles, segments)
        args = (body, theta, hw, hd, circles, segments)
        dense = _gaps_at(mount_at, samples, *args)
        assert _gaps_at(mount_at, [s], *args)[0] == pytest.approx(gap, abs=1e-9)
        assert gap <= min(dense) + 1e-12
        if dense[0] > 0.0 and min(dense) == 0.0:
            touched += 1
            contact = payload_first_contact(motion, corners, edges, circles, segments)
            assert contact is not None
            assert _gaps_at(mount_at, [contact], *args)[0] == pytest.approx(0.0, abs=1e-9)
            assert contact <= next(t for t, d in zip(samples, dense, strict=True) if d == 0.0)
    assert touched > 10  # (contacts were drawn)


HELPED = """
team: helped
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    variables: {{holding: 1}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 1.0}}, period: {period!r}}}}}
  helper:
    plant: {{kind: unicycle, state: {{x: -3, y: -3, theta: 0}}}}
    variables: {{helping: {helping}}}
    modes: {{Wait: {{inputs: {{v: 0.0, omega: 0.0}}, period: {period!r}}}}}
world:
  - use: payload
    with:
      name: box
      width: 0.4
      depth: 0.2
      pose: [0.2, 0.0, 0.0]
      grasps:
        - {{agent: r, point: [-0.2, 0.0], engaged: holding}}
        - {{agent: helper, point: [0.2, 0.0], engaged: helping}}
  - use: obstacles
    with:
      circles: [[1.8, 1.0, 0.25]]
simulation: {{duration: 3.0}}
"""


def test_a_grasp_alone_among_others_that_let_go_carries_the_payload_over_its_motion(
    team_from_yaml,
):
    """The box has a second grasp, the parked helper's, engaged by its variable
    ``helping``: at 0 robot r's grasp alone holds, the box moves as in the one-grasp team
    and its least gap is the one between ticks, 0.15; at 1 both hold, the springs'
    equilibrium has no closed form over the motion, and the box is judged at the ticks
    only (its clearance is then no longer 0.15: the box hangs between the two robots)."""
    alone = team_from_yaml(HELPED.format(period=PERIOD, helping=0))
    stats = ht.simulate(alone).diagnostics[0]["stats"]
    assert stats["payload_clearance"] == pytest.approx(0.15, abs=1e-12)
    both = team_from_yaml(HELPED.format(period=PERIOD, helping=1))
    stats = ht.simulate(both).diagnostics[0]["stats"]
    assert stats["payload_clearance"] > 0.2

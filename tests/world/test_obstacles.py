"""The ``obstacles`` world component: ring readings, detection events, clearances, errors."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from hybridteam.api import load, simulate
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.simulator import Simulator
from hybridteam.io.loader import InputErrors
from hybridteam.laws import LawContext, law
from hybridteam.robots import resolve
from hybridteam.world.obstacles import Obstacles, ObstacleWork

FIXTURES = Path(__file__).parents[1] / "fixtures" / "world"
IR_WALL = FIXTURES / "ir_wall.yaml"


def run_sim(team, n=1, duration=0.0, overrides=None) -> Ensemble:
    """The ensemble state after a run (its world components, recorder, agent states)."""
    sim = Simulator(compile_team(team), n, duration=duration, overrides=overrides)
    sim.run()
    return sim.ensemble


def started_ir_wall(n: int) -> tuple[Simulator, Obstacles]:
    """``n`` instances of the IR wall fixture, started (run for no time), and their
    obstacles component: poses may then be set and readings taken directly."""
    sim = Simulator(compile_team(load(IR_WALL)), n, duration=0.0)
    sim.run()
    (obs,) = [c for c in sim.ensemble.world.components if isinstance(c, Obstacles)]
    return sim, obs


def with_preset(team, **models):
    """``team`` with robot models attached to the named agents (as ``model:`` would)."""
    agents = tuple(
        dataclasses.replace(a, preset=resolve(models[a.name])) if a.name in models else a
        for a in team.agents
    )
    return dataclasses.replace(team, agents=agents)


def variant(tmp_path, text: str, name: str = "team.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return load(path)


def ir_wall_with_payload(name: str, width: float, depth: float, pose: list[float]) -> str:
    """The IR wall fixture's text with a resting payload (its grasp, by a robot B standing
    far away at (5, 5), is not engaged)."""
    return (
        IR_WALL.read_text()
        .replace(
            "world:\n",
            f"""world:
  - use: payload
    with:
      name: {name}
      width: {width}
      depth: {depth}
      pose: {pose}
      grasps: [{{agent: B, point: [0, 0], engaged: holding}}]
""",
            1,
        )
        .replace(
            "simulation:",
            """  B:
    plant: {kind: holonomic, state: {x: 5, y: 5, theta: 0}}
    variables: {holding: 0}
    modes: {Wait: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
simulation:""",
        )
    )


def test_readings_against_a_wall_a_post_and_a_box_turn_with_the_robot():
    """Beams ahead, left, behind, right from a hull of 0.3 (see the fixture): 1.7 to the
    wall, 0.7 to the post, nothing behind (max_range 2), 0.8 to the box; turned by 90
    degrees the same obstacles are one beam further round."""
    sim = run_sim(load(IR_WALL), n=2, overrides={"th0": [0.0, math.pi / 2]})
    got = sim.world.sense(0, np.arange(2), "ir")
    np.testing.assert_allclose(got, [[1.7, 0.7, 2.0, 0.8], [0.7, 2.0, 0.8, 1.7]], atol=1e-12)


def test_detection_is_raised_once_at_the_first_tick_past_the_threshold():
    run = simulate(load(IR_WALL))
    tr = run.transitions
    fired = [row for row in tr if row.cause == "event:obstacle_detected"]
    # beam 0 reads 1.7 - 0.1 t: 0.26 at the tick 14.4, below 0.255 from t* = 14.45 on,
    # reported at the next tick; standing at the wall after that raises nothing more
    # (Stop counts every obstacle_detected it receives: none)
    assert len(fired) == 1 and (fired[0].source, fired[0].target) == ("Drive", "Stop")
    assert abs(fired[0].t - 14.5) < 1e-9
    (out,) = run._outcomes
    # it stopped at x = 1.45: 2 - 1.45 - 0.3 from the wall; the post and box are farther
    np.testing.assert_allclose(out["stats"]["min_clearance"], [0.25], atol=1e-9)
    x = run.samples["R"][:, 0, 0]
    assert abs(x[-1] - 1.45) < 1e-9


def test_a_ring_that_keeps_seeing_something_within_the_threshold_skips_the_floor():
    """Once every instance's rule beams read below the threshold, the floor (which could
    rule out none) is not computed until a reading is beyond it again (issue 48: the
    XR4000's IR on the box it carries). The verdicts are the hand-computed ones: R stops
    at the tick 14.5 with beam 0 at 2 - 1.45 - 0.3 = 0.25 < 0.255, and standing there it
    is told once. Before that the floor prunes every instant: the centre is at least
    0.555 from every obstacle (0.255 + the hull) until x = 1.445, t = 14.45; once R stands
    still, its verdicts are the last ones (nothing they depend on moved). The work is
    read off the component's counters after runs that stop at ticks (every 0.1 s: a run
    that stops between ticks has an instant at its end the whole run does not have)."""

    def work(duration: float) -> ObstacleWork:
        ens = run_sim(load(IR_WALL), duration=duration)
        (obs,) = [c for c in ens.world.components if isinstance(c, Obstacles)]
        return obs.work

    run = simulate(load(IR_WALL))
    fired = [row for row in run.transitions if row.cause == "event:obstacle_detected"]
    assert len(fired) == 1 and abs(fired[0].t - 14.5) < 1e-9
    pruned, first_read, later, whole = work(14.4), work(14.5), work(15.0), work(20.0)
    assert pruned.reads == 0 and first_read.reads >= 1  # first read at the tick 14.5
    assert pruned.floors > 100 and first_read.floors == pruned.floors + 1  # (its instant's)
    assert whole.floors == first_read.floors  # not once after it
    # standing still from then on (Stop): its last verdicts stand, read once
    assert whole.reads == later.reads and whole.still - later.still >= 40


def test_a_resting_payload_is_an_obstacle_and_its_clearance_is_measured(tmp_path):
    """A 0.4 box turned 45 degrees rests at (1, 0) (its grasp is not engaged): R's front
    beam meets its corner at x = 1 - 0.2 sqrt 2; the corner on the other side is
    2 - (1 + 0.2 sqrt 2) from the wall. B, far away with no footprint, is a point."""
    text = ir_wall_with_payload("box", 0.4, 0.4, [1, 0, 0.7853981633974483])
    # listed after the payload in one team and before it in the other: the same result
    first = variant(tmp_path, text, "payload_first.yaml")
    spec = first.world
    second = dataclasses.replace(first, world=(spec[1], spec[0]))
    half_diag = 0.2 * math.sqrt(2)
    for team in (first, second):
        sim = run_sim(team)
        got = sim.world.sense(0, np.arange(1), "ir")
        np.testing.assert_allclose(got, [[1 - half_diag - 0.3, 0.7, 2.0, 0.8]], atol=1e-12)
        stats = sim.world.summary(0)
        # R: the post at 1.5 - 0.5 - 0.3; B at (5, 5): the wall's end (2, 1) at 5
        np.testing.assert_allclose(stats["min_clearance"], [0.7, 5.0], atol=1e-12)
        assert abs(stats["payload_clearance"] - (1 - half_diag)) < 1e-12


def test_payload_clearance_is_zero_when_it_overlaps_an_obstacle():
    """Outline/obstacle gaps in the payload's frame, against hand-placed cases."""
    from hybridteam.world.carried import _segment_box

    hw, hd = np.array([1.0]), np.array([0.5])
    # through the box, ends outside: 0; beside it: 0.5; off a corner along the diagonal
    cases = [
        ((-3, 0, 3, 0), 0.0),
        ((-3, 1, 3, 1), 0.5),
        ((2, 1.5, 3, 2.5), math.sqrt(2)),
        ((0.2, 0.1, 0.3, 0.2), 0.0),
        ((1.5, -3, 1.5, 3), 0.5),
    ]
    for (ax, ay, bx, by), want in cases:
        got = _segment_box(np.array([ax]), np.array([ay]), np.array([bx]), np.array([by]), hw, hd)
        assert abs(got[0] - want) < 1e-12, (ax, ay, bx, by)


@law("tests.ir_keep", plants=("holonomic",))
def ir_keep(ctx: LawContext) -> np.ndarray:
    """Stand still and keep what the IR ring reads (beams 0, 1 and 12)."""
    r = ctx.sense("ir")
    for k in (0, 1, 12):
        ctx.keep(f"ir{k}", r[:, k])
    return np.zeros((r.shape[0], 3))


def test_a_robot_model_gives_the_ring_and_the_footprint(tmp_path):
    """An XR4000 (IR: 24 beams on its 0.33 hull, 0.5 range) facing a wall 0.6 ahead: beam
    0 reads 0.6 - 0.33, beam 1 (15 degrees) 0.6 / cos 15 - 0.33, beam 12 nothing."""
    team = variant(
        tmp_path,
        """
kind: team
team: xr
world:
  - use: obstacles
    with:
      walls: [[0.6, -1, 0.6, 1]]
      detect: [{agent: X, sensor: ir, sector: [-45, 45], below: 0.3, raise: near}]
agents:
  X:
    model: xr4000
    plant: {state: {x: 0, y: 0, theta: 0}}
    initial: Look
    modes:
      Look:
        law: {use: tests.ir_keep, period: 0.1}
        transitions: [{to: Seen, on: near}]
      Seen: {law: {use: tests.ir_keep, period: 0.1}}
simulation: {duration: 1}
""",
    )
    sim = run_sim(team, duration=1.0)
    # in range from the start: reported at the first instant
    (row,) = [r for r in sim.rec.tables()[0] if r.cause == "event:near"]
    assert row.t == 0.0
    mem = sim.states[0].memory
    assert abs(mem["ir0"][0] - 0.27) < 1e-12
    assert abs(mem["ir1"][0] - (0.6 / math.cos(math.radians(15)) - 0.33)) < 1e-12
    assert mem["ir12"][0] == 0.5
    assert sim.world.components[0].senses() == ("ir", "sonar")
    np.testing.assert_allclose(sim.world.summary(0)["min_clearance"], [0.6 - 0.33], atol=1e-12)
    assert sim.world.meta()["footprints"] == {"X": {"radius": 0.33}}


def test_sector_picks_the_beams_whose_axis_falls_in_it(tmp_path):
    team = with_preset(load(IR_WALL), R="xr4000")
    values = {
        **Obstacles.params,
        "detect": [
            {"agent": "R", "sensor": "ir", "sector": [-45, 45], "below": 0.3, "raise": "near"},
            {"agent": "R", "sensor": "ir", "sector": [90, 120], "below": 0.3, "raise": "side"},
        ],
    }
    comp = Obstacles(team, 1, values)
    assert comp.rules[0].beams.tolist() == [0, 1, 2, 3, 21, 22, 23]  # 15-degree beams
    assert comp.rules[1].beams.tolist() == [6, 7, 8]
    assert comp.raises == ("near", "side")


RING = "          ring: {count: 4, max_range: 2.0, mount_radius: 0.3}\n"


@pytest.mark.parametrize(
    ("old", "new", "where", "message"),
    [
        ("- agent: R", "- agent: Q", "detect[0].agent", "unknown agent 'Q'"),
        ("sensor: ir", "sensor: 7", "detect[0].sensor", "expected a sensor name"),
        ("below: 0.255", "below: 3", "detect[0].below", "expected a range in (0, max_range = 2]"),
        ("beams: [0]", "beams: [4]", "detect[0].beams", "expected beam indices 0..3"),
        ("beams: [0]", "sector: [30, 60]", "detect[0].sector", "no beam of 'ir' points within"),
        ("raise: obstacle_detected", "rise: x", "detect[0]", "a rule needs raise"),
        ("walls: [[2, -1, 2, 1]]", "walls: [[2, -1, 2]]", "walls[0]", "expected [x0, y0, x1, y1]"),
        ("radius: [[R, 0.3]]", "radius: [[S, 0.3]]", "radius[0][0]", "unknown agent 'S'"),
        ("radius: [[R, 0.3]]", "radius: [[R, -1]]", "radius[0]", "expected [agent, radius >= 0]"),
        (RING, "", "detect[0].sensor", "agent 'R' has no robot model to take 'ir' from"),
    ],
)
def test_bad_settings_are_located_errors_naming_the_setting(tmp_path, old, new, where, message):
    text = IR_WALL.read_text()
    assert old in text
    with pytest.raises(InputErrors) as exc:
        variant(tmp_path, text.replace(old, new, 1))
    got = str(exc.value)
    assert "team.yaml:" in got and f"world[0].with.{where}: {message}" in got, got


def test_python_built_teams_get_the_same_messages_as_value_errors():
    team = with_preset(load(IR_WALL), R="xr4000")
    values = {
        **Obstacles.params,
        "detect": [{"agent": "R", "sensor": "lidar", "below": 0.3, "raise": "near"}],
    }
    with pytest.raises(
        ValueError,
        match=r"obstacles: detect\[0\]\.sensor: agent 'R': "
        r"'lidar' is not a sensor of this robot",
    ):
        Obstacles(team, 1, values)


def test_obstacles_are_drawn_as_grey_shapes_in_the_trajectory_plot():
    from hybridteam.export.trajectories import trajectory_figure

    run = simulate(load(IR_WALL))
    world = run.meta["world"]
    assert world["obstacles"][0] == {"kind": "wall", "points": [[2.0, -1.0], [2.0, 1.0]]}
    assert world["obstacles"][1] == {"kind": "circle", "x": 0.0, "y": 1.5, "r": 0.5}
    np.testing.assert_allclose(
        world["obstacles"][2]["points"], [[-0.5, -1.5], [0.5, -1.5], [0.5, -1.1], [-0.5, -1.1]]
    )
    assert run.meta["agents"][0]["footprint"] == {"radius": 0.3}
    ax = trajectory_figure(run).axes[0]
    shapes = [p for p in ax.patches if p.get_gid() == "obstacle"]
    assert len(shapes) == 2 and all(
        p.get_facecolor()[:3] == shapes[0].get_facecolor()[:3] for p in shapes
    )
    (walls,) = [c for c in ax.collections if c.get_gid() == "obstacle-walls"]
    np.testing.assert_allclose(walls.get_segments()[0], [[2, -1], [2, 1]])


def test_a_reading_skips_the_static_scene_only_where_it_is_out_of_range_bit_for_bit():
    """A detect rule's reading does not cast against walls, posts and boxes where this
    instant's centre clearance puts all of them beyond the ring's hull plus range; what it
    reads there must be exactly what the full cast reads (max_range), everywhere else the
    cast itself. Poses at random, and on the edge: 0.3 + 2.0 from the wall, facing it."""
    import hybridteam.world.obstacles as obstacles_module

    rng = np.random.default_rng(7)
    n = 3000
    sim, obs = started_ir_wall(n)
    ens = sim.ensemble
    x, y, th = rng.uniform(-4, 5, n), rng.uniform(-4, 4, n), rng.uniform(-math.pi, math.pi, n)
    x[:4], y[:4], th[:4] = [-0.3, -0.3 - 1e-12, -0.3 + 1e-12, -0.3 - 1e-6], 0.0, 0.0
    ens.states[0].x[:, 0], ens.states[0].x[:, 1], ens.states[0].x[:, 2] = x, y, th
    idx = np.arange(n)
    reach = obs._measure(sim.access, idx, obs.scenes[0])[0]
    ring = obs.rings[(0, "ir")]
    short = obs.read(0, ring, idx, reach)
    np.testing.assert_array_equal(short, obs.read(0, ring, idx))
    far = reach - ring.mount_radius > ring.max_range + obstacles_module._SLACK * 10
    assert n / 10 < far.sum() < n * 9 / 10  # both ways were taken
    assert (short[far] == ring.max_range).all()
    assert short[0, 0] == ring.max_range and short[3, 0] == ring.max_range  # on the edge


def test_a_rule_reads_only_its_beams_and_they_read_as_in_the_whole_ring():
    """Detect rules cast only the beams they read (a front-IR rule reads 3 of 24): each of
    those beams, cones of three rays included, must read exactly what it reads when the
    whole ring is cast, wherever the robot stands."""
    from hybridteam.world.sensors import RangeRing

    rng = np.random.default_rng(11)
    n = 500
    sim, obs = started_ir_wall(n)
    st = sim.ensemble.states[0]
    st.x[:, 0], st.x[:, 1] = rng.uniform(-3, 4, n), rng.uniform(-3, 3, n)
    st.x[:, 2] = rng.uniform(-math.pi, math.pi, n)
    idx = np.arange(n)
    line = obs.rings[(0, "ir")]
    cone = RangeRing(count=8, max_range=2.0, mount_radius=0.3, half_angle=0.2, rays_per_beam=3)
    for ring in (line, cone):
        whole = obs.read(0, ring, idx)
        assert (whole < ring.max_range).any() and (whole == ring.max_range).any()
        for beams in (np.array([0]), np.array([1, 3]), np.arange(ring.count)[::-2]):
            beams = np.sort(beams)
            np.testing.assert_array_equal(obs.read(0, ring, idx, beams=beams), whole[:, beams])
    # the rules' own bookkeeping: each rule's columns among its ring's beams read
    for rule, columns in zip(obs.rules, obs.rule_columns, strict=True):
        np.testing.assert_array_equal(
            obs.read_beams[(rule.agent, rule.sensor)][columns], rule.beams
        )


def test_no_beam_reads_nearer_than_the_floor_and_rules_skip_only_where_none_can_fire(tmp_path):
    """A rule casts only where the floor (centre clearance from the static scene and from
    every payload's outline, less the hull) is below its threshold. The floor must bound
    every beam of the whole ring from below, and the rule's instances must see what casting
    everywhere gives wherever it is below the threshold (static obstacles farther than that
    are not cast against: those beams read no nearer than the threshold). Poses at random
    around a wall, a post, a box and a resting payload turned 30 degrees, some on the
    payload itself."""
    text = (
        ir_wall_with_payload("crate", 0.6, 0.3, [-1.5, -0.5, 0.5235987755982988])
        .replace("below: 0.255", "below: 0.6")
        .replace("beams: [0]", "beams: [0, 1]")
    )
    n = 4000
    sim = Simulator(compile_team(variant(tmp_path, text)), n, duration=0.0)
    sim.run()
    (obs,) = [c for c in sim.ensemble.world.components if isinstance(c, Obstacles)]
    rng = np.random.default_rng(3)
    st = sim.ensemble.states[0]
    st.x[:, 0], st.x[:, 1] = rng.uniform(-3.5, 3.5, n), rng.uniform(-3, 3, n)
    st.x[:, 2] = rng.uniform(-math.pi, math.pi, n)
    st.x[:20, 0], st.x[:20, 1] = -1.5, -0.5  # the centre on the payload
    idx = np.arange(n)
    reach = obs._measure(sim.access, idx, obs.scenes[0])[0]
    key = (0, "ir")
    ring = obs.rings[key]
    whole = obs.read(0, ring, idx)
    floor = obs.floor(0, ring, idx, reach)
    assert (floor <= whole.min(axis=1)).all()
    readings, rows = obs._rule_readings(key, idx, obs.scenes[0], reach)
    assert rows is not None and n / 10 < rows.size < n * 9 / 10  # both ways were taken
    (rule,) = obs.rules
    exact = whole[rows][:, obs.read_beams[key]]
    np.testing.assert_array_equal(np.minimum(readings, rule.below), np.minimum(exact, rule.below))
    assert (readings != exact).any()  # some static obstacle was beyond the threshold
    skipped = np.setdiff1d(idx, rows)
    assert (whole[skipped][:, rule.beams].min(axis=1) >= rule.below).all()
    # and each instance's rule state after an update is what casting everywhere says
    obs.near[:] = False
    obs._update(sim.access, idx, obs.scenes[0])  # (as at a sensing instant of the robot)
    np.testing.assert_array_equal(obs.near[0], whole[:, rule.beams].min(axis=1) < rule.below)

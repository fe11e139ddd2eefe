"""The framework's ``payload`` world component: equilibrium pose, arm readings, breaks."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridteam.api import load, simulate
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator
from hybridteam.laws import LawContext, law
from hybridteam.robots import resolve
from hybridteam.world.carried import CarriedPayload

FIXTURE = Path(__file__).parents[1] / "fixtures" / "world" / "bar_pull.yaml"


def test_stretched_bar_settles_by_the_spring_ratio_and_breaks_on_time():
    run = simulate(load(FIXTURE))
    (out,) = run.outcomes
    assert out == "link_broken"
    o = run._outcomes[0]
    # limit 0.31 on A's side, which takes 3/4 of the stretch 0.1 t: t* = 4.1333, next tick 4.2
    assert abs(o["t"] - 4.2) < 1e-9
    assert "bar dropped: the grasp of 'A' is offset 0.315 > limit 0.31" in o["message"]
    t = run.sample_times
    bar = run.samples["bar"][:, 0]
    ok = ~np.isnan(bar[:, 0])
    # weighted centroids coincide: x = (1 (2 + 0.1 t) + 3 * 0) / 4 + 0.5 = 1 + 0.025 t
    np.testing.assert_allclose(bar[ok, 0], 1 + 0.025 * t[ok], atol=1e-12)
    np.testing.assert_allclose(bar[ok, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(o["stats"]["max_grasp_offset"], [0.315, 0.105], atol=1e-12)
    assert run.meta["payloads"] == ["bar"]


@law("tests.arm_probe", plants=("holonomic",))
def arm_probe(ctx: LawContext) -> np.ndarray:
    """Drive at the arm's reading: vx = x_a, vy = y_a, omega = theta_a (a probe)."""
    return np.asarray(ctx.sense("arm"), dtype=float).copy()


def test_arm_reads_the_offset_in_the_robot_frame(tmp_path):
    """A robot turned by 90 degrees reads a world-x stretch as its own -y."""
    text = (
        FIXTURE.read_text()
        .replace("state: {x: 0, y: 0, theta: 0}", "state: {x: 0, y: 0, theta: 1.5707963267948966}")
        .replace(
            "Hold: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}",
            "Hold: {law: {use: tests.arm_probe, period: 0.5}}",
        )
        .replace("duration: 10", "duration: 1")
    )
    path = tmp_path / "probe.yaml"
    path.write_text(text)
    run = simulate(load(path))
    # at t = 0.5 the bar (x = 1 + 0.025 t) puts B's grasp point at world x = 0.0125, so B's
    # offset is (-0.0125, 0) in the world and (0, 0.0125) in its own frame (turned 90 deg);
    # the probe drives at that for 0.5 s (holonomic inputs are world-frame velocities)
    b = run.samples["B"][:, 0]
    k = int(np.argmin(abs(run.sample_times - 1.0)))
    np.testing.assert_allclose(b[k], [0.0, 0.5 * 0.0125, np.pi / 2], atol=1e-12)


PICKUP = Path(__file__).parents[1] / "fixtures" / "world" / "box_pickup.yaml"


def test_a_resting_box_stays_put_until_grasped_then_follows_the_engaged_grasps():
    run = simulate(load(PICKUP))
    (o,) = run._outcomes
    assert o["outcome"] == "ok"
    t = run.sample_times
    box = run.samples["box"][:, 0]
    rest, alone, both = t < 2.05, (t > 2.05) & (t < 4.05), t > 4.05
    np.testing.assert_allclose(box[rest], [[1.0, 0.0, 0.0]] * rest.sum(), atol=1e-12)
    # A alone: a point spring turns nothing, so the box keeps its angle and its right end
    # (body point [1, 0]) is at A: x = 2 + 0.1 t - 1
    np.testing.assert_allclose(box[alone, 0], 1 + 0.1 * t[alone], atol=1e-12)
    np.testing.assert_allclose(box[both, 0], (0.5 + 0.1 * t[both]) / 4 + 0.5, atol=1e-12)
    np.testing.assert_allclose(box[~rest, 1:], 0.0, atol=1e-12)
    # engaged time only: B was 0.9 short of its end at t = 4 but held nothing then; at the
    # end the springs (1 : 3) share the mismatch 0.5 + 0.1 t = 1.1 as 3/4 and 1/4
    np.testing.assert_allclose(o["stats"]["max_grasp_offset"], [0.825, 0.275], atol=1e-12)


def test_arms_read_their_offsets_before_they_hold_anything():
    """The Labmate docks by its arm's reading, before it holds the box."""
    run = Simulator(compile_team(load(PICKUP)), 1, duration=1.0)
    run.run()
    sim = run.ensemble
    # at t = 1: A is 0.1 past the box's right end, B 0.5 short of its left end
    np.testing.assert_allclose(
        sim.world.sense(0, np.arange(1), "arm"), [[0.1, 0.0, 0.0]], atol=1e-12
    )
    np.testing.assert_allclose(
        sim.world.sense(1, np.arange(1), "arm"), [[-0.5, 0.0, 0.0]], atol=1e-12
    )
    np.testing.assert_allclose(sim.world.sense(1, np.arange(1), "payload"), [[1.0, 0.0, 0.0]])


def xr4000_bar(tmp_path, grasp_b: str = "{agent: B, point: [-1, 0]}"):
    """The bar pull with both robots XR4000s and grasps that say only where they hold."""
    text = (
        FIXTURE.read_text()
        .replace("{agent: A, point: [1, 0], spring: 1, limit: 0.31}", "{agent: A, point: [1, 0]}")
        .replace("{agent: B, point: [-1, 0], spring: 3, limit: 0.31}", grasp_b)
    )
    path = tmp_path / "xr_bar.yaml"
    path.write_text(text)
    team = load(path)
    preset = resolve("xr4000")
    return dataclasses.replace(
        team, agents=tuple(dataclasses.replace(a, preset=preset) for a in team.agents)
    )


def test_grasps_default_to_the_robot_models_manipulator(tmp_path):
    """XR4000 forks: mount 0.45 ahead, spring 5000, limit 0.05. The mount points start
    2 apart (the bar's length); A pulls at 0.1 and equal springs share the stretch, so
    each offset is 0.05 t: past the limit after 1 s, reported at the next tick."""
    team = xr4000_bar(tmp_path)
    comp = CarriedPayload(
        team, 1, {**CarriedPayload.params, "grasps": team.world[0].values["grasps"]}
    )
    np.testing.assert_allclose(comp.mount, [[0.45, 0.0], [0.45, 0.0]])
    np.testing.assert_allclose(comp.spring, [5000.0, 5000.0])
    np.testing.assert_allclose(comp.limit, [0.05, 0.05])
    run = simulate(team)
    (o,) = run._outcomes
    assert o["outcome"] == "link_broken" and abs(o["t"] - 1.1) < 1e-9


def test_explicit_grasp_keys_win_over_the_model(tmp_path):
    team = xr4000_bar(tmp_path, "{agent: B, point: [-1, 0], spring: 2, mount: [0, 0.1]}")
    comp = CarriedPayload(
        team, 1, {**CarriedPayload.params, "grasps": team.world[0].values["grasps"]}
    )
    np.testing.assert_allclose(comp.mount, [[0.45, 0.0], [0.0, 0.1]])
    np.testing.assert_allclose(comp.spring, [5000.0, 2.0])
    np.testing.assert_allclose(comp.limit, [0.05, 0.05])


def test_an_engaged_grasp_must_name_a_variable_of_its_agent(tmp_path):
    text = PICKUP.read_text().replace(
        "point: [1, 0], spring: 1, engaged: holding", "point: [1, 0], spring: 1, engaged: hodling"
    )
    path = tmp_path / "typo.yaml"
    path.write_text(text)
    with pytest.raises(
        ValueError,
        match=r"payload: grasps\[0\]\.engaged: agent 'A' has no "
        r"variable 'hodling' \(its variables: holding\)",
    ):
        simulate(load(path))


THREE_GRASPS = """
kind: team
team: three-grasps
world:
  - use: payload
    with:
      name: box
      width: 2
      depth: 0.4
      pose: [0.3, -0.2, 0.4]
      grasps:
        - {agent: A, point: [1, 0], mount: [0.2, 0.05], spring: 1, engaged: holding}
        - {agent: B, point: [-1, 0.1], mount: [-0.1, 0.0], spring: 3, engaged: holding}
        - {agent: C, point: [0.2, 0.2], spring: 0.7GRASP_C}
agents:
  A:
    plant: {kind: unicycle, state: {x: 2, y: 0, theta: 0}}
    variables: {holding: 0}
    modes: {Stay: {inputs: {v: 0, omega: 0}, period: 0.1}}
  B:
    plant: {kind: holonomic, state: {x: -0.5, y: 0, theta: 0}}
    variables: {holding: 0}
    modes: {Stay: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
  C:
    plant: {kind: holonomic, state: {x: 0, y: 1, theta: 0}}
    variables: {holding: 0}
    modes: {Stay: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
"""


@pytest.fixture(
    scope="module", params=["", ", engaged: holding"], ids=["C always holds", "C engages"]
)
def three_grasps(tmp_path_factory, request):
    path = tmp_path_factory.mktemp("settle") / "three.yaml"
    path.write_text(THREE_GRASPS.replace("GRASP_C", request.param))
    sim = Simulator(compile_team(load(path)), 4, duration=1.0)
    (box,) = [c for c in sim.ensemble.world.components if isinstance(c, CarriedPayload)]
    return sim, box


_KEPT = ("pose", "rest", "engaged", "offset", "arm")


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.data())
def test_one_instance_settles_on_floats_to_the_array_versions_bits(three_grasps, data):
    """A single run settles its payload on Python floats (settle_one), an ensemble on
    arrays: every number the component keeps (its offsets and engagement included) or
    returns is the same, bit for bit, for every engagement (none held: at rest; one: no
    torque; two or three: the spring equilibrium), with grasps that always hold and grasps
    engaged by a variable."""
    sim, box = three_grasps
    ens, world = sim.ensemble, sim.access
    coords = st.floats(-50, 50, allow_nan=False)
    for s in ens.states:
        s.x[:, :3] = data.draw(st.lists(st.tuples(coords, coords, coords), min_size=4, max_size=4))
    for s in ens.states:
        s.v[:, 0] = data.draw(st.lists(st.sampled_from([0.0, 1.0]), min_size=4, max_size=4))
    box.rest[:] = data.draw(st.lists(st.tuples(coords, coords, coords), min_size=4, max_size=4))
    box.rel0[:] = data.draw(st.lists(st.tuples(coords, coords, coords), min_size=4, max_size=4))
    before = {k: getattr(box, k).copy() for k in _KEPT}
    together = box.settle(world, np.arange(4))  # (more than one: the array version)
    kept = {k: getattr(box, k).copy() for k in _KEPT}
    for k in _KEPT:
        getattr(box, k)[:] = before[k]
    for i in range(4):
        alone = box.settle(world, np.array([i]))
        assert alone.shape == together[i : i + 1].shape
        assert alone.tobytes() == together[i : i + 1].tobytes()
    for k in _KEPT:
        assert getattr(box, k).tobytes() == kept[k].tobytes(), k

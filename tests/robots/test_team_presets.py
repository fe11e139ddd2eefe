"""Robot models in team files (``model: xr4000``) and plant-neutral velocity symbols.

Numbers are hand-computed: a saturated straight line is speed x time; a unicycle at v, omega
draws the circle of radius v/omega; a holonomic base moves on the line of its world velocity.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.dynamics.plants import make_plant
from hybridteam.engine.compile.compiled import Ctx
from hybridteam.engine.compile.protocols import velocity_symbols
from hybridteam.export.trajectories import trajectory_figure
from hybridteam.io.loader import InputErrors
from hybridteam.laws import _dead_reckon, law
from hybridteam.robots import load_presets
from hybridteam.world.component import WorldComponent, world_component
from hybridteam.world.scene import Footprint, SceneDescription
from tests.conftest import FIXTURES

TWO_ROBOTS = """\
    team: carry
    agents:
      xr:
        model: xr4000
        plant:
          state: {x: 0, y: 0, theta: 0}
          limits: {vy: [-0.2, 0.2]}            # the model's vx, omega limits stay
        sensors: {ir: {max_range: 0.6}}
        modes:
          Go: {inputs: {vx: 5, vy: 5, omega: 0}}
      lab:
        model: labmate
        plant: {kind: unicycle, state: {x: 0, y: 5, theta: 0}}   # agrees with the model
        manipulator: null
        modes:
          Go: {inputs: {v: 5, omega: 0.5}}
      plain:
        plant: {kind: unicycle, state: {x: 0, y: -5, theta: 0}}
        modes:
          Go: {inputs: {v: 5, omega: 0}}
    simulation: {duration: 2, sample_period: 0.5}
    """


# ----------------------------------------------------------------- model: in a team file
def test_models_give_the_plant_and_overrides_merge(team_from_yaml):
    team = team_from_yaml(TWO_ROBOTS)
    presets = load_presets()
    xr, lab, plain = team.agent("xr"), team.agent("lab"), team.agent("plain")
    assert xr.plant.kind == "holonomic" and lab.plant.kind == "unicycle"
    assert xr.plant.limits == {"vx": (-0.5, 0.5), "vy": (-0.2, 0.2), "omega": (-1.0, 1.0)}
    assert xr.preset.plant.limits == xr.plant.limits
    assert lab.plant.limits == {"v": (-0.5, 0.5), "omega": (-1.0, 1.0)}
    ir = xr.preset.ring("ir")
    assert (ir.count, ir.max_range) == (24, 0.6)
    assert xr.preset.ring("sonar") == presets["xr4000"].ring("sonar")  # not overridden
    assert xr.preset.footprint.radius == 0.33 and xr.preset.manipulator.kind == "forklift"
    assert lab.preset.manipulator is None  # null removed it
    assert lab.preset.sensors == presets["labmate"].sensors
    assert plain.preset is None and plain.plant.limits == {}


def test_the_models_limits_saturate_the_inputs(team_from_yaml):
    run = ht.simulate(team_from_yaml(TWO_ROBOTS))
    # xr asks for 5 m/s: vx is held at the model's 0.5, vy at the team's 0.2, for 2 s
    np.testing.assert_allclose(run.samples["xr"][-1, 0], [1.0, 0.4, 0.0], atol=1e-12)
    # lab at v = 0.5, omega = 0.5: the unit circle about (0, 6), one radian round it
    np.testing.assert_allclose(
        run.samples["lab"][-1, 0], [math.sin(1.0), 5.0 + 1.0 - math.cos(1.0), 1.0], atol=1e-12
    )
    np.testing.assert_allclose(run.samples["plain"][-1, 0], [10.0, -5.0, 0.0], atol=1e-12)


def test_a_models_footprint_is_drawn_unless_a_component_draws_one(team_from_yaml):
    run = ht.simulate(
        team_from_yaml(
            TWO_ROBOTS.replace("sensors: {ir:", "footprint: {radius: 0.4}\n        sensors: {ir:")
        )
    )
    feet = {a["name"]: a.get("footprint") for a in run.meta["agents"]}
    assert feet == {"xr": {"radius": 0.4}, "lab": {"radius": 0.35}, "plain": None}
    ax = trajectory_figure(run).axes[0]
    (heads,) = [c for c in ax.collections if c.get_gid() == "headings:lab"]
    # heading strokes are one footprint radius long
    assert [np.hypot(*np.diff(s, axis=0)[0]) for s in heads.get_segments()] == pytest.approx(
        [0.35] * len(heads.get_segments())
    )
    assert [c for c in ax.collections if c.get_gid() == "footprints:plain"]  # a pose marker

    @world_component("test.draws_xr")
    class Draws(WorldComponent):
        def describe(self) -> SceneDescription:
            return SceneDescription(footprints={"xr": Footprint(0.9)})

    text = TWO_ROBOTS.rstrip(" ") + "    world: [{use: test.draws_xr}]\n"
    run = ht.simulate(team_from_yaml(text, "drawn.yaml"))
    feet = {a["name"]: a.get("footprint") for a in run.meta["agents"]}
    assert feet["xr"] == {"radius": 0.9} and feet["lab"] == {"radius": 0.35}


MODELS = FIXTURES / "bad" / "models"
# file -> (line:column, path in the message, words the message must contain)
BAD = {
    "unknown_model.yaml": (
        "5:12",
        "agents.xr.model",
        "unknown robot model 'xr400'; did you mean 'xr4000'?",
    ),
    "model_bad_override.yaml": (
        "9:12",
        "agents.xr.sensors.ir.max_rang",
        "unknown key 'max_rang'; did you mean 'max_range'?",
    ),
    "model_kind_conflict.yaml": (
        "7:13",
        "agents.lab.plant.kind",
        "robot model 'labmate' is a unicycle, not a holonomic",
    ),
    "model_bad_limit.yaml": (
        "8:16",
        "agents.lab.plant.limits.vx",
        "a unicycle plant has no input 'vx'; did you mean 'v'?",
    ),
    "sensors_without_model.yaml": (
        "6:14",
        "agents.xr.sensors",
        "'sensors' overrides a robot model's; add 'model: <name>'",
    ),
    "plant_without_kind.yaml": ("6:7", "agents.xr.plant", "missing required key 'kind'"),
}


def test_bad_model_files_are_listed():
    assert set(BAD) == {p.name for p in MODELS.glob("*.yaml")}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_model_use_gives_one_located_error_and_exit_2(name, capsys):
    at, path, words = BAD[name]
    assert main(["validate", str(MODELS / name)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"{MODELS / name}:{at}: {path}: {words}"), err


OVERRIDE = """\
    team: t
    agents:
      xr:
        model: xr4000
        modes: {{Go: {{inputs: {{vx: 0.1}}}}}}
        plant: {{state: {{x: 0}}{limits}}}
        {extra}
    """


@pytest.mark.parametrize(
    ("limits", "extra", "message"),
    [
        ("", "footprint: {radius: -1}", ":7:25: agents.xr.footprint.radius: must be > 0, got -1"),
        (
            "",
            "sensors: {sonr: {count: 8}}",
            ":7:15: agents.xr.sensors.sonr: xr4000 has no sensor 'sonr'; did you mean 'sonar'?",
        ),
        (
            "",
            "manipulator: {kind: compliant_arm}",
            ":7:18: agents.xr.manipulator: missing required key 'spring'",
        ),
        (
            ", limits: {vx: [1, -1]}",
            "",
            ":6:41: agents.xr.plant.limits.vx: lower limit 1.0 exceeds upper -1.0",
        ),
    ],
)
def test_override_errors_are_located_in_the_team_file(team_from_yaml, limits, extra, message):
    with pytest.raises(InputErrors) as exc:
        team_from_yaml(OVERRIDE.format(limits=limits, extra=extra))
    assert any(str(e).endswith(message) for e in exc.value.errors), str(exc.value)


def test_an_operator_has_no_model(team_from_yaml):
    with pytest.raises(InputErrors, match="an operator agent has no body; remove 'model'"):
        team_from_yaml("""\
            team: t
            agents:
              op: {operator: role_assignment, model: scout}
            """)


def test_the_schema_shows_the_new_keys(capsys):
    import json

    assert main(["schema", "team"]) == 0
    schema = json.loads(capsys.readouterr().out)
    agent = schema["$defs"]["AgentSchema"]["properties"]
    assert {"model", "sensors", "manipulator", "footprint"} <= set(agent)
    assert "model" in schema["$defs"]["PlantSchema"]["properties"]["kind"]["description"]


# ----------------------------------------------------------------- velocity symbols
def test_velocity_symbols_are_world_rates_for_every_plant():
    x = np.array([[1.0, 2.0, 0.5], [0.0, 0.0, -2.0]])
    vel = {}
    for kind, u in (
        ("unicycle", [[0.4, 0.3], [-0.2, 1.0]]),
        ("holonomic", [[0.3, -0.1, 0.2], [0.0, 0.5, -1.0]]),
    ):
        ctx = Ctx(x, np.zeros((2, 0)), np.zeros((2, 0)), np.zeros(2))
        ctx.u = np.array(u)
        vel[kind] = {k: f(ctx) for k, f in velocity_symbols(make_plant(kind)).items()}
    c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
    uni, hol = vel["unicycle"], vel["holonomic"]
    np.testing.assert_allclose(uni["vel_x"], [0.4 * c[0], -0.2 * c[1]], atol=1e-15)
    np.testing.assert_allclose(uni["vel_y"], [0.4 * s[0], -0.2 * s[1]], atol=1e-15)
    np.testing.assert_allclose(uni["vel_theta"], [0.3, 1.0])
    np.testing.assert_allclose(uni["vel_forward"], [0.4, -0.2], atol=1e-15)
    np.testing.assert_allclose(hol["vel_x"], [0.3, 0.0])
    np.testing.assert_allclose(hol["vel_y"], [-0.1, 0.5])
    np.testing.assert_allclose(hol["vel_theta"], [0.2, -1.0])
    np.testing.assert_allclose(
        hol["vel_forward"], [0.3 * c[0] - 0.1 * s[0], 0.5 * s[1]], atol=1e-15
    )
    for plant in (make_plant("flow", ("h", "v")), make_plant("none")):
        ctx = Ctx(
            np.ones((3, len(plant.state_names))), np.zeros((3, 0)), np.zeros((3, 0)), np.zeros(3)
        )
        ctx.u = np.zeros((3, 0))
        for f in velocity_symbols(plant).values():
            assert f(ctx).tolist() == [0.0, 0.0, 0.0]


def _as_streamed(x0: np.ndarray, rates: np.ndarray) -> dict[str, np.ndarray]:
    """The fields the role-assignment stream sends for pose x0 and world rates."""
    vx, vy, w = rates.T
    th = x0[:, 2]
    return {
        "x": x0[:, 0],
        "y": x0[:, 1],
        "theta": th,
        "v": vx * np.cos(th) + vy * np.sin(th),
        "vx": vx,
        "vy": vy,
        "omega": w,
    }


def test_dead_reckoning_a_stream_from_either_plant_is_exact():
    rng = np.random.default_rng(5)
    x0, age = rng.normal(size=(200, 3)), rng.uniform(0, 0.5, 200)
    uni, hol = make_plant("unicycle"), make_plant("holonomic")
    u = rng.normal(size=(200, 2))  # a unicycle: velocity along its heading -> the arc
    est = _dead_reckon(_as_streamed(x0, uni.derivative(x0, u)), age)
    np.testing.assert_allclose(
        np.c_[est["x"], est["y"], est["theta"]], uni.propagate(x0, u, age), atol=1e-12
    )
    u = rng.normal(size=(200, 3))  # a holonomic base (velocity off its heading) -> the line
    est = _dead_reckon(_as_streamed(x0, hol.derivative(x0, u)), age)
    np.testing.assert_allclose(
        np.c_[est["x"], est["y"], est["theta"]], hol.propagate(x0, u, age), atol=1e-12
    )
    # documented limit: a holonomic base driving along its heading while turning looks
    # like a unicycle and is moved on the arc (here a quarter turn at unit speed)
    one = {
        "x": np.zeros(1),
        "y": np.zeros(1),
        "theta": np.zeros(1),
        "v": np.ones(1),
        "vx": np.ones(1),
        "vy": np.zeros(1),
        "omega": np.full(1, math.pi / 2),
    }
    est = _dead_reckon(one, np.ones(1))
    assert (est["x"][0], est["y"][0]) == pytest.approx((2 / math.pi, 2 / math.pi))


SEEN: list[tuple[float, int, np.ndarray, float]] = []


@law("test.record_leaders")
def record_leaders(ctx):
    """Stand still; keep every dead-reckoned leader estimate with the time it was made."""
    for sender in (0, 1):
        est = ctx.estimate("state", sender=sender, extrapolate=True)
        if np.isfinite(est.age[0]):  # a copy from this sender has arrived
            SEEN.append(
                (
                    float(ctx.t[0]),
                    sender,
                    np.array([est["x"][0], est["y"][0], est["theta"][0]]),
                    float(est.age[0]),
                )
            )
    return np.zeros((ctx.size, len(ctx.inputs)))


LEADERS = """\
    team: mixed
    network: {latency: 0.03}
    agents:
      xr:                                       # holonomic, moving off its heading
        model: xr4000
        plant: {state: {x: 1, y: 2, theta: 2.0}}
        modes:
          T:
            protocol: role_assignment
            initial: Lead
            roles: {lead: {inputs: {vx: 0.3, vy: 0.2, omega: -0.3}, period: 0.05}}
      lab:                                      # a unicycle on a circle of radius 0.8
        model: labmate
        plant: {state: {x: -1, y: 0, theta: 0.5}}
        modes:
          T:
            protocol: role_assignment
            initial: Lead
            roles: {lead: {inputs: {v: 0.4, omega: 0.5}, period: 0.05}}
      scout:
        model: scout
        plant: {state: {x: 0, y: -3, theta: 0}}
        modes:
          T:
            protocol: role_assignment
            initial: Follow
            roles: {follow: {law: {use: test.record_leaders, period: 0.05}}}
    simulation: {duration: 3}
    """


def test_a_follower_dead_reckons_holonomic_and_unicycle_leaders_exactly(team_from_yaml):
    SEEN.clear()
    ht.simulate(team_from_yaml(LEADERS))
    assert {s for _, s, _, _ in SEEN} == {0, 1} and len(SEEN) == 2 * 60

    def truth(t: float, sender: int) -> list[float]:
        if sender == 0:  # straight line at the world velocity, turning as it goes
            return [1 + 0.3 * t, 2 + 0.2 * t, 2.0 - 0.3 * t]
        r, th = 0.4 / 0.5, 0.5 + 0.5 * t  # the arc of radius v / omega
        return [-1 + r * (math.sin(th) - math.sin(0.5)), -r * (math.cos(th) - math.cos(0.5)), th]

    worst = max(np.abs(pose - truth(t, s)).max() for t, s, pose, _ in SEEN)
    assert worst < 1e-9
    # the copies really were old (sent a period before, 30 ms on the way): moved 50 ms on
    assert [age for *_, age in SEEN] == pytest.approx([0.05] * len(SEEN))


def test_the_shipped_handover_still_hands_over():
    run = ht.simulate(ht.load(FIXTURES.parent.parent / "examples" / "protocols" / "handover.yaml"))
    t = run.transitions
    leads = [
        (a, cause)
        for a, target, cause in zip(t["agent"], t["target"], t["cause"], strict=True)
        if target.endswith("Lead") and cause != "init"
    ]
    assert leads == [("labmate", "message:grant")]
    # the XR4000 then follows one metre ahead of the Labmate
    xr, lab = run.samples["xr4000"][-1, 0], run.samples["labmate"][-1, 0]
    ahead = (xr[0] - lab[0]) * math.cos(lab[2]) + (xr[1] - lab[1]) * math.sin(lab[2])
    assert ahead == pytest.approx(1.0, abs=0.05)

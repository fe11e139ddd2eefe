"""Same model and seed, same bytes; an ensemble equals its single runs; exact round trips."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.trace import Trace
from tests.conftest import EXAMPLES

N = 64


def test_same_model_and_seed_give_byte_identical_trace(tmp_path):
    team = ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml")
    first = ht.simulate(team, seed=3).to_json()
    again = ht.simulate(ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml"), seed=3).to_json()
    assert first == again
    run = ht.simulate(team, seed=3)
    run.to_json(tmp_path / "trace.json")
    assert (tmp_path / "trace.json").read_text() == first


def test_json_round_trip_is_exact(tmp_path):
    run = ht.simulate(
        ht.load(EXAMPLES / "automata" / "thermostat.yaml"),
        duration=40.0,
        n=3,
        overrides={"thermostat.K": [0.1, 0.12, 0.15]},
    )
    text = run.to_json(tmp_path / "trace.json")
    back = ht.Run.load(tmp_path / "trace.json")
    assert back.to_json() == text
    np.testing.assert_array_equal(back.transitions["t"], run.transitions["t"])
    assert back.outcomes == run.outcomes
    assert isinstance(Trace.load(tmp_path / "trace.json"), Trace)
    doc = json.loads(text)
    assert doc["format"] == "hybridteam.trace" and doc["meta"]["n"] == 3


def _compare(single: ht.Run, member: ht.Run) -> None:
    assert single.outcomes == member.outcomes
    a, b = single.transitions, member.transitions
    assert list(a["target"]) == list(b["target"])
    assert list(a["step"]) == list(b["step"])
    np.testing.assert_allclose(a["t"], b["t"], rtol=0, atol=1e-12)
    for agent in single.samples:
        np.testing.assert_allclose(
            single.samples[agent], member.samples[agent], rtol=0, atol=1e-12, equal_nan=True
        )


def test_ensemble_of_flows_equals_single_runs():
    team = ht.load(EXAMPLES / "automata" / "thermostat.yaml")
    rng = np.random.default_rng(7)
    K = rng.uniform(0.05, 0.3, N)
    high = rng.uniform(21.0, 24.0, N)
    ens = ht.simulate(
        team, n=N, duration=30.0, overrides={"thermostat.K": K, "thermostat.high": high}
    )
    assert len(set(ens.outcomes)) == 1
    for i in range(N):
        single = ht.simulate(
            team, duration=30.0, overrides={"thermostat.K": K[i], "thermostat.high": high[i]}
        )
        _compare(single, ens.instance(i))


def test_ensemble_with_mixed_outcomes_equals_single_runs():
    """Balls with different restitutions reach their Zeno points at different times."""
    team = ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml")
    e = np.linspace(0.3, 0.8, 16)
    h0 = np.linspace(0.2, 1.5, 16)
    ens = ht.simulate(team, n=16, duration=3.0, overrides={"ball.e": e, "ball.h0": h0})
    for i in range(16):
        single = ht.simulate(team, duration=3.0, overrides={"ball.e": e[i], "ball.h0": h0[i]})
        _compare(single, ens.instance(i))
    zeno_t = np.array([d["t"] for d in ens.diagnostics])
    v1 = np.sqrt(2 * 9.81 * h0)
    expected = np.sqrt(2 * h0 / 9.81) + 2 * v1 / 9.81 * e / (1 - e)
    done = expected < 3.0
    assert np.all(np.array(ens.outcomes)[done] == "zeno")
    np.testing.assert_allclose(zeno_t[done], expected[done], atol=1e-6)


def test_ensemble_of_kinematic_agents_equals_single_runs():
    team = ht.load(EXAMPLES / "automata" / "unicycle_square.yaml")
    speeds = np.linspace(0.3, 1.0, N)
    ens = ht.simulate(team, n=N, overrides={"robot.speed": speeds}, duration=40.0)
    for i in range(0, N, 7):
        single = ht.simulate(team, overrides={"robot.speed": speeds[i]}, duration=40.0)
        _compare(single, ens.instance(i))


def test_overrides_are_checked():
    team = ht.load(EXAMPLES / "automata" / "thermostat.yaml")
    with pytest.raises(ValueError, match=r"did you mean 'thermostat\.K'"):
        ht.simulate(team, overrides={"thermostat.k": 0.2})
    with pytest.raises(ValueError, match="expected a number or 4 values"):
        ht.simulate(team, n=4, overrides={"thermostat.K": [0.1, 0.2]})


def test_run_outcome_of_an_ensemble_says_how_to_read_it():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"), n=2)
    with pytest.raises(ValueError, match=r"run\.outcomes"):
        _ = run.outcome
    assert run.outcomes == ["ok", "ok"]
    assert run.instance(1).outcome == "ok"


RING = """
team: ring
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    parameters: {speed: 0.5, turn: 0.2, radius: 3.0}
    initial: Circle
    modes:
      Circle:
        inputs: {v: speed, omega: turn}
        period: 0.1
        transitions:
          - {to: Out, guard: x*x + y*y >= radius*radius}
      Out:
        inputs: {v: 0.2 * speed, omega: 0.0}
        period: 0.1
simulation: {duration: 12.0, sample_period: 0.5}
"""


def test_members_leaving_a_guarded_mode_at_different_times_equal_single_runs(team_from_yaml):
    """Once some members have left the guarded mode, the crossing checks evaluate only the
    members still in it: each member's run is its single run, bit for bit, and leaves the
    ring when the closed-form arc says (chord 2 (v/w) sin(w t / 2) = radius)."""
    team = team_from_yaml(RING)
    speed = np.linspace(0.4, 0.8, 9)
    turn = np.linspace(0.05, 0.25, 9)[::-1]
    ens = ht.simulate(team, n=9, overrides={"robot.speed": speed, "robot.turn": turn})
    left = []
    for i in range(9):
        single = ht.simulate(team, overrides={"robot.speed": speed[i], "robot.turn": turn[i]})
        member = ens.instance(i)
        np.testing.assert_array_equal(single.transitions["t"], member.transitions["t"])
        np.testing.assert_array_equal(single.samples["robot"], member.samples["robot"])
        left.append(member.transitions["t"][-1])
    exact = 2.0 / turn * np.arcsin(3.0 * turn / (2.0 * speed))
    assert len(set(np.round(exact, 1))) == 9  # they leave at nine different times
    np.testing.assert_allclose(left, exact, rtol=0, atol=1e-9)


def test_ensemble_message_table_equals_single_runs():
    """An ensemble records a send's copies as arrays, a single run copy by copy
    (:meth:`Recorder.message_row`): both give the same rows, in the same order, with
    their lost, delivered and acknowledged copies."""
    team = ht.load(EXAMPLES / "protocols" / "handover.yaml")
    loss, jitter = [0.0, 0.3, 0.6], [0.0, 0.01, 0.02]
    ens = ht.simulate(
        team, n=3, seed=[5, 6, 7], overrides={"network.loss": loss, "network.jitter": jitter}
    )
    for i in range(3):
        single = ht.simulate(
            team, seed=5 + i, overrides={"network.loss": loss[i], "network.jitter": jitter[i]}
        )
        mine, theirs = single.messages, ens.instance(i).messages
        lost_on_links = any(str(r).startswith("loss") for r in mine["reason"])
        assert len(mine) > 100 and lost_on_links == (i > 0)
        for name in mine.names:
            assert mine[name].dtype == theirs[name].dtype, name
            np.testing.assert_array_equal(mine[name], theirs[name], err_msg=name)

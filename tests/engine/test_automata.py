"""Classical hybrid automata against their closed-form solutions."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from tests.conftest import EXAMPLES

G, H0, E = 9.81, 1.0, 0.7


def ball_impacts(k: int, h0: float = H0) -> np.ndarray:
    """t1 = sqrt(2 h0 / g); each later flight lasts 2 e^j v1 / g."""
    v1 = math.sqrt(2 * G * h0)
    times = [math.sqrt(2 * h0 / G)]
    for j in range(1, k):
        times.append(times[-1] + 2 * E**j * v1 / G)
    return np.array(times)


def guard_times(run: ht.Run) -> np.ndarray:
    tr = run.transitions
    return tr["t"][tr["cause"] != "init"]


def test_ball_first_twenty_impacts_match_closed_form():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml"))
    times = guard_times(run)
    expected = ball_impacts(20)
    assert expected[0] == pytest.approx(0.451523640986, abs=1e-12)
    assert np.max(np.abs(times[:20] - expected)) < 1e-9


def test_ball_ends_zeno_at_the_zeno_time():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml"))
    zeno_time = 2.558633965586
    v1 = math.sqrt(2 * G * H0)
    assert zeno_time == pytest.approx(math.sqrt(2 * H0 / G) + 2 * v1 / G * E / (1 - E), abs=1e-12)
    assert run.outcome == "zeno"
    assert abs(run.diagnostics[0]["t"] - zeno_time) < 1e-6
    msg = run.message
    assert "'ball'" in msg and "Fall" in msg and "h <= 0 and v < 0" in msg and "t=2.5586" in msg


def thermostat_switches(k: int, K: float = 0.1) -> np.ndarray:
    first = math.log(11 / 8) / K
    down, up = math.log(22 / 18) / K, math.log(12 / 8) / K
    out = [first]
    for j in range(1, k):
        out.append(out[-1] + (down if j % 2 == 1 else up))
    return np.array(out)


def test_thermostat_switch_times_match_closed_form():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat.yaml"))
    times = guard_times(run)
    expected = thermostat_switches(50)
    assert expected[0] == pytest.approx(3.184537311185, abs=1e-11)
    assert expected[49] == pytest.approx(150.6638371, abs=1e-7)
    assert abs(times[0] - expected[0]) < 1e-8
    assert abs(times[49] - expected[49]) < 1e-8
    assert np.max(np.abs(times[:50] - expected)) < 1e-8
    assert run.outcome == "ok"


def test_chattering_thermostat_is_zeno_with_a_named_cause():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat_chatter.yaml"))
    assert run.outcome == "zeno"
    reach = 10 * math.log(11 / 10)  # x: 19 -> 20 under K (30 - x)
    assert abs(run.diagnostics[0]["t"] - reach) < 1e-6
    msg = run.message
    assert "'thermostat'" in msg and "setpoint" in msg and ("Heat" in msg or "Cool" in msg)
    assert "t=0.9531" in msg


def test_water_tanks_switch_times_and_zeno_point():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "water_tanks.yaml"))
    times = guard_times(run)
    # volumes fall at 0.25 in total; each phase empties the other tank: closed form
    np.testing.assert_allclose(times[:6], [2.0, 5.0, 6.5, 7.25, 7.625, 7.8125], atol=1e-9)
    assert run.outcome == "zeno"
    assert abs(run.diagnostics[0]["t"] - 8.0) < 1e-6


def test_unicycle_square_corners_are_exact():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    assert run.outcome == "ok"
    assert "final" in run.message
    tr = run.transitions
    np.testing.assert_allclose(tr["t"], [0, 1, 5, 7, 11, 13, 17, 19, 23, 25], atol=1e-12)
    assert list(tr["target"]) == [
        "Wait",
        "Drive",
        "Turn",
        "Drive",
        "Turn",
        "Drive",
        "Turn",
        "Drive",
        "Turn",
        "Done",
    ]
    t = run.sample_times
    xs = run.samples["robot"][:, 0]
    for when, (x, y, th) in {
        5: (2, 0, 0),
        11: (2, 2, math.pi / 2),
        17: (0, 2, math.pi),
        23: (0, 0, 1.5 * math.pi),
        25: (0, 0, 2 * math.pi),
    }.items():
        k = int(np.argmin(np.abs(t - when)))
        np.testing.assert_allclose(xs[k], [x, y, th], atol=1e-12)


def test_thin_band_crossed_within_one_step_records_both_crossings(team_from_yaml):
    """The band guard is false at both ends of the step that crosses it."""
    team = team_from_yaml("""
        team: band
        agents:
          ball:
            plant: {kind: flow, state: {h: 1.0, v: 0.0}}
            parameters: {g: 9.81}
            initial: Above
            modes:
              Above:
                flow: {h: v, v: -g}
                transitions: [{to: Inside, guard: h < 0.51 and h > 0.49}]
              Inside:
                flow: {h: v, v: -g}
                transitions: [{to: Below, guard: h <= 0.49}]
              Below:
                flow: {h: v, v: -g}
                final: true
        simulation: {duration: 1.0, sample_period: 1.0}
    """)
    run = ht.simulate(team)
    times = guard_times(run)
    assert list(run.transitions["target"][1:]) == ["Inside", "Below"]
    expected = [math.sqrt(2 * 0.49 / 9.81), math.sqrt(2 * 0.51 / 9.81)]
    np.testing.assert_allclose(times, expected, atol=1e-9)
    # the band is 0.02 high: the ball crosses it in ~6 ms, far less than one step here
    assert expected[1] - expected[0] < 0.01


def test_invariant_false_at_start_is_stuck_naming_the_mode(team_from_yaml):
    team = team_from_yaml("""
        team: stuck
        agents:
          tank:
            plant: {kind: flow, state: {x: 1.0}}
            initial: Low
            modes:
              Low:
                flow: {x: -1}
                invariant: x <= 0.5
                transitions: [{to: Empty, guard: x <= 0}]
              Empty: {final: true}
    """)
    run = ht.simulate(team)
    assert run.outcome == "stuck"
    assert run.diagnostics[0]["t"] == 0.0
    assert "'Low'" in run.message and "x <= 0.5" in run.message and "'tank'" in run.message


def test_invariant_boundary_forces_the_exit(team_from_yaml):
    """Leaving on the invariant's boundary: exactly when x reaches 2 (t = 1)."""
    team = team_from_yaml("""
        team: boundary
        agents:
          a:
            plant: {kind: flow, state: {x: 0.0}}
            initial: Grow
            modes:
              Grow:
                flow: {x: 2}
                invariant: x <= 2
                transitions: [{to: Done, guard: x >= 2}]
              Done: {final: true}
    """)
    run = ht.simulate(team)
    assert run.outcome == "ok"
    assert guard_times(run)[0] == pytest.approx(1.0, abs=1e-11)


def test_invariant_crossed_before_any_guard_is_stuck(team_from_yaml):
    team = team_from_yaml("""
        team: boundary
        agents:
          a:
            plant: {kind: flow, state: {x: 0.0}}
            initial: Grow
            modes:
              Grow:
                flow: {x: 2}
                invariant: x <= 2
                transitions: [{to: Done, guard: x >= 3}]
              Done: {final: true}
    """)
    run = ht.simulate(team)
    assert run.outcome == "stuck"
    assert run.diagnostics[0]["t"] == pytest.approx(1.0, abs=1e-11)


def test_a_located_flow_crossing_costs_two_true_steps():
    """Each thermostat switch is located with one true step at the dense-output guess
    (its exponential flow is not followed to a tolerance by the interpolant, so the
    bracket around the dense crossing does not confirm), a Newton correction from there,
    and one step confirming the bracket around it, which is final: the bracket is at most
    event_tol wide also after rounding (the search used to pay a third step to halve a
    bracket 1.0001 event_tol wide)."""
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat.yaml"), duration=151.0)
    switches = guard_times(run)
    assert switches.size == 50
    assert np.max(np.abs(switches - thermostat_switches(50))) < 1e-8
    # 52 crossings located: the 50 guards', and at the first and the last switch the
    # invariant's comparison too (x <= high, x >= low), which flips there within rounding
    assert run.costs.located == 52
    assert run.costs.true_steps == 2 * 52


def test_the_ball_stops_only_at_its_impacts():
    """A flip that does not enable its guard does not stop the run. The apex flips
    ``v < 0`` while ``h <= 0`` is false, and right after a bounce ``h <= 0`` turns false
    while ``v < 0`` is: neither enables ``h <= 0 and v < 0``, though each shares its
    sub-interval of the step with a flip of the other atom, so only the state at the
    located crossing tells. The run stops at the 20 impacts, its start and its end (it
    used to stop three times a bounce). The impacts still match the closed form, which
    also shows that the impact after an apex in the same sub-interval is not missed."""
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.simulator import Simulator

    team = ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml")
    end = float(np.mean(ball_impacts(21)[-2:]))  # between the 20th and 21st impacts
    sim = Simulator(compile_team(team), 1, duration=end, snapshots=True)
    trace = sim.run()
    stops = {float(t) for _, times, _ in sim.ensemble.rec.snapshots for t in times}
    impacts = trace.transitions["t"][trace.transitions["cause"] != "init"]
    assert impacts.size == 20
    assert np.max(np.abs(impacts - ball_impacts(20))) < 1e-9
    assert stops == {0.0, end, *impacts.tolist()}


def test_flips_that_do_not_matter_are_judged_on_the_dense_output():
    """The apex (``v < 0`` flips while ``h <= 0`` is false) shares its sub-interval with
    the impact, so it is searched; its guard is false on the dense output there, as at the
    checkpoints, so it is not located on true steps. The impact is: its flow is a
    polynomial, which the interpolant follows to rounding, so the one true step around
    the dense output's crossing confirms the bracket. One true step per impact, then (the
    search paid two at every apex and two at every impact, 76 in all). The impacts still
    match the closed form."""
    end = float(np.mean(ball_impacts(21)[-2:]))  # between the 20th and 21st impacts
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml"), duration=end)
    impacts = guard_times(run)
    assert impacts.size == 20
    assert np.max(np.abs(impacts - ball_impacts(20))) < 1e-9
    assert run.costs.true_steps == 20


def test_balls_dropped_from_several_heights_equal_single_runs_and_the_closed_form():
    """The search past crossings that do not matter starts each crossing's bracket from
    one place whatever the other instances do, so an ensemble's members equal single runs
    bit for bit; their impacts stay on the closed form (heights give steps of other
    phases, so apexes, bounces and impacts share sub-intervals in other ways)."""
    team = ht.load(EXAMPLES / "automata" / "bouncing_ball.yaml")
    heights = [1.0, 0.37, 2.2, 0.81, 1.5]
    ens = ht.simulate(team, n=len(heights), overrides={"ball.h0": np.array(heights)}, duration=3.0)
    for i, h0 in enumerate(heights):
        one = ht.simulate(team, overrides={"ball.h0": np.array([h0])}, duration=3.0)
        mine = ens.transitions.filter(ens.transitions["instance"] == i)
        np.testing.assert_array_equal(mine["t"], one.transitions["t"])
        times = guard_times(one)
        expected = ball_impacts(min(times.size, 20), h0)
        assert times.size >= 4
        assert np.max(np.abs(times[: expected.size] - expected)) < 1e-9

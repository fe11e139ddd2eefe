"""Readings of the ladder paper's Section 3 (``Settings.correction``, ``Settings.update``):
each against a hand-computed steady state, the stepper against the scalar reference, and
the engine's settings and errors."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hybridteam.modes.ladder import (
    Pairs,
    Robot,
    Scenario,
    Settings,
    random_pairs,
    reference,
    sample_run,
)
from hybridteam.modes.ladder import simulate as kernel

from hybridteam.cli import main

SAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ladder" / "sample.yaml"


def _straight(front_speed: float, rear_speed: float) -> Scenario:
    """A pair on straight guide paths (alpha 0.5 puts the corner points on the centre line,
    so the path runs straight up the first leg), orsp 0, equal springs, ladder 240."""
    robot = Robot(lookahead=16, alpha=0.5, olim=10.0, orsp=0.0, kc=1.0, sc=1.0)
    return Scenario(240.0, replace(robot, v_max=front_speed), replace(robot, v_max=rear_speed))


def _offset_after(scenario: Scenario, settings: Settings, step: int) -> float:
    r = kernel(Pairs.of(scenario), settings=settings, record=True)
    assert r.steps[0] > step
    pos, tips = r.trajectory[step, 0], r.tips[step, 0]
    assert np.all(pos[:, 1] < 900.0)  # both robots still in the straight first leg
    return float(np.hypot(*(tips[0] - pos[0])))


# Steady state of a pair in a straight leg, faster robot in front, rear robot clamped at its
# full speed (its correction points the way it goes). With k = |o| / olim (orsp 0):
#   scaled:   v_f (1 - k) = v_s          ->  |o| = olim (1 - v_s / v_f)
#   distance: v_f - k = v_s              ->  |o| = olim (v_f - v_s)
#   capped:   min(1 - k, v_f) = v_s      ->  |o| = olim (1 - v_s)      (v_s <= 1)
@pytest.mark.parametrize(
    ("correction", "speeds", "offset"),
    [
        ("scaled", (1.0, 0.5), 5.0),
        ("scaled", (1.5, 0.75), 5.0),  # the printed formula depends on the ratio only
        ("distance", (1.0, 0.5), 5.0),
        ("distance", (1.5, 0.75), 7.5),  # ... this reading on the difference
        ("capped", (1.5, 0.75), 2.5),
        ("scaled", (1.0, 1.0), 0.0),
    ],
)
def test_steady_offset_in_a_straight_leg_is_the_hand_computed_one(correction, speeds, offset):
    got = _offset_after(_straight(*speeds), Settings(correction=correction), 350)
    assert got == pytest.approx(offset, abs=0.02)


@pytest.mark.parametrize(("update", "offset"), [("front_first", 5.0), ("rear_first", 5.25)])
def test_sequential_update_steady_offset(update, offset):
    """One robot after the other: the robot that moves second reads the offset the first
    one left. Front first, the front robot reads the step's start, as when synchronous
    (5.0); rear first, it reads the offset less the rear's half step (v_s / 2 = 0.25 less
    than at the step's start), so the start-of-step offset settles 0.25 higher."""
    got = _offset_after(_straight(1.0, 0.5), Settings(update=update), 350)
    assert got == pytest.approx(offset, abs=0.02)


@pytest.mark.parametrize(
    "settings",
    [
        Settings(correction="distance"),
        Settings(correction="capped"),
        Settings(update="front_first"),
        Settings(update="rear_first", correction="distance"),
    ],
)
def test_stepper_equals_the_reference_under_each_reading(settings):
    pairs = random_pairs(np.random.default_rng(7), 6, length=420.0)
    pairs.robot["v_max"][:, :3] = [[1.5] * 3, [0.75] * 3]  # speed differences, both ways
    pairs.robot["v_max"][:, 3:] = [[0.75] * 3, [1.5] * 3]
    batch = kernel(pairs, settings=settings)
    outcomes = set()
    for i in range(pairs.size):
        ref = reference.run(pairs.scenario(i), settings=settings)
        assert ref.outcome[0] == batch.outcome[i]
        assert ref.steps[0] == batch.steps[i]
        assert ref.corner_steps[0] == batch.corner_steps[i]
        np.testing.assert_array_equal(ref.path[0], batch.path[i])
        np.testing.assert_array_equal(ref.max_offset[0], batch.max_offset[i])
        outcomes.add(int(batch.outcome[i]))
    assert len(outcomes) >= 2  # the cases are not all alike


def test_sequential_update_breaks_a_link_between_the_two_moves():
    """A link stretched past its limit by the first robot's move breaks, even when the
    second robot's move would bring it back within the limit by the step's end."""
    # Offsets 9.8, k_c 0.5: the front robot's correction is 0.49, so it steps 1.5 * 0.51
    # forward (offsets +0.3825 -> 10.18 midway); the rear one then steps 1.5 (-0.75 -> 9.43).
    # Synchronous, the offsets only ever see 9.43.
    robot = Robot(lookahead=16, alpha=0.5, olim=10.0, orsp=0.0, kc=0.5, sc=1.0, v_max=1.5)
    scenario = Scenario(240.0, robot, robot)
    start = np.array([[[100.0, 70.0 + 240.0 + 2 * 9.8]], [[100.0, 70.0]]])
    sync = kernel(Pairs.of(scenario), settings=Settings(), start=start, record=True)
    seq = kernel(
        Pairs.of(scenario), settings=Settings(update="front_first"), start=start, record=True
    )
    # Both end the first step at the same state, offsets 9.43 (to 1e-3: the spline toward
    # the corner's exit point bends the path a little, so the target is not quite along it).
    for r in (sync, seq):
        pos, tips = r.trajectory[1, 0], r.tips[1, 0]
        assert np.hypot(*(tips[0] - pos[0])) == pytest.approx(9.8 + 0.3825 - 0.75, abs=1e-3)
    assert sync.steps[0] > 1
    assert seq.outcome_names == ["link_broken"] and seq.steps[0] == 1
    assert seq.max_offset[0].max() == pytest.approx(9.8 + 0.3825, abs=1e-3)


def test_readings_are_checked(tmp_path, capsys):
    with pytest.raises(ValueError, match="unknown correction reading 'scale'"):
        kernel(Pairs.of(_straight(1.0, 1.0)), settings=Settings(correction="scale"))
    text = SAMPLE.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        text.replace("      goal_gap: 70 ", "      update: rear_frist\n      goal_gap: 70 ", 1)
    )
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{bad}:19:") and "with.update: expected one of synchronous" in err
    seq = tmp_path / "seq.yaml"
    seq.write_text(
        text.replace("      goal_gap: 70 ", "      update: rear_first\n      goal_gap: 70 ", 1)
    )
    assert main(["run", str(seq), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{seq}:19:") and "with.update: 'rear_first' moves one robot" in err
    assert "only the vectorized stepper" in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_engine_runs_the_distance_reading_as_the_stepper_does(tmp_path):
    """The sample team with ``correction: distance`` through the engine (the law reads the
    reading from the corridor) gives the stepper's run under the same reading."""
    from hybridteam.api import load, simulate

    team = tmp_path / "distance.yaml"
    team.write_text(
        SAMPLE.read_text().replace(
            "      goal_gap: 70 ", "      correction: distance\n      goal_gap: 70 ", 1
        )
    )
    row = simulate(load(team)).summary()["instances"][0]
    k = kernel(Pairs.of(sample_run()), settings=Settings(correction="distance"))
    printed = kernel(Pairs.of(sample_run()))
    assert row["outcome"] == "success"
    assert row["steps"] == k.steps[0] != printed.steps[0]
    assert row["steps_in_corner"] == k.corner_steps[0]
    np.testing.assert_allclose(row["max_offset"], k.max_offset[0], rtol=1e-9)


def test_an_error_found_when_the_run_starts_is_located(tmp_path, capsys):
    """The corridor finds an unknown robot only when the run starts (agents are known
    then); the message still names the file and the component's line."""
    text = SAMPLE.read_text()
    head, rest = text.split("requirements:", 1)
    bad = tmp_path / "bad.yaml"  # no requirements (they would name R2's offset first)
    bad.write_text(
        head.replace("      rear: R2", "      rear: R3")
        + "simulation:"
        + rest.split("simulation:", 1)[1]
    )
    assert main(["run", str(bad), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{bad}:14:") and "world[0]: ladder.corridor: rear robot 'R3'" in err

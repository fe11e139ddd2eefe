"""Clearances as series (``obstacles`` with ``clearance: true``): what requirements read.

The scene, by hand: a wall along x = 2 (y from -2 to 1); a 0.6 x 0.4 box resting at
(1, 0) turned by 45 degrees, so its rightmost corner is at x = 1 + (0.3 + 0.2) / sqrt 2
and its clearance is 1 - 0.5 / sqrt 2 = 0.646447 throughout; robot A (footprint 0.2)
drives at 0.1 m/s from (0, -1.5) towards the wall, so its clearance is 1.8 - 0.1 t.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.cli import main

SCENE = """\
team: clear
agents:
  A:
    plant: {{kind: holonomic, state: {{x: 0, y: -1.5, theta: 0}}}}
    variables: {{holding: 0}}
    modes:
      Go: {{inputs: {{vx: 0.1, vy: 0, omega: 0}}, period: 0.1}}
world:
  - use: payload
    with:
      name: box
      width: 0.6
      depth: 0.4
      pose: [1.0, 0.0, 0.7853981633974483]
      grasps: [{{agent: A, point: [-0.3, 0], engaged: holding}}]
  - use: obstacles
    with:
      walls: [[2, -2, 2, 1]]
      radius: [[A, 0.2]]
{clearance}
{requirements}
simulation: {{duration: 5, sample_period: 0.5}}
"""

REQUIREMENTS = """\
requirements:
  box_clear: always(payload_clearance.box > 0.6)
  robot_clear: always(robot_clearance.A > 1.5)"""

BOX_GAP = 1.0 - 0.5 / math.sqrt(2.0)


def scene(team_from_yaml, clearance: bool = True, requirements: str = REQUIREMENTS):
    return team_from_yaml(
        SCENE.format(
            clearance="      clearance: true" if clearance else "", requirements=requirements
        )
    )


def test_the_series_are_the_hand_computed_clearances(team_from_yaml):
    run = ht.simulate(scene(team_from_yaml))
    t = run.sample_times
    np.testing.assert_allclose(run.samples["robot_clearance"][:, 0, 0], 1.8 - 0.1 * t, atol=1e-12)
    np.testing.assert_allclose(run.samples["payload_clearance"][:, 0, 0], BOX_GAP, atol=1e-12)
    assert run.meta["series"]["robot_clearance"] == ["A"]
    assert run.meta["series"]["payload_clearance"] == ["box"]


def test_requirements_on_them_hold_or_fail_by_the_hand_computed_margins(team_from_yaml):
    verdicts = ht.simulate(scene(team_from_yaml)).summary()["instances"][0]["requirements"]
    assert verdicts["box_clear"]["satisfied"]
    assert verdicts["box_clear"]["robustness"] == pytest.approx(BOX_GAP - 0.6, abs=1e-12)
    robot = verdicts["robot_clear"]
    assert not robot["satisfied"]
    assert robot["robustness"] == pytest.approx(1.3 - 1.5, abs=1e-12)  # at the end, t = 5
    assert robot["violated_at"] == pytest.approx(3.0, abs=1e-9)  # 1.8 - 0.1 t = 1.5


def test_an_ensemble_instance_equals_its_single_run(team_from_yaml):
    team = scene(team_from_yaml)
    both = ht.simulate(team, n=2)  # arrays, where a single run takes its float paths
    one = ht.simulate(team)
    for key in ("robot_clearance", "payload_clearance"):
        np.testing.assert_array_equal(both.samples[key][:, 1], one.samples[key][:, 0])


def test_without_the_setting_there_is_no_series_and_a_requirement_on_it_is_refused(
    team_from_yaml, tmp_path, capsys
):
    run = ht.simulate(scene(team_from_yaml, clearance=False, requirements=""))
    assert "robot_clearance" not in run.samples and "payload_clearance" not in run.samples
    path = tmp_path / "off.yaml"
    path.write_text(SCENE.format(clearance="", requirements=REQUIREMENTS))
    assert main(["validate", str(path)]) == 2
    assert "unknown signal 'payload_clearance.box'" in capsys.readouterr().err


def test_clearance_with_nothing_to_measure_from_is_a_located_error(tmp_path, capsys):
    path = tmp_path / "empty.yaml"
    path.write_text(
        SCENE.format(clearance="      clearance: true", requirements="").replace(
            "walls: [[2, -2, 2, 1]]", "walls: []"
        )
    )
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        f"{path}:20:18: world[1].with.clearance: there is no wall, circle "
        "or box to measure a clearance from"
    ), err


# ---------------------------------------------------------------------- swept obstacles
SWEPT = SCENE.replace("walls: [[2, -2, 2, 1]]", 'walls: [[wall_x, -2, "wall_x", 1]]').replace(
    "team: clear\n", "team: clear\nparameters: {{wall_x: 2.0}}\n"
)


def test_a_wall_may_be_an_expression_of_team_parameters_and_an_ensemble_sweeps_it(team_from_yaml):
    """Instance k has its wall at x = wall_x[k]: each instance's clearances are the hand
    computed ones for its wall, and equal its single run's bit for bit."""
    team = team_from_yaml(SWEPT.format(clearance="      clearance: true", requirements=""))
    walls = [2.0, 2.5, 2.0]
    run = ht.simulate(team, n=3, overrides={"wall_x": walls})
    t = run.sample_times
    for k, x in enumerate(walls):
        np.testing.assert_allclose(
            run.samples["robot_clearance"][:, k, 0], x - 0.2 - 0.1 * t, atol=1e-12
        )
        np.testing.assert_allclose(
            run.samples["payload_clearance"][:, k, 0], BOX_GAP + (x - 2.0), atol=1e-12
        )
        one = ht.simulate(team, overrides={"wall_x": [x]})
        for key in ("robot_clearance", "payload_clearance", "A", "box"):
            np.testing.assert_array_equal(run.samples[key][:, k], one.samples[key][:, 0])
    assert run.meta["world"]["obstacles"][0]["points"] == [[2.0, -2.0], [2.0, 1.0]]


def test_a_bad_expression_in_a_wall_is_located_where_it_is_written(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(
        SWEPT.format(clearance="", requirements="").replace('"wall_x", 1]]', '"wall_y", 1]]')
    )
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:19:29: world[1].with.walls[0][2]: unknown name 'wall_y'"), err


def test_an_expression_of_a_circle_radius_is_checked_once_it_has_a_value(team_from_yaml):
    text = SWEPT.format(clearance="", requirements="").replace(
        "radius: [[A, 0.2]]", 'radius: [[A, 0.2]]\n      circles: [[5, 5, "wall_x - 2"]]'
    )
    with pytest.raises(ValueError, match=r"circles\[0\]: a circle's radius must be positive"):
        ht.simulate(team_from_yaml(text))


def test_a_study_over_the_wall_tabulates_the_requirements_on_the_series(tmp_path):
    """By hand: the box's clearance is BOX_GAP + (wall_x - 2), the requirement's margin
    that less 0.6."""
    import csv

    (tmp_path / "team.yaml").write_text(
        SWEPT.format(clearance="      clearance: true", requirements=REQUIREMENTS)
    )
    (tmp_path / "study.yaml").write_text(
        "kind: study\nteam: team.yaml\nfactors: {wall_x: [1.9, 2.2]}\n"
    )
    assert (
        main(
            [
                "sweep",
                str(tmp_path / "study.yaml"),
                "-o",
                str(tmp_path / "out"),
                "--progress",
                "none",
            ]
        )
        == 0
    )
    with open(tmp_path / "out" / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["box_clear_satisfied"]) for r in rows] == [0.0, 1.0]
    for row, x in zip(rows, (1.9, 2.2), strict=True):
        assert float(row["box_clear_min_robustness"]) == pytest.approx(
            BOX_GAP + (x - 2.0) - 0.6, abs=1e-12
        )


# ---------------------------------------------------------------------- measured once
def test_an_instant_measures_the_payload_gap_once(team_from_yaml):
    """The series sampled at an instant are the gaps its update measured (issue 48: the
    doorway team measured every payload gap twice an instant); the numbers stay the
    hand-computed ones. The work is read off the components' public counters."""
    from hybridteam.api import Run
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.simulator import Simulator
    from hybridteam.world.carried import CarriedPayload
    from hybridteam.world.obstacles import Obstacles

    sim = Simulator(compile_team(scene(team_from_yaml)), 1)
    run = Run.of(sim.run())
    components = sim.ensemble.world.components
    (obstacles,) = [c for c in components if isinstance(c, Obstacles)]
    (box,) = [c for c in components if isinstance(c, CarriedPayload)]
    assert obstacles.work.updates > 50 and box.work.gaps == obstacles.work.updates
    np.testing.assert_allclose(run.samples["payload_clearance"][:, 0, 0], BOX_GAP, atol=1e-12)


def test_a_reset_between_the_update_and_the_sample_is_measured_afresh(team_from_yaml):
    """At t = 1 a transition puts robot A at x = 1 (a reset, after the components ran):
    the series at that instant read its new clearance, 2 - 1 - 0.2 = 0.8 (it stands still
    from then on), so a requirement of more than 0.9 fails by 0.1, at the crossing of the
    line between the instants t = 0.9 (1.8 - 0.09 = 1.71) and t = 1 (0.8). Had the sample
    at t = 1 kept the update's 1.7, the crossing would lie between t = 1 and the next
    instant, t = 1.1."""
    text = SCENE.format(
        clearance="      clearance: true",
        requirements="""\
requirements:
  robot_clear: always(robot_clearance.A > 0.9)""",
    ).replace(
        "    modes:\n      Go: {{inputs: {{vx: 0.1, vy: 0, omega: 0}}, period: 0.1}}".format(),
        "    initial: Go\n    modes:\n      Go: {inputs: {vx: 0.1, vy: 0, omega: 0}, period: 0.1,\n"
        "           transitions: [{to: Stay, after: 1.0, do: [x = 1.0]}]}\n"
        "      Stay: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}",
    )
    verdict = ht.simulate(team_from_yaml(text)).summary()["instances"][0]["requirements"][
        "robot_clear"
    ]
    assert not verdict["satisfied"]
    assert verdict["violated_at"] == pytest.approx(
        0.9 + 0.1 * (1.71 - 0.9) / (1.71 - 0.8), abs=1e-9
    )
    assert verdict["robustness"] == pytest.approx(0.8 - 0.9, abs=1e-12)

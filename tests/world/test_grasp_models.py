"""A robot whose model has no manipulator (a Scout) must say how it holds a payload.

Before, its grasp silently took the free defaults (at its centre, spring 1, no limit), so
a beam it carried could never drop and ``validate`` said ok. Now the grasp is refused,
located at its line, unless it gives ``spring`` and ``limit`` or the robot is given a
manipulator (with its ``kind``, as a new sensor needs one).
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.io.loader import InputErrors

BEAM = """\
team: beam
agents:
  xr4000:
    model: xr4000
    plant: {{state: {{x: 1.45, y: 0, theta: 3.141592653589793}}}}
    modes:
      Hold: {{inputs: {{vx: 0, vy: 0, omega: 0}}, period: 0.1}}
  scout:
    model: scout
    plant: {{state: {{x: -1.0, y: 0, theta: 0}}}}
    {scout_extra}
    modes:
      Back: {{inputs: {{v: -0.08, omega: 0}}, period: 0.1}}
world:
  - use: payload
    with:
      name: beam
      shape: bar
      length: 2.0
      grasps:
        - {{agent: xr4000, point: [1.0, 0]}}
        - {{agent: scout, point: [-1.0, 0]{scout_grasp}}}
simulation: {{duration: 3}}
"""


def write(tmp_path, scout_extra: str = "", scout_grasp: str = ""):
    path = tmp_path / "beam.yaml"
    path.write_text(BEAM.format(scout_extra=scout_extra, scout_grasp=scout_grasp))
    return path


def test_a_scout_grasp_without_spring_and_limit_is_a_located_error(tmp_path, capsys):
    path = write(tmp_path)
    assert main(["validate", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    # line 22 holds the Scout's grasp, column 11 its mapping
    assert err.startswith(
        f"{path}:22:11: world[0].with.grasps[1]: robot 'scout' has no "
        "manipulator in its model to take the grasp's spring and limit "
        "from; give them in the grasp"
    ), err
    assert "manipulator: {kind: spring_link" in err


def test_a_scout_grasp_missing_only_the_limit_names_the_limit(tmp_path):
    with pytest.raises(InputErrors, match="to take the grasp's limit from"):
        ht.load(write(tmp_path, scout_grasp=", spring: 300"))


def test_a_scout_grasp_with_spring_and_limit_holds_and_breaks_at_its_limit(tmp_path):
    """The XR4000's forks (mount 0.45 ahead, spring 5000) hold the front end at x = 1.0;
    the Scout's grasp (at its centre, spring 5000, limit 0.05) the back end at -1.0. The
    Scout backs off at 0.08 m/s, so the bar is stretched by 0.08 t and the equal springs
    share it: the Scout's offset is 0.04 t, past 0.05 after 1.25 s, seen at the 1.3 s
    tick."""
    team = ht.load(write(tmp_path, scout_grasp=", spring: 5000, limit: 0.05"))
    run = ht.simulate(team)
    (o,) = run._outcomes
    assert o["outcome"] == "link_broken" and abs(o["t"] - 1.3) < 1e-9
    assert "the grasp of 'scout' is offset" in o["message"]
    grasp = run.samples["beam_grasp"][:, 0]
    t = run.sample_times
    ok = (t <= 1.2) & ~np.isnan(grasp[:, 1])
    np.testing.assert_allclose(grasp[ok, 1], 0.04 * t[ok], atol=1e-9)


def test_a_scout_given_a_manipulator_lends_it_to_the_grasp(tmp_path):
    extra = "manipulator: {kind: spring_link, spring: 5000, limit: 0.05}"
    team = ht.load(write(tmp_path, scout_extra=extra))
    assert team.agent("scout").preset.manipulator.limit == 0.05
    (o,) = ht.simulate(team)._outcomes
    assert o["outcome"] == "link_broken" and abs(o["t"] - 1.3) < 1e-9


def test_a_manipulator_override_without_kind_on_a_scout_says_a_new_one_needs_it(tmp_path, capsys):
    path = write(
        tmp_path, scout_extra="manipulator: {spring: 3}", scout_grasp=", spring: 1, limit: 1"
    )
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        f"{path}:11:5: agents.scout.manipulator: scout has no manipulator; "
        "a new one needs its 'kind'"
    ), err


def test_a_robot_without_a_model_keeps_the_free_grasp(team_from_yaml):
    """A plain plant claims no hardware: its grasp defaults to the idealized hold."""
    team = team_from_yaml("""\
        team: plain
        agents:
          A:
            plant: {kind: holonomic, state: {x: 1, y: 0, theta: 0}}
            modes: {Hold: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
        world:
          - use: payload
            with: {shape: bar, length: 2, grasps: [{agent: A, point: [1, 0]}]}
        simulation: {duration: 0.2}
        """)
    assert ht.simulate(team).outcomes == ["ok"]

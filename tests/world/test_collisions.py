"""Collisions (issue 16, item 5): an overlap with a wall, an obstacle or another robot ends
the run with outcome ``collision`` (or is listed, or ignored, as ``on_collision`` says).

Hand-timed cases: robots at 1 m/s under a 0.1 s law, so positions at the ticks are exact.
"""

from __future__ import annotations

import pytest

import hybridteam as ht

TEAM = """
team: crash
agents:
  a:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0}}, period: 0.1}}}}
  b:
    plant: {{kind: unicycle, state: {{x: 3.0, y: {b_y}, theta: 3.141592653589793}}}}
    modes: {{Go: {{inputs: {{v: 1.0, omega: 0}}, period: 0.1}}}}
world:
  - use: obstacles
    with:
      walls: {walls}
      radius: [[a, 0.25], [b, 0.25]]
      on_collision: {mode}
simulation: {{duration: 4.0}}
"""


def team(
    team_from_yaml, mode: str = "outcome", b_y: float = 5.0, walls: str = "[[2.0, -1.0, 2.0, 1.0]]"
):
    return team_from_yaml(TEAM.format(mode=mode, b_y=b_y, walls=walls))


def test_robots_that_meet_collide(team_from_yaml):
    """Head on, closing at 2 m/s from 3 m apart: the 0.25 m disks touch at t = 1.25 s,
    between two ticks (the swept pair test); the first tick after, t = 1.3 s, sees them
    overlapping by 0.1 m."""
    run = ht.simulate(team(team_from_yaml, b_y=0.0, walls="[]"))
    assert run.outcome == "collision"
    assert run.diagnostics[0]["t"] == pytest.approx(1.3, abs=1e-12)
    assert run.message.startswith(
        "robots 'a' and 'b' collided (their footprints overlapping by up to 0.1 by the tick "
        "at t=1.3), first touching at t="
    )
    assert float(run.message.rsplit("at t=", 1)[1]) == pytest.approx(1.25, abs=1e-12)


def test_a_robot_that_drives_into_a_wall_collides(team_from_yaml):
    """Robot b is kept out of the way (y = 5); robot a's disk reaches the wall at x = 2
    when x = 1.75: it first touches it at t = 1.75 s, between its ticks (the swept test),
    and is seen at the tick t = 1.8 s, overlapping it by 0.05 m."""
    run = ht.simulate(team(team_from_yaml))
    assert run.outcome == "collision"
    assert run.diagnostics[0]["t"] == pytest.approx(1.8, abs=1e-12)
    prefix = "robot 'a' hit walls[0] (its footprint overlapping it by up to 0.05 by its tick at t="
    assert run.message.startswith(prefix)
    assert run.message.endswith("), first touching it at t=1.75")


def test_warn_lists_collisions_and_ignore_keeps_only_clearances(team_from_yaml):
    warned = ht.simulate(team(team_from_yaml, "warn"))
    assert warned.outcome == "ok" and warned.diagnostics[0]["t"] == 4.0
    (first,) = warned.diagnostics[0]["stats"]["collisions"]
    assert first.startswith("robot 'a' hit walls[0]") and first.endswith("at t=1.75")
    ignored = ht.simulate(team(team_from_yaml, "ignore"))
    assert ignored.outcome == "ok"
    assert "collisions" not in ignored.diagnostics[0]["stats"]
    assert ignored.diagnostics[0]["stats"]["min_clearance"][0] < 0  # it went through


def test_where_and_when_each_first_collision_was_is_kept_for_the_views(team_from_yaml):
    """Robot a's disk first touches the wall at t = 1.75 s, its centre at (1.75, 0)
    (between its ticks 1.7 and 1.8): recorded under warn and under outcome, not under
    ignore."""
    for mode in ("warn", "outcome"):
        (mark,) = ht.simulate(team(team_from_yaml, mode)).meta["world"]["collisions"]
        assert mark == {
            "instance": 0,
            "who": "a",
            "t": pytest.approx(1.75, abs=1e-12),
            "x": pytest.approx(1.75, abs=1e-12),
            "y": 0.0,
        }
    assert "collisions" not in ht.simulate(team(team_from_yaml, "ignore")).meta["world"]


def test_an_unknown_collision_mode_is_a_located_error(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(
        InputErrors,
        match=r"world\[0\].with.on_collision: expected one of "
        r"outcome, warn, ignore, got 'stopp'",
    ):
        team(team_from_yaml, "stopp")


def test_the_terminal_says_none_where_a_warned_run_had_no_collision(tmp_path, monkeypatch, capsys):
    """Under ``on_collision: warn`` the summary line ended in a bare 'collisions ' when
    nothing was hit; it says 'collisions none'."""
    from hybridteam.cli import main

    (tmp_path / "team.yaml").write_text("""\
team: clear
agents:
  r:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
world:
  - use: obstacles
    with: {walls: [[5, -1, 5, 1]], radius: [[r, 0.2]], on_collision: warn}
simulation: {duration: 2.0}
""")
    monkeypatch.chdir(tmp_path)
    assert main(["run", "team.yaml", "-o", "out", "--no-views"]) == 0
    assert "      min_clearance 3.8, collisions none\n" in capsys.readouterr().out


def test_the_message_prints_the_tick_as_a_time(team_from_yaml):
    """Robot a reaches the wall at x = 3 when x = 2.75: it first touches it at t = 2.75 s,
    and the tick that sees it is the 28th of 0.1 s, which the run's time holds as
    2.8000000000000003: the message says t=2.8."""
    run = ht.simulate(team(team_from_yaml, walls="[[3.0, -1.0, 3.0, 1.0]]"))
    assert run.outcome == "collision"
    assert "by its tick at t=2.8)" in run.message, run.message
    assert run.message.endswith("), first touching it at t=2.75")

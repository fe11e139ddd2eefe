"""The engine's plant seam (engine/run/plant.py), without ROS or the wall clock: a scripted
robot that ignores its commands and moves at 0.3 m/s, where the model says 0.5 m/s, so
every time and pose is known by hand and differs from what integrating the model gives.
Also the team file's deploy: section as the model reads it, and what ``hybridteam live
--plant ros2`` refuses before any ROS (the run against a robot: test_live_robot.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator

TEAM = Path(__file__).parent / "fixtures" / "live" / "drive.yaml"
SPEED = 0.3  # the scripted robot's, m/s (the model commands 0.5)


class ScriptedRobot:
    """A plant that records its commands and is at ``(SPEED t, 0, 0)`` at run time t."""

    def __init__(self) -> None:
        self.commands: list[tuple[float, list[float]]] = []

    def command(self, inputs: np.ndarray, t: float) -> None:
        self.commands.append((t, inputs.tolist()))

    def state(self, t: float) -> np.ndarray:
        return np.array([SPEED * t, 0.0, 0.0])


def stops(trace) -> list[tuple[float, str]]:
    return [(float(t), s) for t, s in zip(trace.transitions["t"], trace.transitions["target"],
                                          strict=True)]


def test_the_integrated_plant_is_the_default():
    """Without plants the engine integrates: x = 0.5 t reaches 1 at t = 2, located."""
    trace = Simulator(compile_team(ht.load(TEAM)), 1).run()
    assert stops(trace) == [(0.0, "Forward"), (2.0, "Stopped")]


def test_an_external_plant_is_commanded_and_read_and_its_guard_sampled():
    """The robot's x = 0.3 t passes 1 at t = 10/3, between the control ticks 3.3 and 3.4
    (the output samples, every 0.25 s, are instants too: 3.25, 3.5): the guard, sampled,
    fires at 3.4, not at 10/3 (no zero-crossing to locate) nor at 2.0 (the model's
    arc). Every instant commands the held inputs, 0.5 m/s until the stop's zero; the
    trace's samples are the robot's poses, 0.3 t, not the model's 0.5 t."""
    robot = ScriptedRobot()
    trace = Simulator(compile_team(ht.load(TEAM)), 1, plants={0: robot}).run()
    (t0, first), (t1, last) = stops(trace)
    assert (t0, first, last) == (0.0, "Forward", "Stopped")
    assert t1 == pytest.approx(3.4, abs=1e-12)
    assert trace.outcomes[0]["outcome"] == "ok"
    times = [t for t, _ in robot.commands]
    ticks = [0.1 * k for k in range(35)]
    for tick in ticks:  # a command at every control tick up to the stop
        assert min(abs(t - tick) for t in times) < 1e-12
    assert all(u == [0.5, 0.0] for t, u in robot.commands[:-1])
    assert robot.commands[-1][1] == [0.0, 0.0]
    assert robot.commands[-1][0] == pytest.approx(3.4, abs=1e-12)
    sampled = trace.sample_times <= t1
    x = trace.samples["robot"][sampled, 0, 0]
    assert trace.sample_times[sampled].tolist() == [0.25 * k for k in range(14)]
    np.testing.assert_allclose(x, SPEED * trace.sample_times[sampled], rtol=0, atol=1e-12)


def test_the_robot_starts_where_it_is():
    """The initial state is the plant's reading, not the file's (x = 0): a robot already
    at x = 1.2 stops at the first instant, t = 0."""

    class Ahead(ScriptedRobot):
        def state(self, t: float) -> np.ndarray:
            return np.array([1.2, 0.0, 0.0])

    trace = Simulator(compile_team(ht.load(TEAM)), 1, plants={0: Ahead()}).run()
    assert stops(trace)[-1] == (0.0, "Stopped")


def test_external_plants_drive_one_run_with_held_inputs(team_from_yaml):
    cteam = compile_team(ht.load(TEAM))
    with pytest.raises(ValueError, match="single run"):
        Simulator(cteam, 2, plants={0: ScriptedRobot()})
    flow = team_from_yaml("""\
        team: f
        agents:
          b:
            plant: {kind: flow, state: {h: 1.0}}
            modes:
              Fall: {flow: {h: -1}}
        """)
    with pytest.raises(ValueError, match="held inputs"):
        Simulator(compile_team(flow), 1, plants={0: ScriptedRobot()})


def test_the_deploy_section_is_read_and_simulation_ignores_it(team_from_yaml):
    """The fixture's deploy: entry is the robot's settings (defaults filled in); the same
    team without it simulates to the same trace."""
    from hybridteam.model.deploy import PlantDeploy

    team = ht.load(TEAM)
    assert team.deploy == {"robot": PlantDeploy("/drive/robot/cmd_vel", "/drive/robot/odom",
                                                None, "odom", 2.0)}
    text = TEAM.read_text()
    bare = team_from_yaml(text[:text.index("\ndeploy:")])
    assert bare.deploy == {}
    with_deploy = Simulator(compile_team(team), 1).run()
    without = Simulator(compile_team(bare), 1).run()
    assert with_deploy.samples["robot"].tobytes() == without.samples["robot"].tobytes()
    assert stops(with_deploy) == stops(without)


@pytest.mark.parametrize(("deploy", "args", "message"), [
    (False, [], "--plant ros2: agent 'robot' has no entry in the team file's deploy: "
                "section (its robot's cmd_vel and odom topics)"),
    (True, ["--time-scale", "2"], "--plant ros2: a robot moves on the wall clock; "
                                  "--time-scale must be 1, got 2"),
    (True, [], "--plant ros2: the ros2 transport and plant need rclpy: "
               "pip install 'hybridteam[ros]'"),
])
def test_plant_ros2_refusals_are_one_line(tmp_path, capsys, monkeypatch, deploy, args,
                                          message):
    """Each before any run or file: one line, exit 2 (rclpy made unimportable here, so
    the last holds wherever the test runs)."""
    import sys

    from hybridteam.cli import main

    monkeypatch.setitem(sys.modules, "rclpy", None)
    text = TEAM.read_text()
    team = tmp_path / "drive.yaml"
    team.write_text(text if deploy else text[:text.index("\ndeploy:")] + "\n")
    out = tmp_path / "out"
    status = main(["live", str(team), "--agent", "robot", "--plant", "ros2", "--listen",
                   "127.0.0.1:0", "-o", str(out), *args])
    assert status == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"hybridteam: error: {message}"]
    assert not out.exists()


def test_a_holonomic_agent_is_not_driven_as_a_twist(tmp_path, capsys):
    """Its (vx, vy) are world-frame, a Twist's body-frame: refused, before any ROS."""
    from hybridteam.cli import main

    text = TEAM.read_text().replace("kind: unicycle", "kind: holonomic").replace(
        "{v: 0.5, omega: 0}", "{vx: 0.5, vy: 0, omega: 0}").replace(
        "{v: 0, omega: 0}", "{vx: 0, vy: 0, omega: 0}")
    team = tmp_path / "omni.yaml"
    team.write_text(text)
    status = main(["live", str(team), "--agent", "robot", "--plant", "ros2", "--listen",
                   "127.0.0.1:0", "-o", str(tmp_path / "out")])
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has a holonomic plant; a robot over ROS 2 drives a unicycle" \
        in err[0], err

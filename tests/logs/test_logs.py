"""Robot logs in and out (issue 45): rosbag2 export and import, requirements on logs.

Precision of a round trip: modes, transitions, stays, messages, the run's header and
outcome exactly (their JSON carries the trace's floats); sample values exactly (``/A/state``
is float64); sample times to the bag's stamps, 1 ns.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the logs commands need rosbags (hybridteam[logs])")

from rosbags.rosbag2 import Reader, Writer
from rosbags.typesys import Stores, get_typestore

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.cli.common import load_trace
from hybridteam.kinds import load_any

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
EXPERIMENT2 = EXAMPLES / "transport" / "experiment2.yaml"
TS = get_typestore(Stores.ROS2_HUMBLE)
T = TS.types


def _example_teams() -> list[Path]:
    """Every example that is a team file and loads here (the extending example's library
    is a package of its own, installed by its own test)."""
    out = []
    for path in sorted(EXAMPLES.rglob("*.yaml")):
        if "extending" in path.parts:
            continue
        try:
            loaded = load_any(str(path))
        except Exception:
            continue
        if loaded.kind == "team":
            out.append(path)
    return out


TEAMS = _example_teams()


def test_the_examples_are_found():
    assert len(TEAMS) >= 13, TEAMS  # automata, doorway, ladder sample, protocols, transport


@pytest.mark.parametrize("path", TEAMS, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_every_example_round_trips(path, tmp_path):
    team = ht.load(path)
    run = ht.simulate(team, duration=min(2.0, team.simulation.duration))
    bag = run.to_bag(tmp_path / "run.mcap")
    back = ht.Run.from_bag(bag, team)
    a, b = run.to_dict(), back.to_dict()
    for key in ("meta", "outcomes", "transitions", "intervals", "messages"):
        assert b[key] == a[key], key
    assert len(back.sample_times) == len(run.sample_times)
    assert np.max(np.abs(back.sample_times - run.sample_times)) <= 1e-9
    assert set(back.samples) == set(run.samples)
    for key, values in run.samples.items():
        assert np.array_equal(back.samples[key], values, equal_nan=True), key


@pytest.mark.parametrize("name", ["run.db3", "bagdir"])
def test_sqlite_and_folder_bags_round_trip(name, tmp_path):
    team = ht.load(EXPERIMENT2)
    run = ht.simulate(team, duration=1.0)
    back = ht.Run.from_bag(run.to_bag(tmp_path / name), team)
    assert back.to_dict()["messages"] == run.to_dict()["messages"]
    assert np.array_equal(back.samples["labmate"], run.samples["labmate"])
    if name == "bagdir":
        assert (tmp_path / name / "metadata.yaml").is_file()


@pytest.mark.parametrize("name", ["run.mcap", "run.db3"])
def test_export_is_deterministic(name, tmp_path):
    """The same run written twice under one name gives the same bytes (the file records
    its own name, and nothing of the wall clock)."""
    run = ht.simulate(ht.load(EXPERIMENT2), duration=0.5)
    first = run.to_bag(tmp_path / name).read_bytes()
    assert run.to_bag(tmp_path / name).read_bytes() == first


def test_one_instance_of_an_ensemble(tmp_path):
    team = ht.load(EXAMPLES / "automata" / "thermostat.yaml")
    run = ht.simulate(team, n=3, duration=2.0, seed=[1, 2, 3])
    back = ht.Run.from_bag(run.to_bag(tmp_path / "i1.mcap", instance=1), team)
    one = run.instance(1)
    assert back.meta["seed"] == 2
    for key in ("meta", "outcomes", "transitions", "intervals", "messages"):
        assert back.to_dict()[key] == one.to_dict()[key], key
    assert np.array_equal(back.samples["thermostat"], one.samples["thermostat"])


def test_experiment2_bag_has_the_documented_topics_and_values(tmp_path):
    team = ht.load(EXPERIMENT2)
    run = ht.simulate(team, duration=2.0)
    path = run.to_bag(tmp_path / "e2.mcap")
    with Reader(path) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        raw = {}
        for conn, ns, data in reader.messages():
            raw.setdefault(conn.topic, []).append((ns, TS.deserialize_cdr(data, conn.msgtype)))
    expected = {
        "/hybridteam/run": "std_msgs/msg/String",
        "/clock": "rosgraph_msgs/msg/Clock",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/payloads/box/pose": "geometry_msgs/msg/PoseStamped",
        "/hybridteam/series/box": "std_msgs/msg/Float64MultiArray",
        "/hybridteam/series/box_grasp": "std_msgs/msg/Float64MultiArray",
    }
    for robot in ("labmate", "xr4000"):
        expected |= {
            f"/{robot}/state": "std_msgs/msg/Float64MultiArray",
            f"/{robot}/pose": "geometry_msgs/msg/PoseStamped",
            f"/{robot}/odom": "nav_msgs/msg/Odometry",
            f"/{robot}/mode": "std_msgs/msg/String",
            f"/{robot}/stays": "std_msgs/msg/String",
            f"/{robot}/messages": "std_msgs/msg/String",
        }
    # the operator has no state and sends nothing in 2 s: its modes only
    expected |= {"/operator/mode": "std_msgs/msg/String", "/operator/stays": "std_msgs/msg/String"}
    assert topics == expected
    # the labmate's first pose is the team file's initial pose, (-0.03, 0.02, 0.04) ...
    ns, first = raw["/labmate/pose"][0]
    assert ns == 0 and first.header.stamp.sec == 0 and first.header.frame_id == "map"
    assert (first.pose.position.x, first.pose.position.y) == (-0.03, 0.02)
    assert (first.pose.orientation.z, first.pose.orientation.w) == (math.sin(0.02), math.cos(0.02))
    # ... and at t = 1 s (sample 20 at 0.05 s) the pose is the trace's, its yaw theta
    ns, pose = raw["/labmate/pose"][20]
    x, y, th = run.samples["labmate"][20, 0].tolist()
    assert ns == 1_000_000_000 and (pose.header.stamp.sec, pose.header.stamp.nanosec) == (1, 0)
    assert (pose.pose.position.x, pose.pose.position.y) == (x, y)
    q = pose.pose.orientation
    assert (q.z, q.w) == (math.sin(th / 2), math.cos(th / 2))
    _, odom = raw["/labmate/odom"][20]
    assert odom.child_frame_id == "labmate/base_link"
    assert odom.pose.pose.position.x == x
    # the odometry's velocity: the difference to the next sample, in the body frame
    x1, y1, _ = run.samples["labmate"][21, 0].tolist()
    forward = (math.cos(th) * (x1 - x) + math.sin(th) * (y1 - y)) / 0.05
    assert odom.twist.twist.linear.x == pytest.approx(forward, rel=1e-12, abs=1e-12)
    _, tf = raw["/tf"][20]
    frames = {(t.header.frame_id, t.child_frame_id) for t in tf.transforms}
    assert frames == {("map", "labmate/base_link"), ("map", "xr4000/base_link"), ("map", "box")}
    # the first team message the xr4000 sent, as the trace has it
    first_sent = next(r for r in run.messages if r.sender == "xr4000")
    import json

    data = json.loads(raw["/xr4000/messages"][0][1].data)
    assert (data["receiver"], data["type"], data["t_send"], data["t_recv"]) == (
        first_sent.receiver,
        first_sent.type,
        first_sent.t_send,
        first_sent.t_recv,
    )


# ---------------------------------------------------------------------- a robot's log
SQUARE_TEAM = """\
team: square-log
agents:
  robot:
    plant:
      kind: unicycle
      state: {x: 0.0, y: 0.0, theta: 0.0}
    initial: Drive
    modes:
      Drive:
        inputs: {v: 0.5, omega: 0}
        transitions:
          - {to: Turn, after: 2.0}
      Turn:
        inputs: {v: 0, omega: 1.5707963267948966}
        transitions:
          - {to: Drive, after: 1.0}
requirements:
  inside: always(x <= 1.0)
  margin: always(x >= -0.1)
  short: always(x <= 0.9)
simulation:
  duration: 12.0
"""

MAPPING = """\
agents:
  robot:
    pose: /amcl_pose
    cmd: /cmd_vel
    modes: /fsm
"""

#: the log's wall-clock start (a robot's stamps are wall time): t = 0 there
START_NS = 1_700_000_000 * 1_000_000_000
DIRS = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
CORNERS = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0)]


def square_pose(k: int) -> tuple[float, float, float, float, float]:
    """The unicycle at t = k / 10 s driving a 1 m square: each side 2 s at 0.5 m/s, then a
    quarter turn in place in 1 s at pi/2 rad/s. Returns (x, y, theta, v, omega)."""
    t = k / 10
    side = min(int(t // 3), 3)
    tau = t - 3 * side
    if tau < 2.0:
        c, d, s = CORNERS[side], DIRS[side], 0.5 * tau
        return c[0] + s * d[0], c[1] + s * d[1], side * math.pi / 2, 0.5, 0.0
    c = CORNERS[side + 1]
    return c[0], c[1], side * math.pi / 2 + math.pi / 2 * (tau - 2.0), 0.0, math.pi / 2


#: the mode the robot logs at each change: Drive at 0, 3, 6, 9 s, Turn at 2, 5, 8, 11 s
CHANGES = {30 * i: "Drive" for i in range(4)} | {30 * i + 20: "Turn" for i in range(4)}


def write_square_bag(
    path: Path,
    pose_topic: str = "/amcl_pose",
    swap: int | None = None,
    modes_topic: str = "/fsm",
    changes: dict[int, str] = CHANGES,
) -> Path:
    """A hand-made log: poses (header stamps) and commands at 10 Hz for 12 s, the mode at
    each change; ``swap``: two poses' header stamps out of order (the bag's own receive
    stamps stay in order, as a recorder's do)."""
    received = [START_NS + k * 100_000_000 for k in range(121)]
    stamps = list(received)
    if swap is not None:
        stamps[swap], stamps[swap + 1] = stamps[swap + 1], stamps[swap]
    with Writer(path, version=9) as w:
        pose_c = w.add_connection(pose_topic, "geometry_msgs/msg/PoseStamped", typestore=TS)
        cmd_c = w.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=TS)
        mode_c = w.add_connection(modes_topic, "std_msgs/msg/String", typestore=TS)
        for k, ns in enumerate(received):
            x, y, th, v, om = square_pose(k)
            if k in changes:
                w.write(
                    mode_c,
                    ns,
                    TS.serialize_cdr(
                        T["std_msgs/msg/String"](data=changes[k]), "std_msgs/msg/String"
                    ),
                )
            sec, nsec = divmod(stamps[k], 1_000_000_000)
            msg = T["geometry_msgs/msg/PoseStamped"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="odom"
                ),
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                    orientation=T["geometry_msgs/msg/Quaternion"](
                        x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)
                    ),
                ),
            )
            w.write(pose_c, ns, TS.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
            twist = T["geometry_msgs/msg/Twist"](
                linear=T["geometry_msgs/msg/Vector3"](x=v, y=0.0, z=0.0),
                angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=om),
            )
            w.write(cmd_c, ns, TS.serialize_cdr(twist, "geometry_msgs/msg/Twist"))
    return path


@pytest.fixture
def square(tmp_path):
    team_file = tmp_path / "square.yaml"
    team_file.write_text(SQUARE_TEAM)
    mapping = tmp_path / "map.yaml"
    mapping.write_text(MAPPING)
    return team_file, mapping, write_square_bag(tmp_path / "square_bag")


def test_a_hand_made_log_imports_as_samples_modes_and_commands(square):
    team_file, mapping, bag = square
    run = ht.Run.from_bag(bag, ht.load(team_file), mapping)
    assert run.sample_times.tolist() == [k / 10 for k in range(121)]  # t = 0 at the start
    x, y, th = run.samples["robot"][:, 0, :].T
    assert x.tolist() == [square_pose(k)[0] for k in range(121)]
    assert y.tolist() == [square_pose(k)[1] for k in range(121)]
    # the yaw turns on past pi: unwrapped, the heading ends a full turn round
    assert th[-1] == pytest.approx(2 * math.pi, abs=1e-12)
    assert np.all(np.diff(th) >= -1e-12)
    cmd = run.samples["robot.cmd"][:, 0, :]
    assert cmd[5].tolist() == [0.5, 0.0] and cmd[25].tolist() == [0.0, math.pi / 2]
    tr = run.transitions
    assert tr["t"].tolist() == [0.0, 2.0, 3.0, 5.0, 6.0, 8.0, 9.0, 11.0]
    assert tr["target"].tolist() == ["Drive", "Turn"] * 4
    stays = run.intervals
    assert [(r.mode, r.start, r.end) for r in stays][:3] == [
        ("Drive", 0.0, 2.0),
        ("Turn", 2.0, 3.0),
        ("Drive", 3.0, 5.0),
    ]
    assert (stays["mode"][-1], stays["end"][-1]) == ("Turn", 12.0)
    # an imported log exported and imported again is the same trace, commands included
    team = ht.load(team_file)
    again = ht.Run.from_bag(run.to_bag(bag.parent / "again.mcap"), team)
    assert again.to_dict() == run.to_dict()


DEPLOY = """\
deploy:
  robot: {cmd_vel: /scout1/cmd_vel, odom: /scout1/odom}
"""


def write_deployed_bag(path: Path) -> Path:
    """The square driven by a robot whose driver publishes where the team's ``deploy:``
    says: ``Odometry`` on /scout1/odom and ``Twist`` on /scout1/cmd_vel, at 10 Hz; the
    mode changes on export's /robot/mode."""
    with Writer(path, version=9) as w:
        odom_c = w.add_connection("/scout1/odom", "nav_msgs/msg/Odometry", typestore=TS)
        cmd_c = w.add_connection("/scout1/cmd_vel", "geometry_msgs/msg/Twist", typestore=TS)
        mode_c = w.add_connection("/robot/mode", "std_msgs/msg/String", typestore=TS)
        for k in range(121):
            ns = START_NS + k * 100_000_000
            x, y, th, v, om = square_pose(k)
            if k in CHANGES:
                w.write(
                    mode_c,
                    ns,
                    TS.serialize_cdr(
                        T["std_msgs/msg/String"](data=CHANGES[k]), "std_msgs/msg/String"
                    ),
                )
            sec, nsec = divmod(ns, 1_000_000_000)
            zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            odom = T["nav_msgs/msg/Odometry"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="odom"
                ),
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](
                    pose=T["geometry_msgs/msg/Pose"](
                        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                        orientation=T["geometry_msgs/msg/Quaternion"](
                            x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)
                        ),
                    ),
                    covariance=np.zeros(36),
                ),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                    covariance=np.zeros(36),
                ),
            )
            w.write(odom_c, ns, TS.serialize_cdr(odom, "nav_msgs/msg/Odometry"))
            twist = T["geometry_msgs/msg/Twist"](
                linear=T["geometry_msgs/msg/Vector3"](x=v, y=0.0, z=0.0),
                angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=om),
            )
            w.write(cmd_c, ns, TS.serialize_cdr(twist, "geometry_msgs/msg/Twist"))
    return path


def test_import_takes_a_deployed_robots_topics_from_the_team_file(tmp_path, capsys):
    """No mapping file: the robot's odometry and commands are on the topics the team's
    ``deploy:`` section names (/scout1/odom, /scout1/cmd_vel, which export's names would
    take for an agent 'scout1' of another team); its mode changes on export's
    /robot/mode. The trace has the square's poses and commands exactly as logged, and
    its mode changes. A mapping file still decides: one naming only the odometry (as the
    pose) and the modes gives the same poses and no commands."""
    team_file = tmp_path / "square.yaml"
    team_file.write_text(SQUARE_TEAM + DEPLOY)
    bag = write_deployed_bag(tmp_path / "deployed")
    out = tmp_path / "trace.json"
    assert main(["import", str(bag), "--team", str(team_file), "-o", str(out)]) == 0
    capsys.readouterr()
    run = ht.Run.of(load_trace(str(out)))
    assert run.sample_times.tolist() == [k / 10 for k in range(121)]
    x, y, _th = run.samples["robot"][:, 0, :].T
    assert x.tolist() == [square_pose(k)[0] for k in range(121)]
    assert y.tolist() == [square_pose(k)[1] for k in range(121)]
    cmd = run.samples["robot.cmd"][:, 0, :]
    assert cmd[5].tolist() == [0.5, 0.0] and cmd[25].tolist() == [0.0, math.pi / 2]
    assert run.transitions["t"].tolist() == [0.0, 2.0, 3.0, 5.0, 6.0, 8.0, 9.0, 11.0]
    mapping = tmp_path / "map.yaml"
    mapping.write_text("agents:\n  robot:\n    pose: /scout1/odom\n    modes: /robot/mode\n")
    mapped = ht.Run.from_bag(bag, ht.load(team_file), mapping)
    assert mapped.samples["robot"][:, 0, :2].tolist() == run.samples["robot"][:, 0, :2].tolist()
    assert "robot.cmd" not in mapped.samples


def test_check_on_a_hand_made_log(square):
    """x reaches exactly 1.0 on the second side: always(x <= 1.0) holds with robustness 0;
    x never goes below 0: always(x >= -0.1) has 0.1; always(x <= 0.9) is violated by
    0.9 - 1.0, from where x = 0.5 t crosses 0.9: t = 1.8 s (a sample; the monitor puts a
    violation where the samples' linear interpolation crosses)."""
    team_file, mapping, bag = square
    team = ht.load(team_file)
    table = ht.check(ht.Run.from_bag(bag, team, mapping), team)
    rows = {r.requirement: r for r in table}
    assert (rows["inside"].satisfied, rows["inside"].robustness) == (True, 0.0)
    assert (rows["margin"].satisfied, rows["margin"].robustness) == (True, 0.1)
    assert not rows["short"].satisfied
    assert rows["short"].robustness == 0.9 - 1.0
    assert rows["short"].violated_at == 1.8


def test_check_command_on_a_log_and_on_its_trace(square, tmp_path, capsys):
    team_file, mapping, bag = square
    code = main(["check", str(bag), "--team", str(team_file), "--map", str(mapping)])
    out = capsys.readouterr().out.splitlines()
    assert code == 1  # a requirement is violated
    assert out[0] == "requirement inside: holds (robustness 0)"
    assert out[1] == "requirement margin: holds (robustness 0.1)"
    assert out[2] == "requirement short: VIOLATED at t=1.8 by x <= 0.9 (robustness -0.1)"
    trace = tmp_path / "trace.json"
    assert (
        main(
            ["import", str(bag), "--team", str(team_file), "--map", str(mapping), "-o", str(trace)]
        )
        == 0
    )
    capsys.readouterr()
    assert main(["check", str(trace), "--team", str(team_file)]) == 1
    assert capsys.readouterr().out.splitlines() == out


def test_check_command_on_a_run_that_holds(tmp_path, capsys):
    """The same verdict lines as `run` prints, exit 0 when every requirement holds."""
    out = tmp_path / "run"
    assert (
        main(["run", str(EXPERIMENT2), "-o", str(out), "--duration", "2", "--no-views", "--quiet"])
        == 0
    )
    assert main(["export", str(out), "-o", str(tmp_path / "run.mcap")]) == 0
    capsys.readouterr()
    assert main(["check", str(tmp_path / "run.mcap"), "--team", str(EXPERIMENT2)]) == 0
    lines = capsys.readouterr().out.splitlines()
    from hybridteam.requirements.report import verdict_lines

    summary = ht.Run.load(out / "trace.json").to_dict()["outcomes"]
    assert lines == verdict_lines(summary)


def test_check_refuses_a_requirement_on_variables(tmp_path, capsys):
    """A recording has no discrete variables: a requirement reading one is refused."""
    text = (EXAMPLES / "automata" / "unicycle_square.yaml").read_text()
    team_file = tmp_path / "square.yaml"
    team_file.write_text(
        text.replace("simulation:", "requirements:\n  few_sides: always(sides <= 4)\nsimulation:")
    )
    team = ht.load(team_file)
    bag = ht.simulate(team, duration=1.0).to_bag(tmp_path / "run.mcap")
    err = _one_line_error(capsys, main(["check", str(bag), "--team", str(team_file)]))
    assert err == (
        f"hybridteam: error: {bag}: requirement few_sides: reads the discrete "
        "variables of agent 'robot', which a recording does not have (variables are not "
        "logged)"
    )


# ---------------------------------------------------------------------- bad input
def _one_line_error(capsys, code: int) -> str:
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert "\n" not in err and "Traceback" not in err, err
    return err


def test_a_bag_of_another_team(square, tmp_path, capsys):
    team_file, _mapping, _bag = square
    e2 = ht.simulate(ht.load(EXPERIMENT2), duration=0.5).to_bag(tmp_path / "e2.mcap")
    out = tmp_path / "t.json"
    err = _one_line_error(
        capsys, main(["import", str(e2), "--team", str(team_file), "-o", str(out)])
    )
    assert err.startswith(f"hybridteam: error: {e2}: topic /hybridteam/run at t=0 s: ")
    assert "team 'experiment2'" in err and "not 'square-log'" in err
    assert not out.exists()
    # a robot's log with export's names, of an agent the team does not have
    robot = write_square_bag(
        tmp_path / "robot_bag", pose_topic="/robot/pose", modes_topic="/robot/mode"
    )
    err = _one_line_error(
        capsys, main(["import", str(robot), "--team", str(EXPERIMENT2), "-o", str(out)])
    )
    assert (
        f"{robot}: topic /robot/mode at t=0 s: agent 'robot' is not in team 'experiment2'" in err
        or f"{robot}: topic /robot/pose at t=0 s: agent 'robot'" in err
    )
    assert not out.exists()


def test_other_topics_of_a_log_of_this_team_are_left_alone(square, tmp_path):
    """A topic named like an agent's (``/camera/state``) is another team's only when the
    team's own agents have no samples: a log of this team may hold more."""
    team_file, _mapping, _bag = square
    bag = write_square_bag(
        tmp_path / "robot_bag", pose_topic="/robot/pose", modes_topic="/robot/mode"
    )
    with Writer(tmp_path / "with_camera", version=9) as w:
        with Reader(bag) as r:
            conns = {
                c.topic: w.add_connection(c.topic, c.msgtype, typestore=TS) for c in r.connections
            }
            for conn, ns, data in r.messages():
                w.write(conns[conn.topic], ns, data)
        cam = w.add_connection("/camera/state", "std_msgs/msg/Float64MultiArray", typestore=TS)
        w.write(
            cam,
            START_NS,
            TS.serialize_cdr(
                T["std_msgs/msg/Float64MultiArray"](
                    layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                    data=np.zeros(2),
                ),
                "std_msgs/msg/Float64MultiArray",
            ),
        )
    run = ht.Run.from_bag(tmp_path / "with_camera", ht.load(team_file))
    assert len(run.sample_times) == 121 and len(run.transitions) == 8


def test_a_missing_topic(square, tmp_path, capsys):
    team_file, mapping, bag = square
    out = tmp_path / "t.json"
    mapping.write_text(MAPPING.replace("/fsm", "/fsm2"))
    err = _one_line_error(
        capsys,
        main(["import", str(bag), "--team", str(team_file), "--map", str(mapping), "-o", str(out)]),
    )
    assert err == (
        f"hybridteam: error: {bag}: topic /fsm2 (robot's modes in the mapping) is not in the log"
    )
    # without a mapping: export's names, and the log has no pose of the robot under them
    err = _one_line_error(
        capsys, main(["import", str(bag), "--team", str(team_file), "-o", str(out)])
    )
    assert err == (
        f"hybridteam: error: {bag}: no topic /robot/state or /robot/pose or "
        "/robot/odom in the log: agent 'robot' has no samples"
    )
    assert not out.exists()


def test_a_mapping_naming_an_agent_the_team_lacks(square, tmp_path, capsys):
    team_file, mapping, bag = square
    mapping.write_text(MAPPING + "  robbot:\n    pose: /x\n")
    out = tmp_path / "t.json"
    err = _one_line_error(
        capsys,
        main(["import", str(bag), "--team", str(team_file), "--map", str(mapping), "-o", str(out)]),
    )
    assert err == (
        f"{mapping}:6:3: agents.robbot: 'robbot' is not one of the team's agents (robot)"
    )
    assert not out.exists()


def test_stamps_that_go_back(square, tmp_path, capsys):
    team_file, mapping, _bag = square
    bag = write_square_bag(tmp_path / "swapped", swap=50)  # 5.1 s logged before 5.0 s
    out = tmp_path / "t.json"
    err = _one_line_error(
        capsys,
        main(["import", str(bag), "--team", str(team_file), "--map", str(mapping), "-o", str(out)]),
    )
    assert err.startswith(
        f"hybridteam: error: {bag}: topic /amcl_pose at t=5 s: stamps go "
        "back or repeat (the previous one is t=5.1 s)"
    )
    assert not out.exists()


def test_messages_that_are_not_what_their_topic_holds(square, tmp_path, capsys):
    team_file, mapping, bag = square
    out = tmp_path / "t.json"
    mapping.write_text(MAPPING.replace("pose: /amcl_pose", "pose: /cmd_vel"))
    err = _one_line_error(
        capsys,
        main(["import", str(bag), "--team", str(team_file), "--map", str(mapping), "-o", str(out)]),
    )
    assert err == (
        f"hybridteam: error: {bag}: topic /cmd_vel at t=0 s: has type "
        "geometry_msgs/msg/Twist, expected geometry_msgs/msg/PoseStamped or "
        "nav_msgs/msg/Odometry"
    )
    # a mode the team does not have, logged at t = 2 s (where the robot starts turning)
    spun = write_square_bag(tmp_path / "spun", changes=CHANGES | {20: "Spin"})
    mapping.write_text(MAPPING)
    err = _one_line_error(
        capsys,
        main(
            ["import", str(spun), "--team", str(team_file), "--map", str(mapping), "-o", str(out)]
        ),
    )
    assert err == (
        f"hybridteam: error: {spun}: topic /fsm at t=2 s: 'Spin' is not a mode of agent 'robot'"
    )
    assert not out.exists()


def test_a_truncated_bag(tmp_path, capsys):
    run = ht.simulate(ht.load(EXPERIMENT2), duration=1.0)
    path = run.to_bag(tmp_path / "cut.mcap")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    out = tmp_path / "t.json"
    err = _one_line_error(
        capsys, main(["import", str(path), "--team", str(EXPERIMENT2), "-o", str(out)])
    )
    assert err.startswith(f"hybridteam: error: {path}: not a readable rosbag2 or cut short")
    assert not out.exists()
    err = _one_line_error(capsys, main(["check", str(path), "--team", str(EXPERIMENT2)]))
    assert err.startswith(f"hybridteam: error: {path}: not a readable rosbag2 or cut short")


def test_export_leaves_nothing_when_writing_fails(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    assert (
        main(
            ["run", str(EXPERIMENT2), "-o", str(out), "--duration", "0.5", "--no-views", "--quiet"]
        )
        == 0
    )
    calls = []

    def failing(self, connection, timestamp, data):
        calls.append(timestamp)
        if len(calls) > 10:
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(Writer, "write", failing)
    bag = tmp_path / "out" / "run.mcap"
    err = _one_line_error(capsys, main(["export", str(out / "trace.json"), "-o", str(bag)]))
    assert err == f"hybridteam: error: cannot write {bag}: No space left on device"
    assert len(calls) == 11
    assert list((tmp_path / "out").iterdir()) == []  # no bag, no temporary folder


def test_export_arguments(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(
            ["run", str(EXPERIMENT2), "-o", str(out), "--duration", "0.5", "--no-views", "--quiet"]
        )
        == 0
    )
    bag = tmp_path / "run.db3"
    err = _one_line_error(capsys, main(["export", str(out), "-o", str(bag), "--format", "mcap"]))
    assert err == (
        f"hybridteam: error: -o {bag} says sqlite3 but --format says mcap; name "
        "the file .mcap or .db3, or a folder, or drop --format"
    )
    err = _one_line_error(capsys, main(["export", str(out), "-o", str(bag), "--instance", "3"]))
    assert err == "hybridteam: error: --instance 3: the trace has instances 0..0"
    assert not bag.exists()


def test_without_rosbags_one_line_says_how_to_install(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    assert (
        main(
            ["run", str(EXPERIMENT2), "-o", str(out), "--duration", "0.5", "--no-views", "--quiet"]
        )
        == 0
    )
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)  # import fails
    err = _one_line_error(capsys, main(["export", str(out), "-o", str(tmp_path / "r.mcap")]))
    assert err == "hybridteam: error: this needs rosbags: pip install 'hybridteam[logs]'"
    err = _one_line_error(
        capsys, main(["check", str(tmp_path / "r.mcap"), "--team", str(EXPERIMENT2)])
    )
    assert err == "hybridteam: error: this needs rosbags: pip install 'hybridteam[logs]'"
    assert not (tmp_path / "r.mcap").exists()


def _same(ours, theirs, where: str) -> None:
    """Field by field: a message as rosbags read it against ROS 2's own class's reading."""
    fields = getattr(ours, "__dataclass_fields__", None)
    if fields is None:  # a value: numbers exactly, arrays element by element
        if (
            isinstance(ours, np.ndarray)
            or isinstance(theirs, list | tuple)
            or type(theirs).__name__ == "array"
        ):
            assert list(np.asarray(ours).tolist()) == list(theirs), where
        else:
            assert ours == theirs, where
        return
    for name in fields:
        if name.startswith("__"):
            continue
        a, b = getattr(ours, name), getattr(theirs, name)
        if isinstance(a, list):  # a sequence of messages
            assert len(a) == len(b), where
            for k, (x, y) in enumerate(zip(a, b, strict=True)):
                _same(x, y, f"{where}.{name}[{k}]")
        else:
            _same(a, b, f"{where}.{name}")


@pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")  # rclpy's lark
def test_ros2s_own_message_classes_read_the_exported_bag(tmp_path):
    """Where rclpy is installed (the ros extra), every message of experiment 2's exported
    bag deserializes with ROS 2's own classes (``rclpy.serialization``) to the values
    rosbags reads, field by field: the bag is what a ROS 2 tool reads. Types whose package
    the wheels do not ship (tf2_msgs) are left to rosbags and named here."""
    import importlib

    pytest.importorskip(
        "rclpy", reason="ROS 2's message classes come with hybridteam[ros]", exc_type=ImportError
    )
    from rclpy.serialization import deserialize_message

    run = ht.simulate(ht.load(EXPERIMENT2), duration=1.0)
    path = run.to_bag(tmp_path / "e2.mcap")
    checked, absent = set(), set()
    with Reader(path) as reader:
        for conn, _ns, data in reader.messages():
            package, _msg, name = conn.msgtype.split("/")
            try:
                cls = getattr(importlib.import_module(f"{package}.msg"), name)
            except ModuleNotFoundError:
                absent.add(conn.msgtype)
                continue
            _same(
                TS.deserialize_cdr(data, conn.msgtype), deserialize_message(data, cls), conn.topic
            )
            checked.add(conn.msgtype)
    assert checked == {
        "std_msgs/msg/String",
        "rosgraph_msgs/msg/Clock",
        "geometry_msgs/msg/PoseStamped",
        "nav_msgs/msg/Odometry",
        "std_msgs/msg/Float64MultiArray",
    }
    assert absent <= {"tf2_msgs/msg/TFMessage"}

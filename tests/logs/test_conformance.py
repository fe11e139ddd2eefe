"""Conformance of a recorded run to its team (issue 45, item 4): the log's arrivals replayed
into the model, mode sequences, transition time shifts and pose deviations compared.

The answers are known without the code under test: a simulated run replayed into its own
team is the same run (the same engine on the same arrivals); a log edited at one agent and
time diverges exactly there; the handover's times follow from its scenario (want_lead at
t = 3) and its 30 ms latency.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.logs import LogError
from hybridteam.logs.conformance import conformance
from hybridteam.trace import Table, Trace

ROOT = Path(__file__).parents[2]
HANDOVER = ROOT / "examples" / "protocols" / "handover.yaml"
HANDSHAKE = ROOT / "tests" / "fixtures" / "live" / "handshake.yaml"
TIMEOUT = 120  # wall seconds the launch may take, however loaded the machine
# the handover's moments: the Labmate asks at 3 s; request and grant take 30 ms each
GRANTED = 3.0 + 0.03 + 0.03


@pytest.fixture(scope="module")
def handover() -> tuple[ht.Team, Trace]:
    team = ht.load(HANDOVER)
    return team, ht.simulate(team)


def edited(run: Trace, transitions: Table | None = None, messages: Table | None = None) -> Trace:
    """``run`` with its transition or message table replaced (a hand-edited log)."""
    return Trace(
        run.meta,
        run.diagnostics,
        transitions or run.transitions,
        run.intervals,
        messages or run.messages,
        run.sample_times,
        run.samples,
    )


def test_a_simulated_run_conforms_to_its_own_team(handover):
    """The same engine on the arrivals the run itself had: every transition at the same
    float (shift exactly 0: the copies are queued at the very times the simulation
    computed), the same trajectory (replay deviation exactly 0), and the replay received
    exactly the copies the log says arrived. A simulated trace records no commands, so
    the pose check under commands is not possible, and the report says so per robot."""
    team, run = handover
    result = conformance(run, team)
    assert result.conformant and result.first is None
    by = {a.agent: a for a in result.agents}
    # init + Lead -> Follow; init + Requesting + Lead; the operator's init
    assert {a: (c.logged, c.model, c.matched) for a, c in by.items()} == {
        "xr4000": (2, 2, 2),
        "labmate": (3, 3, 3),
        "operator": (1, 1, 1),
    }
    assert all(s == 0.0 for a in result.agents for _, s, _ in a.shifts)
    assert by["xr4000"].max_replay_deviation == 0.0
    assert by["labmate"].max_replay_deviation == 0.0
    assert by["operator"].max_replay_deviation is None  # no plant
    assert [(a.agent, a.max_pose_deviation, a.no_pose_check) for a in result.agents] == [
        ("xr4000", None, "the log has no commands for it"),
        ("labmate", None, "the log has no commands for it"),
        ("operator", None, ""),
    ]  # no plant: nothing to drive, nothing to say
    lines = result.lines()
    assert lines[-3:-1] == [
        "xr4000: no pose check under commands: the log has no commands for it",
        "labmate: no pose check under commands: the log has no commands for it",
    ]
    got, want = result.model.messages, run.messages
    arrived = np.isfinite(want["t_recv"])
    for column in ("sender", "receiver", "type", "t_recv", "status"):
        assert got[column].tolist() == want[column][arrived].tolist()


def test_a_removed_transition_diverges_at_that_agent_and_time(handover, capsys, tmp_path):
    """The Labmate's logged change to Lead removed: the model, given the grant the log
    says reached it, takes the lead at the grant's arrival; the log stays Requesting."""
    team, run = handover
    tr = run.transitions
    mutated = edited(
        run,
        transitions=tr.filter(~((tr["agent"] == "labmate") & (tr["target"] == "Transport.Lead"))),
    )
    result = conformance(mutated, team)
    first = result.first
    assert first is not None and first.agent == "labmate"
    assert first.t == pytest.approx(GRANTED, abs=1e-12)
    assert (first.expected, first.observed) == ("Transport.Lead", "Transport.Requesting")
    assert "message:grant" in first.why and "'grant' from xr4000" in first.why
    assert [a.divergence for a in result.agents if a.agent != "labmate"] == [None, None]
    # the command says so, exit 1
    path = tmp_path / "mutated.json"
    mutated.to_json(path)
    assert main(["check", str(path), "--team", str(HANDOVER), "--conformance"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith(
        "DIVERGENT: first divergence at t=3.06 s, agent labmate: the "
        "model is in Transport.Lead, the log in Transport.Requesting"
    )


def test_a_later_receive_time_diverges_where_the_log_moved(handover):
    """The grant's logged arrival moved from 3.06 s to 4 s: the guardless grant transition
    cannot fire before the copy is there, so at 3.06 s the log has the Labmate leading and
    the model has it still asking."""
    team, run = handover
    m = dict(run.messages.columns)
    m["t_recv"] = np.where(m["type"] == "grant", 4.0, m["t_recv"])
    result = conformance(edited(run, messages=Table(run.messages.names, m)), team)
    first = result.first
    assert first is not None and first.agent == "labmate"
    assert first.t == pytest.approx(GRANTED, abs=1e-12)
    assert (first.expected, first.observed) == ("Transport.Requesting", "Transport.Lead")
    assert (
        "the log's transition Transport.Requesting -> Transport.Lead (message:grant)" in first.why
    )
    labmate = next(a for a in result.agents if a.agent == "labmate")
    assert [target for _, _, target in labmate.shifts] == [
        "Transport.Follow",
        "Transport.Requesting",
    ]


def test_a_paused_agent_shows_the_shift_at_the_transitions_after_the_pause(handover):
    """The Labmate paused for 2 s from t = 3.01 (after its request): its logged transitions
    after that come 2 s late. The shift is +2 s at those and 0 before; with a tolerance
    above 2 s the run conforms, with the default the first divergence is there."""
    team, run = handover
    tr = dict(run.transitions.columns)
    late = (tr["agent"] == "labmate") & (tr["t"] > 3.01)
    tr["t"] = np.where(late, tr["t"] + 2.0, tr["t"])
    paused = edited(run, transitions=Table(run.transitions.names, tr))
    lenient = conformance(paused, team, tolerance=2.5)
    assert lenient.conformant
    labmate = next(a for a in lenient.agents if a.agent == "labmate")
    assert [(target, s) for _, s, target in labmate.shifts] == [
        ("Transport.Follow", 0.0),
        ("Transport.Requesting", 0.0),
        ("Transport.Lead", pytest.approx(2.0, abs=1e-12)),
    ]
    assert all(s == 0.0 for a in lenient.agents if a.agent != "labmate" for _, s, _ in a.shifts)
    strict = conformance(paused, team).first
    assert strict is not None and strict.agent == "labmate"
    assert strict.t == pytest.approx(GRANTED, abs=1e-12)  # the model's time: the log is late
    assert (strict.expected, strict.observed) == ("Transport.Lead", "Transport.Requesting")
    assert "+2 s from the model's time" in strict.why


def test_a_live_run_conforms_to_its_team(tmp_path, capsys):
    """``hybridteam launch`` of the handshake team, at 4x: conformant. The bound asserted,
    per transition: the model starts every agent at t = 0, while the merged trace has each
    process start at its wall-clock offset (``meta.live.offsets``). So an agent's
    transitions before its first message-caused one (its initial mode, ``after:`` from the
    start) are late by exactly its process's offset, and from a message on the model is
    at the logged arrival itself, as the live engine was (shift 0, to 1e-9 s of float
    rounding). The offsets themselves are the processes' start jitter: milliseconds."""
    out = tmp_path / "launch"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(HANDSHAKE),
            "--time-scale",
            "4",
            "-o",
            str(out),
        ],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    trace = Trace.load(out / "trace.json")
    result = conformance(trace, ht.load(HANDSHAKE))
    assert result.conformant, result.lines()
    live = trace.meta["live"]
    offset = {
        agent: off
        for p, off in zip(live["processes"], live["offsets"], strict=True)
        for agent in p["agents"]
    }
    logged = {a: [r.cause for r in trace.transitions if r.agent == a] for a in offset}
    for agent in result.agents:
        causes = logged[agent.agent]
        first_message = next(k for k, c in enumerate(causes) if c.startswith("message:"))
        assert agent.matched == len(causes)
        for k, (_, shift, _) in enumerate(agent.shifts):
            want = offset[agent.agent] if k < first_message else 0.0
            assert abs(shift - want) <= 1e-9, (agent.agent, k, shift, want)
    assert main(["check", str(out / "trace.json"), "--team", str(HANDSHAKE), "--conformance"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("conformant:")


def test_an_exported_bag_conforms_like_its_trace(handover, tmp_path, capsys):
    """The handover's run as a rosbag2, checked with ``--conformance``: the bag keeps
    modes, messages and their times exactly, so it conforms as the trace does."""
    pytest.importorskip("rosbags", reason="the bag needs rosbags (hybridteam[logs])")
    _team, run = handover
    bag = tmp_path / "run.mcap"
    run.to_bag(bag)
    assert main(["check", str(bag), "--team", str(HANDOVER), "--conformance"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:2] == ["agent", "transitions"]
    assert lines[-1].startswith("conformant:")


def test_a_trace_of_another_team_is_one_line_and_exit_2(handover, tmp_path, capsys):
    """Bad input: a run of another team (by name, or one whose agents are not the team's)
    is refused in one line, exit 2, with no report."""
    team, run = handover
    path = tmp_path / "handover.json"
    run.to_json(path)
    assert main(["check", str(path), "--team", str(HANDSHAKE), "--conformance"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip().splitlines() == [
        f"hybridteam: error: {path}: a run of team 'handover', not 'live handshake'"
    ]
    renamed = Trace(
        {**run.meta, "team": "live handshake"},
        run.diagnostics,
        run.transitions,
        run.intervals,
        run.messages,
        run.sample_times,
        run.samples,
    )
    with pytest.raises(
        LogError,
        match=r"^the run's agents \(xr4000, labmate, operator\) "
        r"are not those of team 'live handshake' \(requester, granter\)$",
    ):
        conformance(renamed, ht.load(HANDSHAKE))
    m = dict(run.messages.columns)
    m["sender"] = np.where(m["sender"] == "labmate", "intruder", m["sender"])
    with pytest.raises(
        LogError,
        match=r"^message at t=0.03 s: 'intruder' is not an agent of "
        r"the team: a log of another team\?$",
    ):
        conformance(edited(run, messages=Table(run.messages.names, m)), team)
    assert main(["check", str(path), "--team", str(HANDOVER), "--tolerance", "1"]) == 2
    assert (
        "--tolerance 1.0: a number of seconds >= 0, with --conformance" in capsys.readouterr().err
    )


def test_the_python_table(handover):
    """``ht.conformance(run, team)``: a row per agent."""
    team, run = handover
    table = ht.conformance(run, team)
    assert table["agent"].tolist() == ["xr4000", "labmate", "operator"]
    assert table["matched"].tolist() == [2, 3, 1]
    assert table["diverges_at"].tolist() == [None, None, None]
    # no commands in a simulated trace: no pose check under them; the replay's, exactly 0
    assert table["max_pose_deviation"].tolist() == [None, None, None]
    assert table["max_replay_deviation"].tolist() == [0.0, 0.0, None]


def test_a_stricter_team_names_the_guard_that_did_not_hold(tmp_path):
    """The handshake's run checked against the same team asking for ``amount >= 3`` (the
    granter grants the 2 asked for): the requester's model does not take the grant that
    the log has it take at 1 + 0.01 + 0.01 s (request after 1 s, 10 ms each way), and
    the report names the model's guard."""
    run = ht.simulate(ht.load(HANDSHAKE))
    stricter = tmp_path / "stricter.yaml"
    stricter.write_text(HANDSHAKE.read_text().replace("msg_amount >= 2", "msg_amount >= 3"))
    first = conformance(run, ht.load(stricter)).first
    assert first is not None and first.agent == "requester"
    assert first.t == pytest.approx(1.02, abs=1e-12)
    assert (first.expected, first.observed) == ("Asking", "Granted")
    assert first.why.endswith("the model's guard msg_amount >= 3 did not hold")


def square_log(tmp_path: Path, drop: int | None = None) -> tuple[ht.Team, Trace]:
    """test_logs' hand-made log: a unicycle driving a 1 m square (each side 2 s at
    0.5 m/s, a quarter turn in place in 1 s), poses at 10 Hz, read with its team;
    ``drop``: that pose sample left out (irregular sample times)."""
    pytest.importorskip("rosbags", reason="the log is a rosbag2 (hybridteam[logs])")
    from tests.logs.test_logs import MAPPING, SQUARE_TEAM, write_square_bag

    (tmp_path / "square.yaml").write_text(SQUARE_TEAM)
    (tmp_path / "map.yaml").write_text(MAPPING)
    team = ht.load(tmp_path / "square.yaml")
    run = ht.Run.from_bag(write_square_bag(tmp_path / "bag"), team, tmp_path / "map.yaml")
    if drop is not None:
        keep = np.arange(run.sample_times.size) != drop
        run = Trace(
            run.meta,
            run.diagnostics,
            run.transitions,
            run.intervals,
            run.messages,
            run.sample_times[keep],
            {k: v[keep] for k, v in run.samples.items()},
        )
    return team, run


def test_a_hand_made_square_log_conforms_with_the_pose_deviation_of_its_closed_form(tmp_path):
    """The square's log against the team describing it (timed Drive and Turn modes, the
    model driven by its own inputs): every mode change at the model's time, exactly (the
    log's stamps are k/10 s; the model's after: 2 and 1 s add up to the same floats). The
    log's times are a regular 0.1 s grid, so the model is sampled on it and read there,
    and the closed form (straight sides at constant speed, turns in place) is what the
    model integrates: the replay's deviation is float rounding, under 1e-9 m. The logged
    commands change on the log's sample grid (a side's last drive command at 1.9 s, the
    turn's first at 2.0 s), so the plant held at each command from the first pose on is
    the closed form too: the deviation under commands is float rounding as well. The
    model's change at t = 12, the log's last instant, is not in the log and is no
    divergence."""
    team, run = square_log(tmp_path)
    result = conformance(run, team)
    assert result.conformant, result.lines()
    (robot,) = result.agents
    assert (robot.logged, robot.model, robot.matched) == (8, 9, 8)
    assert [s for _, s, _ in robot.shifts] == [0.0] * 8
    assert robot.max_replay_deviation <= 1e-9
    assert robot.max_pose_deviation <= 1e-9
    path = result.agents[0].commanded
    assert path.t.tolist() == run.sample_times.tolist()  # a step to every logged time
    from tests.logs.test_logs import square_pose

    assert np.max(np.abs(path.xy - [square_pose(k)[:2] for k in range(121)])) <= 1e-9


def test_irregular_log_times_read_the_model_between_its_samples(tmp_path):
    """One pose of the square's log left out (t = 0.5 s): its times are no regular grid,
    so the model keeps its own samples (every 12 / 500 = 0.024 s) and is read linearly
    between them. The largest deviation is then the interpolation's across a corner: the
    robot reaches (1, 0) at t = 2 between model samples at 1.992 and 2.016 s, so the
    model's line there is 0.5 m/s * 0.008 s * 0.016 s / 0.024 s = 1/375 m short."""
    team, run = square_log(tmp_path, drop=5)
    (robot,) = conformance(run, team).agents
    assert robot.max_replay_deviation == pytest.approx(1 / 375, abs=1e-9)


# ---------------------------------------------------------------------- poses under commands
#: a robot whose model drives straight ahead at 0.5 m/s (``{kind}``, ``{inputs}``: a unicycle's
#: or a holonomic base's); ``{limits}``: its plant's limits
STRAIGHT_TEAM = """\
team: commanded-log
agents:
  robot:
    plant:
      kind: {kind}
      state: {{x: 0.0, y: 0.0, theta: 0.0}}{limits}
    initial: Drive
    modes:
      Drive:
        inputs: {inputs}
simulation:
  duration: {end}
"""
V = 0.5  # m/s, the speed every log below is driven at
H = 0.1  # s, the log's sample period (poses and commands)


UNICYCLE = {"kind": "unicycle", "inputs": "{v: 0.5, omega: 0}"}
HOLONOMIC = {"kind": "holonomic", "inputs": "{vx: 0.5, vy: 0, omega: 0}"}


def commanded_log(
    tmp_path: Path,
    pose,
    command,
    end: float = 4.0,
    limits: str = "",
    plant: dict[str, str] = UNICYCLE,
) -> tuple[ht.Team, Trace]:
    """A hand-made log of a robot of :data:`STRAIGHT_TEAM`: its pose ``pose(t)`` (x, y,
    theta) and the command it was given ``command(t)`` (the plant's inputs: v, omega or
    vx, vy, omega), both logged at t = k H from 0 to ``end``; its mode is the team's (the
    model's own run of it)."""
    path = tmp_path / "team.yaml"
    path.write_text(STRAIGHT_TEAM.format(limits=limits, end=end, **plant))
    team = ht.load(path)
    run = ht.simulate(team)
    times = np.arange(round(end / H) + 1) * H
    samples = {
        "robot": np.array([pose(t) for t in times], float)[:, None, :],
        "robot.cmd": np.array([command(t) for t in times], float)[:, None, :],
    }
    inputs = next(a["inputs"] for a in run.meta["agents"] if a["name"] == "robot")
    meta = {**run.meta, "series": {**run.meta.get("series", {}), "robot.cmd": list(inputs)}}
    return team, Trace(
        meta, run.diagnostics, run.transitions, run.intervals, run.messages, times, samples
    )


def test_a_circle_driven_as_commanded_has_no_pose_deviation(tmp_path):
    """A unicycle commanded (0.5 m/s, 0.25 rad/s), its poses from the closed form of the
    circle it drives (radius R = v / omega = 2 m, from the origin heading along x:
    x = R sin(omega t), y = R (1 - cos(omega t)), theta = omega t), logged every 0.1 s for
    8 s: the plant under the logged commands is that circle, so the pose deviation is float
    rounding. The team's model drives straight ahead: the replay's deviation is the
    distance from the circle to the line, kept apart (at 8 s: (2 sin 2 - 4, 2 - 2 cos 2)),
    largest there."""
    omega, radius = 0.25, V / 0.25

    def circle(t: float) -> tuple[float, float, float]:
        return radius * np.sin(omega * t), radius * (1 - np.cos(omega * t)), omega * t

    team, run = commanded_log(tmp_path, circle, lambda t: (V, omega), end=8.0)
    result = conformance(run, team)
    (robot,) = result.agents
    assert robot.max_pose_deviation <= 1e-12
    assert robot.max_replay_deviation == pytest.approx(
        np.hypot(radius * np.sin(2.0) - 4.0, radius * (1 - np.cos(2.0))), abs=1e-9
    )
    assert result.replay_deviation("robot").t == pytest.approx(8.0, abs=1e-12)


def test_a_turn_between_samples_deviates_by_the_held_commands_closed_form(tmp_path):
    """The robot drives along x at v, and its controller starts a quarter turn in place
    (pi/2 rad/s for 1 s) at T1 = 1 + D s, D = 0.03 s after a sample, then drives along y.
    The log samples the commands every H = 0.1 s, so it has the turn from 1.1 s to 2.0 s
    and the drive again from 2.1 s: held, the plant drives H - D too long, then turns the
    same quarter (10 samples of pi/2 rad/s), then drives H - D late. From 2.1 s on the two
    are both on their last side: the model at (v (T1 + H - D), v (t - T1 - 1 - (H - D))),
    the log at (v T1, v (t - T1 - 1)): apart by v (H - D) (1, -1), a distance of
    sqrt(2) v (H - D) = 0.0495 m (|e_x - e_y| = 2 sin(pi/4) for a quarter turn). Before,
    during the turn, they are v (H - D) apart along x."""
    d = 0.03
    t1 = 1.0 + d

    def truth(t: float) -> tuple[float, float, float]:
        if t < t1:
            return V * t, 0.0, 0.0
        if t < t1 + 1.0:
            return V * t1, 0.0, np.pi / 2 * (t - t1)
        return V * t1, V * (t - t1 - 1.0), np.pi / 2

    def given(t: float) -> tuple[float, float]:
        return (0.0, np.pi / 2) if t1 <= t < t1 + 1.0 else (V, 0.0)

    team, run = commanded_log(tmp_path, truth, given)
    result = conformance(run, team)
    worst = result.deviation("robot")
    lag = V * (H - d)
    assert worst.distance == pytest.approx(np.sqrt(2) * lag, abs=1e-12)
    assert worst.t >= 2.1 - 1e-9  # on the last side, where the offset is the largest
    assert np.subtract(worst.model, worst.logged) == pytest.approx([lag, -lag], abs=1e-12)
    path = result.agents[0].commanded
    at = int(np.argmin(np.abs(path.t - 1.5)))  # in the turn: ahead along x only
    assert path.xy[at] == pytest.approx([V * t1 + lag, 0.0], abs=1e-12)
    assert result.agents[0].max_pose_deviation == worst.distance


def test_a_slipping_robot_deviates_by_the_speed_it_lost(tmp_path):
    """Wheel slip: the robot is commanded u = 0.4 m/s straight ahead for 4 s (slower than
    its model's 0.5: an operator drives it) and its logged poses show it at 0.9 of that
    (x = 0.9 u t): the plant under the commands is at u t, so the deviation grows as
    0.1 u t and is largest at the end, 0.1 * 0.4 * 4 = 0.16 m, from (1.44, 0) logged to
    (1.6, 0) commanded. The replay, driven by the model's own 0.5 m/s, is
    (0.5 - 0.36) * 4 = 0.56 m off there: the other question."""
    u = 0.4
    team, run = commanded_log(tmp_path, lambda t: (0.9 * u * t, 0.0, 0.0), lambda t: (u, 0.0))
    result = conformance(run, team)
    worst = result.deviation("robot")
    assert worst.distance == pytest.approx(0.1 * u * 4.0, abs=1e-12)
    assert worst.t == pytest.approx(4.0, abs=1e-12)
    assert worst.logged == pytest.approx((1.44, 0.0), abs=1e-12)
    assert worst.model == pytest.approx((1.6, 0.0), abs=1e-12)
    assert result.agents[0].max_replay_deviation == pytest.approx(0.56, abs=1e-9)


def test_a_holonomic_base_drifting_sideways_deviates_by_its_drift(tmp_path):
    """A holonomic base commanded (vx, vy, omega) = (0.3, 0.4, 0.5) in the world frame for
    4 s: where its poses are the closed form (0.3 t, 0.4 t, 0.5 t) the deviation is float
    rounding; where it makes only half the commanded vy (y = 0.2 t) it is 0.2 t, largest
    at the end, 0.8 m, from (1.2, 0.8) logged to (1.2, 1.6) commanded."""
    team, run = commanded_log(
        tmp_path, lambda t: (0.3 * t, 0.4 * t, 0.5 * t), lambda t: (0.3, 0.4, 0.5), plant=HOLONOMIC
    )
    assert conformance(run, team).agents[0].max_pose_deviation <= 1e-12
    team, run = commanded_log(
        tmp_path, lambda t: (0.3 * t, 0.2 * t, 0.5 * t), lambda t: (0.3, 0.4, 0.5), plant=HOLONOMIC
    )
    worst = conformance(run, team).deviation("robot")
    assert worst.distance == pytest.approx(0.8, abs=1e-12)
    assert worst.t == pytest.approx(4.0, abs=1e-12)
    assert worst.logged == pytest.approx((1.2, 0.8), abs=1e-12)
    assert worst.model == pytest.approx((1.2, 1.6), abs=1e-12)


def test_commands_beyond_the_limits_are_saturated_as_the_model_saturates_them(tmp_path):
    """The plant's ``limits: {v: [-0.5, 0.5]}`` and a log commanding 0.6 m/s of a robot
    moving at 0.5 m/s (its driver clips as the model does): the plant under the commands
    moves at 0.5 m/s too, no deviation; unclipped it would be 0.1 m/s * 4 s = 0.4 m off."""
    team, run = commanded_log(
        tmp_path,
        lambda t: (V * t, 0.0, 0.0),
        lambda t: (0.6, 0.0),
        limits="\n      limits: {v: [-0.5, 0.5]}",
    )
    assert conformance(run, team).agents[0].max_pose_deviation <= 1e-12


def test_a_log_without_commands_says_the_pose_check_was_not_possible(tmp_path, capsys):
    """Bad input that is no error: the robot's commands are not in the log. Its line
    says the check under commands was not possible; the replay's deviation is still
    reported and ``check --conformance`` exits as the mode comparison says (0)."""
    team, run = commanded_log(tmp_path, lambda t: (V * t, 0.0, 0.0), lambda t: (V, 0.0))
    bare = Trace(
        {**run.meta, "series": {}},
        run.outcomes,
        run.transitions,
        run.intervals,
        run.messages,
        run.sample_times,
        {"robot": run.samples["robot"]},
    )
    (robot,) = conformance(bare, team).agents
    assert (robot.max_pose_deviation, robot.no_pose_check) == (
        None,
        "the log has no commands for it",
    )
    assert robot.max_replay_deviation <= 1e-12
    path = tmp_path / "bare.json"
    bare.to_json(path)
    assert main(["check", str(path), "--team", str(tmp_path / "team.yaml"), "--conformance"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split("  ")[-2:] == ["max pose deviation m", "max replay deviation m"]
    assert out[1].split()[-2] == "-"
    assert out[2] == "robot: no pose check under commands: the log has no commands for it"
    assert out[3].startswith("conformant:")
    # commands logged only after the robot's last pose: nothing to start from
    late = {"robot": run.samples["robot"].copy(), "robot.cmd": run.samples["robot.cmd"].copy()}
    late["robot"][-1] = np.nan
    late["robot.cmd"][:-1] = np.nan
    (robot,) = conformance(
        Trace(
            run.meta,
            run.outcomes,
            run.transitions,
            run.intervals,
            run.messages,
            run.sample_times,
            late,
        ),
        team,
    ).agents
    assert (robot.max_pose_deviation, robot.no_pose_check) == (
        None,
        "the log has no pose of it once commands are given",
    )


def mutated_handover(tmp_path: Path) -> tuple[Path, Path]:
    """The handover team with the XR4000 resigning at t = 3 (an offer to everyone)
    (``resign.yaml``), and the same team running a mutated role-assignment protocol, an
    offer taken as leadership without waiting for the confirmation (``mutant.yaml``)."""
    original = (ROOT / "protocols" / "role_assignment.yaml").read_text()
    taken = (
        "        - to: Accepting\n          on: offer\n          do: [{send: accept, to: sender}]\n"
    )
    assert taken in original
    (tmp_path / "mutated.yaml").write_text(
        original.replace(
            taken,
            (
                "        - to: Lead\n          on: offer\n          do: [leader = -1, last_change "
                "= t, {send: announce, fields: {old: msg_sender}}]\n"
            ),
        )
    )
    team_text = HANDOVER.read_text().replace(
        "{at: 3.0, agent: labmate, raise: want_lead}", "{at: 3.0, agent: xr4000, raise: resign}"
    )
    (tmp_path / "resign.yaml").write_text(team_text)
    (tmp_path / "mutant.yaml").write_text(
        team_text.replace("protocol: role_assignment", "protocol: ./mutated.yaml").replace(
            "operator: role_assignment", "operator: ./mutated.yaml"
        )
    )
    return tmp_path / "resign.yaml", tmp_path / "mutant.yaml"


def test_a_mutated_protocol_diverges_at_the_agents_first_offer(tmp_path):
    """The handover team with the XR4000 resigning at t = 3 (an offer to everyone), run
    with a mutated role-assignment protocol (an offer taken as leadership without waiting
    for the confirmation), checked against the team with the real one: the Labmate
    diverges at the offer's arrival, 3 + 0.03 s, where the model accepts and waits
    (Accepting) and the log leads; the report names the offer. The XR4000, given the
    log's arrivals (no acceptance ever comes), does in the model what it did in the log."""
    resign, mutant = mutated_handover(tmp_path)
    run = ht.simulate(ht.load(mutant))
    result = conformance(run, ht.load(resign))
    first = result.first
    assert first is not None and first.agent == "labmate"
    assert first.t == pytest.approx(3.0 + 0.03, abs=1e-12)
    # both leave Follow at that instant: the log's mode is where it went instead
    assert (first.expected, first.observed) == ("Transport.Accepting", "Transport.Lead")
    assert (
        "message:offer; the log has 'offer' from xr4000 sent at t=3, reaching labmate" in first.why
    )
    assert "the log's next is Transport.Follow -> Transport.Lead" in first.why
    assert next(a for a in result.agents if a.agent == "xr4000").divergence is None


def test_a_live_agent_running_a_mutated_protocol_diverges_at_its_first_offer(tmp_path, capsys):
    """The acceptance's live run: ``launch`` of the resigning handover team with the
    Labmate's process running the mutated protocol (``--agent-team``), speaking the
    team's wire (``live --wire-team``). Checked against the team, the first divergence
    is the Labmate's, at the logged arrival of the XR4000's first offer, where the model
    accepts and the robot leads; the report names the offer. Nothing here is a wall-clock
    margin: the time asserted is the one the merged trace records for that arrival. At
    time scale 1 (and run to t = 4, past the offer at t = 3) a process that starts late
    shifts its initial mode by its wall-clock start offset in run seconds, which stays
    within the default 0.1 s tolerance for offsets up to 100 ms, a loaded machine's."""
    resign, mutant = mutated_handover(tmp_path)
    out = tmp_path / "live"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(resign),
            "--agent-team",
            f"labmate={mutant}",
            "--duration",
            "4",
            "-o",
            str(out),
        ],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    merged = out / "trace.json"
    trace = Trace.load(merged)
    assert not trace.meta["live"]["missing"], proc.stderr.decode()  # every process's trace
    offers = [
        r
        for r in trace.messages
        if r.type == "offer" and r.receiver == "labmate" and r.status == "delivered"
    ]
    arrival = min(r.t_recv for r in offers)
    assert main(["check", str(merged), "--team", str(resign), "--conformance"]) == 1
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith(
        f"DIVERGENT: first divergence at t={arrival:.6g} s, agent "
        "labmate: the model is in Transport.Accepting, the log in "
        "Transport.Lead (the model's transition Transport.Follow -> "
        "Transport.Accepting (message:offer; the log has 'offer' from "
        "xr4000"
    ), last
    assert "the log's next is Transport.Follow -> Transport.Lead" in last
    first = conformance(trace, ht.load(resign)).first
    assert (first.agent, first.t) == ("labmate", arrival)


def test_a_wire_team_that_is_not_the_same_team_is_refused(tmp_path, capsys):
    """``live MUTATED --wire-team TEAM``: a file with another message (or other agents,
    or another name) cannot speak the team's wire: one line, exit 2, nothing written;
    ``launch --agent-team`` refuses it before starting a process."""
    resign, mutant = mutated_handover(tmp_path)
    (tmp_path / "other_protocol.yaml").write_text(
        (tmp_path / "mutated.yaml").read_text().replace("send: announce", "send: announce2")
    )
    other = tmp_path / "other.yaml"
    other.write_text(mutant.read_text().replace("./mutated.yaml", "./other_protocol.yaml"))
    out = tmp_path / "out"
    code = main(
        [
            "live",
            str(other),
            "--agent",
            "labmate",
            "--wire-team",
            str(resign),
            "--listen",
            "127.0.0.1:0",
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert err.endswith("--wire-team: message 'announce2' is not one the wire team declares")
    assert not out.exists()
    renamed = tmp_path / "renamed.yaml"
    renamed.write_text(mutant.read_text().replace("team: handover", "team: handover2"))
    code = main(["launch", str(resign), "--agent-team", f"labmate={renamed}", "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err == (
        f"hybridteam: error: --agent-team labmate={renamed}: the "
        "team is 'handover2', the wire team 'handover'"
    ), err
    assert main(["launch", str(resign), "--agent-team", "labmat=x.yaml", "-o", str(out)]) == 2
    assert "no agent 'labmat' in the team" in capsys.readouterr().err

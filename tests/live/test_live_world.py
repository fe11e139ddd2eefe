"""The world process (hybridteam/live/world.py, docs/live.md *The world process*): the
wire's two world kinds, the world process's components on the poses it receives, the
agents' reading of it, and experiment 2 launched live against ``hybridteam run``."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.simulator import Simulator
from hybridteam.live import run as live_run
from hybridteam.live.hosting import HostingError
from hybridteam.live.run import LiveRun
from hybridteam.live.transport import UdpTransport
from hybridteam.live.wire import POSE, READING, WORLD_INDEX, Codec, WireError
from hybridteam.live.world import WorldHost, WorldLink, WorldReadings, world_seam
from hybridteam.trace import Trace
from hybridteam.trace_schema import check_trace

EXPERIMENT2 = Path(__file__).parents[2] / "examples" / "transport" / "experiment2.yaml"
HANDSHAKE = Path(__file__).parents[1] / "fixtures" / "live" / "handshake.yaml"
XR4000, LABMATE = 0, 1
TIMEOUT = 60


@pytest.fixture(scope="module")
def team():
    return ht.load(EXPERIMENT2)


@pytest.fixture(scope="module")
def cteam(team):
    return compile_team(team)


class Sent:
    """A transport that keeps what is sent (and receives nothing)."""

    def __init__(self) -> None:
        self.payloads: list[bytes] = []

    def send(self, payload: bytes, socket: str) -> None:
        self.payloads.append(payload)


def codec_of(cteam) -> Codec:
    return Codec(cteam, frozenset({"arm", "payload", "ir", "sonar"}))


# ---------------------------------------------------------------------- the wire
def test_world_datagrams_round_trip(cteam):
    codec = codec_of(cteam)
    pose = codec.decode(
        codec.encode_world(
            POSE, XR4000, WORLD_INDEX, 0, {"x": 1.0, "y": 2.0, "theta": 0.5, "holding": 1.0}, 10.0
        )
    )
    assert (pose.sender, pose.to, pose.type, pose.fields) == (
        XR4000,
        WORLD_INDEX,
        POSE,
        {"x": 1.0, "y": 2.0, "theta": 0.5, "holding": 1.0},
    )
    reading = codec.decode(
        codec.encode_world(
            READING, WORLD_INDEX, XR4000, 0, {"ir.0": 0.2, "event.at_box": 1.0}, 10.0
        )
    )
    assert (reading.sender, reading.to, reading.fields) == (
        WORLD_INDEX,
        XR4000,
        {"ir.0": 0.2, "event.at_box": 1.0},
    )
    # poses and readings are numbered apart from the sender's messages
    assert codec.decode(codec.encode_world(POSE, XR4000, WORLD_INDEX, 1, {"x": 0.0}, 10.0)).seq == 1


@pytest.mark.parametrize(
    ("kind", "sender", "to", "fields", "reason"),
    [
        (POSE, XR4000, WORLD_INDEX, {"v": 1.0}, "forged"),  # the XR4000 is holonomic: no v
        (POSE, XR4000, WORLD_INDEX, {"leader": float("nan")}, None),  # (not encodable)
        (READING, WORLD_INDEX, LABMATE, {"event.at_box": 1.0}, "forged"),  # not its event
        (READING, WORLD_INDEX, XR4000, {"lidar.0": 1.0}, "forged"),  # no component's sense
        (READING, WORLD_INDEX, XR4000, {"ir.x": 1.0}, "forged"),
        (READING, WORLD_INDEX, XR4000, {"ir.\u00b2": 1.0}, "forged"),  # (a digit, not 0-9)
        (READING, WORLD_INDEX, XR4000, {"ir.0": 1.0, "ir.2": 1.0}, "forged"),  # ir.1 missing
        (READING, WORLD_INDEX, XR4000, {"ir": 1.0, "ir.0": 1.0}, "forged"),
    ],
)
def test_world_datagrams_are_checked_field_by_field(cteam, kind, sender, to, fields, reason):
    codec = codec_of(cteam)
    if reason is None:
        with pytest.raises(ValueError):
            codec.encode_world(kind, sender, to, 0, fields, 1.0)
        return
    with pytest.raises(WireError) as err:
        codec.decode(codec.encode_world(kind, sender, to, 0, fields, 1.0))
    assert err.value.reason == reason


def test_a_reading_names_the_pose_it_answers_and_a_pose_names_none(cteam):
    """Wire version 3: a reading's ``id`` is the number of the pose it answers (-1: none
    asked for it); a pose answers nothing."""
    codec = codec_of(cteam)
    for answers in (-1, 0, 41):
        assert (
            codec.decode(
                codec.encode_world(READING, WORLD_INDEX, XR4000, answers + 1, {}, 1.0, answers)
            ).msg_id
            == answers
        )
    for kind, sender, to, answers in (
        (READING, WORLD_INDEX, XR4000, -2),
        (POSE, XR4000, WORLD_INDEX, 3),
    ):
        with pytest.raises(WireError) as err:
            codec.decode(codec.encode_world(kind, sender, to, 50, {}, 1.0, answers))
        assert err.value.reason == "forged"


def test_a_reading_from_an_agent_and_a_replayed_pose_are_refused(cteam):
    codec = codec_of(cteam)
    data = json.loads(codec.encode_world(READING, WORLD_INDEX, XR4000, 0, {}, 1.0))
    with pytest.raises(WireError, match="forged"):
        codec.decode(json.dumps({**data, "from": "labmate"}).encode())
    pose = codec.encode_world(POSE, XR4000, WORLD_INDEX, 4, {"x": 0.0}, 1.0)
    codec.decode(pose)
    with pytest.raises(WireError) as err:
        codec.decode(pose)
    assert err.value.reason == "replayed"


# ---------------------------------------------------------------------- the world process
def host(cteam):
    """The world process's engine over experiment 2 with a transport that keeps what it
    sends; the components started."""
    transport = Sent()
    link = WorldLink(codec_of(cteam), transport, [], host=True)
    sim = Simulator(cteam, 1, world=world_seam(WorldHost, link))
    sim.ensemble.world.start(sim.access)
    return sim, link, transport


def readings(
    codec: Codec, transport: Sent, answers: dict[int, int] | None = None
) -> dict[int, dict[str, float]]:
    """The readings sent, by agent; ``answers`` gets the pose number each answers."""
    out = {}
    for payload in transport.payloads:
        dg = codec.decode(payload)
        out[dg.to] = dg.fields
        if answers is not None:
            answers[dg.to] = dg.msg_id
    transport.payloads.clear()
    return out


def test_the_world_process_runs_the_payload_on_the_poses_received(cteam):
    """Only the XR4000 holds (holding 1, the Labmate 0): a single grasp transmits no
    torque, so the box keeps its angle and follows the grasp point; moving the robot by
    (0.1, -0.05) without turning it moves the box by exactly that."""
    sim, link, transport = host(cteam)
    world, idx = sim.ensemble.world, np.array([0])
    x0, y0, th0 = 2.4, 0.0, np.pi
    link.poses = {
        XR4000: {"x": x0, "y": y0, "theta": th0, "holding": 1.0},
        LABMATE: {"holding": 0.0},
    }
    world.update(sim.access, idx)
    answers: dict[int, int] = {}
    first = readings(link.codec, transport, answers)
    assert set(first) == {0, 1, 2}  # the start: every agent's first reading
    assert answers == {0: -1, 1: -1, 2: -1}  # (which no pose asked for)
    before = [first[XR4000][f"payload.{k}"] for k in range(3)]
    link.poses = {XR4000: {"x": x0 + 0.1, "y": y0 - 0.05, "theta": th0, "holding": 1.0}}
    link.pending = {XR4000: 7}  # (the number of the pose that arrived)
    world.update(sim.access, idx)
    after = readings(link.codec, transport, answers)
    assert set(after) == {XR4000}  # a pose is answered to its sender
    assert answers[XR4000] == 7  # naming the pose it answers
    got = [after[XR4000][f"payload.{k}"] for k in range(3)]
    assert got == pytest.approx([before[0] + 0.1, before[1] - 0.05, before[2]], abs=1e-9)
    # the pose was written into the (remote) agent's state the components read
    assert sim.access.state(XR4000, idx)[0].tolist() == pytest.approx([x0 + 0.1, -0.05, th0])


def test_an_agent_process_senses_the_latest_reading_and_sends_its_pose(cteam):
    transport = Sent()
    link = WorldLink(codec_of(cteam), transport, [LABMATE], host=False)
    sim = Simulator(cteam, 1, world=world_seam(WorldReadings, link))
    world, idx = sim.ensemble.world, np.array([0])
    reading = link.codec.decode(
        link.codec.encode_world(
            READING,
            WORLD_INDEX,
            LABMATE,
            0,
            {"arm.2": 0.3, "arm.0": 0.1, "arm.1": -0.2, "event.docked": 1.0},
            1.0,
        )
    )
    assert link.take(reading) == (["docked"], None)
    assert world.sense(LABMATE, idx, "arm").tolist() == [[0.1, -0.2, 0.3]]
    with pytest.raises(KeyError, match="no reading of 'ir'"):
        world.sense(LABMATE, idx, "ir")
    sim.access.set_state(LABMATE, idx, np.array([[1.0, 2.0, 0.5]]))
    sim.access.set_variable(LABMATE, "holding", idx, np.array([1.0]))
    world.update(sim.access, idx)
    (pose,) = [link.codec.decode(p) for p in transport.payloads]
    assert (pose.type, pose.sender) == (POSE, LABMATE)
    # its plant state and every variable (the components read 'holding')
    assert {k: pose.fields[k] for k in ("x", "y", "theta", "holding")} == {
        "x": 1.0,
        "y": 2.0,
        "theta": 0.5,
        "holding": 1.0,
    }
    assert set(pose.fields) == {"x", "y", "theta", *sim.access.variable_names(LABMATE)}


def test_an_agent_with_no_world_process_is_one_line(team, monkeypatch):
    monkeypatch.setattr(live_run, "FIRST_READING", 0.2)
    transport = UdpTransport(("127.0.0.1", 0))
    try:
        with pytest.raises(
            HostingError,
            match=r"no reading from the world process within "
            r"0\.2 s",
        ):
            LiveRun(team, ["labmate"], transport).run()
    finally:
        transport.close()


def test_an_agent_whose_first_reading_was_lost_asks_again(team, cteam, monkeypatch):
    """The world process answers every pose. An agent process still without its first
    reading after ASK_AGAIN sends a pose of no field (where the agent is is not known
    before its run starts) and keeps asking: a stand-in world process whose first reading
    was lost answers the ask, and the agent's run goes on (before, it waited the whole
    FIRST_READING out and stopped)."""
    import threading

    monkeypatch.setattr(live_run, "FIRST_READING", 2.0)
    world = UdpTransport(("127.0.0.1", 0))
    transport = UdpTransport(("127.0.0.1", 0), [world.address])
    world.peers.append(transport.address)
    asks: list[dict[str, float]] = []
    done = threading.Event()
    live = LiveRun(team, ["labmate"], transport, duration=0.2, time_scale=5)
    codec = codec_of(cteam)

    def stand_in() -> None:
        while not done.is_set() and not asks:
            world.wait(0.02)
            for data, _ in world.receive():
                dg = codec.decode(data)
                if dg.type == POSE and dg.sender == LABMATE:
                    asks.append(dg.fields)
                    world.send(
                        live.codec.encode_world(
                            READING,
                            WORLD_INDEX,
                            LABMATE,
                            0,
                            {"arm.0": 0.0, "arm.1": 0.0, "arm.2": 0.0},
                            0.0,
                        ),
                        "data",
                    )

    thread = threading.Thread(target=stand_in)
    thread.start()
    try:
        trace = live.run()
    finally:
        done.set()
        thread.join()
        transport.close()
        world.close()
    assert asks == [{}]
    assert trace.outcomes[0]["outcome"] == "ok"  # (ended at its duration)


class StandIn:
    """A stand-in world process on its own socket (a thread of the test), answering each
    pose of the XR4000 that ``answer`` answers: with an IR ring reading the pose's x on
    every beam, naming the pose it answers. Its first reading (the answer to the agent's
    ask, a pose of no field) reads ``first`` on every beam."""

    BEAMS = 8

    def __init__(
        self,
        live: LiveRun,
        world: UdpTransport,
        answer: Callable[[dict[str, float]], bool],
        first: float,
    ) -> None:
        self.live, self.world, self.answer, self.first = live, world, answer, first
        self.done = threading.Event()
        self.thread = threading.Thread(target=self.serve)
        self.sent = 0

    def serve(self) -> None:
        codec = codec_of(self.live.full)
        while not self.done.is_set():
            self.world.wait(0.01)
            for data, _ in self.world.receive():
                dg = codec.decode(data)
                if dg.type != POSE or dg.sender != XR4000:
                    continue
                if dg.fields and not self.answer(dg.fields):
                    continue
                x = dg.fields.get("x", self.first)
                self.world.send(
                    self.live.codec.encode_world(
                        READING,
                        WORLD_INDEX,
                        XR4000,
                        self.sent,
                        {f"ir.{k}": x for k in range(self.BEAMS)},
                        0.0,
                        dg.seq,
                    ),
                    "data",
                )
                self.sent += 1


def xr4000_reading(
    team, answer: Callable[[dict[str, float]], bool], first: float, monkeypatch
) -> tuple[LiveRun, list[tuple[float, float, float]]]:
    """The XR4000's process (in this one; experiment 2, its Approach law, which reads its
    IR ring at every tick and drives it along x) against a :class:`StandIn` world, for 0.5
    run seconds at time scale 5. Returns the run and, for each reading of the ring by the
    law: the run time, the x the ring read, the XR4000's x then."""
    world = UdpTransport(("127.0.0.1", 0))
    transport = UdpTransport(("127.0.0.1", 0), [world.address])
    world.peers.append(transport.address)
    live = LiveRun(team, ["xr4000"], transport, duration=0.5, time_scale=5)
    ens = live.sim.ensemble
    column = list(ens.states[XR4000].ca.plant.state_names).index("x")
    read: list[tuple[float, float, float]] = []
    sense = ens.world.sense

    def spy(agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        values = sense(agent, idx, name)
        if name == "ir":
            read.append(
                (float(ens.t[0]), float(values[0, 0]), float(ens.states[XR4000].x[0, column]))
            )
        return values

    monkeypatch.setattr(ens.world, "sense", spy)
    stand_in = StandIn(live, world, answer, first)
    stand_in.thread.start()
    try:
        live.run()
    finally:
        stand_in.done.set()
        stand_in.thread.join()
        transport.close()
        world.close()
    return live, read


def test_a_law_reads_the_worlds_answer_to_its_own_instants_pose(team, monkeypatch):
    """At each tick of the XR4000's Approach law the IR ring it reads is the stand-in
    world's answer to the pose sent at that instant: the x the ring reads is the robot's x
    then (moving 0.1 m/s * 0.05 s = 5 mm a tick, so the answer to the previous tick's pose
    would read 5 mm off). The wait's bound is raised to 4 control periods so that a
    loaded machine does not make answers late; a late one would be counted, and only a
    counted one may read an older x."""
    monkeypatch.setattr(live_run, "ANSWER_WAIT", 4.0)
    live, read = xr4000_reading(team, lambda fields: True, 2.4, monkeypatch)
    ticks = [(t, ring, x) for t, ring, x in read if t > 0]
    assert len(ticks) >= 8  # (0.5 s of 20 Hz ticks)
    assert len({x for _, _, x in ticks}) == len(ticks)  # (it moves at every tick)
    older = [(t, ring, x) for t, ring, x in ticks if ring != x]
    assert len(older) == live.link.late <= len(ticks) // 4, older
    record = live.answers_record()
    assert record["world_late"] == live.link.late
    assert record["world_answer_ms"]["count"] == len(ticks) - live.link.late


def test_a_late_answer_leaves_the_latest_reading_counted_and_logged_once(team, monkeypatch, caplog):
    """A stand-in world that answers the first ask and no pose after: every tick's
    answer is late; each is counted and the laws read the latest reading (the first,
    x 2.0); one logged line says so. The first tick waits its bound, the later ones do not
    (the world process is behind), so the run keeps its pace."""
    caplog.set_level(logging.INFO, "hybridteam.live")
    live, read = xr4000_reading(team, lambda fields: False, 2.0, monkeypatch)
    ticks = [ring for t, ring, _ in read if t > 0]
    assert len(ticks) >= 8
    assert ticks == [2.0] * len(ticks)
    assert live.link.late == len(ticks)
    assert live.answers_record()["world_answer_ms"] == {"count": 0}
    warned = [r for r in caplog.records if "did not come within" in r.getMessage()]
    assert len(warned) == 1
    assert live.link.wait == pytest.approx(0.5 * 0.05 / 5)  # (half a period, wall seconds)


@pytest.mark.parametrize(("message", "ends"), [("ready", True), ("state", False)])
def test_a_message_ends_the_wait_for_the_world_and_a_streams_copy_does_not(team, message, ends):
    """While the XR4000's process waits for the world's answer, the Labmate's 'ready'
    (a control message: its reply must not be held for the world) ends the wait at once,
    queued for the next instant; a copy of the 'state' stream (20 Hz from each teammate)
    does not, the wait runs to its bound."""
    transport = UdpTransport(("127.0.0.1", 0))
    labmate = UdpTransport(("127.0.0.1", 0), [transport.address])
    try:
        live = LiveRun(team, ["xr4000"], transport, duration=1.0)
        socket, fields = {
            "ready": ("control", {}),
            "state": ("data", dict.fromkeys(("omega", "theta", "v", "vx", "vy", "x", "y"), 0.0)),
        }[message]
        labmate.send(
            live.codec.encode(
                Message(LABMATE, XR4000, 0, 0.0, socket, message, fields), 0.0, time.time()
            ),
            socket,
        )
        bound = 0.3 if ends else 0.1
        start = time.monotonic()
        live.clock.take_until(live.sim.ensemble, lambda: False, bound)
        took = time.monotonic() - start
    finally:
        transport.close()
        labmate.close()
    assert live.clock.delivered == 1, live.clock.dropped  # (queued either way)
    assert (took < bound) if ends else (took >= bound)


@pytest.mark.parametrize(
    ("team_file", "args", "message"),
    [
        (
            EXPERIMENT2,
            ["--world", "--agent", "labmate"],
            "give the agents this process runs (--agent NAME) or --world, not both",
        ),
        (HANDSHAKE, ["--world"], "--world: this team declares no world components"),
        (
            EXPERIMENT2,
            ["--world", "--plant", "ros2"],
            "--world hosts no agent: --plant is for the agents' processes",
        ),
    ],
)
def test_world_process_arguments_are_one_line(tmp_path, team_file, args, message):
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "live",
            str(team_file),
            *args,
            "--listen",
            "127.0.0.1:0",
            "-o",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert proc.returncode == 2
    lines = proc.stderr.decode().strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------- experiment 2
def test_experiment2_launched_live_hands_over_as_the_simulation_does(tmp_path, team):
    """The issue's acceptance over loopback UDP (:func:`launched_as_simulated`)."""
    launched_as_simulated(tmp_path / "launch", team, [])


#: Experiment 2's acknowledged messages' resend delay (its protocol's ack_timeout), s
ACK_TIMEOUT = 0.1


def launched_as_simulated(out: Path, team, options: list[str], time_scale: int = 4) -> None:
    """The issue's acceptance: the world process, three robots' and the operator's
    processes (``launch`` with ``options``, e.g. a transport) at ``time_scale`` end
    ``success``; every agent's mode sequence is ``hybridteam run``'s with the latency set
    to the latency measured in this run, and every transition (the hand-overs among them)
    is within two control periods (0.05 s) of the simulated one; every requirement's
    verdict on the live run is the simulated run's."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(EXPERIMENT2),
            "--time-scale",
            str(time_scale),
            *options,
            "-o",
            str(out),
        ],
        capture_output=True,
        timeout=TIMEOUT * 3,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    data = json.loads((out / "trace.json").read_text())
    assert check_trace(data) is None
    live = Trace.from_dict(data)
    assert live.outcomes[0]["outcome"] == "success", live.outcomes[0]["message"]
    delivered = live.messages.where(status="delivered")
    latency = float(np.median(delivered["t_recv"] - delivered["t_send"]))
    assert 0 <= latency < 0.02  # (on this machine, in run seconds: 5 ms of wall time at 4)
    sim = ht.simulate(team, overrides={"network.latency": latency})
    # a copy the transport itself lost (best-effort ROS 2 topics can, loopback UDP did not
    # here): its message arrives as a retransmission (the acknowledged layer's, one ack
    # timeout, 0.1 s, later) with no earlier copy of its id, and what follows it is as
    # late. The simulation has no such loss: the bound grows by one ack timeout for each,
    # from its first send on; and there are at most two in a run
    seen: set[tuple] = set()  # (sender, receiver, id): the copies in arrival order
    resent = []
    for t, sender, receiver, msg_id, reason in zip(
        delivered["t_send"].tolist(),
        delivered["sender"].tolist(),
        delivered["receiver"].tolist(),
        delivered["msg_id"].tolist(),
        delivered["reason"].tolist(),
        strict=True,
    ):
        if msg_id >= 0 and (sender, receiver, msg_id) not in seen:
            seen.add((sender, receiver, msg_id))
            if reason == "retransmission":
                resent.append(t - ACK_TIMEOUT)
    assert len(set(resent)) <= 2, resent
    for agent in ("xr4000", "labmate", "operator"):
        ours = live.transitions.where(agent=agent)
        theirs = sim.transitions.where(agent=agent)
        assert ours["target"].tolist() == theirs["target"].tolist(), agent
        assert ours["cause"].tolist() == theirs["cause"].tolist(), agent
        # (a loss counts for a transition it may precede by up to the bound: the resend's
        # send time, less one ack timeout, is its first send's plus the outlet's delay)
        losses = np.searchsorted(np.unique(resent), theirs["t"] + 2 * 0.05, side="right")
        bound = 2 * 0.05 + ACK_TIMEOUT * losses
        assert (np.abs(ours["t"] - theirs["t"]) <= bound + 1e-9).all(), (agent, resent)
    # the requirements (issue 45's acceptance: a live run checked against its team): where
    # the runs agree, each verdict is the simulated run's. They agree on the modes (above)
    # and on the box held (the run ended success, no grasp past its limit): one_leader,
    # no_takeover and box_carried (its margin in the simulation: 0.049 m). steady_grasps
    # reads the grasp offsets to within 0.024 m (the simulation's margin), where live
    # the world process moves the box on poses up to a control period old (0.3 m/s x
    # 0.05 s = 0.015 m) plus each pose's hop: its verdict is where the runs need not
    # agree, and is only reported
    from hybridteam.logs.check import check_run

    verdicts = [
        {name: v["satisfied"] for name, v in check_run(run, team)[0].items()} for run in (live, sim)
    ]
    assert set(verdicts[0]) == {"box_carried", "steady_grasps", "one_leader", "no_takeover"}
    agreed = ("box_carried", "one_leader", "no_takeover")
    assert [verdicts[0][r] for r in agreed] == [verdicts[1][r] for r in agreed], verdicts
    # the box's pose is the world process's record, carried into the team's trace
    box = live.samples["box"]
    assert np.isfinite(box[: np.searchsorted(live.sample_times, 40.0)]).all()
    assert (out / "agents" / "@world" / "trace.json").exists()


def agent_process_given(team, cteam, fields: dict[str, float]) -> Trace:
    """The Labmate's process (in this one) whose first reading from a stand-in world
    process carries ``fields``; run for 0.5 run seconds."""
    transport = UdpTransport(("127.0.0.1", 0))
    world = UdpTransport(("127.0.0.1", 0), [transport.address])
    try:
        live = LiveRun(team, ["labmate"], transport, duration=0.5, time_scale=5)
        world.send(
            live.codec.encode_world(
                READING,
                WORLD_INDEX,
                LABMATE,
                0,
                {"arm.0": 0.0, "arm.1": 0.0, "arm.2": 0.0, **fields},
                0.0,
            ),
            "data",
        )
        return live.run()
    finally:
        transport.close()
        world.close()


def test_an_event_in_a_reading_is_raised_in_its_agent_at_its_arrival(team, cteam):
    """``docked`` takes the Labmate from Idle to Align (experiment 2's file): raised by
    the first reading, at run time 0, where the process takes it."""
    trace = agent_process_given(team, cteam, {"event.docked": 1.0})
    rows = trace.transitions.where(agent="labmate")
    assert rows["target"].tolist() == ["Dock.Idle", "Dock.Align"]
    assert rows["t"][1] == pytest.approx(0.0, abs=1e-9)
    assert trace.outcomes[0]["outcome"] == "ok"  # (ended at the duration)


def test_an_outcome_in_a_reading_ends_the_agents_run(team, cteam):
    trace = agent_process_given(team, cteam, {"outcome.link_broken": 1.0})
    outcome = trace.outcomes[0]
    assert (outcome["outcome"], outcome["t"]) == ("link_broken", pytest.approx(0.0, abs=1e-9))
    assert "the world process concluded 'link_broken'" in outcome["message"]

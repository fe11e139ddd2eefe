"""``hybridteam live``: agents of a team as processes over loopback UDP, on the wall clock.

Every process and socket a test starts is stopped by the test, also when it fails (the
``processes`` and ``udp`` fixtures' finalizers); ports are ephemeral ones on 127.0.0.1.
"""

from __future__ import annotations

import json
import select
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.network import Message
from hybridteam.live.wire import MAX_BYTES, Codec
from hybridteam.trace import Trace
from hybridteam.trace_schema import check_trace

TEAM = Path(__file__).parents[1] / "fixtures" / "live" / "handshake.yaml"
LOCAL = "127.0.0.1"
TIMEOUT = 60  # wall seconds any process of a test may take, however loaded the machine


@pytest.fixture
def udp():
    """``open()`` a UDP socket on a free loopback port; every one is closed afterwards."""
    opened: list[socket.socket] = []

    def open_() -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind((LOCAL, 0))
        opened.append(s)
        return s

    yield open_
    for s in opened:
        s.close()


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((LOCAL, 0))
        return s.getsockname()[1]


@pytest.fixture
def processes():
    """``start(args)`` a ``hybridteam live`` process; every one is killed afterwards."""
    started: list[subprocess.Popen] = []

    def start(*args: str) -> subprocess.Popen:
        proc = subprocess.Popen(
            [sys.executable, "-m", "hybridteam.cli", "live", *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        started.append(proc)
        return proc

    yield start
    for proc in started:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=TIMEOUT)


def wait_running(proc: subprocess.Popen) -> bytes:
    """Block until ``proc`` logs that its run started (its port is bound by then)."""
    seen = b""
    end = time.monotonic() + TIMEOUT
    while b"live (time scale" not in seen:
        assert time.monotonic() < end and proc.poll() is None, seen.decode()
        ready, _, _ = select.select([proc.stderr], [], [], 1.0)
        if ready:
            seen += proc.stderr.readline()
    return seen


def start_together(*procs: subprocess.Popen) -> None:
    """Wait for each ``--ready`` process's ready line (its port bound, its team compiled),
    then say ``go WALL`` to every one, as ``launch`` does: their run clocks start at the
    same wall time, however late each process came up on a loaded machine."""
    for proc in procs:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], TIMEOUT)
        line = proc.stdout.readline() if ready else b""
        assert line.startswith(b"ready "), (
            line,
            proc.stderr.read() if proc.poll() is not None else b"",
        )
    now = time.time()
    for proc in procs:
        assert proc.stdin is not None
        proc.stdin.write(f"go {now!r}\n".encode())
        proc.stdin.flush()  # (closed by ``communicate``)


def finish(proc: subprocess.Popen) -> None:
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 0, err.decode()


def mode_sequences(trace) -> dict[str, list[tuple[str, str, str]]]:
    """Each agent's transitions as (source, target, cause): the order, not the times."""
    out: dict[str, list[tuple[str, str, str]]] = {}
    for row in trace.transitions:
        out.setdefault(row.agent, []).append((row.source, row.target, row.cause))
    return out


def simulated() -> dict[str, list[tuple[str, str, str]]]:
    return mode_sequences(ht.simulate(ht.load(TEAM)))


def hostile(codec: Codec) -> list[bytes]:
    """Datagrams of no genuine sender: malformed, oversized, foreign, forged."""
    genuine = json.loads(
        codec.encode(
            Message(0, 1, 10**6, 1.0, "control", "request", {"need": 2.0}), 0.0, time.time()
        )
    )
    return [
        b"{not json",
        b" " * (MAX_BYTES + 1),
        json.dumps({**genuine, "team": "another team"}).encode(),
        json.dumps({**genuine, "ht": 2}).encode(),
        json.dumps({**genuine, "from": "intruder"}).encode(),
    ]


def test_two_processes_shake_hands_as_the_simulation_does_despite_hostile_datagrams(
    tmp_path, processes, udp
):
    """Requester and granter in two processes over loopback (4x the wall clock), their
    clocks started together (``--ready``, then ``go``: the granter's 1.5 wall seconds run
    from the requester's start, not from its own, however late the other came up): each
    process's transitions are its agent's in ``hybridteam run``, in the same order, with
    the same causes. Hostile datagrams sent at both ports during the run, and a replay of
    the requester's own 'request' to the granter, are counted by reason and dropped."""
    sniffer = udp()  # a peer of the requester: sees its datagrams, to replay one
    bad = hostile(Codec(compile_team(ht.load(TEAM))))  # (ready before the run starts)
    ports = {"requester": free_port(), "granter": free_port()}
    granter = processes(
        str(TEAM),
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{ports['granter']}",
        "--peer",
        f"{LOCAL}:{ports['requester']}",
        "--time-scale",
        "4",
        "--ready",
        "-o",
        str(tmp_path / "granter"),
    )
    requester = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--listen",
        f"{LOCAL}:{ports['requester']}",
        "--peer",
        f"{LOCAL}:{ports['granter']}",
        "--peer",
        f"{LOCAL}:{sniffer.getsockname()[1]}",
        "--time-scale",
        "4",
        "--ready",
        "-o",
        str(tmp_path / "requester"),
    )
    start_together(granter, requester)
    ready, _, _ = select.select([sniffer], [], [], TIMEOUT)
    assert ready, "the requester sent nothing"
    first = sniffer.recv(65535)  # the request, which the granter has had by now
    assert json.loads(first)["type"] == "request"
    sniffer.sendto(first, (LOCAL, ports["granter"]))
    for data in bad:
        for port in ports.values():
            sniffer.sendto(data, (LOCAL, port))
    finish(requester)
    finish(granter)

    expected = simulated()
    for agent in ("requester", "granter"):
        data = json.loads((tmp_path / agent / "trace.json").read_text())
        assert check_trace(data) is None  # an ordinary trace: the views read it
        trace = Trace.from_dict(data)
        assert mode_sequences(trace) == {agent: expected[agent]}
        assert trace.outcomes[0]["outcome"] == "ok"
        assert trace.outcomes[0]["message"] == f"'{agent}' reached a final mode (the end rule)"
        live = trace.meta["live"]
        assert live["agents"] == [agent]
        want = {"foreign team": 1, "forged": 1, "malformed": 1, "oversized": 1, "version": 1}
        if agent == "granter":
            want["replayed"] = 1
        assert live["datagrams"]["dropped"] == want
        summary = json.loads((tmp_path / agent / "summary.json").read_text())
        assert summary["live"]["datagrams"]["dropped"] == want
    # each copy is recorded where it arrived, with both times on the run's clock
    granter_msgs = Trace.load(tmp_path / "granter" / "trace.json").messages
    assert granter_msgs["type"].tolist() == ["request", "done"]
    assert granter_msgs["status"].tolist() == ["delivered", "delivered"]
    assert (granter_msgs["t_recv"] >= granter_msgs["t_send"]).all()
    assert granter_msgs["msg_id"].tolist() == [-1, 0]  # 'done' is acknowledged


@pytest.mark.parametrize(
    ("said", "start"),
    [
        ("go\n", None),
        ("go 1000.25\n", 1000.25),
        ("go   1000.25  \n", 1000.25),
        ("", "stdin did not say 'go'"),
        ("start\n", "stdin did not say 'go'"),
        ("go 1000 1\n", "stdin did not say 'go'"),
        ("go 939.75\n", "'go 939.75' is no wall time within 60 s of now"),
        ("go nan\n", "'go nan' is no wall time"),
        ("go soon\n", "'go soon' is no wall time"),
    ],
)
def test_the_start_a_ready_process_is_given(monkeypatch, said, start):
    """``--ready``'s ``go`` (the clock starts when it is read) or ``go WALL`` (run time 0
    at that wall time, launch's for every process; within START_TIMEOUT, 60 s, of now,
    here 1000 s); anything else is a usage error, before the run."""
    from hybridteam.cli import live as live_cli
    from hybridteam.cli.common import UsageError

    monkeypatch.setattr(live_cli.time, "time", lambda: 1000.0)
    if start is None or isinstance(start, float):
        assert live_cli.go_time(said) == start
        return
    with pytest.raises(UsageError, match=start):
        live_cli.go_time(said)


def test_a_clock_started_at_a_past_wall_time_is_that_far_into_its_run():
    """``WallClock.start(at)``: run time 0 at wall time ``at`` (launch's ``go WALL``), so a
    process that reads it 0.5 s late is 0.5 s (time scale 4: 2 run seconds) into its run,
    and its send times count from ``at``."""
    from hybridteam.live.clock import WallClock

    clock = WallClock(Codec(compile_team(ht.load(TEAM))), None, [], time_scale=4)
    at = time.time() - 0.5
    clock.start(at)
    assert clock.wall0 == at
    assert 2.0 <= clock.now() < 2.0 + 4 * TIMEOUT


def test_agents_sharing_a_process_talk_through_the_socket(tmp_path, processes):
    port = free_port()
    proc = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{port}",
        "--time-scale",
        "4",
        "-o",
        str(tmp_path / "both"),
    )
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == simulated()
    assert trace.outcomes[0]["outcome"] == "ok"
    # request, grant, done and done's ack went out once each; the first three came back,
    # the ack only at the instant the run ended (the granter sent it as it became final)
    assert trace.meta["live"]["sent"] == 4
    assert trace.meta["live"]["datagrams"] == {"received": 3, "delivered": 3, "dropped": {}}
    assert trace.messages["type"].tolist() == ["request", "grant", "done"]


def test_sigint_stops_the_run_with_its_trace_complete(tmp_path, processes):
    """The granter alone waits for a request that never comes: SIGINT ends it cleanly,
    and its trace says so."""
    proc = processes(
        str(TEAM),
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--duration",
        "1000",
        "-o",
        str(tmp_path / "g"),
    )
    wait_running(proc)
    proc.send_signal(signal.SIGINT)
    finish(proc)
    trace = Trace.load(tmp_path / "g" / "trace.json")
    assert trace.outcomes[0]["outcome"] == "stopped"
    assert trace.outcomes[0]["message"].startswith("stopped by SIGINT at t=")
    assert mode_sequences(trace) == {"granter": [("", "Listening", "init")]}
    assert json.loads((tmp_path / "g" / "summary.json").read_text())["outcome"] == "stopped"


def test_a_sigterm_while_the_folder_is_written_waits_for_it(tmp_path, monkeypatch):
    """``launch`` stops its other processes with SIGTERM as soon as the end rule's have
    ended, which may be while one of them is writing its folder: live's own handler is
    still the one then (the signal is noted, the folder completed), and the caller's is
    back once it is written."""
    from hybridteam.cli import live as live_cli
    from hybridteam.cli import main

    write = live_cli.write_folder
    during: list[object] = []

    def write_signalled(out, trace, summary) -> None:
        during.append(signal.getsignal(signal.SIGTERM))
        signal.raise_signal(signal.SIGTERM)  # (with the caller's handler: it would be told)
        write(out, trace, summary)

    told: list[int] = []

    def caller(signum, _frame) -> None:
        told.append(signum)

    monkeypatch.setattr(live_cli, "write_folder", write_signalled)
    previous = signal.signal(signal.SIGTERM, caller)
    try:
        assert (
            main(
                [
                    "live",
                    str(TEAM),
                    "--agent",
                    "requester",
                    "--agent",
                    "granter",
                    "--listen",
                    f"{LOCAL}:0",
                    "--time-scale",
                    "8",
                    "--duration",
                    "0.5",
                    "-o",
                    str(tmp_path / "both"),
                ]
            )
            == 0
        )
        assert signal.getsignal(signal.SIGTERM) is caller
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert told == [] and during and during[0] is not caller
    assert (tmp_path / "both" / "summary.json").exists()


def test_a_taken_port_is_one_line_and_nothing_written(tmp_path, processes, udp):
    taken = udp()
    proc = processes(
        str(TEAM),
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{taken.getsockname()[1]}",
        "-o",
        str(tmp_path / "g"),
    )
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    assert err.decode().strip() == (
        f"hybridteam: error: UDP port {LOCAL}:"
        f"{taken.getsockname()[1]} is taken (another process "
        "listens there)"
    )
    assert not (tmp_path / "g").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--agent", "nobody"],
            "--agent 'nobody' is not an agent of the team (its agents: requester, granter)",
        ),
        (["--agent", "granter", "--listen", "localhost"], "--listen must be HOST:PORT"),
        (["--agent", "granter", "--time-scale", "0"], "--time-scale must be a finite number > 0"),
    ],
)
def test_bad_arguments_are_one_line(tmp_path, processes, args, message):
    if "--listen" not in args:
        args = [*args, "--listen", f"{LOCAL}:{free_port()}"]
    proc = processes(str(TEAM), *args, "-o", str(tmp_path / "x"))
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not (tmp_path / "x").exists()


def test_launch_runs_every_agent_and_merges_their_traces(tmp_path):
    """``hybridteam launch``: one process per agent, started together; the merged trace
    has every agent's transitions of ``hybridteam run``, in the same order, and is a trace
    the views read."""
    out = tmp_path / "launch"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(TEAM),
            "--time-scale",
            "4",
            "-o",
            str(out),
        ],
        capture_output=True,
        timeout=TIMEOUT * 2,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    data = json.loads((out / "trace.json").read_text())
    assert check_trace(data) is None
    merged = Trace.from_dict(data)
    assert mode_sequences(merged) == simulated()
    # the team's order of transitions too: the causal chain crosses the processes (the
    # initial modes are entered at each process's start, in whichever order they began)
    sim = ht.simulate(ht.load(TEAM))
    assert [(r.agent, r.target) for r in merged.transitions if r.cause != "init"] == [
        (r.agent, r.target) for r in sim.transitions if r.cause != "init"
    ]
    assert merged.outcomes[0]["outcome"] == "ok"
    assert [p["agents"] for p in merged.meta["live"]["processes"]] == [["requester"], ["granter"]]
    for agent in ("requester", "granter"):
        assert (out / "agents" / agent / "trace.json").exists()


HANDOVER = Path(__file__).parents[2] / "examples" / "protocols" / "handover.yaml"


def test_a_killed_teammate_is_met_as_the_protocol_says(tmp_path):
    """``launch`` of the handover team; the XR4000's process is killed (SIGKILL) as the
    run starts, before the Labmate asks it for the lead at t = 3. The Labmate's request
    goes unacknowledged, it calls the operator, who takes command: what the simulator
    says of the same team whose XR4000 is silent (every copy it sends lost). The merged
    trace has the two survivors and says which process left none, and why."""
    psutil = pytest.importorskip("psutil", reason="finds launch's child processes")
    muted = tmp_path / "muted.yaml"
    muted.write_text(
        HANDOVER.read_text().replace(
            "  latency: 0.03\n",
            "  latency: 0.03\n  links:\n    xr4000 -> labmate: {loss: 1}\n"
            "    xr4000 -> operator: {loss: 1}\n",
        )
    )
    expected = mode_sequences(ht.simulate(ht.load(muted), duration=4.0))
    assert expected["labmate"][-1] == (
        "Transport.Requesting",
        "Transport.Operated",
        "event:request_undeliverable",
    )
    out = tmp_path / "launch"
    launch = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(HANDOVER),
            "--time-scale",
            "4",
            "--duration",
            "4",
            "-o",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        log = out / "agents" / "xr4000" / "live.log"
        end = time.monotonic() + TIMEOUT
        while not (log.exists() and b"live (time scale" in log.read_bytes()):
            assert time.monotonic() < end and launch.poll() is None
            time.sleep(0.01)
        (victim,) = [c for c in psutil.Process(launch.pid).children() if "xr4000" in c.cmdline()]
        victim.send_signal(signal.SIGKILL)
        _, err = launch.communicate(timeout=TIMEOUT)
    finally:
        if launch.poll() is None:
            launch.kill()
            launch.communicate(timeout=TIMEOUT)
    assert launch.returncode == 0, err.decode()
    assert "agent 'xr4000' left no trace: killed by SIGKILL" in err.decode()
    merged = Trace.load(out / "trace.json")
    assert mode_sequences(merged) == {a: expected[a] for a in ("labmate", "operator")}
    assert merged.meta["live"]["missing"] == {"xr4000": "killed by SIGKILL"}
    assert merged.outcomes[0]["message"].endswith("; xr4000: no trace (killed by SIGKILL)")
    # when (the bound): the Labmate asks at t = 3 (its own scenario event) and is
    # operated once its request's copy and 3 resends, 0.1 s apart, went unacknowledged
    # (t >= 3.4: a resend is never early), and within the answer timeout (1 s) plus one
    # control period (0.05 s) of asking
    (t_operated,) = [
        r.t for r in merged.transitions if r.agent == "labmate" and r.target == "Transport.Operated"
    ]
    assert 3.0 + 4 * 0.1 - 1e-9 <= t_operated <= 3.0 + 1.0 + 0.05


def test_injected_loss_drops_what_arrives(tmp_path, processes):
    """``--drop 1``: no datagram reaches an agent, so the requester asks and waits while
    the granter listens, as the simulator has it with every copy lost; every datagram the
    process sent came back to its socket and was dropped there, and counted."""
    lossy = tmp_path / "lossy.yaml"
    lossy.write_text(TEAM.read_text().replace("  latency: 0.01\n", "  latency: 0.01\n  loss: 1\n"))
    expected = mode_sequences(ht.simulate(ht.load(lossy)))
    assert expected["requester"][-1][1] == "Asking"
    proc = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--time-scale",
        "8",
        "--duration",
        "2",
        "--drop",
        "1",
        "-o",
        str(tmp_path / "both"),
    )
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == expected
    live = trace.meta["live"]
    assert live["sent"] == 1  # the request
    assert live["injected"] == {
        "drop": 1.0,
        "delay": 0.0,
        "drop_copies": {},
        "dropped": 1,
        "delayed": 0,
        "scripted": 0,
    }
    assert len(trace.messages) == 0


def test_injected_delay_holds_each_arrival(tmp_path, processes):
    """``--delay 0.25``: each copy reaches its agent at least 0.25 run seconds after it
    was sent; the handshake is the simulator's all the same."""
    proc = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--time-scale",
        "4",
        "--delay",
        "0.25",
        "-o",
        str(tmp_path / "both"),
    )
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == simulated()
    m = trace.messages
    assert m["type"].tolist() == ["request", "grant", "done"]
    assert (m["t_recv"] - m["t_send"] >= 0.25).all()
    granting = trace.transitions.where(agent="granter", target="Granting")
    assert granting["t"][0] >= 1.25  # the request left at 1.0
    assert trace.meta["live"]["injected"]["delayed"] == 3


def test_a_value_out_of_range_during_the_run_is_located_and_nothing_written(tmp_path, processes):
    """A delay that turns out negative as the run goes (the grant sets it): one line at
    its place in the file, exit status 2, no folder; as ``hybridteam run`` says it."""
    team = tmp_path / "negative.yaml"
    team.write_text(
        TEAM.read_text()
        .replace(
            "    plant: {kind: flow, state: {x: 0}}\n    initial: Idle",
            "    plant: {kind: flow, state: {x: 0}}\n    variables: {wait: 0.5}\n    initial: Idle",
        )
        .replace(
            'guard: "msg_amount >= 2"}', 'guard: "msg_amount >= 2", do: ["wait = msg_amount - 3"]}'
        )
        .replace("Finished, after: 0.5,", "Finished, after: wait,")
    )
    proc = processes(
        str(team),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--time-scale",
        "8",
        "--log-level",
        "warning",
        "-o",
        str(tmp_path / "out"),
    )
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    assert err.decode().strip().splitlines() == [
        f"{team}:16:53: agents.requester.modes.Granted.transitions[0].after: the delay "
        "'wait' is -1.0 in instance 0; it must be a number >= 0"
    ]
    assert not (tmp_path / "out").exists()


def test_a_scripted_loss_of_a_plain_grant_strands_the_requester(tmp_path, processes):
    """``--drop-copy grant``: the one grant is lost. The requester waits in Asking for
    good, as the simulator has it with the granter's copies lost (where it concludes a
    deadlock: live, a copy may still come, so the run goes to its end)."""
    lost = tmp_path / "lost.yaml"
    lost.write_text(
        TEAM.read_text().replace(
            "  latency: 0.01\n", "  latency: 0.01\n  links:\n    granter -> requester: {loss: 1}\n"
        )
    )
    sim = ht.simulate(ht.load(lost))
    assert sim.outcome == "deadlock"
    proc = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--time-scale",
        "8",
        "--duration",
        "3",
        "--drop-copy",
        "grant",
        "-o",
        str(tmp_path / "both"),
    )
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == mode_sequences(sim)
    assert mode_sequences(trace)["requester"][-1][1] == "Asking"
    assert trace.meta["live"]["injected"]["scripted"] == 1
    # the grant is in the trace as the copy lost on its way (as a replay shows its loss)
    assert trace.messages["type"].tolist() == ["request", "grant"]
    grant = trace.messages.where(type="grant")
    assert (grant["status"].tolist(), grant["reason"].tolist()) == (["lost"], ["loss (scripted)"])


def test_an_acknowledged_grant_survives_the_same_loss(tmp_path, processes):
    """The same loss with 'grant' acknowledged: its retransmission gets through, and the
    handshake ends as the simulator's does without loss."""
    acked = tmp_path / "acked.yaml"
    acked.write_text(
        TEAM.read_text().replace(
            "messages:\n", "messages:\n  grant: {ack: {timeout: 0.2, retries: 3}}\n"
        )
    )
    expected = mode_sequences(ht.simulate(ht.load(acked)))
    proc = processes(
        str(acked),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "--time-scale",
        "4",
        "--drop-copy",
        "grant",
        "-o",
        str(tmp_path / "both"),
    )
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == expected
    grants = trace.messages.where(type="grant", status="delivered")
    assert grants["reason"].tolist() == ["retransmission"]  # the first copy never arrived
    assert grants["t_send"][0] >= 1.0 + 0.2  # sent again after the ack timeout
    lost = trace.messages.where(type="grant", status="lost")
    assert lost["reason"].tolist() == ["loss (scripted)"]
    assert lost["msg_id"].tolist() == grants["msg_id"].tolist()  # the same message
    assert trace.meta["live"]["injected"]["scripted"] == 1


def test_a_paused_process_takes_its_instants_late_and_says_so(tmp_path, processes):
    """The process is stopped (SIGSTOP) from about 0.2 s to 1.4 s of the wall clock, over
    the requester's first instant (1.0): it takes that instant late, by more than 0.3 s,
    the record says so, and the handshake still ends as the simulator's."""
    proc = processes(
        str(TEAM),
        "--agent",
        "requester",
        "--agent",
        "granter",
        "--listen",
        f"{LOCAL}:{free_port()}",
        "-o",
        str(tmp_path / "both"),
    )
    wait_running(proc)
    time.sleep(0.2)
    proc.send_signal(signal.SIGSTOP)
    time.sleep(1.2)
    proc.send_signal(signal.SIGCONT)
    finish(proc)
    trace = Trace.load(tmp_path / "both" / "trace.json")
    assert mode_sequences(trace) == simulated()
    assert trace.meta["live"]["late_ms"]["max"] > 300

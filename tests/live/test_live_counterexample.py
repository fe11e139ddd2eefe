"""A ``verify`` counterexample run live (issue 44's acceptance; docs/live.md *A verify
counterexample, live*): ``hybridteam launch TEAM.yaml --losses-from VERIFY_OUT/PROPERTY``
drops, at its receiver's process, every copy the counterexample loses.

The counterexample is found here, by ``hybridteam verify`` on experiment 2's docking
handshake with plain datagrams and one loss (docs/verify.md *What it found*): the
XR4000's ``docked`` is lost, and the team deadlocks with the XR4000 in ``Dock.Wait`` and
the Labmate in ``Dock.Idle``. Launched live with that loss, the plain team deadlocks the
same way; the acknowledged experiment 2 with the same scripted drop sends ``docked``
again, docks, and hands the leadership over as the simulation does.
"""

from __future__ import annotations

import copy
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.live.counterexample import CounterexampleError, drops, losses
from hybridteam.trace import Trace

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT2 = ROOT / "examples" / "transport" / "experiment2.yaml"
HANDSHAKE = ROOT / "tests" / "fixtures" / "live" / "handshake.yaml"
TIMEOUT = 120  # wall seconds a launch may take, however loaded the machine
ACK_TIMEOUT = 0.1  # the role protocol's ack_timeout, experiment 2's docked/ready resend
#: run seconds the live runs take: the plain one a while past the lost 'docked' (11.25 s),
#: the acknowledged one past the first hand-over of the leadership (19.8 s)
PLAIN_END, ACKED_END = 16.0, 21.0
#: requirements verify checks beside deadlock: one violated with the deadlock, one that
#: holds (the Labmate aligns only while the XR4000 waits for it)
REQUIREMENTS = (
    "requirements:\n"
    "  carried: always(implies(in_mode(xr4000, Dock.Wait), "
    "eventually(in_mode(xr4000, Transport))))\n"
    "  docked_first: always(implies(in_mode(labmate, Dock.Align), "
    "in_mode(xr4000, Dock.Wait)))\n"
)


def experiment2(folder: Path, acknowledged: bool) -> Path:
    """Experiment 2 with the requirements above; without acknowledgements (plain
    datagrams, as docs/verify.md has it) unless ``acknowledged``."""
    text = EXPERIMENT2.read_text().replace("requirements_from: [requirements.yaml]\n", REQUIREMENTS)
    if not acknowledged:
        text = text.replace(", ack: {timeout: ack_timeout, retries: 10}}", "}")
    path = folder / ("acked.yaml" if acknowledged else "plain.yaml")
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    """``hybridteam verify`` of the plain handshake with one loss: its output folder."""
    folder = tmp_path_factory.mktemp("counterexample")
    out = folder / "verify"
    assert (
        main(
            [
                "verify",
                str(experiment2(folder, False)),
                "--losses",
                "1",
                "-o",
                str(out),
                "--progress",
                "none",
            ]
        )
        == 1
    )  # a violation a run reproduces
    return out


def launch(team: Path, out: Path, *args: str) -> Trace:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            str(team),
            "--time-scale",
            "4",
            "-o",
            str(out),
            *args,
        ],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    assert (
        b"xr4000 -> labmate: docked sent at t=11.25 s is dropped at labmate's process "
        b"(--drop-copy docked:1)" in proc.stderr
    )  # (said what it drops)
    return Trace.load(out / "trace.json")


def lifted(trace: Trace) -> None:
    """The XR4000 lifted its end (and sent 'docked') once: what the rest depends on. A
    machine so loaded that the processes fall seconds behind the wall clock (the world
    process first: it runs every component) reaches the box late or never; said so."""
    wait = trace.transitions.where(agent="xr4000", target="Dock.Wait")
    behind = {
        ",".join(p["agents"]) or "@world": round(p["reaction_ms"].get("p99", 0))
        for p in trace.meta["live"]["processes"]
    }
    assert len(wait) == 1, (
        f"the XR4000 did not lift its end (at t=11.25 s simulated): "
        f"the processes fell behind (arrival to reaction p99, ms: {behind})"
    )


def configuration(trace: Trace) -> str:
    """The agents' leaf modes at the end, as verify words a configuration."""
    return "; ".join(
        f"{a} in {trace.transitions.where(agent=a)['target'][-1]}" for a in trace.agents
    )


def scripted(trace: Trace) -> dict[str, int]:
    """Copies each process dropped by --drop-copy, by its agents."""
    return {
        ",".join(p["agents"]) or "@world": p["injected"]["scripted"]
        for p in trace.meta["live"]["processes"]
    }


@pytest.mark.slow
def test_the_plain_handshake_deadlocks_live_as_the_counterexample_says(found, tmp_path):
    """The counterexample verify found (the XR4000's 'docked' lost), launched live over
    UDP at time scale 4 with that loss scripted at the Labmate's process: the copy is
    lost, and the team stays in the counterexample's deadlocked configuration with no
    transition after it (to the end of the run, 4.75 run seconds later)."""
    summary = json.loads((found / "verify.json").read_text())["properties"]["deadlock"]
    assert summary["verdict"] == "violated" and summary["replay"]["verdict"] == "reproduced"
    lost = Trace.load(found / "deadlock" / "trace.json").messages.where(
        status="lost", reason="loss (replay)"
    )
    assert list(zip(lost["sender"], lost["receiver"], lost["type"], strict=True)) == [
        ("xr4000", "labmate", "docked")
    ]  # what verify found (docs/verify.md)
    trace = launch(
        experiment2(tmp_path, False),
        tmp_path / "live",
        "--losses-from",
        str(found / "deadlock"),
        "--duration",
        str(PLAIN_END),
    )
    assert trace.meta["live"]["losses_from"]["drops"] == {"labmate": {"docked": [1]}}
    lifted(trace)
    assert scripted(trace) == {"xr4000": 0, "labmate": 1, "operator": 0, "@world": 0}
    # the one docked copy the XR4000 sent is lost on its way to the Labmate
    docked = trace.messages.where(type="docked")
    assert (
        docked["sender"].tolist(),
        docked["receiver"].tolist(),
        docked["status"].tolist(),
        docked["reason"].tolist(),
    ) == (["xr4000"], ["labmate"], ["lost"], ["loss (scripted)"])
    # the counterexample's deadlocked configuration, and nothing after the loss
    assert (
        configuration(trace)
        == summary["configurations"][0]
        == "xr4000 in Dock.Wait; labmate in Dock.Idle; operator in Standby"
    )
    later = trace.transitions.filter(trace.transitions["t"] > docked["t_send"][0])
    assert len(later) == 0, list(later)
    assert trace.outcomes[0]["outcome"] == "ok"  # (to the duration: never concluded live)
    assert trace.outcomes[0]["t"] >= PLAIN_END - 0.1


@pytest.mark.slow
def test_the_acknowledged_handshake_docks_through_the_same_loss(found, tmp_path):
    """The same counterexample against experiment 2 as it is (docked and ready
    acknowledged): the same copy is dropped, the XR4000 sends 'docked' again after the
    ack timeout, the Labmate docks on it, and the team changes modes as the simulation
    without loss does, the leadership hand-over at the obstacle included."""
    team = experiment2(tmp_path, True)
    trace = launch(
        team,
        tmp_path / "live",
        "--losses-from",
        str(found / "deadlock"),
        "--duration",
        str(ACKED_END),
    )
    lifted(trace)
    assert scripted(trace) == {"xr4000": 0, "labmate": 1, "operator": 0, "@world": 0}
    docked = trace.messages.where(type="docked")
    lost, got = docked.where(status="lost"), docked.where(status="delivered")
    assert lost["reason"].tolist() == ["loss (scripted)"]
    assert got["reason"].tolist() == ["retransmission"]  # the ack timeout's resend
    assert got["msg_id"].tolist() == lost["msg_id"].tolist()
    # the Labmate docks on the resend: an ack timeout after the XR4000 began to wait
    wait = trace.transitions.where(agent="xr4000", target="Dock.Wait")["t"][0]
    align = trace.transitions.where(agent="labmate", target="Dock.Align")
    assert align["cause"].tolist() == ["message:docked"]
    assert align["t"][0] >= wait + ACK_TIMEOUT - 1e-3
    # then everything goes as simulated without loss: the docking completes, the Labmate
    # leads, the XR4000 meets the obstacle, asks for the leadership and gets it
    sim = ht.simulate(ht.load(team), duration=ACKED_END)
    for agent in ("xr4000", "labmate", "operator"):
        ours = trace.transitions.where(agent=agent)
        theirs = sim.transitions.filter(
            (sim.transitions["agent"] == agent) & (sim.transitions["t"] < ACKED_END)
        )
        assert ours["target"].tolist() == theirs["target"].tolist(), agent
        assert ours["cause"].tolist() == theirs["cause"].tolist(), agent
    assert trace.transitions.where(agent="xr4000", target="Transport.Lead")["cause"].tolist() == [
        "message:grant"
    ]


# ------------------------------------------------------------------ the copies' numbers
def counterexample_with(found: Path, rows: list[tuple]) -> Trace:
    """The counterexample's run with its message table replaced by ``rows`` (sender,
    receiver, type, seq, t_send, status, reason)."""
    data = json.loads((found / "deadlock" / "trace.json").read_text())
    data["messages"] = {
        "instance": [0] * len(rows),
        "seq": [r[3] for r in rows],
        "sender": [r[0] for r in rows],
        "receiver": [r[1] for r in rows],
        "socket": ["data" if r[2] == "state" else "control" for r in rows],
        "type": [r[2] for r in rows],
        "t_send": [r[4] for r in rows],
        "t_recv": [None if r[5] == "lost" else r[4] + 0.01 for r in rows],
        "status": [r[5] for r in rows],
        "reason": [r[6] for r in rows],
        "msg_id": [-1] * len(rows),
    }
    return Trace.from_dict(data)


LOST = ("lost", "loss (replay)")
DELIVERED = ("delivered", "")


def test_each_lost_copy_is_numbered_among_its_types_datagrams_to_its_process(found):
    """Hand-counted: the Labmate is sent 'docked' at 1.0 and 2.0 (the second lost: copy
    2; the streams' copies in between do not count, nor does a 'docked' to another
    process's agent), 'ready' once (lost: copy 1), and two 'docked' by the XR4000 at one
    moment, numbered by its sequence (the one lost: copy 3); the XR4000's first 'ack'
    from the Labmate is lost (copy 1 at its process). A process hosting the Labmate and
    the operator counts the 'docked' to the operator too; a datagram lost to both of its
    agents is one drop."""
    cteam = compile_team(ht.load(EXPERIMENT2))
    rows = [
        ("xr4000", "labmate", "docked", 3, 1.0, *DELIVERED),
        ("xr4000", "labmate", "state", 4, 1.5, *LOST),  # (a stream: not a scripted loss)
        ("xr4000", "operator", "docked", 5, 1.6, *DELIVERED),
        ("xr4000", "labmate", "docked", 6, 2.0, *LOST),
        ("labmate", "xr4000", "ack", 2, 2.5, *LOST),
        ("labmate", "xr4000", "ready", 3, 3.0, *DELIVERED),
        ("xr4000", "labmate", "ready", 7, 3.0, *LOST),
        ("xr4000", "labmate", "docked", 9, 4.0, *DELIVERED),
        ("xr4000", "labmate", "docked", 8, 4.0, *LOST),
        ("xr4000", "labmate", "docked", 10, 5.0, *LOST),  # (a broadcast, lost to both)
        ("xr4000", "operator", "docked", 10, 5.0, *LOST),
    ]
    trace = counterexample_with(found, rows)
    labmate = losses(trace, cteam, ["labmate"])
    assert [(x.sender, x.receivers, x.type, x.copy) for x in labmate] == [
        ("xr4000", ("labmate",), "docked", 2),
        ("xr4000", ("labmate",), "ready", 1),
        ("xr4000", ("labmate",), "docked", 3),
        ("xr4000", ("labmate",), "docked", 5),
    ]
    assert drops(labmate) == {"docked": {2, 3, 5}, "ready": {1}}
    assert drops(losses(trace, cteam, ["xr4000"])) == {"ack": {1}}
    assert drops(losses(trace, cteam, ["operator"])) == {"docked": {2}}
    both = losses(trace, cteam, ["operator", "labmate"])
    assert drops(both) == {"docked": {3, 4, 6}, "ready": {1}}
    assert both[-1].receivers == ("labmate", "operator")
    assert (
        both[-1].text == "xr4000 -> labmate, operator: docked sent at t=5 s is dropped "
        "at labmate, operator's process (--drop-copy docked:6)"
    )


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (
            [
                ("xr4000", "labmate", "docked", 3, 1.0, *DELIVERED),
                ("xr4000", "labmate", "docked", 3, 1.0, *DELIVERED),
            ],
            "xr4000 -> labmate: docked sent at t=1 s is duplicated: a live run can drop a "
            "datagram, not duplicate one",
        ),
        (
            [
                ("xr4000", "labmate", "docked", 3, 1.0, *LOST),
                ("operator", "labmate", "docked", 0, 1.0, *DELIVERED),
            ],
            "xr4000 -> labmate: docked is lost, and operator's 'docked' to labmate was sent at "
            "the same moment (t=1 s): which of them arrives first live",
        ),
        (
            [("xr4000", "labmate", "undock", 3, 1.0, *LOST)],
            "it loses a copy of 'undock', a type this team does not declare",
        ),
        (
            [
                ("xr4000", "labmate", "docked", 3, 1.0, *LOST),
                ("xr4000", "operator", "docked", 3, 1.0, *DELIVERED),
            ],
            "xr4000 -> labmate: docked is lost, and reaches operator in the same process: a "
            "process drops a datagram for all its agents",
        ),
    ],
)
def test_losses_a_live_run_cannot_script_are_refused(found, rows, message):
    with pytest.raises(CounterexampleError, match=re.escape(message)):
        losses(
            counterexample_with(found, rows),
            compile_team(ht.load(EXPERIMENT2)),
            ["labmate", "operator"],
        )


# ------------------------------------------------------------------ bad input
def refused(args: list[str], capsys, tmp_path: Path, command: str = "launch") -> str:
    """``launch`` (or ``live``) with ``args``: exit 2, one line, nothing written or
    started."""
    out = tmp_path / "out"
    assert main([command, *args, "--time-scale", "4", "-o", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert not out.exists()
    return lines[0]


def test_bad_counterexamples_are_one_line_and_start_nothing(found, tmp_path, capsys):
    plain = str(experiment2(tmp_path, False))
    # another team's
    line = refused([str(HANDSHAKE), "--losses-from", str(found / "deadlock")], capsys, tmp_path)
    assert (
        "a counterexample of team 'experiment2' (agents xr4000, labmate, operator), "
        "not of this team 'live handshake' (agents requester, granter)" in line
    )
    assert line == refused(
        [
            str(HANDSHAKE),
            "--agent",
            "requester",
            "--listen",
            "127.0.0.1:0",
            "--losses-from",
            str(found / "deadlock"),
        ],
        capsys,
        tmp_path,
        "live",
    )
    # a property that holds: verify wrote no counterexample of it
    line = refused([plain, "--losses-from", str(found / "docked_first")], capsys, tmp_path)
    assert "'docked_first' holds" in line and "no counterexample to replay" in line
    # verify's folder itself: which of its counterexamples?
    line = refused([plain, "--losses-from", str(found)], capsys, tmp_path)
    assert (
        "is verify's output folder: give one of its counterexamples ("
        f"{found / 'carried'}, {found / 'deadlock'})" in line
    )
    # not something verify wrote
    line = refused([plain, "--losses-from", str(tmp_path)], capsys, tmp_path)
    assert "not a counterexample 'hybridteam verify' wrote" in line
    # a violation no run reproduced
    spurious = tmp_path / "spurious"
    shutil.copytree(found, spurious)
    summary = json.loads((spurious / "verify.json").read_text())
    changed = copy.deepcopy(summary)
    changed["properties"]["deadlock"]["replay"]["verdict"] = "spurious (abstraction)"
    (spurious / "verify.json").write_text(json.dumps(changed))
    line = refused(
        [plain, "--losses-from", str(spurious / "deadlock" / "trace.json")], capsys, tmp_path
    )
    assert "'deadlock' is violated in the skeleton only" in line
    # a counterexample whose loss a live run cannot script (a copy duplicated)
    (spurious / "verify.json").write_text(json.dumps(summary))
    data = json.loads((found / "deadlock" / "trace.json").read_text())
    messages = data["messages"]
    dup = messages["type"].index("docked")
    for column in messages.values():
        column.append(column[dup])
    (spurious / "deadlock" / "trace.json").write_text(json.dumps(data))
    line = refused([plain, "--losses-from", str(spurious / "deadlock")], capsys, tmp_path)
    assert (
        "docked sent at t=11.25 s is duplicated: a live run can drop a datagram, not "
        "duplicate one" in line
    )


# ------------------------------------------------------------------ one process: live
@pytest.mark.slow
def test_live_drops_the_counterexample_losses_of_its_agents(tmp_path):
    """``live --losses-from``: verify's counterexample of the small handshake (its
    request lost: the requester waits in Asking for good) in one process hosting both
    agents: the request is dropped there, as the counterexample loses it."""
    out = tmp_path / "verify"
    assert (
        main(["verify", str(HANDSHAKE), "--losses", "1", "-o", str(out), "--progress", "none"]) == 1
    )
    cex = json.loads((out / "verify.json").read_text())["properties"]["deadlock"]
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "live",
            str(HANDSHAKE),
            "--agent",
            "requester",
            "--agent",
            "granter",
            "--listen",
            "127.0.0.1:0",
            "--time-scale",
            "8",
            "--duration",
            "3",
            "--losses-from",
            str(out / "deadlock"),
            "-o",
            str(tmp_path / "live"),
        ],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    trace = Trace.load(tmp_path / "live" / "trace.json")
    assert trace.meta["live"]["injected"]["drop_copies"] == {"request": [1]}
    assert (
        trace.messages["type"].tolist(),
        trace.messages["status"].tolist(),
        trace.messages["reason"].tolist(),
    ) == (["request"], ["lost"], ["loss (scripted)"])
    assert (
        configuration(trace)
        == cex["configurations"][0]
        == "requester in Asking; granter in Listening"
    )

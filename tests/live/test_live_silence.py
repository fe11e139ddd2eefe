"""Silence between the world process and the agents' processes (docs/live.md, *The world
process*): an agent's process whose poses go unanswered stops with its trace; the world
process holds a silent agent's last pose and records the silence."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import time

import numpy as np

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.live import world as world_module
from hybridteam.live.run import LiveRun
from hybridteam.live.transport import UdpTransport
from hybridteam.live.wire import POSE, READING, WORLD_INDEX, Codec
from hybridteam.trace import Trace
from tests.live.test_live import free_port
from tests.live.test_live_world import EXPERIMENT2, LABMATE, TIMEOUT, XR4000, cteam, host, team

__all__ = ["cteam", "team"]  # (the fixtures, imported to be used here)

OPERATOR = 2


def test_an_agent_whose_world_process_falls_silent_stops_with_its_trace(tmp_path):
    """A stand-in world process gives the Labmate its first reading, then answers none of
    its poses: with ``--world-timeout 0.5`` the run ends 'stopped', saying why, in one
    logged line, its trace and summary written. It cannot end before 0.5 wall seconds
    (2.5 run seconds at time scale 5) after its first pose, sent at run time 0 or later;
    without the rule it would run its whole --duration (200 run seconds)."""
    world = UdpTransport(("127.0.0.1", 0))
    port = free_port()  # (the process's)
    out = tmp_path / "labmate"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "live",
            str(EXPERIMENT2),
            "--agent",
            "labmate",
            "--listen",
            f"127.0.0.1:{port}",
            "--peer",
            f"127.0.0.1:{world.address[1]}",
            "--world-timeout",
            "0.5",
            "--time-scale",
            "5",
            "--duration",
            "200",
            "-o",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        # its first reading, sent until it arrives (the process binds its port first)
        codec = Codec(compile_team(ht.load(EXPERIMENT2)))
        world.peers = [("127.0.0.1", port)]
        end, seq, poses = time.monotonic() + TIMEOUT, 0, 0
        while proc.poll() is None and time.monotonic() < end:
            if not poses:
                world.send(
                    codec.encode_world(
                        READING,
                        WORLD_INDEX,
                        LABMATE,
                        seq,
                        {"arm.0": 0.0, "arm.1": 0.0, "arm.2": 0.0},
                        time.time(),
                    ),
                    "data",
                )
                seq += 1
            if world.wait(0.1):
                poses += sum(codec.decode(d).type == POSE for d, _ in world.receive())
        stdout, stderr = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        world.close()
    assert proc.returncode == 0, stderr.decode()
    assert poses >= 1
    why = "the world process's silence (no reading within 0.5 s of a pose sent)"
    warnings = [line for line in stderr.decode().splitlines() if "WARNING" in line]
    assert len(warnings) == 1 and warnings[0].endswith(why), warnings
    trace = Trace.load(out / "trace.json")
    outcome = trace.outcomes[0]
    assert outcome["outcome"] == "stopped"
    assert outcome["message"].startswith(f"stopped by {why} at t=")
    assert 2.5 <= outcome["t"] < 200
    assert trace.transitions.where(agent="labmate")["target"].tolist()[0] == "Dock.Idle"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "stopped"
    assert stdout == b""
    assert (
        f"labmate stopped at t={outcome['t']:.6g}: stopped by {why}"
        in stderr.decode().strip().splitlines()[-1]
    )


class FakeTime:
    """The world module's clock, moved by hand (``time.time`` for send times)."""

    def __init__(self) -> None:
        self.now = 100.0

    def monotonic(self) -> float:
        return self.now

    @staticmethod
    def time() -> float:
        return time.time()


def test_the_world_process_holds_a_silent_agent_s_last_pose_and_records_the_silence(
    cteam, monkeypatch, caplog
):
    """Timeout 1 s. t=1: poses of the XR4000 and the Labmate (the operator sends none).
    0.6 s later, t=2: the Labmate's alone; nobody silent yet. 0.6 s later, t=3: the
    Labmate's again; the XR4000 (1.2 s since its pose) and the operator (1.2 s since the
    world's start) are silent: logged and recorded, the XR4000's last pose held as its
    state. t=4: the XR4000 sends again: its silence ends there."""
    clock = FakeTime()
    monkeypatch.setattr(world_module, "time", clock)
    sim, link, _ = host(cteam)
    link.timeout = 1.0
    world, idx = sim.ensemble.world, np.array([0])
    codec = link.codec
    seq = {XR4000: 0, LABMATE: 0}

    def pose(agent: int, x: float) -> None:
        link.take(
            codec.decode(
                codec.encode_world(
                    POSE, agent, WORLD_INDEX, seq[agent], {"x": x, "y": 0.0, "theta": 0.0}, 0.0
                )
            )
        )
        seq[agent] += 1

    def instant(t: float) -> None:
        sim.ensemble.t[:] = t
        world.update(sim.access, idx)

    caplog.set_level(logging.INFO, logger="hybridteam.live")
    pose(XR4000, 2.0)
    pose(LABMATE, -1.0)
    instant(1.0)
    clock.now += 0.6
    pose(LABMATE, -1.1)
    instant(2.0)
    assert link.silence_record() == []
    clock.now += 0.6
    pose(LABMATE, -1.2)
    instant(3.0)
    assert link.silence_record() == [
        {"agent": "xr4000", "from": 1.0, "noticed": 3.0, "to": None},
        {"agent": "operator", "from": None, "noticed": 3.0, "to": None},
    ]
    assert sim.access.state(XR4000, idx)[0].tolist() == [2.0, 0.0, 0.0]  # held
    assert sim.access.state(LABMATE, idx)[0].tolist() == [-1.2, 0.0, 0.0]
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warned == [
        "agent 'xr4000' silent for 1 s (last pose at t=1.000): the world holds its last pose",
        "agent 'operator' silent for 1 s (no pose yet): the world holds its last pose",
    ]
    clock.now += 0.1
    pose(XR4000, 2.5)
    instant(4.0)
    assert link.silence_record() == [
        {"agent": "xr4000", "from": 1.0, "noticed": 3.0, "to": 4.0},
        {"agent": "operator", "from": None, "noticed": 3.0, "to": None},
    ]
    assert sim.access.state(XR4000, idx)[0].tolist() == [2.5, 0.0, 0.0]


def test_a_world_process_that_hears_no_agent_records_every_silence(team):
    """A world process with no agent running: every agent is silent from its start, in
    its trace's meta.live (the run goes on to its duration)."""
    transport = UdpTransport(("127.0.0.1", 0))
    try:
        trace = LiveRun(
            team, [], transport, world=True, duration=1.0, time_scale=1, world_timeout=0.2
        ).run()
    finally:
        transport.close()
    assert trace.outcomes[0]["outcome"] == "ok"
    silent = trace.meta["live"]["world_silent"]
    assert [(s["agent"], s["from"], s["to"]) for s in silent] == [
        ("xr4000", None, None),
        ("labmate", None, None),
        ("operator", None, None),
    ]
    assert all(0.2 <= s["noticed"] <= 1.0 for s in silent)

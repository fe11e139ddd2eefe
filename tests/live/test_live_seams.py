"""The engine's seams for live runs, without sockets or the wall clock: a scripted clock
puts arrivals on the queue (``Network.arrive``) and an outlet collects what the hosted
agent sends (``Network.outlet``), so every time is known exactly."""

from __future__ import annotations

from pathlib import Path

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.schedule import earliest
from hybridteam.engine.run.simulator import Simulator
from hybridteam.live.hosting import hosted_team

TEAM = Path(__file__).parents[1] / "fixtures" / "live" / "handshake.yaml"
REQUESTER, GRANTER = 0, 1


class ScriptedClock:
    """Arrivals at scripted run times, each queued once the run is about to pass it."""

    def __init__(self, arrivals: list[tuple[float, Message]]) -> None:
        self.arrivals = arrivals
        self.asked = 0

    def advance(self, ens) -> None:
        self.asked += 1
        due = float(earliest(ens.instants, ens.instants_at.shape[0])[0][0])
        while self.arrivals and self.arrivals[0][0] <= due:
            t, msg = self.arrivals.pop(0)
            ens.network.arrive(0, msg, t)


class Collect:
    """An outlet that keeps what it is handed."""

    def __init__(self) -> None:
        self.sent: list[tuple[Message, float]] = []

    def send(self, msg: Message, rank: float) -> None:
        self.sent.append((msg, rank))


def granter_alone(arrivals, outlet=None) -> tuple[Simulator, ScriptedClock]:
    cteam = hosted_team(compile_team(ht.load(TEAM)), ["granter"])
    clock = ScriptedClock(arrivals)
    sim = Simulator(cteam, 1, clock=clock)
    sim.ensemble.network.outlet = outlet
    return sim, clock


def test_arrivals_and_sends_go_through_the_seams():
    """A request arriving at 1.25 is answered at 1.25 with the grant the model says
    (amount = need); the acknowledged 'done' at 2.0 is acknowledged and ends the run."""
    outlet = Collect()
    sim, clock = granter_alone(
        [
            (1.25, Message(REQUESTER, GRANTER, 0, 1.0, "control", "request", {"need": 3.0})),
            (2.0, Message(REQUESTER, GRANTER, 1, 1.75, "control", "done", {}, msg_id=0)),
        ],
        outlet,
    )
    trace = sim.run()
    assert [
        (r.t, r.source, r.target, r.cause) for r in trace.transitions if r.agent == "granter"
    ] == [
        (0.0, "", "Listening", "init"),
        (1.25, "Listening", "Granting", "message:request"),
        (2.0, "Granting", "Closed", "message:done"),
    ]
    (grant, rank), (ack, _) = outlet.sent
    assert (grant.sender, grant.receiver, grant.type, grant.fields, grant.t_send, rank) == (
        GRANTER,
        REQUESTER,
        "grant",
        {"amount": 3.0},
        1.25,
        0.0,
    )
    assert (ack.receiver, ack.type, ack.fields, ack.note, ack.t_send) == (
        REQUESTER,
        "ack",
        {"id": 0.0},
        "ack",
        2.0,
    )
    m = trace.messages
    assert list(zip(m["type"], m["t_send"], m["t_recv"], m["status"], strict=True)) == [
        ("request", 1.0, 1.25, "delivered"),
        ("done", 1.75, 2.0, "delivered"),
    ]
    assert trace.outcomes[0]["outcome"] == "ok" and trace.outcomes[0]["t"] == 2.0
    assert trace.outcomes[0]["message"] == "'granter' reached a final mode (the end rule)"
    assert clock.asked >= 3  # asked before every step


def test_no_deadlock_is_concluded_while_datagrams_may_arrive():
    """Both agents in one process: the request leaves through the outlet at 1.0 and is
    on the wire, not on the queue, so nothing is pending while both wait. A simulation
    would call that a deadlock; live, the copy may still arrive, so the run goes on to
    its end (6 s) when, as here, it never does."""
    outlet = Collect()
    sim = Simulator(
        hosted_team(compile_team(ht.load(TEAM)), ["requester", "granter"]),
        1,
        clock=ScriptedClock([]),
    )
    sim.ensemble.network.outlet = outlet
    trace = sim.run()
    assert [m.type for m, _ in outlet.sent] == ["request"]
    assert (trace.outcomes[0]["outcome"], trace.outcomes[0]["t"]) == ("ok", 6.0)


def test_a_remote_agent_is_inert():
    """The requester, hosted elsewhere, neither moves on its own (its 'after: 1.0') nor
    sends anything here; only the granter's modes are entered and left."""
    outlet = Collect()
    sim, _ = granter_alone([], outlet)
    trace = sim.run()
    assert outlet.sent == []
    assert trace.transitions.where(agent="requester")["target"].tolist() == ["Idle"]
    assert trace.outcomes[0]["t"] == 6.0


BEACON = """\
kind: protocol
protocol: beacon
streams:
  - {message: ping, rate: 10, fields: {x: x}}
region:
  roles: [go]
  initial: Going
  modes:
    Going: {role: go}
"""

WATCHED = """\
team: watched
network: {latency: 0.01}
agents:
  r:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    modes:
      Run:
        protocol: beacon.yaml
        roles: {go: {inputs: {v: 1, omega: 0}, period: 0.1}}
  s:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Waiting
    modes:
      Waiting: {transitions: [{to: Seen, guard: "est_ping_x > 0.5"}]}
      Seen: {final: true}
simulation: {duration: 2.0}
"""


def test_an_agent_without_streams_reads_a_remote_agent_s_stream(tmp_path, team_from_yaml):
    """The watcher streams nothing and its streaming teammate is remote, so no agent here
    streams; the copies that arrive still update its estimates, and its guard on them
    holds at the first copy past x = 0.5 (x = 0.6, sent at 0.6, arriving at 0.65)."""
    (tmp_path / "beacon.yaml").write_text(BEACON)
    team = team_from_yaml(WATCHED)
    cteam = hosted_team(compile_team(team), ["s"])
    pings = [
        (0.05 + 0.1 * k, Message(0, -1, k, 0.1 * k, "data", "ping", {"x": 0.1 * k}))
        for k in range(10)
    ]
    for _, msg in pings:
        msg.receiver = 1
    sim = Simulator(cteam, 1, clock=ScriptedClock(pings))
    sim.ensemble.network.outlet = Collect()
    trace = sim.run()
    assert trace.transitions.where(agent="s", target="Seen")["t"].tolist() == [0.05 + 0.1 * 6]

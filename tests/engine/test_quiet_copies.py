"""A stream copy that nothing reads before the receiver's next tick is not an instant.

``r`` drives at 0.5 m/s and streams its ``x`` at 10 Hz over a link of 30 ms latency and
20 ms jitter; ``s`` samples a law every 0.1 s. With jitter every copy arrives at a time
of its own, and each arrival used to be an instant (a step ending there, the world, the
discrete phase, the checks). No transition of ``s`` waits for the copies and its law
reads them only at its ticks, so the run's instants are the ticks alone; the copies are
still received at their own arrival times, in the same order, with the same rows, and the
law reads the same estimates (the closed form below).
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator

BEACON = """\
kind: protocol
protocol: beacon
streams:
  - {message: ping, rate: 10, fields: {x: x}, while: [Going]}
region:
  roles: [go]
  initial: Going
  modes:
    Going: {role: go}
"""

TEAM = """\
team: chase
network: {{latency: {latency}, jitter: {jitter}}}
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    initial: Run
    modes:
      Run:
        protocol: beacon.yaml
        roles: {{go: {{inputs: {{v: 0.5, omega: 0}}, period: 0.1}}}}
        transitions: [{{to: Off, after: {stop}}}]
      Off: {{inputs: {{v: 0, omega: 0}}, period: 0.1, transitions: [{{to: Done, on: go}}]}}
      Done: {{final: true}}
  s:
    plant: {{kind: unicycle, state: {{x: 0, y: 1, theta: 0}}}}
    initial: Wait
    modes:
      Wait:
        inputs: {{v: 0, omega: 0}}
        period: 0.1
        transitions: [{{to: Go, after: {go_at}}}{listen}]
      Go:
        inputs: {{v: est_ping_x, omega: 0}}
        period: 0.1
        transitions: [{{to: Done, on: go}}{listen}]
      Done: {{final: true}}
simulation: {{duration: 1.0, sample_period: 0.1}}
"""


def chase(tmp_path, *, latency=0.03, jitter=0.02, stop=5.0, go_at=0.2, listen=False):
    """The team; ``listen``: ``s`` has a transition on ``ping`` (it runs nothing), so each
    copy's arrival is an instant, as every copy's was before quiet copies."""
    (tmp_path / "beacon.yaml").write_text(BEACON)
    path = tmp_path / "team.yaml"
    on_ping = ", {on: ping}" if listen else ""
    path.write_text(
        TEAM.format(latency=latency, jitter=jitter, stop=stop, go_at=go_at, listen=on_ping)
    )
    return ht.load(path)


def instants(team):
    """The run and the times of its instants (each instant takes one snapshot)."""
    sim = Simulator(compile_team(team), snapshots=True)
    trace = sim.run()
    snapshots = sim.ensemble.rec.snapshots
    assert snapshots is not None
    return trace, sorted({t for _, times, _ in snapshots for t in times.tolist()})


def test_jittered_copies_make_no_instants(tmp_path):
    trace, times = instants(chase(tmp_path))
    ticks = [k * 0.1 for k in range(11)]  # both laws' ticks; the run ends at the last
    assert times == ticks
    m = trace.messages
    np.testing.assert_array_equal(m["t_send"], ticks)  # a copy sent at every tick,
    # received at its own arrival time, but the last, in flight when the run ends
    assert m["status"].tolist() == ["delivered"] * 10 + ["lost"]
    assert m["reason"][-1] == "run ended"
    late = m["t_recv"][:10] - m["t_send"][:10]
    assert np.all((late >= 0.03) & (late < 0.05))
    assert len(set(late.tolist())) == 10  # jitter: each copy at a time of its own


def test_a_copy_a_transition_waits_for_is_an_instant(tmp_path):
    _, times = instants(chase(tmp_path, listen=True))
    trace, _ = instants(chase(tmp_path))
    arrivals = trace.messages["t_recv"][trace.messages["t_recv"] < 1.0]
    assert set(arrivals.tolist()) <= set(times)
    assert len(times) == 11 + arrivals.size


def test_held_copies_are_received_as_instants_would_receive_them(tmp_path):
    """The same copies, rows and estimates whether each arrival is an instant or not."""
    quiet = ht.simulate(chase(tmp_path))
    heard = ht.simulate(chase(tmp_path, listen=True))
    for column in ("sender", "receiver", "seq", "t_send", "t_recv", "status", "reason"):
        np.testing.assert_array_equal(quiet.messages[column], heard.messages[column])
    # s enters Go at 0.2 and at each tick k * 0.1 reads the copy sent one tick before
    # (30-50 ms old), r's x = 0.5 (k - 1) 0.1: its speed over [0.2, 1.0] is 0.05, 0.10,
    # ..., 0.40, so it ends 0.1 * 0.05 * (1 + ... + 8) = 0.18 m on
    for run in (quiet, heard):
        x_end = run.samples["s"][-1, 0, 0]
        assert x_end == pytest.approx(0.18, abs=1e-12)


def test_copies_in_flight_when_the_streams_stop_are_instants_again(tmp_path):
    """r stops streaming at 0.5 s with copies still in flight (latency 0.25 s): then the
    team is stalled (both wait for ``go``), and the deadlock is found where the last
    copy, sent at 0.4 s, arrives (s reads its first estimate at 0.3 s, the copy of 0 s)."""
    run = ht.simulate(chase(tmp_path, latency=0.25, jitter=0.0, stop=0.5, go_at=0.3))
    (end,) = run.summary()["instances"]
    assert end["outcome"] == "deadlock"
    assert end["t_end"] == 4 * 0.1 + 0.25


def test_a_copy_without_latency_is_read_at_its_send_instant(tmp_path):
    """With no latency a copy arrives within the instant it is sent at, where a law whose
    mode was entered then samples again: s enters Go at 0.2 s and reads the copy r sends
    at 0.2 s (x = 0.1), not the one of 0.1 s. At its later ticks k * 0.1 the laws sample
    before the streams send, so s reads the copy of the tick before: speeds 0.10, 0.10,
    0.15, ..., 0.40 over [0.2, 1.0], so s ends 0.1 * (0.1 + 0.05 * (2 + ... + 8)) m on."""
    run = ht.simulate(chase(tmp_path, latency=0.0, jitter=0.0))
    assert run.samples["s"][-1, 0, 0] == pytest.approx(0.1 * (0.1 + 0.05 * 35), abs=1e-12)

"""Messages nobody waits for, arriving together, are taken a run at a time.

Six robots each send ``hello`` at t = 1 s; with 0.03 s of latency all six copies reach
``r`` at 1.03 s, and ``r`` waits only for ``go``. Each copy is a micro-step of its own
(delivered, recorded, counted towards the Zeno cap) whether the engine takes them in
rounds (an ensemble's instants, one array pass per copy) or in one run (a single run's).
The single run and every member of an ensemble must agree, and the Zeno cap must cut the
run of copies where the rounds would.
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht

SENDER = """
  s{k}:
    plant: {{kind: flow, state: {{c: 0}}}}
    initial: Wait
    modes:
      Wait: {{transitions: [{{to: Sent, after: 1.0, do: [{{send: {what}, to: r}}]}}]}}
      Sent: {{final: true}}"""

TEAM = """
team: chorus
network: {{latency: 0.03}}
agents:
  r:
    plant: {{kind: flow, state: {{c: 0}}}}
    initial: Listen
    modes:
      Listen: {{transitions: [{{to: Done, on: go}}]}}
      Done: {{final: true}}{senders}
simulation: {{duration: 2.0{zeno}}}
"""


def chorus(make, cap=None, go_from=None):
    """``go_from``: that sender sends ``go`` instead, which ``r`` waits for."""
    senders = "".join(SENDER.format(k=k, what="go" if k == go_from else "hello") for k in range(6))
    zeno = "" if cap is None else f", zeno: {{max_steps_per_instant: {cap}}}"
    return make(TEAM.format(senders=senders, zeno=zeno))


def rows(run, i=0):
    """Instance ``i``'s message rows, in the trace's order (reprs: NaN equals NaN)."""
    m = run.messages
    keep = m["instance"] == i
    return [
        repr(tuple(m[c][keep].tolist()))
        for c in ("sender", "receiver", "t_send", "t_recv", "status", "reason")
    ]


def ends(run):
    return [(row["outcome"], row["t_end"], row["message"]) for row in run.summary()["instances"]]


@pytest.mark.parametrize("cap", [None, 4])
def test_a_single_run_takes_the_copies_as_an_ensemble_member_does(team_from_yaml, cap):
    team = chorus(team_from_yaml, cap)
    single = ht.simulate(team)
    many = ht.simulate(team, n=6, seed=[0] * 6)  # six members: the copies go in rounds
    assert ends(many) == ends(single) * 6
    for i in range(6):
        assert rows(many, i) == rows(single)
    delivered = np.sum(single.messages["status"] == "delivered")
    ((outcome, t_end, _),) = ends(single)
    assert t_end == 1.0 + 0.03
    if cap is None:  # every copy delivered at 1.03 s; then nothing is pending: deadlock
        assert (delivered, outcome) == (6, "deadlock")
    else:  # the 4th micro-step at 1.03 s reaches the cap: two copies never delivered
        assert (delivered, outcome) == (4, "zeno")


def test_a_message_waited_for_inside_the_run_still_fires(team_from_yaml):
    """s3 sends ``go``: the run of copies stops at it (queue order: the senders' order),
    ``r`` takes Listen -> Done in its own micro-step, then the last two copies arrive."""
    team = chorus(team_from_yaml, go_from=3)
    single = ht.simulate(team)
    many = ht.simulate(team, n=6, seed=[0] * 6)
    assert ends(many) == ends(single) * 6
    for i in range(6):
        assert rows(many, i) == rows(single)
    tr = single.transitions
    done = [(r.t, r.step, r.cause) for r in tr if r.agent == "r" and r.target == "Done"]
    assert done == [(1.0 + 0.03, 3, "message:go")]  # after the copies of s0, s1, s2

"""``hybridteam verify`` on the role-assignment protocol, its mutants and the docking
handshake: each verdict is one the protocol's design says must come out (a known
mistake is found, with a counterexample that shows it; the correct protocol holds)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hybridteam import load
from hybridteam.api import simulate
from hybridteam.cli import main
from hybridteam.verify import Options, verify
from hybridteam.verify.machine import Machine
from hybridteam.verify.paths import leaves

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = (ROOT / "protocols" / "role_assignment.yaml").read_text()
ROLES = (ROOT / "examples" / "protocols" / "roles_verify.yaml").read_text()
SCENARIO = {
    "b": "  - {at: 1.0, agent: b, raise: want_lead}\n",
    "c": "  - {at: 2.0, agent: c, raise: want_lead}\n",
    "a": "  - {at: 3.0, agent: a, raise: resign}\n",
}
NO_OPERATOR = "  no_operator: always(not in_mode(operator, Command))\n"


def roles_team(
    tmp_path: Path, events: str, protocol: str = PROTOCOL, extra: str = "", without_c: bool = False
):
    """The example's three robots and operator (``without_c``: two robots) with a
    (mutated) protocol beside them, the scenario's events ``events`` (a subset of 'bca')
    and extra requirements."""
    text = ROLES.replace("protocol: role_assignment", "protocol: mutant.yaml").replace(
        "operator: role_assignment", "operator: mutant.yaml"
    )
    if without_c:
        text = text[: text.index("  c:\n")] + text[text.index("  operator:\n") :]
        text = text[: text.index("  c_answered:")] + text[text.index("simulation:") :]
    head, rest = text.split("scenario:\n", 1)
    reqs = rest[rest.index("requirements:\n") :]
    text = head + "scenario:\n" + "".join(SCENARIO[e] for e in events) + reqs
    text = text.replace("requirements:\n", "requirements:\n" + extra)
    (tmp_path / "mutant.yaml").write_text(protocol)
    path = tmp_path / "team.yaml"
    path.write_text(text)
    return load(path)


def mutate(old: str, new: str) -> str:
    assert old in PROTOCOL
    return PROTOCOL.replace(old, new)


def verdicts(report) -> dict:
    return {v.prop.name: v for v in report.verdicts}


def replayed(report, name: str):
    """The run that replays property ``name``'s counterexample (it must reproduce it)."""
    _, r, _ = report.replays[name]
    assert r.reproduced, r.reason
    return r.run


def together(run, mode: str) -> set[str]:
    """The agents that are in ``mode`` at one moment with another agent in it (read from
    the trace's mode intervals, not from the replay's own verdict)."""
    iv = [r for r in run.intervals if r.mode == mode and r.end > r.start]
    out = set()
    for x in iv:
        for y in iv:
            if x.agent != y.agent and x.start < y.end and y.start < x.end:
                out |= {x.agent, y.agent}
    return out


def final_modes(report, v) -> dict[str, list[str]]:
    """Each agent's active leaves in the violating state."""
    sk = report.skeleton
    return {
        ca.name: m
        for ca, m in zip(sk.original.agents, leaves(sk, report.graph.states[v.state]), strict=True)
    }


def test_the_role_protocol_holds_with_a_request_and_a_lost_copy(tmp_path):
    report = verify(roles_team(tmp_path, "b"), Options(losses=1))
    assert report.graph.exhaustive
    # states are canonical: the form is idempotent, with no duplicate filter entry twice
    # (a retransmission's filter entry is in the parent and read back from the engine)
    m = Machine(report.skeleton)
    for s in report.graph.states:
        assert len(set(s.seen)) == len(s.seen) and m.canonical(s) == s
    assert {n: v.holds for n, v in verdicts(report).items()} == {
        "one_leader": True,
        "b_answered": True,
        "c_answered": True,
        "deadlock": True,
    }


def test_three_requests_and_a_resignation_hold_without_losses():
    report = verify(load(ROOT / "examples" / "protocols" / "roles_verify.yaml"), Options(losses=0))
    assert report.graph.exhaustive and len(report.graph.states) > 10_000
    assert all(v.holds for v in report.verdicts)


# -- mutants: plausible design mistakes, each found --------------------------------------

GRANT = """        - to: Follow
          on: request
          guard: t - last_change >= min_hold
          do: [leader = msg_sender, last_change = t, {send: grant, to: sender}]"""
REQUEST = """        - to: Requesting
          on: want_lead
          do: [{send: request, to: leader, fields: {priority: priority}}]"""


def test_mutant_leader_stays_lead_after_granting(tmp_path):
    bad = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
    report = verify(roles_team(tmp_path, "b", bad), Options(losses=0))
    v = verdicts(report)["one_leader"]
    assert v.holds is False
    assert final_modes(report, v)["a"] == ["Transport.Lead"]
    assert final_modes(report, v)["b"] == ["Transport.Lead"]
    text = "\n".join(report.counterexample(v))
    assert "b -> a: request #0 (priority=0) arrives" in text
    assert "a -> b: grant #0 arrives" in text
    assert together(replayed(report, "one_leader"), "Transport.Lead") == {"a", "b"}


def test_mutant_requester_leads_when_it_asks(tmp_path):
    bad = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
    report = verify(roles_team(tmp_path, "b", bad), Options(losses=0))
    v = verdicts(report)["one_leader"]
    assert v.holds is False
    assert report.counterexample(v)[1:] == [  # replayed a millisecond into the run
        "  1. t=0.001000 s  scenario: b raises want_lead",
        "       b: Transport.Follow -> Transport.Lead",
    ]
    run = replayed(report, "one_leader")
    assert together(run, "Transport.Lead") == {"a", "b"}
    assert [r.t for r in run.transitions if r.cause == "event:want_lead"] == [0.001]


def test_mutant_offer_confirmed_to_every_acceptor(tmp_path):
    reject = "        - {on: accept, do: [{send: reject, to: sender}]}"
    bad = mutate(
        reject, reject.replace("reject", "confirm", 1).replace("{send: reject", "{send: confirm")
    )
    report = verify(roles_team(tmp_path, "a", bad), Options(losses=0))
    v = verdicts(report)["one_leader"]
    assert v.holds is False
    modes = final_modes(report, v)
    assert modes["b"] == modes["c"] == ["Transport.Lead"]
    text = "\n".join(report.counterexample(v))
    assert text.count("confirm #") >= 2 and "a -> operator: offer" not in text.split("confirm")[-1]
    assert together(replayed(report, "one_leader"), "Transport.Lead") == {"b", "c"}


def test_mutant_min_hold_deny_removed(tmp_path):
    """Within min_hold of its last change a leader must deny; without the deny the request
    goes unanswered, the requester times out and the operator takes command, though no
    message was lost. With timeouts that exceed every exchange (--timeouts long) the
    correct protocol never calls the operator without a loss."""
    deny = "        - on: request\n          do: [{send: deny, to: sender}]\n        - to: Offering"
    bad = mutate(deny, "        - to: Offering")
    opts = Options(losses=0, timeouts="long")
    good = verify(roles_team(tmp_path, "bc", extra=NO_OPERATOR), opts)
    assert verdicts(good)["no_operator"].holds is True
    # with timeouts that exceed only each robot's own exchanges the mistake shows as well
    own = verify(
        roles_team(tmp_path, "bc", mutate(deny, "        - to: Offering"), extra=NO_OPERATOR),
        Options(losses=0, timeouts="own"),
    )
    assert verdicts(own)["no_operator"].holds is False
    replayed(own, "no_operator")
    report = verify(roles_team(tmp_path, "bc", bad, extra=NO_OPERATOR), opts)
    v = verdicts(report)["no_operator"]
    assert v.holds is False
    text = "\n".join(report.counterexample(v))
    assert "Transport.Requesting -> Transport.Operated (after answer_timeout)" in text
    assert "deny" not in text and " lost" not in text
    # the shortest path is spurious (a robot that never changed role always grants: its
    # min-hold guard reads the initial last_change = -1e9), so the replay goes on to the
    # next one, where the second requester asks the new leader within min_hold
    run = replayed(report, "no_operator")
    assert report.replays["no_operator"][2] >= 2
    ms = run.messages
    assert not [r for r in ms if r.reason == "loss (replay)"]  # nothing lost
    operated = [r for r in run.transitions if r.target == "Transport.Operated"]
    granted = [r for r in run.transitions if r.cause == "message:grant"]
    assert operated and granted
    # the answer timeout (1 s) expired after the request had been ignored: exactly then
    request = max(r.t_recv for r in ms if r.type == "request" and r.status == "delivered")
    assert (
        operated[0].t >= request
        and [r.target for r in run.transitions if r.agent == "operator"][-1] == "Command"
    )


def test_mutant_duplicate_suppression_off(tmp_path):
    """A resent accept (its ack was lost) reaches the resigning leader twice: the first
    gets a confirm, the copy a reject. Whichever arrives first at the acceptor decides:
    a reject first and nobody leads, a confirm after it is ignored — leadership lost for
    good without the operator. With dedupe the copy is withheld and this cannot happen."""
    restored = (
        "  leadership_restored: always(implies(count_in_role(lead) == 0, eventually("
        "count_in_role(lead) == 1 or in_mode(operator, Command))))\n"
    )
    opts = Options(losses=1)
    good = verify(roles_team(tmp_path, "a", extra=restored, without_c=True), opts)
    assert verdicts(good)["leadership_restored"].holds is True
    bad = mutate(
        "  accept: {ack: {timeout: ack_timeout, retries: ack_retries}}",
        "  accept: {ack: {timeout: ack_timeout, retries: ack_retries, dedupe: false}}",
    )
    report = verify(roles_team(tmp_path, "a", bad, extra=restored, without_c=True), opts)
    v = verdicts(report)["leadership_restored"]
    assert v.holds is False
    text = "\n".join(report.counterexample(v))
    assert "ack arrives" in text and "is lost" in text and "accept #" in text
    assert "reject" in text
    run = replayed(report, "leadership_restored")
    ms = run.messages
    lost = [r for r in ms if r.reason == "loss (replay)"]
    assert [(r.sender, r.receiver, r.type) for r in lost] == [("a", "b", "ack")]
    accepts = [r for r in ms if r.type == "accept" and r.status == "delivered"]
    assert len(accepts) == 2 and accepts[1].reason == "retransmission"
    # nobody leads from the resignation to the end of the run, and no operator came
    assert not [r for r in run.modes if r.mode == "Transport.Lead" and r.end > 0.001]
    assert "Command" not in {r.mode for r in run.modes if r.agent == "operator"}
    # the same mistake through a network that duplicates a copy (no loss): the replay
    # delivers the one accept twice, same sequence number, no retransmission
    dup = verify(
        roles_team(tmp_path, "a", bad, extra=restored, without_c=True),
        Options(losses=0, duplicates=1),
    )
    run = replayed(dup, "leadership_restored")
    accepts = [r for r in run.messages if r.type == "accept" and r.status == "delivered"]
    assert len(accepts) == 2 and accepts[0].seq == accepts[1].seq
    assert accepts[0].reason == accepts[1].reason == ""


# -- the docking handshake --------------------------------------------------------------


def docking(tmp_path: Path, acknowledged: bool):
    text = (ROOT / "examples" / "transport" / "experiment2.yaml").read_text()
    text = text.replace(
        "requirements_from: [requirements.yaml]\n",
        "requirements:\n"
        "  carried: always(implies(in_mode(xr4000, Dock.Wait), "
        "eventually(in_mode(xr4000, Transport))))\n",
    )
    if not acknowledged:
        text = text.replace(", ack: {timeout: ack_timeout, retries: 10}}", "}")
    path = tmp_path / "experiment2.yaml"
    path.write_text(text)
    return load(path)


def test_plain_datagram_handshake_deadlocks_when_ready_is_lost(tmp_path):
    report = verify(docking(tmp_path, acknowledged=False), Options(losses=1))
    v = verdicts(report)["deadlock"]
    assert v.holds is False
    configs = report.configurations(v)
    assert (
        "xr4000 in Dock.Wait; labmate in Transport.Lead.Stop; operator in Standby" in configs
    )  # the sweep's failure: the Labmate led off, the XR4000 waits
    carried = verdicts(report)["carried"]
    assert carried.holds is False
    text = "\n".join(report.counterexample(carried))
    assert "is lost" in text and ("docked" in text or "ready" in text)
    # the replay: the engine's own run, plant and world and all, with that one copy lost
    run = replayed(report, "deadlock")
    lost = [(r.sender, r.type) for r in run.messages if r.reason == "loss (replay)"]
    assert lost == [("xr4000", "docked")]
    wait = [r for r in run.modes if r.agent == "xr4000" and r.mode == "Dock.Wait"]
    assert len(wait) == 1 and wait[0].end == run.meta["duration"] == 55.0
    assert (
        replayed(report, "carried").diagnostics[0]["requirements"]["carried"]["satisfied"] is False
    )


def test_acknowledged_handshake_survives_a_loss(tmp_path):
    report = verify(docking(tmp_path, acknowledged=True), Options(losses=1))
    assert report.graph.exhaustive
    assert verdicts(report)["deadlock"].holds and verdicts(report)["carried"].holds


# -- the explorer and the simulator agree -----------------------------------------------


def test_every_simulated_configuration_is_explored(tmp_path):
    """Lossy simulations of the three-robot team with one request (1 copy in 10 lost):
    every joint mode configuration the engine passes through is a state of the skeleton
    explored with as many control-message losses as the run had (stream copies are not
    in the skeleton)."""
    team = roles_team(tmp_path, "b")
    text = (tmp_path / "team.yaml").read_text()
    path = tmp_path / "lossy.yaml"
    path.write_text(
        text.replace("simulation:\n", "network: {latency: 0.03, loss: 0.1}\nsimulation:\n")
    )
    lossy = load(path)
    run = simulate(lossy, seed=list(range(12)), n=12)
    ms = run.messages
    worst = 0
    paths: list[list[tuple]] = []
    for i in range(12):
        lost = int(
            np.sum(
                (ms["instance"] == i)
                & (ms["status"] == "lost")
                & (ms["reason"] != "run ended")
                & (ms["type"] != "state")
            )
        )
        if lost > 1:
            continue
        worst = max(worst, lost)
        paths.append(_configurations(run, i))
    assert len(paths) > 3 and worst == 1  # runs with a lost control message among them
    report = verify(team, Options(losses=worst))
    explored = {tuple(tuple(m) for m in leaves(report.skeleton, s)) for s in report.graph.states}
    for seq in paths:
        assert set(seq) <= explored


def _configurations(run, i: int) -> list[tuple]:
    """Joint leaf configurations of instance ``i`` after each instant."""
    iv = run.intervals
    rows = iv["instance"] == i
    names = [a["name"] for a in run.meta["agents"]]
    times = sorted(set(iv["start"][rows].tolist()))
    out = []
    for t in times:
        here = (
            rows
            & (iv["start"] <= t)
            & ((iv["end"] > t) | (iv["end"] == iv["end"][rows].max()) & (iv["end"] >= t))
        )
        config = []
        for name in names:
            sel = here & (iv["agent"] == name)
            config.append(
                tuple(sorted(str(m) for m in iv["mode"][sel] if m in _leaf_paths(run, name)))
            )
        out.append(tuple(config))
    return out


def _leaf_paths(run, agent: str) -> set[str]:
    meta = next(a for a in run.meta["agents"] if a["name"] == agent)
    paths = [m["path"] for m in meta["modes"]]
    return {p for p in paths if not any(q.startswith(p + ".") for q in paths)}


# -- command line -------------------------------------------------------------------------


def test_cli_exit_codes_and_output(tmp_path, capsys):
    team = roles_team(tmp_path, "b")
    del team
    out = tmp_path / "out"
    assert (
        main(
            [
                "verify",
                str(tmp_path / "team.yaml"),
                "--losses",
                "0",
                "-o",
                str(out),
                "--progress",
                "none",
            ]
        )
        == 0
    )
    summary = json.loads((out / "verify.json").read_text())
    assert summary["exhaustive"] and summary["properties"]["one_leader"]["verdict"] == "holds"
    printed = capsys.readouterr().out
    assert "one_leader: holds" in printed and "deadlock: holds" in printed
    bad = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
    (tmp_path / "mutant.yaml").write_text(bad)
    assert (
        main(
            [
                "verify",
                str(tmp_path / "team.yaml"),
                "--losses",
                "0",
                "-o",
                str(out),
                "--progress",
                "none",
            ]
        )
        == 1
    )
    assert "one_leader: VIOLATED" in capsys.readouterr().out
    assert main(["verify", str(tmp_path / "team.yaml"), "--losses", "-1", "-o", str(out)]) == 2
    assert main(["verify", str(tmp_path / "team.yaml"), "-p", "one_ledaer", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--losses must be 0 or more" in err and "did you mean" in err.lower()


def test_fifo_order_keeps_the_verdicts(tmp_path):
    """Per-link order removes arrival orders, not the protocol's mistakes: the correct
    protocol holds and the leader-stays-Lead mutant is found in fifo order too."""
    fifo = Options(losses=1, order="fifo")
    assert all(v.holds for v in verify(roles_team(tmp_path, "b"), fifo).verdicts)
    bad = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
    report = verify(roles_team(tmp_path, "b", bad), fifo)
    assert verdicts(report)["one_leader"].holds is False
    assert together(replayed(report, "one_leader"), "Transport.Lead") == {"a", "b"}


def test_a_bounded_exploration_has_no_false_dead_ends():
    """States whose successors the bound refused are not dead ends: the response
    properties and deadlock stay unviolated (they hold exhaustively with no losses, and
    a bound cannot create a violation)."""
    report = verify(
        load(ROOT / "examples" / "protocols" / "roles_verify.yaml"),
        Options(losses=1, max_states=3000),
    )
    assert not report.graph.exhaustive and report.graph.cut
    assert not report.violated
    assert report.summary()["properties"]["one_leader"]["verdict"] == "holds (bounded)"


# -- replay: counterexamples as runs ------------------------------------------------------

FAR = """team: far
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    initial: Drive
    modes:
      Drive:
        inputs: {v: 0.5, omega: 0}
        transitions:
          - {to: Far, guard: x > 100}
      Far:
        final: true
requirements:
  stays_near: always(not in_mode(robot, Far))
simulation: {duration: 10.0}
"""


def test_a_path_the_simulator_cannot_follow_is_spurious(tmp_path, capsys):
    """At 0.5 m/s the robot is 5 m out when the 10 s run ends: the skeleton, which knows
    nothing of x, reaches Far; the run never does. The verdict says so, at which step and
    why, and the command exits 3 (only spurious violations)."""
    path = tmp_path / "far.yaml"
    path.write_text(FAR)
    report = verify(load(path), Options(losses=0))
    v = verdicts(report)["stays_near"]
    assert v.holds is False
    _, r, tried = report.replays["stays_near"]
    assert not r.reproduced and r.verdict == "spurious (abstraction)" and tried == 1
    assert (
        r.reason == "step 1 (robot: Drive -> Far ('x > 100')) does not happen in the "
        "run after t=0 s"
    )
    out = tmp_path / "out"
    assert main(["verify", str(path), "-o", str(out), "--progress", "none"]) == 3
    printed = capsys.readouterr().out
    assert "replayed in the simulator: SPURIOUS (ABSTRACTION): step 1" in printed
    summary = json.loads((out / "verify.json").read_text())
    assert summary["properties"]["stays_near"]["replay"]["verdict"] == "spurious (abstraction)"
    assert not (out / "stays_near").exists()
    assert main(["verify", str(path), "-o", str(out), "--progress", "none", "--no-replay"]) == 1


def test_a_replay_is_deterministic_and_written_as_a_run(tmp_path, capsys):
    """The same counterexample gives the same run, bit for bit; the command writes it as
    an ordinary run (trace, timeline, sequence chart) that loads back."""
    from hybridteam.trace import Trace

    reject = "        - {on: accept, do: [{send: reject, to: sender}]}"
    bad = mutate(reject, reject.replace("{send: reject", "{send: confirm"))
    team = roles_team(tmp_path, "a", bad)
    one = verify(team, Options(losses=0))
    two = verify(team, Options(losses=0))
    assert replayed(one, "one_leader").to_json() == replayed(two, "one_leader").to_json()
    out = tmp_path / "out"
    assert (
        main(
            [
                "verify",
                str(tmp_path / "team.yaml"),
                "--losses",
                "0",
                "-o",
                str(out),
                "--progress",
                "none",
            ]
        )
        == 1
    )
    assert "REPRODUCED" in capsys.readouterr().out
    trace = Trace.load(out / "one_leader" / "trace.json")
    assert together(trace, "Transport.Lead") == {"b", "c"}
    assert (out / "one_leader" / "timeline.png").stat().st_size > 10_000
    assert "confirm" in (out / "one_leader" / "sequence.mmd").read_text()
    summary = json.loads((out / "verify.json").read_text())
    assert summary["properties"]["one_leader"]["replay"]["files"][0].endswith("trace.json")


def test_schedule_earliest_moments_and_contradictions():
    """Hand-computed simple temporal networks: steps 1 ms apart, a timeout of 0.1 s from
    step 0 to step 3, and an ack that must come within 0.05 s of step 1 pushes step 1 to
    0.05 s; a timeout that would have to expire before its own step is named."""
    from hybridteam.verify.schedule import Bound, solve

    chain = [Bound(k - 1, k, 1e-3, float("inf"), f"order {k}") for k in (1, 2, 3)]
    assert solve(3, chain) == [0.0, 0.001, 0.002, 0.003]
    timer = Bound(0, 3, 0.1, 0.1, "timer")
    assert solve(3, [*chain, timer]) == [0.0, 0.001, 0.002, 0.1]
    ack = Bound(1, 3, float("-inf"), 0.05, "ack before its timeout")
    assert solve(3, [*chain, timer, ack]) == [0.0, 0.05, 0.051, 0.1]
    early = Bound(0, 2, float("-inf"), 0.0015, "step 2 early")
    why = solve(3, [*chain, Bound(0, 1, 0.1, 0.1, "timer at 1"), early])
    assert isinstance(why, str) and "timer at 1" in why and "step 2 early" in why


GO = """team: go
agents:
  leader:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Wait
    modes:
      Wait:
        inputs: {v: 0, omega: 0}
        transitions:
          - {to: Drive, after: 2.0, do: [{send: go, to: follower}]}
      Drive:
        inputs: {v: 0.5, omega: 0}
        transitions:
          - {to: Done, guard: x > 3}
      Done:
        final: true
  follower:
    plant: {kind: unicycle, state: {x: -1, y: 0, theta: 0}}
    initial: Wait
    modes:
      Wait:
        transitions:
          - {to: Drive, on: go}
      Drive:
        inputs: {v: 0.5, omega: 0}
      Done:
        final: true
simulation: {duration: 20}
"""


def test_a_lost_go_replays_to_the_engines_own_deadlock(tmp_path):
    """A plain datagram 'go', lost: the leader drives 3 m at 0.5 m/s after waiting 2 s, so
    its guard fires at t = 8 s (measured in the run), and the run stops there with the
    follower waiting — the engine's own deadlock outcome. The replay's last step is at
    the run's end, where the team's end rule closed every mode interval."""
    path = tmp_path / "go.yaml"
    path.write_text(GO)
    report = verify(load(path), Options(losses=1))
    run = replayed(report, "deadlock")
    _, r, _ = report.replays["deadlock"]
    assert abs(r.times[-1] - 8.0) < 1e-6 and r.times[1] == 2.0
    assert run.diagnostics[0]["outcome"] == "deadlock"
    assert [(m.sender, m.type) for m in run.messages if m.reason == "loss (replay)"] == [
        ("leader", "go")
    ]

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
from hybridteam.verify.paths import leaves

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = (ROOT / "protocols" / "role_assignment.yaml").read_text()
ROLES = (ROOT / "examples" / "protocols" / "roles_verify.yaml").read_text()
SCENARIO = {
    "b": "  - {at: 1.0, agent: b, raise: want_lead}\n",
    "c": "  - {at: 2.0, agent: c, raise: want_lead}\n",
    "a": "  - {at: 3.0, agent: a, raise: resign}\n",
}
NO_OPERATOR = "  no_operator: always(not in_mode(operator, Command))\n"


def roles_team(tmp_path: Path, events: str, protocol: str = PROTOCOL, extra: str = "",
               without_c: bool = False):
    """The example's three robots and operator (``without_c``: two robots) with a
    (mutated) protocol beside them, the scenario's events ``events`` (a subset of 'bca')
    and extra requirements."""
    text = ROLES.replace("protocol: role_assignment", "protocol: mutant.yaml").replace(
        "operator: role_assignment", "operator: mutant.yaml")
    if without_c:
        text = text[:text.index("  c:\n")] + text[text.index("  operator:\n"):]
        text = text[:text.index("  c_answered:")] + text[text.index("simulation:"):]
    head, rest = text.split("scenario:\n", 1)
    reqs = rest[rest.index("requirements:\n"):]
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


def final_modes(report, v) -> dict[str, list[str]]:
    """Each agent's active leaves in the violating state."""
    sk = report.skeleton
    return {ca.name: m for ca, m in zip(sk.original.agents,
                                        leaves(sk, report.graph.states[v.state]), strict=True)}


def test_the_role_protocol_holds_with_a_request_and_a_lost_copy(tmp_path):
    report = verify(roles_team(tmp_path, "b"), Options(losses=1))
    assert report.graph.exhaustive
    assert {n: v.holds for n, v in verdicts(report).items()} == {
        "one_leader": True, "b_answered": True, "c_answered": True, "deadlock": True}


def test_three_requests_and_a_resignation_hold_without_losses():
    report = verify(load(ROOT / "examples" / "protocols" / "roles_verify.yaml"),
                    Options(losses=0))
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


def test_mutant_requester_leads_when_it_asks(tmp_path):
    bad = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
    report = verify(roles_team(tmp_path, "b", bad), Options(losses=0))
    v = verdicts(report)["one_leader"]
    assert v.holds is False
    assert report.counterexample(v)[1:] == [
        "  1. scenario: b raises want_lead",
        "       b: Transport.Follow -> Transport.Lead"]


def test_mutant_offer_confirmed_to_every_acceptor(tmp_path):
    reject = "        - {on: accept, do: [{send: reject, to: sender}]}"
    bad = mutate(reject, reject.replace("reject", "confirm", 1).replace(
        "{send: reject", "{send: confirm"))
    report = verify(roles_team(tmp_path, "a", bad), Options(losses=0))
    v = verdicts(report)["one_leader"]
    assert v.holds is False
    modes = final_modes(report, v)
    assert modes["b"] == modes["c"] == ["Transport.Lead"]
    text = "\n".join(report.counterexample(v))
    assert text.count("confirm #") >= 2 and "a -> operator: offer" not in text.split(
        "confirm")[-1]


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
    report = verify(roles_team(tmp_path, "bc", bad, extra=NO_OPERATOR), opts)
    v = verdicts(report)["no_operator"]
    assert v.holds is False
    text = "\n".join(report.counterexample(v))
    assert "Transport.Requesting -> Transport.Operated (after answer_timeout)" in text
    assert "deny" not in text and " lost" not in text


def test_mutant_duplicate_suppression_off(tmp_path):
    """A resent accept (its ack was lost) reaches the resigning leader twice: the first
    gets a confirm, the copy a reject. Whichever arrives first at the acceptor decides:
    a reject first and nobody leads, a confirm after it is ignored — leadership lost for
    good without the operator. With dedupe the copy is withheld and this cannot happen."""
    restored = ("  leadership_restored: always(implies(count_in_role(lead) == 0, eventually("
                "count_in_role(lead) == 1 or in_mode(operator, Command))))\n")
    opts = Options(losses=1)
    good = verify(roles_team(tmp_path, "a", extra=restored, without_c=True), opts)
    assert verdicts(good)["leadership_restored"].holds is True
    bad = mutate("  accept: {ack: {timeout: ack_timeout, retries: ack_retries}}",
                 "  accept: {ack: {timeout: ack_timeout, retries: ack_retries, dedupe: false}}")
    report = verify(roles_team(tmp_path, "a", bad, extra=restored, without_c=True), opts)
    v = verdicts(report)["leadership_restored"]
    assert v.holds is False
    text = "\n".join(report.counterexample(v))
    assert "ack arrives" in text and "is lost" in text and "accept #" in text
    assert "reject" in text


# -- the docking handshake --------------------------------------------------------------

def docking(tmp_path: Path, acknowledged: bool):
    text = (ROOT / "examples" / "transport" / "experiment2.yaml").read_text()
    text = text.replace("requirements_from: [requirements.yaml]\n", "requirements:\n"
                        "  carried: always(implies(in_mode(xr4000, Dock.Wait), "
                        "eventually(in_mode(xr4000, Transport))))\n")
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
    assert "xr4000 in Dock.Wait; labmate in Transport.Lead.Stop; operator in Standby" in \
        configs  # the sweep's failure: the Labmate led off, the XR4000 waits
    carried = verdicts(report)["carried"]
    assert carried.holds is False
    text = "\n".join(report.counterexample(carried))
    assert "is lost" in text and ("docked" in text or "ready" in text)


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
    path.write_text(text.replace("simulation:\n", "network: {latency: 0.03, loss: 0.1}\n"
                                 "simulation:\n"))
    lossy = load(path)
    run = simulate(lossy, seed=list(range(12)), n=12)
    ms = run.messages
    worst = 0
    paths: list[list[tuple]] = []
    for i in range(12):
        lost = int(np.sum((ms["instance"] == i) & (ms["status"] == "lost")
                          & (ms["reason"] != "run ended") & (ms["type"] != "state")))
        if lost > 1:
            continue
        worst = max(worst, lost)
        paths.append(_configurations(run, i))
    assert len(paths) > 3 and worst == 1  # runs with a lost control message among them
    report = verify(team, Options(losses=worst))
    explored = {tuple(tuple(m) for m in leaves(report.skeleton, s))
                for s in report.graph.states}
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
        here = rows & (iv["start"] <= t) & ((iv["end"] > t) | (iv["end"] == iv["end"][rows]
                                                               .max()) & (iv["end"] >= t))
        config = []
        for name in names:
            sel = here & (iv["agent"] == name)
            config.append(tuple(sorted(str(m) for m in iv["mode"][sel]
                                       if m in _leaf_paths(run, name))))
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
    assert main(["verify", str(tmp_path / "team.yaml"), "--losses", "0", "-o", str(out),
                 "--progress", "none"]) == 0
    summary = json.loads((out / "verify.json").read_text())
    assert summary["exhaustive"] and summary["properties"]["one_leader"]["verdict"] == "holds"
    printed = capsys.readouterr().out
    assert "one_leader: holds" in printed and "deadlock: holds" in printed
    bad = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
    (tmp_path / "mutant.yaml").write_text(bad)
    assert main(["verify", str(tmp_path / "team.yaml"), "--losses", "0", "-o", str(out),
                 "--progress", "none"]) == 1
    assert "one_leader: VIOLATED" in capsys.readouterr().out
    assert main(["verify", str(tmp_path / "team.yaml"), "--losses", "-1", "-o",
                 str(out)]) == 2
    assert main(["verify", str(tmp_path / "team.yaml"), "-p", "one_ledaer", "-o",
                 str(out)]) == 2
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


def test_a_bounded_exploration_has_no_false_dead_ends():
    """States whose successors the bound refused are not dead ends: the response
    properties and deadlock stay unviolated (they hold exhaustively with no losses, and
    a bound cannot create a violation)."""
    report = verify(load(ROOT / "examples" / "protocols" / "roles_verify.yaml"),
                    Options(losses=1, max_states=3000))
    assert not report.graph.exhaustive and report.graph.cut
    assert not report.violated

"""The reaction tables (the default successor function) against the engine-per-successor
explorer (``Options(reference=True)``, ``verify --reference``): on every verify test model,
mutant and example the two explorations are the same graph — the same states in the same
order, the same edges with the same choices, the same BFS tree, Zeno and cut states — so
the verdicts and the counterexamples (their paths, step by step) are the same too."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.verify import Options, verify
from hybridteam.verify.abstraction import skeleton
from hybridteam.verify.explore import Graph, choices
from hybridteam.verify.machine import Machine
from hybridteam.verify.reactions import Reactions
from tests.verify.test_verify import GO, GRANT, REQUEST, docking, mutate, roles_team
from tests.verify.test_verify_bounds import BOUNDED, COUNTERS
from tests.verify.test_verify_promela import PARALLEL, PINGPONG, acked_go

ROOT = Path(__file__).resolve().parents[2]


def same_graph(a: Graph, b: Graph) -> None:
    assert len(a.states) == len(b.states)
    assert [a.states.keys[k] for k in range(len(a.states))] == [
        b.states.keys[k] for k in range(len(b.states))
    ]
    assert list(a.parent) == list(b.parent)
    assert a.transitions == b.transitions
    assert (list(a.edges.src), list(a.edges.dst)) == (list(b.edges.src), list(b.edges.dst))
    assert [a.edges.choices.values[h] for h in a.edges.how] == [
        b.edges.choices.values[h] for h in b.edges.how
    ]
    assert (a.zeno, a.cut, a.exhaustive, a.bound) == (b.zeno, b.cut, b.exhaustive, b.bound)


def both(team, **kw) -> None:
    """Explore ``team`` with the tables and with the reference; the same graph, verdicts
    and counterexamples."""
    ours = verify(team, Options(kernel="off", **kw), replay=False)  # (the Python loop)
    ref = verify(team, Options(reference=True, **kw), replay=False)
    assert len(ours.graph.states) > 1
    same_graph(ours.graph, ref.graph)
    assert [(v.prop.name, v.holds, v.state) for v in ours.verdicts] == [
        (v.prop.name, v.holds, v.state) for v in ref.verdicts
    ]
    for v, w in zip(ours.violated, ref.violated, strict=True):
        assert ours.path(v) == ref.path(w)
        assert ours.counterexample(v) == ref.counterexample(w)


STAYS = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
LEADS = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
REJECT = "        - {on: accept, do: [{send: reject, to: sender}]}"
CONFIRMS = mutate(
    REJECT, REJECT.replace("reject", "confirm", 1).replace("{send: reject", "{send: confirm")
)
DENY = "        - on: request\n          do: [{send: deny, to: sender}]\n        - to: Offering"
NO_DENY = mutate(DENY, "        - to: Offering")
NO_DEDUPE = mutate(
    "  accept: {ack: {timeout: ack_timeout, retries: ack_retries}}",
    "  accept: {ack: {timeout: ack_timeout, retries: ack_retries, dedupe: false}}",
)
RESTORED = (
    "  leadership_restored: always(implies(count_in_role(lead) == 0, eventually("
    "count_in_role(lead) == 1 or in_mode(operator, Command))))\n"
)


#: (scenario events, protocol text, extra requirements, without agent c, options) of the
#: role protocol and its mutants, with their ids (test_verify_kernel compares its loop on
#: the same models)
ROLE_CASES = [
    ("b", None, "", False, {"losses": 1}),
    ("b", None, "", False, {"losses": 1, "order": "fifo"}),
    ("b", None, "", True, {"losses": 1, "ack_timing": "any", "max_states": 3000}),
    ("b", STAYS, "", False, {"losses": 0}),
    ("b", STAYS, "", False, {"losses": 1, "order": "fifo"}),
    ("b", LEADS, "", False, {"losses": 0}),
    ("a", CONFIRMS, "", False, {"losses": 0}),
    ("bc", NO_DENY, "no_operator", False, {"losses": 0, "timeouts": "long"}),
    ("bc", NO_DENY, "no_operator", False, {"losses": 0, "timeouts": "own"}),
    ("a", NO_DEDUPE, RESTORED, True, {"losses": 1}),
    ("a", NO_DEDUPE, RESTORED, True, {"losses": 0, "duplicates": 1}),
    ("a", None, RESTORED, True, {"losses": 1}),
]
ROLE_IDS = [
    "roles",
    "roles-fifo",
    "roles-ack-any",
    "stays-lead",
    "stays-lead-fifo",
    "leads-when-asking",
    "confirms-all",
    "no-deny-long",
    "no-deny-own",
    "no-dedupe",
    "no-dedupe-duplicated",
    "restored",
]


@pytest.mark.parametrize("events,protocol,extra,without_c,opts", ROLE_CASES, ids=ROLE_IDS)
def test_the_role_protocol_and_its_mutants(tmp_path, events, protocol, extra, without_c, opts):
    if extra == "no_operator":
        extra = "  no_operator: always(not in_mode(operator, Command))\n"
    kw = {} if protocol is None else {"protocol": protocol}
    both(roles_team(tmp_path, events, extra=extra, without_c=without_c, **kw), **opts)


@pytest.mark.parametrize("acknowledged", [False, True])
def test_the_docking_handshake(tmp_path, acknowledged):
    both(docking(tmp_path, acknowledged), losses=1)


#: (team text, options) of the small verify test models, with their ids (test_verify_kernel
#: compares its loop on the same models)
SMALL_CASES = [
    (PINGPONG, {"losses": 1, "duplicates": 1}),
    (PARALLEL, {"losses": 1, "duplicates": 1}),
    (GO, {"losses": 1}),
    (acked_go(1), {"losses": 1, "duplicates": 1}),
    (acked_go(0), {"losses": 1}),
    (BOUNDED, {"losses": 0}),
    (COUNTERS, {"max_values": 10}),  # stops at the value bound: at the same level
]
SMALL_IDS = ["pingpong", "parallel", "go", "acked-go", "acked-go-no-retry", "bounded", "counters"]


@pytest.mark.parametrize("text,opts", SMALL_CASES, ids=SMALL_IDS)
def test_the_small_models(tmp_path, text, opts):
    path = tmp_path / "team.yaml"
    path.write_text(text)
    both(load(path), **opts)


#: (example under examples/, options) that verify explores (test_verify_kernel too)
EXAMPLES = [
    ("protocols/roles_verify.yaml", {"losses": 1, "max_states": 4000}),
    ("protocols/handover.yaml", {"losses": 1}),
    ("automata/relay.yaml", {}),
    ("automata/thermostat.yaml", {}),
    ("automata/thermostat_chatter.yaml", {}),
    ("automata/unicycle_square.yaml", {}),
    ("automata/water_tanks.yaml", {}),
]


@pytest.mark.parametrize("path,opts", EXAMPLES)
def test_the_examples(path, opts):
    both(load(ROOT / "examples" / path), **opts)


# A kick sends b round an urgent loop that never ends (exact guards, no trigger): the
# phase is cut short as Zeno with b still able to step. a's time-driven toggles (Q, R)
# came before from states where b was quiescent, so their table entries say b does nothing; in
# the Zeno state the engine steps b too. Such a state is expanded by the engine.
ZENO = """team: zeno
agents:
  a:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: P
    modes:
      P:
        transitions: [{to: Q, after: 1.0, do: [{send: kick, to: b}]}]
      Q:
        transitions: [{to: R, after: 1.0}]
      R:
        transitions: [{to: Q, after: 1.0}]
  b:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    variables: {n: 0}
    initial: Idle
    modes:
      Idle:
        transitions: [{to: L1, on: kick}]
      L1:
        transitions: [{to: L2, guard: n >= 0}]
      L2:
        transitions: [{to: L1, guard: n >= 0}]
simulation: {duration: 5}
"""


def test_a_state_left_by_a_zeno_phase_is_expanded_by_the_engine(tmp_path):
    path = tmp_path / "zeno.yaml"
    path.write_text(ZENO)
    report = verify(load(path), Options(losses=0), replay=False)
    assert report.graph.zeno  # the kick's arrival is cut short
    both(load(path), losses=0)


def test_the_tables_serve_most_successors(tmp_path):
    """The engine runs once per distinct reaction, not once per successor: on the role
    protocol with a lost copy most successors come from the tables, each equal to the
    engine's (checked against a machine that runs the engine for each)."""
    team = roles_team(tmp_path, "b")
    sk = skeleton(compile_team(team))
    report = verify(team, Options(losses=1), replay=False)
    m = Reactions(sk, 64)
    ref = Machine(sk, 64)
    for s in list(report.graph.states)[:400]:
        jobs = [(s, ch, ()) for ch in choices(m, sk, s, Options(losses=1))]
        for k in range(0, len(jobs), 64):
            got = m.run(jobs[k : k + 64])
            want = ref.run(jobs[k : k + 64])
            assert [(r.state, r.zeno, r.reads) for r in got] == [
                (r.state, r.zeno, r.reads) for r in want
            ]
    assert m.hits > 4 * m.misses


def test_a_successors_free_reads_do_not_depend_on_its_batch(tmp_path):
    """GO's leader leaves Drive on a guard over its position (a free comparison, read only
    when that time-driven transition is chosen). Delivering go to the follower reads no
    free comparison, whether or not a job in the same engine batch chose the leader's
    transition (before, the guard's tree read the tapes of every instance in Drive, so a
    reaction's reads, and with them its table entry, depended on its neighbours)."""
    path = tmp_path / "go.yaml"
    path.write_text(GO)
    sk = skeleton(compile_team(load(path)))
    m = Machine(sk, 4)
    sent = m.run([(m.initial(), ("time", 0, 0), ())])[0].state  # the leader drives
    deliver, done = (sent, ("deliver", 0), ()), (sent, ("time", 0, 1), ())
    assert [r.reads for r in m.run([deliver])] == [0]
    assert [r.reads for r in m.run([deliver, done])] == [0, 1]


def test_cli_reference_prints_the_same_verdicts(tmp_path, capsys):
    roles_team(tmp_path, "b", STAYS)
    team = str(tmp_path / "team.yaml")
    args = ["verify", team, "--losses", "0", "--no-replay", "-o", str(tmp_path / "out")]
    assert main(args) == 1
    ours = capsys.readouterr().out
    assert main([*args, "--reference"]) == 1
    ref = capsys.readouterr().out
    assert "one_leader: VIOLATED" in ours

    def untimed(out: str) -> list[str]:  # (progress lines, seconds and the loop differ)
        return [
            re.sub(r"[0-9.]+ s\b|; (compiled kernel|python loop[^)]*)", "", line)
            for line in out.splitlines()
            if "/s" not in line
        ]

    assert untimed(ours) == untimed(ref)

"""Partial-order reduction by ample sets (``--por ample``): independent exchanges explored
in one order, with the same verdicts, the same dead ends and every counterexample found
and reproduced by a run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.verify import Options, verify
from hybridteam.verify.ample import ample
from hybridteam.verify.properties import properties
from tests.verify.test_verify import GO
from tests.verify.test_verify_symmetry import ASK

PAIR = """  w{k}:
    plant: {{kind: unicycle, state: {{x: {k}, y: 0, theta: 0}}}}
    initial: Start
    modes:
      Start:
        transitions:
          - {{to: Wait, on: go, do: [{{send: req, to: p{k}}}]}}
      Wait:
        transitions:
          - {{to: Done, on: rep}}
      Done:
        final: true
  p{k}:
    plant: {{kind: unicycle, state: {{x: {k}, y: 1, theta: 0}}}}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {{to: Served, on: req, do: [{{send: rep, to: sender}}]}}
      Served:
        final: true
"""

#: A starter broadcasts 'go' once; three workers each ask their own partner, which
#: answers: three exchanges that nothing connects.
PAIRS = (
    """team: pairs
agents:
  starter:
    plant: {kind: unicycle, state: {x: 0, y: 5, theta: 0}}
    initial: Start
    modes:
      Start:
        transitions:
          - {to: Sent, after: 1.0, do: [{send: go}]}
      Sent:
        final: true
"""
    + "".join(PAIR.format(k=k) for k in (1, 2, 3))
    + "simulation: {duration: 10}\n"
)

#: p and q pass a ball for ever; z may go Bad at any moment. A reduction that always
#: followed the ball would never let z move (the cycle proviso is what lets it).
PINGPONG = """team: pingpong
agents:
  p:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Serve
    modes:
      Serve:
        transitions:
          - {to: Play, after: 1.0, do: [{send: ball, to: q}]}
      Play:
        transitions:
          - {on: ball, do: [{send: ball, to: q}]}
  q:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    initial: Play
    modes:
      Play:
        transitions:
          - {on: ball, do: [{send: ball, to: p}]}
  z:
    plant: {kind: unicycle, state: {x: 2, y: 0, theta: 0}}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {to: Bad, after: 2.0}
      Bad:
        final: true
requirements:
  z_idle:
    formula: always(not in_mode(z, Bad))
simulation: {duration: 10}
"""

#: the symmetry tests' boss and followers, with a property that reads only the boss
ASK_BOSS = ASK.replace(
    "always(count_in_mode(Done) <= 2)", "always(in_mode(boss, Start) or in_mode(boss, Serve))"
).replace("{extra}", "")


def team_of(tmp_path: Path, text: str):
    path = tmp_path / "team.yaml"
    path.write_text(text)
    return load(path)


def outcome(report) -> dict:
    """Per property: its verdict, and for a violation whether a run reproduced it."""
    replays = report.replays
    return {
        v.prop.name: (v.holds, replays[v.prop.name][1].reproduced if v.holds is False else None)
        for v in report.verdicts
    }


def dead_ends(report) -> set:
    g = report.graph
    return {g.states[k] for k in np.flatnonzero(g.terminal()).tolist()}


def both(team, **options):
    """The full exploration and the one reduced by ample sets (no symmetry in either)."""
    full = verify(team, Options(symmetry="off", **options))
    reduced = verify(team, Options(symmetry="off", por="ample", **options))
    return full, reduced


def test_independent_exchanges_are_explored_in_one_order(tmp_path):
    """Without losses: after the broadcast (the partners' 'go' copies, which they do not
    hear, arrive first, one at a time: 4 states from the start) each pair is at one of
    four stages — 'go' to the worker in flight, 'req' in flight, 'rep' in flight, done —
    independently: 4 + 4**3 = 68 states. With ample sets every step is one worker's or
    partner's, in one order: the 4 states, then 3 steps per pair, 13 steps in a row."""
    team = team_of(tmp_path, PAIRS)
    full, reduced = both(team, losses=0)
    assert len(full.graph.states) == 68
    assert len(reduced.graph.states) == 14 and len(reduced.graph.edges) == 13
    assert outcome(full) == outcome(reduced) == {"deadlock": (True, None)}
    full, reduced = both(team, losses=1)
    n_full, n_reduced = len(full.graph.states), len(reduced.graph.states)
    print(f"pairs, one loss: {n_full} states without ample sets, {n_reduced} with")
    assert n_reduced * 2 <= n_full
    # a lost copy leaves a worker or a partner waiting: found, and reproduced by a run
    assert outcome(full) == outcome(reduced) == {"deadlock": (False, True)}
    assert dead_ends(reduced) == dead_ends(full)


def test_the_cycle_proviso_lets_a_choice_the_cycle_would_put_off_happen(tmp_path):
    """The ball's arrivals are ample (z does not hear them), and they go round a cycle:
    the state that closes it is expanded fully, so z's timeout is explored and z_idle's
    violation found (and reproduced) as without the reduction."""
    full, reduced = both(team_of(tmp_path, PINGPONG), losses=0)
    assert len(reduced.graph.states) < len(full.graph.states)
    assert outcome(full) == outcome(reduced) == {"z_idle": (False, True), "deadlock": (True, None)}


@pytest.mark.parametrize(
    ("text", "options"),
    [
        (PAIRS, {"losses": 1, "duplicates": 1}),
        (ASK_BOSS, {"losses": 1}),
        (ASK_BOSS, {"losses": 0, "duplicates": 1}),
        (PINGPONG, {"losses": 1}),
        (GO, {"losses": 1}),
    ],
    ids=["pairs-dup", "ask-loss", "ask-dup", "pingpong-loss", "go-loss"],
)
def test_verdicts_dead_ends_and_counterexamples_are_kept(tmp_path, text, options):
    full, reduced = both(team_of(tmp_path, text), **options)
    assert len(reduced.graph.states) <= len(full.graph.states)
    assert outcome(reduced) == outcome(full)
    assert dead_ends(reduced) == dead_ends(full)  # kept exactly, not just the verdict


def test_symmetry_and_ample_sets_combine(tmp_path):
    """The boss's followers are interchangeable and no property reads them: both
    reductions at once keep the verdicts, the reproduced counterexample and the dead
    ends (up to the followers' arrangement)."""
    team = team_of(tmp_path, ASK_BOSS)
    full = verify(team, Options(losses=1, symmetry="off"))
    both_on = verify(team, Options(losses=1, por="ample"))
    sym = both_on.symmetry
    assert sym is not None and sym.classes == [(1, 2, 3)]
    print(f"ask, one loss: {len(full.graph.states)} states, {len(both_on.graph.states)} reduced")
    assert len(both_on.graph.states) * 4 <= len(full.graph.states)
    assert outcome(both_on) == outcome(full)
    assert outcome(full) == {"two_done": (True, None), "deadlock": (False, True)}
    assert {sym.representative(s) for s in dead_ends(full)} == dead_ends(both_on)


def test_a_property_that_reads_an_agent_keeps_its_interleavings(tmp_path):
    """count_in_mode reads every follower and the boss: nothing is ample."""
    team = team_of(tmp_path, ASK.replace("{extra}", ""))
    full, reduced = both(team, losses=0)
    assert len(reduced.graph.states) == len(full.graph.states) == 65


def test_timing_options_under_which_arrivals_interact_turn_it_off(tmp_path):
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.verify.abstraction import skeleton

    sk = skeleton(compile_team(team_of(tmp_path, PAIRS)))
    props = properties(sk)
    assert ample(sk, props, Options(por="ample")) is not None
    for bad in ({"timeouts": "own"}, {"ack_timing": "any"}, {"order": "fifo"}):
        assert ample(sk, props, Options(por="ample", **bad)) is None


def test_cli_por_option(tmp_path, capsys):
    team_of(tmp_path, PAIRS)
    args = ["verify", str(tmp_path / "team.yaml"), "--losses", "0", "--progress", "none"]
    assert main([*args, "--por", "ample", "-o", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "skeleton of 14 states" in out and "ample sets" in out
    assert main([*args, "--por", "ample", "--timeouts", "long", "-o", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "--por ample needs" in err and "--timeouts long" in err
    assert not (tmp_path / "b").exists()


def test_role_protocol_mutants_keep_their_verdicts(tmp_path):
    """The role protocol's properties read every robot (count_in_role): the mutants'
    violations are found and reproduced with ample sets as without."""
    from tests.verify.test_verify import GRANT, mutate, roles_team

    stays = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
    full, reduced = both(roles_team(tmp_path, "b", stays), losses=0)
    assert outcome(full) == outcome(reduced)
    assert outcome(reduced)["one_leader"] == (False, True)

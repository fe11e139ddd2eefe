"""Symmetry reduction (``--symmetry``): interchangeable agents explored once per
arrangement, with the same verdicts and counterexamples as the full exploration."""

from __future__ import annotations

import importlib
import json
from itertools import pairwise, permutations
from pathlib import Path

import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.verify import Options, promela, spin, verify
from hybridteam.verify.abstraction import skeleton
from hybridteam.verify.explore import choices
from hybridteam.verify.machine import Machine
from hybridteam.verify.properties import properties
from hybridteam.verify.symmetry import permute, symmetry

ROOT = Path(__file__).resolve().parents[2]

FOLLOWER = """  {name}:
    plant: {{kind: unicycle, state: {{x: {x}, y: 0, theta: 0}}}}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {{to: Asking, on: go, do: [{{send: ask, to: boss}}]}}
      Asking:
        transitions:
          - {{to: Done, on: grant}}
      Done:
        final: true
"""

#: A boss that broadcasts 'go' once and grants every 'ask'; three identical followers
#: that each ask once when told to go. Nothing but the followers' names tells them apart.
ASK = (
    """team: ask
agents:
  boss:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Start
    modes:
      Start:
        inputs: {v: 0, omega: 0}
        transitions:
          - {to: Serve, after: 1.0, do: [{send: go}]}
      Serve:
        inputs: {v: 0, omega: 0}
        transitions:
          - {on: ask, do: [{send: grant, to: sender}]}
"""
    + "".join(FOLLOWER.format(name=f"f{k}", x=-k) for k in (1, 2, 3))
    + """requirements:
  two_done:
    formula: always(count_in_mode(Done) <= 2)
{extra}simulation: {duration: 10}
"""
)


def ask_team(tmp_path: Path, extra: str = "", scenario: str = ""):
    text = ASK.replace("{extra}", extra)
    if scenario:
        text = text.replace("requirements:\n", f"scenario:\n{scenario}requirements:\n")
    path = tmp_path / "ask.yaml"
    path.write_text(text)
    return load(path)


def outcome(report) -> dict:
    """Per property: its verdict, and for a violation whether the replay reproduced it
    and the counterexample's lines (each step at its replayed moment)."""
    out = {}
    for v in report.verdicts:
        out[v.prop.name] = (v.holds,)
        if v.holds is False:
            out[v.prop.name] += (
                report.replays[v.prop.name][1].reproduced,
                report.counterexample(v),
            )
    return out


def test_three_interchangeable_followers_are_explored_once_per_arrangement(tmp_path):
    team = ask_team(tmp_path)
    full = verify(team, Options(losses=1, symmetry="off"))
    reduced = verify(team, Options(losses=1, symmetry="on"))
    assert full.symmetry is None and reduced.symmetry is not None
    assert reduced.symmetry.classes == [(1, 2, 3)]  # boss is named by 'to: boss'
    n_full, n_reduced = len(full.graph.states), len(reduced.graph.states)
    print(f"ask, one loss: {n_full} states without symmetry, {n_reduced} with")
    assert n_reduced * 2 <= n_full
    # the reduced graph holds exactly one state per class: the least of each full
    # state's six permutations
    reps = {
        min(permute(s, p) for p in permutations(range(4)) if p[0] == 0) for s in full.graph.states
    }
    assert reps == set(reduced.graph.states)
    # the same verdicts; each violation reproduced by a run, with the same steps
    assert outcome(reduced) == outcome(full)
    assert outcome(full)["two_done"][:2] == (False, True)
    assert outcome(full)["deadlock"][:2] == (False, True)  # a lost 'go' or 'ask'
    # paths through representatives map back to paths of the team's own states: each
    # step a successor the machine computes, ending in a state of the representative's
    # class; for some the representative is another arrangement than the state itself
    sym, m = reduced.symmetry, Machine(reduced.skeleton, 4)
    moved = 0
    for k in range(len(reduced.graph.states)):
        path = reduced.graph.path(k)
        g, concrete = reduced.concrete(path)
        assert len(concrete) == len(path) and g.states[concrete[0]] == m.initial()
        for a, b in pairwise(concrete):
            s, choice = g.states[a], g.edge_choice(a, b)
            assert choice in choices(m, reduced.skeleton, s, reduced.options)
            assert g.states[b] in {r.state for r in _answers(m, s, choice)}
        assert sym.representative(g.states[concrete[-1]]) == reduced.graph.states[k]
        moved += g.states[concrete[-1]] != reduced.graph.states[k]
    assert moved > 0


def test_a_property_naming_an_agent_pins_it(tmp_path):
    team = ask_team(tmp_path, extra="  f1_waits:\n    formula: always(not in_mode(f1, Done))\n")
    sk = skeleton(_compiled(team))
    sym = symmetry(sk, properties(sk))
    assert sym.classes == [(2, 3)] and len(sym.group(0)) == 2
    full = verify(team, Options(losses=0, symmetry="off"))
    reduced = verify(team, Options(losses=0))
    assert len(full.graph.states) > len(reduced.graph.states)
    assert outcome(reduced) == outcome(full)
    assert outcome(full)["f1_waits"][:2] == (False, True)


def test_the_scenario_pins_the_agents_its_remaining_entries_name(tmp_path):
    team = ask_team(tmp_path, scenario="  - {at: 0.5, agent: f2, raise: hello}\n")
    sk = skeleton(_compiled(team))
    sym = symmetry(sk, properties(sk))
    assert sym.classes == [(1, 2, 3)]
    # before the entry f2 stays put (f1 and f3 may swap); after it all three are free
    assert sorted(sym.group(0)) == [(0, 1, 2, 3), (0, 3, 2, 1)]
    assert len(sym.group(1)) == 6


def test_an_agent_index_in_a_variable_turns_symmetry_off():
    """The role protocol stores 'leader = msg_sender': permuting the agents would have to
    permute that value too; no reduction, and the reason says why."""
    team = load(ROOT / "examples" / "protocols" / "roles_verify.yaml")
    sk = skeleton(_compiled(team))
    sym = symmetry(sk, properties(sk))
    assert not sym.active and "msg_sender" in sym.reason


def test_a_lost_go_on_the_test_models_is_the_same_with_and_without_symmetry(tmp_path):
    """The verify tests' own handshake (no two agents alike): the option changes nothing."""
    from tests.verify.test_verify import GO

    path = tmp_path / "go.yaml"
    path.write_text(GO)
    team = load(path)
    on, off = verify(team, Options(losses=1)), verify(team, Options(losses=1, symmetry="off"))
    assert on.symmetry is not None and not on.symmetry.active
    assert len(on.graph.states) == len(off.graph.states)
    assert outcome(on) == outcome(off)


def test_cli_symmetry_option(tmp_path, capsys):
    ask_team(tmp_path)
    team = str(tmp_path / "ask.yaml")
    args = ["verify", team, "--losses", "0", "--no-replay", "--progress", "none"]
    assert main([*args, "-o", str(tmp_path / "a")]) == 1
    on = capsys.readouterr().out
    assert "symmetry: interchangeable agents f1, f2, f3" in on
    # without losses each follower is at one of four stages (its 'go' in flight; asking
    # with its 'ask' in flight; asking with its 'grant' in flight; done), independently of
    # the others, after the one state before the boss broadcasts: 1 + 4**3 = 65 states;
    # up to symmetry, a multiset of three stages out of four: 1 + C(6, 3) = 21
    assert "skeleton of 21 states" in on
    summary = json.loads((tmp_path / "a" / "verify.json").read_text())
    assert summary["states"] == 21 and summary["options"]["symmetry"] == "on"
    assert summary["symmetry"].startswith("interchangeable agents f1, f2, f3")
    assert main([*args, "--symmetry", "off", "-o", str(tmp_path / "b")]) == 1
    off = capsys.readouterr().out
    assert "symmetry:" not in off and "skeleton of 65 states" in off
    with pytest.raises(SystemExit) as bad:
        main([*args, "--symmetry", "both", "-o", str(tmp_path / "c")])
    assert bad.value.code == 2 and "invalid choice: 'both'" in capsys.readouterr().err


def _answers(m: Machine, s, choice) -> list:
    """Every successor of ``s`` by ``choice``, one per answer of its free comparisons."""
    out, tapes = [], [()]
    while tapes:
        tape = tapes.pop(0)
        r = m.run([(s, choice, tape)])[0]
        out.append(r)
        tapes += [tape + (False,) * (k - len(tape)) + (True,) for k in range(len(tape), r.reads)]
    return out


def _compiled(team):
    from hybridteam.engine.compile.compiler import compile_team

    return compile_team(team)


def test_too_many_ties_keep_a_sound_arrangement(tmp_path, monkeypatch):
    """With orders among equal agents not tried (the cap at 1), states are sorted by
    their parts only: a member of the class, not always the least — more states than
    the canonical reduction, fewer than none, the same verdicts."""
    module = importlib.import_module("hybridteam.verify.symmetry")

    team = ask_team(tmp_path)
    canonical = verify(team, Options(losses=0), replay=False)
    full = verify(team, Options(losses=0, symmetry="off"), replay=False)
    monkeypatch.setattr(module, "MAX_TIES", 1)
    capped = verify(team, Options(losses=0), replay=False)
    assert len(canonical.graph.states) == 21 and len(full.graph.states) == 65
    assert 21 < len(capped.graph.states) < 65
    assert [v.holds for v in capped.verdicts] == [v.holds for v in full.verdicts]


@pytest.mark.skipif(spin.missing() is not None, reason=f"SPIN cannot run here: {spin.missing()}")
def test_spin_on_the_rules_agrees_with_the_states_representatives_stand_for(tmp_path):
    """SPIN explores the rules without symmetry; our representatives, each expanded to
    the arrangements it stands for, reach the same configurations and dead ends."""
    team = ask_team(tmp_path)
    opts = Options(losses=1)
    report = verify(team, opts, replay=False)
    assert len(report.graph.states) == 41  # representatives
    c = promela.compare(report, opts, tmp_path / "spin-rules")
    assert not c.differences()
    assert c.ours.configurations == c.spin.configurations and not c.ours.deadlock
    # one loss: go lost (a follower idle for ever) or ask/grant lost (one asking)
    assert len(c.ours.dead_ends) >= 2


def test_ample_sets_are_not_compared_with_spin(tmp_path):
    report = verify(ask_team(tmp_path), Options(losses=0, por="ample"), replay=False)
    with pytest.raises(promela.Unsupported, match="--por ample"):
        promela.check(report, report.options)

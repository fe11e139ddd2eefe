"""Flips that need not be located: a conjunct of a guard turning false.

Just past such a flip the guard is false, so the crossing cannot matter; where nothing
else would be learnt from locating it, the search skips it. The run must be the one the
search gives when it locates every flip (``search.SKIP_FOREGONE`` false), bit for bit, and
it must have located fewer (``Run.costs.located``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import hybridteam as ht
from hybridteam.engine.run.crossing import search
from hybridteam.expr.compiler import compile_expression

BALL = Path(__file__).parents[2] / "examples" / "automata" / "bouncing_ball.yaml"
SYMS = {name: (lambda ctx: 0.0) for name in ("h", "v", "x")}


@pytest.mark.parametrize(
    ("source", "conjuncts"),
    [
        ("h <= 0 and v < 0", ["h <= 0", "v < 0"]),
        ("h <= 0", ["h <= 0"]),
        ("h <= 0 or v < 0", []),  # either may hold alone
        ("not (h <= 0) and v < 0", ["v < 0"]),  # h <= 0 false makes the guard true
        ("(h <= 0 or x > 1) and v < 0", ["v < 0"]),
        ("(h <= 0 and x > 1) and 0 < v < 2", ["h <= 0", "x > 1", "0 < v", "v < 2"]),
        ("h == 0 and v < 0", ["v < 0"]),  # an equality is no atom
    ],
)
def test_the_conjuncts_of_a_condition(source, conjuncts):
    expr = compile_expression(source, SYMS, condition=True)
    assert [a.source for a in expr.conjuncts] == conjuncts
    assert all(any(a is b for b in expr.atoms) for a in expr.conjuncts)


def _run(team, monkeypatch, skip: bool, n: int = 1):
    """The run, and how many flips its searches located, with foregone flips skipped or
    located."""
    with monkeypatch.context() as m:
        m.setattr(search, "SKIP_FOREGONE", skip)
        run = ht.simulate(
            team,
            n=n,
            seed=list(range(n)) if n > 1 else None,
            overrides={"ball.e": [0.7, 0.75, 0.8, 0.85][:n]} if n > 1 else None,
        )
    return run, run.costs.located


@pytest.mark.parametrize("n", [1, 4])
def test_skipping_foregone_flips_changes_no_bit_of_the_run(monkeypatch, n):
    """The bouncing ball up to its Zeno point: after a late bounce, ``h <= 0`` (a conjunct
    of ``h <= 0 and v < 0``) turns false a picosecond after the impact, in the same
    sub-interval as the apex. Both runs must be identical, and the skipping one must have
    located fewer crossings."""
    team = dataclasses.replace(ht.load(BALL), requirements=())
    fast, fewer = _run(team, monkeypatch, skip=True, n=n)
    full, located_all = _run(team, monkeypatch, skip=False, n=n)
    assert fast.to_json() == full.to_json()
    assert fewer < located_all


BOTH_TRUE = """
team: two-conjuncts
agents:
  clock:
    plant: {kind: flow, state: {x: 0.0, y: 0.02}}
    initial: Run
    modes:
      Run:
        flow: {x: 1, y: 1}
        transitions:
          - {to: Done, guard: x >= 1 and y >= 1}   # y turns true at 0.98, x at 1
      Done:
        flow: {x: 0, y: 0}
simulation: {duration: 3.0, sample_period: 1.0, max_step: 3.0}
"""


def test_conjuncts_turning_true_are_still_located(team_from_yaml, monkeypatch):
    """Both atoms turn true in one sub-interval (one step spans the run): the transition
    is at x = 1, t = 1, found by locating both flips; only flips to false are skipped."""
    team = team_from_yaml(BOTH_TRUE)
    fast, fewer = _run(team, monkeypatch, skip=True)
    full, located_all = _run(team, monkeypatch, skip=False)
    (done,) = fast.transitions.filter(fast.transitions["target"] == "Done")
    assert done.t == pytest.approx(1.0, abs=1e-9)
    assert fast.to_json() == full.to_json()
    assert fewer == located_all == 2


def test_no_flip_is_skipped_while_another_watched_atom_is_not_searched(team_from_yaml, monkeypatch):
    """A second transition out of the ball's mode watches ``h > 100``, which never flips:
    a skipped flip could no longer reveal a flip of it that the sub-interval's ends hide,
    so nothing is skipped, and the run is located as before."""
    text = BALL.read_text()
    anchor = '            do: ["v = -e * v", "bounces += 1"]\n'
    assert anchor in text
    team = team_from_yaml(text.replace(anchor, anchor + "          - {to: Fall, guard: h > 100}\n"))
    team = dataclasses.replace(team, requirements=())
    fast, fewer = _run(team, monkeypatch, skip=True)
    full, located_all = _run(team, monkeypatch, skip=False)
    assert fast.to_json() == full.to_json()
    assert fewer == located_all

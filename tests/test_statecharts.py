"""Statechart semantics beyond plain hierarchy (issue 49): history on parallel modes,
transitions without a target, regions as sources, against hand-derived traces.

A counter ``n`` is a flow plant's state with no flow (``dn/dt = 0``), so an assignment to
it is a reset the final sample shows exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht


def steps(run: ht.Run) -> list[tuple[float, int, str, str]]:
    return [(round(r.t, 9), r.step, r.source, r.target) for r in run.transitions
            if r.cause != "init"]


def leaves_from(run: ht.Run, t: float) -> list[str]:
    """The leaf modes whose interval starts at ``t`` (entered then), in document order."""
    inner = {r.mode for r in run.intervals if r.start == t}
    return sorted(m for m in inner if not any(o.startswith(m + ".") for o in inner))


def counter(run: ht.Run) -> float:
    """The counter's last sampled value (a run that ends waiting samples NaN after)."""
    values = run.samples["a"][:, 0, 0]
    return float(values[~np.isnan(values)][-1])


PARALLEL_HISTORY = """
    team: parallel_history
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            history: {kind}
            transitions: [{{to: Out, on: pause}}]
            modes:
              R1:
                initial: a
                modes:
                  a: {{transitions: [{{to: b, after: 1}}]}}
                  b:
                    initial: b1
                    modes:
                      b1: {{transitions: [{{to: b2, after: 0.25}}]}}
                      b2: {{}}
              R2:
                initial: c
                modes:
                  c: {{transitions: [{{to: d, after: 1}}]}}
                  d: {{}}
          Out: {{transitions: [{{to: P, after: 1}}]}}
    scenario: [{{at: 1.5, agent: a, raise: pause}}]
    simulation: {{duration: 3}}
"""


@pytest.mark.parametrize(("kind", "back"), [
    ("none", ["P.R1.a", "P.R2.c"]),
    ("shallow", ["P.R1.b.b1", "P.R2.d"]),   # each region's child, b's initial below it
    ("deep", ["P.R1.b.b2", "P.R2.d"]),      # the whole configuration
])
def test_history_on_a_parallel_mode_restores_its_regions(team_from_yaml, kind, back):
    run = ht.simulate(team_from_yaml(PARALLEL_HISTORY.format(kind=kind)))
    assert steps(run)[:4] == [
        (1.0, 0, "P.R1.a", "P.R1.b"), (1.0, 0, "P.R2.c", "P.R2.d"),
        (1.25, 0, "P.R1.b.b1", "P.R1.b.b2"), (1.5, 0, "P", "Out")]
    assert steps(run)[4] == (2.5, 0, "Out", "P")
    assert leaves_from(run, 2.5) == back


def test_a_transition_without_target_on_a_region_runs_in_place(team_from_yaml):
    team = team_from_yaml("""
        team: region_internal
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: P
            modes:
              P:
                parallel: true
                modes:
                  R1:
                    initial: a
                    transitions: [{on: ping, do: ["n = n + 1"]}]
                    modes:
                      a: {transitions: [{to: b, after: 1}]}
                      b: {}
                  R2:
                    initial: c
                    modes:
                      c: {transitions: [{to: d, guard: n >= 2}]}
                      d: {}
        scenario: [{at: 0.5, agent: a, raise: ping}, {at: 2, agent: a, raise: ping}]
        simulation: {duration: 3}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(0.5, 0, "P.R1", "P.R1"), (1.0, 0, "P.R1.a", "P.R1.b"),
                          (2.0, 0, "P.R1", "P.R1"), (2.0, 1, "P.R2.c", "P.R2.d")]
    # (R2 moved at 2: n reached 2.) R1's child b was not left by the second ping: one
    # interval of it, from 1 to the end of the run
    assert [(r.start, r.end) for r in run.intervals if r.mode == "P.R1.b"] == [(1.0, 2.0)]


OUTER_INTERNAL = """
    team: outer_internal
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: S
        modes:
          S:
            initial: a
            transitions: [{{on: go, do: ["n = n + 1"]{outer}}}]
            modes:
              a: {{transitions: [{{to: b, on: go, do: ["n = n * 10"]}}]}}
              b: {{}}
          T: {{}}
    scenario: [{{at: 1, agent: a, raise: go}}]
    simulation: {{duration: 2}}
"""


def test_a_transition_without_target_exits_nothing_so_inner_ones_still_fire(team_from_yaml):
    """The outer transition exits nothing: it neither blocks nor is blocked by the inner
    one on the same event. Outer first: n = (0 + 1) * 10."""
    run = ht.simulate(team_from_yaml(OUTER_INTERNAL.format(outer="")))
    assert steps(run) == [(1.0, 0, "S", "S"), (1.0, 0, "S.a", "S.b")]
    assert counter(run) == 10.0


def test_an_outer_transition_that_leaves_still_preempts_the_inner_one(team_from_yaml):
    run = ht.simulate(team_from_yaml(OUTER_INTERNAL.format(outer=", to: T")))
    assert steps(run) == [(1.0, 0, "S", "T")]
    assert counter(run) == 1.0


REGION_SELF = """
    team: region_self
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            modes:
              R1:
                initial: a
                transitions: [{{on: reset, to: {target}}}]
                modes:
                  a: {{transitions: [{{to: b, after: 1}}]}}
                  b: {{}}
              R2:
                initial: c
                modes:
                  c: {{transitions: [{{to: d, after: 1}}]}}
                  d: {{}}
    scenario: [{{at: 1.5, agent: a, raise: reset}}]
    simulation: {{duration: 2}}
"""


@pytest.mark.parametrize(("target", "back"), [
    ("R1", ["P.R1.a", "P.R2.c"]), ("R1.b", ["P.R1.b", "P.R2.c"])])
def test_a_region_to_itself_leaves_and_reenters_the_parallel_mode(team_from_yaml, target,
                                                                  back):
    """SCXML's transition domain skips parallel modes: the whole of P is exited and entered
    again, R2 by default."""
    run = ht.simulate(team_from_yaml(REGION_SELF.format(target=target)))
    assert steps(run)[2] == (1.5, 0, "P.R1", f"P.{target}")
    assert leaves_from(run, 1.5) == back
    assert ("P", 0.0, 1.5) in {(r.mode, r.start, r.end) for r in run.intervals}


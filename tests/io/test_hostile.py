"""Hostile and degenerate input: one clear error or a diagnosed outcome, never a traceback,
a hang, or a model's text injected into an export."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.export.diagram import diagram_graph
from hybridteam.export.render import render
from hybridteam.io.filekind import InputErrors

TWO_MODES = """
team: {name}
agents:
  r:
    plant: {{kind: flow, state: {{x: 0.0}}}}
    initial: A
    modes:
      A:
        flow: {{x: 1}}
        transitions: [{{to: B, guard: x >= 1}}]
      B: {{flow: {{x: 0}}}}
simulation: {{duration: 2.0}}
"""


@pytest.mark.parametrize("fmt", ["mermaid", "plantuml", "dot"])
@pytest.mark.parametrize("brk", ["\\n", "\\r", "\\u2028"])
def test_a_team_name_cannot_inject_lines_into_text_exports(team_from_yaml, fmt, brk):
    """A line break in the team's name is a space in Mermaid and PlantUML: the file is the
    one a name with a space gives, so it parses to the same diagram. DOT quotes the name
    (a line break becomes the escape ``\\n`` of a two-line label): no line of its own. A
    carriage return, which a terminal acts on (it overwrites the line), is refused where the
    name is written."""
    if brk == "\\r":
        with pytest.raises(
            InputErrors,
            match=r"team\.yaml:2:7: team: team name .* has "
            "control characters",
        ):
            team_from_yaml(TWO_MODES.format(name=f'"evil{brk}    Injected --> Other"'))
        return
    evil = team_from_yaml(TWO_MODES.format(name=f'"evil{brk}    Injected --> Other"'))
    plain = team_from_yaml(TWO_MODES.format(name='"evil     Injected --> Other"'), "p.yaml")
    got, expected = render(diagram_graph(evil), fmt), render(diagram_graph(plain), fmt)
    if fmt == "dot":
        assert got.count("\n") == expected.count("\n")
    else:
        assert got == expected
    assert not any(line.lstrip().startswith("Injected") for line in got.splitlines())


# ----------------------------------------------------------------------------- numerics
FLOW = """
team: numerics
agents:
  a:
    plant: {{kind: flow, state: {{x: 1.0}}}}
    parameters: {{c: 0.0}}
    initial: A
    modes:
      A:
        flow: {{x: "{flow}"}}
simulation: {{duration: 2.0}}
"""


@pytest.mark.parametrize(
    ("flow", "outcome", "words"),
    [
        ("1/(x-1)", "numerical_error", "the derivative of state 'x' is inf (flow x: 1/(x-1))"),
        ("sqrt(-x)", "numerical_error", "the derivative of state 'x' is nan (flow x: sqrt(-x))"),
        ("exp(1000*x)", "numerical_error", "the derivative of state 'x' is inf"),
        ("log(x-1)", "numerical_error", "the derivative of state 'x' is -inf"),
        ("1e6*sin(1e6*t)", "stiff", "step size fell to"),
        ("-1e9*x", "stiff", "below 2e-06 s (flow x: -1e9*x)"),
        ("x*x", "stiff", "step size fell to"),  # blows up at t = 1
        ("1/(1-t)", "stiff", "step size fell to"),
    ],
)
def test_numerical_failure_is_an_outcome_not_a_hang(team_from_yaml, flow, outcome, words):
    run = ht.simulate(team_from_yaml(FLOW.format(flow=flow)))
    assert run.outcome == outcome
    assert words in run.message
    assert run.message.startswith("agent 'a' in mode 'A' at t=")


def test_the_blow_up_is_diagnosed_where_it_happens(team_from_yaml):
    """x' = x^2 from x = 1 is 1 / (1 - t): the run ends just before t = 1."""
    run = ht.simulate(team_from_yaml(FLOW.format(flow="x*x")))
    assert run.outcome == "stiff"
    assert 0.999 < run.diagnostics[0]["t"] < 1.0


def test_a_numerical_failure_ends_only_its_instance(team_from_yaml):
    """x' = 1/(x - c): the instance with c = 1 divides by zero at once; the others are the
    runs they are alone (x(t) = c + sqrt((1 - c)^2 + 2t) for x > c)."""
    team = team_from_yaml(FLOW.format(flow="1/(x-c)"))
    run = ht.simulate(team, n=3, overrides={"c": [0.0, 1.0, -1.0]})
    assert run.outcomes == ["ok", "numerical_error", "ok"]
    for i, c in ((0, 0.0), (2, -1.0)):
        final = run.samples["a"][-1, i, 0]
        assert final == pytest.approx(c + math.sqrt((1 - c) ** 2 + 4.0), rel=1e-8)
        alone = ht.simulate(team, overrides={"c": c})
        np.testing.assert_array_equal(alone.samples["a"][:, 0], run.samples["a"][:, i])


def test_an_input_that_is_not_a_number_ends_the_run(team_from_yaml):
    team = team_from_yaml("""
        team: u
        agents:
          r:
            plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
            modes:
              Go:
                inputs: {v: 1/(1-t), omega: 0}
                period: 0.25
        simulation: {duration: 2.0}
    """)
    run = ht.simulate(team)
    assert run.outcome == "numerical_error"
    assert run.diagnostics[0]["t"] == 1.0
    assert run.message == (
        "agent 'r' in mode 'Go' at t=1.0: input 'v' is inf (inputs: v: 1/(1-t), omega: 0.0)"
    )


def test_min_step_lets_a_model_ask_for_smaller_steps(team_from_yaml):
    """A stiff transient (rate 1e7 /s, fading in about a millisecond) needs steps of a few
    1e-7 s, below the default floor of 1e-6 of the duration; with min_step it runs, and
    x relaxes to 2."""
    text = FLOW.format(flow="-1e7*exp(-1000*t)*(x-2)").replace("duration: 2.0", "duration: 1.0")
    assert ht.simulate(team_from_yaml(text)).outcome == "stiff"
    ok = ht.simulate(team_from_yaml(text.replace("duration: 1.0", "duration: 1.0, min_step: 1e-9")))
    assert ok.outcome == "ok"
    assert ok.samples["a"][-1, 0, 0] == pytest.approx(2.0, abs=1e-9)

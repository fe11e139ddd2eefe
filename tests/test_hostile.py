"""Hostile and degenerate input: one clear error or a diagnosed outcome, never a traceback,
a hang, or a model's text injected into an export."""

from __future__ import annotations

import pytest

from hybridteam.export.diagram import diagram_graph
from hybridteam.export.render import render

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
    (a line break becomes the escape ``\\n`` of a two-line label): no line of its own."""
    evil = team_from_yaml(TWO_MODES.format(name=f'"evil{brk}    Injected --> Other"'))
    plain = team_from_yaml(TWO_MODES.format(name='"evil     Injected --> Other"'), "p.yaml")
    got, expected = render(diagram_graph(evil), fmt), render(diagram_graph(plain), fmt)
    if fmt == "dot":
        assert got.count("\n") == expected.count("\n")
    else:
        assert got == expected
    assert not any(line.lstrip().startswith("Injected") for line in got.splitlines())

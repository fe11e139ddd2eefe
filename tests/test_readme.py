"""What the README tells a newcomer, checked against what the code does.

Each test reads the README's own text (a code block, a line, a backticked key) and holds it
to the behaviour it describes, so the text cannot drift from the product unnoticed.
"""

from __future__ import annotations

import re
import textwrap

import yaml

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.overrides import key_problem
from hybridteam.trace import INTERVAL_COLUMNS
from tests.conftest import EXAMPLES, ROOT

README = (ROOT / "README.md").read_text()
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def section(title: str) -> str:
    """The text under a heading, up to the next heading of any level."""
    start = README.index(f"{title}\n")
    rest = README[start + len(title) + 1:]
    end = re.search(r"^#{2,3} ", rest, re.M)
    return rest[:end.start()] if end else rest


def test_quick_start_makes_a_virtual_environment_first():
    """The venv comes before the two commands, which stay exactly what CI runs."""
    quick = section("## Quick start")
    blocks = [body.strip() for lang, body in BLOCK.findall(quick) if lang == "bash"]
    assert blocks[0] == "python3 -m venv .venv && . .venv/bin/activate"
    assert blocks[1] == ("pip install . && hybridteam run examples/automata/bouncing_ball.yaml"
                         " -o out/ball")
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert blocks[2] == ci == "pip install -e '.[test]' && python -m pytest"
    assert "about 4 minutes on a 2-core machine" in " ".join(quick.split())


def test_run_modes_is_described_as_the_interval_table():
    (line,) = [ln for ln in README.splitlines() if ln.startswith("run.modes ")]
    comment = line + " " + README.splitlines()[README.splitlines().index(line) + 1]
    assert "interval table" in comment and "run.intervals" in comment
    assert all(col in comment for col in INTERVAL_COLUMNS)
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat.yaml"), duration=10.0)
    assert run.modes is run.intervals and run.modes.names == INTERVAL_COLUMNS


def test_network_section_names_the_cost_of_jitter_and_working_override_keys(tmp_path):
    """The keys the section names are override keys of a team with the link it names."""
    text = " ".join(section("### Messages and the network").split())
    assert "about three times as long" in text and "`--set network.jitter=0`" in text
    keys = sorted(set(re.findall(r"`(network\.[^`=\s]+)`", text)))
    assert keys == ["network.jitter", "network.latency", "network.links.xr4000->labmate.latency",
                    "network.loss"]
    team_file = tmp_path / "team.yaml"
    team_file.write_text(textwrap.dedent("""\
        team: pair
        network: {latency: 0.03, links: {"xr4000->labmate": {latency: 0.05}}}
        agents:
          xr4000: {plant: {kind: flow, state: {c: 0}}, modes: {A: {}}}
          labmate: {plant: {kind: flow, state: {c: 0}}, modes: {A: {}}}
        """))
    cteam = compile_team(ht.load(team_file))
    for key in keys:
        assert key_problem(cteam.agents, key, cteam.team.network) is None, key
    assert key_problem(cteam.agents, "network.links.labmate->xr4000.latency",
                       cteam.team.network) is not None


def test_on_collision_has_a_yaml_example_that_loads(tmp_path):
    """The obstacles example, with its ``on_collision: warn``, inside a team of the robots
    it names: it validates and the component reads the setting."""
    (example,) = [body for lang, body in BLOCK.findall(README)
                  if lang == "yaml" and "on_collision:" in body]
    team_file = tmp_path / "team.yaml"
    team_file.write_text(textwrap.dedent("""\
        team: readme
        agents:
          xr4000:
            model: xr4000
            plant: {state: {x: 0, y: 0, theta: 0}}
            modes: {Stay: {}}
          rover:
            plant: {kind: unicycle, state: {x: 5, y: 0, theta: 0}}
            modes: {Stay: {}}
        world:
        """) + example)
    team = ht.load(team_file)
    (obstacles,) = [w for w in team.world if w.use == "obstacles"]
    assert obstacles.values["on_collision"] == "warn"
    assert yaml.safe_load(example)[0]["with"]["on_collision"] == "warn"

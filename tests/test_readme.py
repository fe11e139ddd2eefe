"""What the README and the manual (docs/) tell a newcomer, checked against what the code does.

Each test reads the text where it lives (a code block, a line, a backticked key) and holds it
to the behaviour it describes, so the text cannot drift from the product unnoticed; the last
tests hold the manual together (every page listed in docs/index.md, every link inside the
repository and alive).
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
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def section(title: str, text: str = README) -> str:
    """The text under a heading, up to the next heading of any level."""
    start = text.index(f"{title}\n")
    rest = text[start + len(title) + 1 :]
    end = re.search(r"^#{2,3} ", rest, re.M)
    return rest[: end.start()] if end else rest


def test_quick_start_makes_a_virtual_environment_first():
    """The venv comes before the two commands, which stay exactly what CI runs."""
    quick = section("## Quick start")
    blocks = [body.strip() for lang, body in BLOCK.findall(quick) if lang == "bash"]
    assert blocks[0] == "python3 -m venv .venv && . .venv/bin/activate"
    assert blocks[1] == (
        "pip install . && hybridteam run examples/automata/bouncing_ball.yaml -o out/ball"
    )
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert blocks[2] == ci == "pip install -e '.[test]' && python -m pytest"
    assert "about 8 minutes on a 2-core machine" in " ".join(quick.split())


def test_run_modes_is_described_as_the_interval_table():
    lines = (DOCS / "python.md").read_text().splitlines()
    (line,) = [ln for ln in lines if ln.startswith("run.modes ")]
    comment = line + " " + lines[lines.index(line) + 1]
    assert "interval table" in comment and "run.intervals" in comment
    assert all(col in comment for col in INTERVAL_COLUMNS)
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat.yaml"), duration=10.0)
    assert run.modes is run.intervals and run.modes.names == INTERVAL_COLUMNS


def test_network_section_names_the_cost_of_jitter_and_working_override_keys(tmp_path):
    """The keys the section names are override keys of a team with the link it names."""
    text = " ".join(
        section("## Messages and the network", (DOCS / "modelling.md").read_text()).split()
    )
    # what jitter costs: quiet stream copies make no instant, the rest still do
    assert "*quiet copy*" in text and "each arrival is still an instant" in text
    assert "`--set network.jitter=0`" in text
    keys = sorted(set(re.findall(r"`(network\.[^`=\s]+)`", text)))
    assert keys == [
        "network.jitter",
        "network.latency",
        "network.links.xr4000->labmate.latency",
        "network.loss",
    ]
    team_file = tmp_path / "team.yaml"
    team_file.write_text(
        textwrap.dedent("""\
        team: pair
        network: {latency: 0.03, links: {"xr4000->labmate": {latency: 0.05}}}
        agents:
          xr4000: {plant: {kind: flow, state: {c: 0}}, modes: {A: {}}}
          labmate: {plant: {kind: flow, state: {c: 0}}, modes: {A: {}}}
        """)
    )
    cteam = compile_team(ht.load(team_file))
    for key in keys:
        assert key_problem(cteam.agents, key, cteam.team.network) is None, key
    assert (
        key_problem(cteam.agents, "network.links.labmate->xr4000.latency", cteam.team.network)
        is not None
    )


def test_on_collision_has_a_yaml_example_that_loads(tmp_path):
    """The obstacles example, with its ``on_collision: warn``, inside a team of the robots
    it names: it validates and the component reads the setting."""
    (example,) = [
        body
        for lang, body in BLOCK.findall((DOCS / "world.md").read_text())
        if lang == "yaml" and "on_collision:" in body
    ]
    team_file = tmp_path / "team.yaml"
    team_file.write_text(
        textwrap.dedent("""\
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
        """)
        + example
    )
    team = ht.load(team_file)
    (obstacles,) = [w for w in team.world if w.use == "obstacles"]
    assert obstacles.values["on_collision"] == "warn"
    assert yaml.safe_load(example)[0]["with"]["on_collision"] == "warn"


def test_the_tour_python_block_runs_as_written(monkeypatch):
    """The README's Python block, run from the repository root: a hundred thermostats,
    each heating rate its own instance, all ending ``ok`` at the file's 160 s."""
    (block,) = [body for lang, body in BLOCK.findall(README) if lang == "python"]
    monkeypatch.chdir(ROOT)
    space: dict = {}
    exec(compile(block, "README.md", "exec"), space)
    run = space["run"]
    assert run.n == 100 and run.outcomes == ["ok"] * 100
    assert {o["t"] for o in run.diagnostics} == {160.0}


LINK = re.compile(r"\]\(([^)\s]+)\)")


def test_the_index_lists_every_page_of_the_manual():
    listed = set(re.findall(r"\]\(([\w-]+\.md)\)", (DOCS / "index.md").read_text()))
    pages = {p.name for p in DOCS.glob("*.md")} - {"index.md"}
    assert pages and listed == pages


def test_links_stay_inside_the_repository_and_lead_somewhere():
    """Every Markdown link of the README and the manual is a relative path to a file of
    the repository (a ``#fragment`` names a heading of it); none leaves the repository."""
    checked = 0
    for page in [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]:
        prose = re.sub(r"`[^`\n]*`", "", BLOCK.sub("", page.read_text()))  # no code
        for target in LINK.findall(prose):
            path, _, fragment = target.partition("#")
            assert "://" not in target and not target.startswith("/"), f"{page.name}: {target}"
            resolved = (page.parent / path).resolve() if path else page
            assert resolved.is_relative_to(ROOT) and resolved.is_file(), f"{page.name}: {target}"
            if fragment:
                slugs = {
                    re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-")
                    for h in re.findall(r"^#+ (.*)$", resolved.read_text(), re.M)
                }
                assert fragment in slugs, f"{page.name}: {target}"
            checked += 1
    assert checked > 20

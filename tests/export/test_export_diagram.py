"""State diagrams: one graph, DOT / Mermaid / PlantUML text, images, checked by structure.

The text formats are parsed back (pydot for DOT, small parsers here for Mermaid and
PlantUML) and compared with the compiled team: every mode once, nested in its parent, and
every transition with the right endpoints.
"""

from __future__ import annotations

import io
import itertools
import re
import shutil
import sys
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pydot
import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.export import image
from hybridteam.export.diagram import diagram_graph, edges_of
from hybridteam.export.render import RENDERERS, register, render
from hybridteam.export.style import FINAL
from tests.conftest import EXAMPLES

# pydot's parser uses pyparsing names that newer pyparsing deprecates; not our concern here
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning:pydot.dot_parser")

AUTOMATA = sorted((EXAMPLES / "automata").glob("*.yaml"))

NESTED = """
    team: nested
    agents:
      carrier:
        plant: {kind: flow, state: {c: 0}}
        initial: Work
        modes:
          Work:
            history: deep
            initial: Dock
            transitions: [{to: Break, on: pause, do: [{send: stop}]}]
            modes:
              Dock:
                initial: Approach
                modes:
                  Approach:
                    flow: {c: 1}
                    invariant: c <= 3
                    transitions: [{to: Latch, guard: c >= 2, do: ["c = 0", {raise: go}]}]
                  Latch: {transitions: [{to: Transport, on: go}]}
              Transport:
                parallel: true
                modes:
                  Drive:
                    initial: Fwd
                    modes:
                      Fwd: {transitions: [{to: Fwd, after: 1}, {to: Back, after: 2}]}
                      Back: {}
                  Talk:
                    {initial: Idle, history: shallow,
                     modes: {Idle: {transitions: [{to: Idle, on: ping, guard: c < 5}]}}}
          Break:
            transitions: [{to: Work, after: 1}, {to: Work.Transport.Drive.Back, on: resume}]
          Done: {final: true}
      helper:
        plant: {kind: flow, state: {c: 0}}
        initial: Idle
        modes:
          Idle:
            transitions: [{to: Busy, on: stop, do: [{send: ping, to: carrier}, {send: resume}]}]
          Busy: {transitions: [{to: Idle, after: 2, do: [{send: pause}]}]}
"""


@pytest.fixture
def nested(team_from_yaml):
    return team_from_yaml(NESTED)


@pytest.fixture
def models(nested) -> list[ht.Team]:
    return [ht.load(p) for p in AUTOMATA] + [nested]


# ------------------------------------------------------------------ what the model says


def expected(team: ht.Team):
    """Modes {agent/path: parent id}, transitions Counter[(src, dst)], composite kinds."""
    cteam = compile_team(team)
    parents, kinds = {}, {}
    trans: Counter = Counter()
    for agent in cteam.agents:

        def mid(i, agent=agent):
            path = agent.modes[i].path
            return f"{agent.name}/{path}" if path else agent.name

        for m in agent.modes[1:]:
            parents[mid(m.index)] = mid(m.parent)
            kinds[mid(m.index)] = m.kind
        for ct in agent.transitions:
            trans[(mid(ct.source), mid(ct.target))] += 1
    return parents, trans, kinds


def sid(node: str) -> str:
    """The plain id the Mermaid and PlantUML renderers give a node."""
    return node.replace("/", "__").replace(".", "__")


# ------------------------------------------------------------------ the graph


def test_graph_of_relay_has_modes_transitions_and_messages():
    g = diagram_graph(ht.load(EXAMPLES / "automata" / "relay.yaml"))
    assert g.graph["name"] == "relay"
    assert g.nodes["runner"] == {
        "kind": "agent",
        "label": "runner",
        "plant": "unicycle",
        "history": "none",
    }
    run = g.nodes["runner/Run"]
    assert run["initial"] and run["mode_kind"] == "leaf" and not run["region"]
    assert run["dynamics"] == "inputs: v = speed, omega = 0 @10 Hz"
    assert g.nodes["runner/Done"]["final"] and g.nodes["runner/Done"]["color"] == FINAL
    # one colour per mode path across the team: different modes never share a colour
    colours = [
        g.nodes[n]["color"] for n in ("runner/Run", "runner/Wait", "anchor/Ready", "anchor/Arc")
    ]
    assert len(set(colours)) == 4 and FINAL not in colours
    trans = [(u, v, d["label"], d["actions"]) for u, v, d in edges_of(g, "transition")]
    assert trans == [
        ("runner/Run", "runner/Wait", "[x >= handover] / send baton", ["send baton -> anchor"]),
        ("runner/Wait", "runner/Done", "done", []),
        ("anchor/Ready", "anchor/Arc", "baton", []),
        (
            "anchor/Arc",
            "anchor/Done",
            "after((pi / 2) * radius / speed) / send done",
            ["send done -> runner"],
        ),
    ]
    msgs = [(u, v, d["message"]) for u, v, d in edges_of(g, "message")]
    assert msgs == [("runner/Run", "anchor/Ready", "baton"), ("anchor/Arc", "runner/Wait", "done")]


def test_graph_of_nested_model_has_hierarchy_attributes(nested):
    g = diagram_graph(nested)
    n = g.nodes
    keys = ("mode_kind", "history", "initial", "region", "depth")
    assert {
        m: tuple(n[f"carrier/{m}"][k] for k in keys)
        for m in (
            "Work",
            "Work.Dock",
            "Work.Transport",
            "Work.Transport.Drive",
            "Work.Transport.Talk",
            "Work.Transport.Drive.Fwd",
            "Work.Transport.Drive.Back",
        )
    } == {
        "Work": ("or", "deep", True, False, 1),
        "Work.Dock": ("or", "none", True, False, 2),
        "Work.Transport": ("and", "none", False, False, 2),  # parallel: no initial
        "Work.Transport.Drive": ("or", "none", False, True, 3),  # regions
        "Work.Transport.Talk": ("or", "shallow", False, True, 3),
        "Work.Transport.Drive.Fwd": ("leaf", "none", True, False, 4),
        "Work.Transport.Drive.Back": ("leaf", "none", False, False, 4),
    }
    approach = n["carrier/Work.Dock.Approach"]
    assert (approach["dynamics"], approach["invariant"]) == ("flow: c' = 1", "c <= 3")
    contains = [(u, v) for u, v, _ in edges_of(g, "contains")]
    assert {
        ("carrier/Work.Transport", "carrier/Work.Transport.Talk"),
        ("carrier", "carrier/Work"),
    } <= set(contains)
    latch = next(d for u, _, d in edges_of(g, "transition") if u == "carrier/Work.Dock.Approach")
    assert latch["guard"] == "c >= 2" and latch["actions"] == ["c = 0", "raise go"]
    assert latch["label"] == "[c >= 2] / c = 0; raise go"
    loops = [d["label"] for u, v, d in edges_of(g, "transition") if u == v]
    assert loops == ["after(1)", "ping [c < 5]"]
    msgs = {(u, v, d["message"]) for u, v, d in edges_of(g, "message")}
    assert msgs == {
        ("carrier/Work", "helper/Idle", "stop"),
        ("helper/Idle", "carrier/Work.Transport.Talk.Idle", "ping"),  # to: carrier
        ("helper/Idle", "carrier/Break", "resume"),  # broadcast
        ("helper/Busy", "carrier/Work", "pause"),
    }


# ------------------------------------------------------------------ DOT


def _unq(s: str | None) -> str:
    return (s or "").strip('"')


def _owner(node: str) -> str:
    """A pseudostate or cluster anchor stands for its composite."""
    return node.rsplit("/", 1)[0] if node.endswith(("/[*]", "/[anchor]")) else node


def parse_dot(text: str):
    (dot,) = pydot.graph_from_dot_data(text)
    parents: dict[str, str] = {}
    leaves: set[str] = set()

    def visit(sub, owner: str | None) -> None:
        for node in sub.get_nodes():
            name = _unq(node.get_name())
            if name in ("graph", "node", "edge") or name.endswith(("/[*]", "/[anchor]")):
                continue
            leaves.add(name)
            parents[name] = owner
        for child in sub.get_subgraphs():
            name = _unq(child.get_name())
            assert name.startswith("cluster_")
            mode = name[len("cluster_") :]
            if owner is not None:
                parents[mode] = owner
            visit(child, mode)

    visit(dot, None)
    edges: dict[str, Counter] = {k: Counter() for k in ("initial", "transition", "message")}
    for e in dot.get_edges():
        attrs = e.get_attributes()
        src, dst = _unq(e.get_source()), _unq(e.get_destination())
        if "ltail" in attrs:
            assert _unq(attrs["ltail"]) == "cluster_" + _owner(src)
        if "lhead" in attrs:
            assert _unq(attrs["lhead"]) == "cluster_" + _owner(dst)
        kind = _unq(attrs["class"])
        assert (_unq(attrs.get("style")) == "dashed") == (kind == "message")
        key = (_owner(src), _owner(dst), _unq(attrs.get("label")))
        edges[kind][key if kind == "message" else key[:2]] += 1
    return parents, leaves, edges


@pytest.mark.parametrize("path", AUTOMATA, ids=lambda p: p.stem)
def test_dot_of_every_example_has_exactly_its_modes_and_transitions(path: Path):
    team = ht.load(path)
    parents, trans, kinds = expected(team)
    got_parents, leaves, edges = parse_dot(render(diagram_graph(team), "dot"))
    assert got_parents == parents
    assert leaves == {m for m, k in kinds.items() if k == "leaf"}
    assert edges["transition"] == trans
    if path.stem == "relay":  # dashed (checked in parse_dot) and labelled with the type
        assert set(edges["message"]) == {
            ("runner/Run", "anchor/Ready", "baton"),
            ("anchor/Arc", "runner/Wait", "done"),
        }


def test_dot_nesting_regions_and_initials(nested):
    parents, trans, kinds = expected(nested)
    text = render(diagram_graph(nested), "dot")
    got_parents, leaves, edges = parse_dot(text)
    assert got_parents == parents
    assert leaves == {m for m, k in kinds.items() if k == "leaf"}
    assert edges["transition"] == trans
    inits = set(edges["initial"])
    assert ("carrier/Work.Transport.Drive", "carrier/Work.Transport.Drive.Fwd") in inits
    assert ("carrier", "carrier/Work") in inits
    assert not any(src == "carrier/Work.Transport" for src, _ in inits)  # parallel: no initial
    (dot,) = pydot.graph_from_dot_data(text)
    (defaults,) = dot.get_node("graph")
    assert _unq(defaults.get_attributes()["compound"]) == "true"
    assert re.search(
        r'subgraph "cluster_carrier/Work.Transport.Talk" \{\s*graph \[label="Talk '
        r'\(H\)", style="rounded,dashed"',
        text,
    )


def test_dot_quotes_awkward_labels():
    g = diagram_graph(ht.load(EXAMPLES / "automata" / "thermostat.yaml"))
    awkward = 'x "quoted" <tag> & \\back; a.b'
    u, v, k = next(
        (u, v, k) for u, v, k, d in g.edges(keys=True, data=True) if d["kind"] == "transition"
    )
    g.edges[u, v, k]["label"] = awkward
    g.nodes["thermostat/Heat"]["dynamics"] = awkward
    (dot,) = pydot.graph_from_dot_data(render(g, "dot"))
    labels = [e.get_attributes().get("label") for e in dot.get_edges()]
    assert '"x \\"quoted\\" <tag> & \\\\back; a.b"' in labels
    assert len(dot.get_edges()) == 3  # initial + two transitions, nothing split


# ------------------------------------------------------------------ Mermaid and PlantUML


def real_ends(a: str, b: str, label: str) -> tuple[str, str, str]:
    """Undo PlantUML's stand-in ends: ``(from Path)`` / ``(to Path)`` name the real modes."""
    for side, path in re.findall(r" \((from|to) ([\w.]+)\)", label):
        agent = (a if side == "from" else b).split("__")[0]
        if side == "from":
            a = sid(f"{agent}/{path}")
        else:
            b = sid(f"{agent}/{path}")
    return a, b, re.sub(r" \((from|to) [\w.]+\)", "", label)


def parse_states(text: str, divider: str, message_arrow: str):
    """Declared states with their enclosing block, relations per block, messages."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    stack: list[str] = []
    parents: dict[str, str | None] = {}
    relations: list[tuple[str | None, str, str, str]] = []
    messages: list[tuple[str, str, str]] = []
    state = re.compile(r'state "([^"]*)" as (\w+)( #[0-9A-Fa-f]{6})?( \{)?$')
    link = re.compile(
        r"(\[\*\]|\w+) (-->|" + re.escape(message_arrow) + r") (\[\*\]|\w+)"
        r"(?: : (.*))?$"
    )
    for ln in lines:
        if (m := state.match(ln)) is not None:
            parents[m.group(2)] = stack[-1] if stack else None
            if m.group(4):
                stack.append(m.group(2))
        elif ln == "}":
            assert stack, "unbalanced }"
            stack.pop()
        elif ln == divider:
            assert stack
        elif (m := link.match(ln)) is not None:
            a, b, label = real_ends(m.group(1), m.group(3), m.group(4) or "")
            if m.group(2) == "-->" and not label.endswith("(message)"):
                relations.append((stack[-1] if stack else None, a, b, label))
            else:
                messages.append((a, b, label.removesuffix(" (message)")))
        else:
            assert re.match(
                r"(stateDiagram-v2|%%|'|classDef|class |@startuml|@enduml|hide |"
                r"skinparam |title |\w+ : )",
                ln,
            ), ln
    assert not stack, "unbalanced {"
    return parents, relations, messages


def check_state_text(team: ht.Team, text: str, divider: str, message_arrow: str) -> None:
    parents, trans, kinds = expected(team)
    got_parents, relations, messages = parse_states(text, divider, message_arrow)
    agents = [a.name for a in team.agents]
    assert {k: v for k, v in got_parents.items() if k not in agents} == {
        sid(m): sid(p) for m, p in parents.items()
    }
    assert all(got_parents[a] is None for a in agents)
    got = Counter((a, b) for _, a, b, _ in relations if "[*]" not in (a, b))
    assert got == Counter({(sid(a), sid(b)): n for (a, b), n in trans.items()})
    initials = {(blk, b) for blk, a, b, _ in relations if a == "[*]"}
    want = {
        (sid(p), sid(m))
        for m, p in parents.items()
        if kinds.get(p) != "and" and diagram_graph(team).nodes[m]["initial"]
    }
    assert initials == want
    g = diagram_graph(team)
    assert {(a, b, m) for a, b, m in messages} == {
        (sid(u), sid(v), d["message"]) for u, v, d in edges_of(g, "message")
    }


@pytest.mark.parametrize(
    "fmt, divider, arrow", [("mermaid", "--", "-->"), ("plantuml", "||", "-[dashed]->")]
)
def test_state_languages_for_every_model(models, fmt, divider, arrow):
    for team in models:
        text = render(diagram_graph(team), fmt)
        if fmt == "mermaid":
            assert text.startswith("stateDiagram-v2\n")
        else:
            assert text.startswith("@startuml\n") and text.rstrip().endswith("@enduml")
            assert text.count("@startuml") == text.count("@enduml") == 1
        check_state_text(team, text, divider, arrow)
        for ln in text.splitlines():  # Mermaid ends a label at ':' or ';', '#' starts a comment
            if fmt == "mermaid" and " --> " in ln and " : " in ln:
                assert not set(ln.split(" : ", 1)[1]) & set(':;#"'), ln


def test_regions_are_separated_in_both_languages(nested):
    g = diagram_graph(nested)
    for fmt, divider in (("mermaid", "--"), ("plantuml", "||")):
        text = render(g, fmt)
        block = text[text.index("as carrier__Work__Transport {") :]
        drive, talk = (
            block.index("carrier__Work__Transport__Drive {"),
            block.index("carrier__Work__Transport__Talk {"),
        )
        assert f"\n{' ' * 16}{divider}\n" in block[drive:talk]
        assert '"Work (H*)"' in text and '"Talk (H)"' in text
    # PlantUML cannot link into a concurrent region from outside: the parallel mode stands in
    assert (
        "carrier__Break --> carrier__Work__Transport : resume (to Work.Transport.Drive.Back)"
        in render(g, "plantuml")
    )


# ------------------------------------------------------------------ determinism, registry


def test_rendering_is_deterministic(models):
    for team in models:
        for fmt in ("dot", "mermaid", "plantuml"):
            assert render(diagram_graph(team), fmt) == render(diagram_graph(team), fmt)


def test_unknown_format_suggests_the_closest_and_register_adds_one():
    g = diagram_graph(ht.load(EXAMPLES / "automata" / "thermostat.yaml"))
    with pytest.raises(ValueError, match="did you mean 'dot'") as err:
        render(g, "dott")
    assert "mermaid" in str(err.value) and "png" in str(err.value)
    register("count", lambda graph: str(graph.number_of_nodes()))
    try:
        assert render(g, "count") == "3"
    finally:
        del RENDERERS["count"]


# ------------------------------------------------------------------ images


def svg_texts(svg: str) -> list[str]:
    root = ET.fromstring(svg)
    return ["".join(el.itertext()) for el in root.iter() if el.tag.endswith("text")]


def names_of(team: ht.Team) -> set[str]:
    """Every agent and mode name (an agent's root mode carries the agent's name)."""
    return {m.name for a in team.agents for _, m in a.root.walk()}


@pytest.fixture
def no_dot(monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda *_a, **_k: None)


@pytest.mark.parametrize("name", [p.stem for p in AUTOMATA] + ["nested"])
def test_builtin_images(no_dot, nested, name):
    team = nested if name == "nested" else ht.load(EXAMPLES / "automata" / f"{name}.yaml")
    g = diagram_graph(team)
    png = render(g, "png")
    assert isinstance(png, bytes) and png.startswith(b"\x89PNG\r\n\x1a\n")
    pixels = mpimg.imread(io.BytesIO(png))
    assert 400 <= pixels.shape[1] <= 6000 and 100 <= pixels.shape[0] <= 6000
    svg = render(g, "svg")
    texts = svg_texts(svg)
    for mode in names_of(team):
        assert any(re.search(rf"\b{mode}\b", t) for t in texts), mode
    assert render(g, "svg") == svg  # deterministic


def test_failing_dot_falls_back(monkeypatch):
    # a "dot" that rejects its arguments: the Python interpreter (exits 2 on -Tsvg)
    monkeypatch.setattr(shutil, "which", lambda *_a, **_k: sys.executable)
    svg = render(diagram_graph(ht.load(EXAMPLES / "automata" / "relay.yaml")), "svg")
    assert "Ready" in " ".join(svg_texts(svg))


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz dot is not installed")
def test_images_through_graphviz(nested):
    g = diagram_graph(nested)
    assert image.via_dot(g, "svg") is not None  # Graphviz did the drawing, no fallback
    texts = svg_texts(render(g, "svg"))
    assert all(any(re.search(rf"\b{m}\b", t) for t in texts) for m in names_of(nested))
    png = render(g, "png")
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    assert 400 <= mpimg.imread(io.BytesIO(png)).shape[1] <= 6000


def test_one_agent_and_elided_details():
    """--agent keeps one robot's modes and the messages among the kept agents only; long
    inputs (the XR4000's sidestep, 97 characters) are cut to 44 with "…" unless details."""
    from hybridteam.export.diagram import ELIDE, diagram_graph

    team = ht.load(EXAMPLES / "transport" / "experiment2.yaml")
    lab = diagram_graph(team, ["labmate"])
    assert {d.get("agent") or n for n, d in lab.nodes(data=True)} == {"labmate"}
    owner = {n: d.get("agent") or n for n, d in lab.nodes(data=True)}
    assert all(owner[u] == owner[v] == "labmate" for u, v in lab.edges())
    whole = diagram_graph(team)
    assert any(d["kind"] == "message" for _u, _v, d in whole.edges(data=True))
    side = next(n for n, d in whole.nodes(data=True) if d.get("path", "").endswith("Sidestep"))
    cut = whole.nodes[side]["dynamics"]
    full = diagram_graph(team, details=True).nodes[side]["dynamics"]
    assert len(full) > ELIDE and len(cut) == ELIDE and cut.endswith("…")
    assert full.startswith(cut[:-1].rstrip())
    with pytest.raises(ValueError, match="no agent 'lab' in team 'experiment2'"):
        diagram_graph(team, ["lab"])


@pytest.mark.parametrize("name", ["experiment1", "experiment2", "experiment3"])
def test_built_in_full_diagram_has_no_overlapping_text(name):
    """The full diagram (every protocol state, transition and message) of each transport
    experiment, drawn by the built-in layout: no two texts — mode names, their inputs,
    composite titles, edge labels, footnote markers — overlap (matplotlib's extents)."""
    from hybridteam.export.image import diagram_figure

    graph = diagram_graph(ht.load(EXAMPLES / "transport" / f"{name}.yaml"))
    fig = diagram_figure(graph, dpi=72.0)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [t for t in fig.axes[0].texts if t.get_text().strip()]
    boxes = [t.get_window_extent(renderer) for t in texts]
    clash = [
        (texts[i].get_text()[:30], texts[j].get_text()[:30])
        for i in range(len(boxes))
        for j in range(i + 1, len(boxes))
        if boxes[i].overlaps(boxes[j])
    ]
    assert clash == []
    assert any(t.get_gid() == "edge-label" for t in texts)


def test_many_message_links_become_labelled_stubs_at_their_senders():
    """Experiment 2's full diagram has dozens of message links between the robots' panels:
    each sending mode gets one short arrow per message, labelled with its receivers
    (``ready → xr4000``), instead of arcs across every box; a team with a few messages
    (the relay) keeps its arcs from sender to receiver."""
    from hybridteam.export import image
    from hybridteam.export.layout import Layout

    graph = diagram_graph(ht.load(EXAMPLES / "transport" / "experiment2.yaml"))
    messages = edges_of(graph, "message")
    assert len(messages) > image.STUBS_AFTER
    edges, notes = image._plan(Layout(graph), graph)
    stubs = [e for e in edges if e.message]
    groups = {(u, d["message"]) for u, _v, d in messages}
    assert len(stubs) == len(groups)
    assert all(abs(e.pb[0] - e.pa[0]) == pytest.approx(18.0) and e.pb[1] == e.pa[1] for e in stubs)
    texts = [" ".join(e.lines) for e in stubs] + notes
    assert any("ready → xr4000" in t for t in texts)
    relay = diagram_graph(ht.load(EXAMPLES / "automata" / "relay.yaml"))
    arcs = [e for e in image._plan(Layout(relay), relay)[0] if e.message]
    assert len(arcs) == len(edges_of(relay, "message")) <= image.STUBS_AFTER


def _drawn_points(edge, n: int = 240) -> np.ndarray:
    """Points along an edge as drawn: its arc, or its routed polyline."""
    from hybridteam.export.route import along, bezier

    ts = tuple(np.linspace(0.0, 1.0, n))
    if edge.path is not None:
        return np.array([p for p, _d in along(edge.path, ts)])
    return np.array([bezier(edge.pa, edge.pb, edge.rad, t) for t in ts])


@pytest.mark.parametrize(
    "path",
    [
        "transport/experiment1.yaml",
        "transport/experiment2.yaml",
        "transport/experiment3.yaml",
        "protocols/handover.yaml",
    ],
)
def test_built_in_full_diagram_has_no_edge_through_a_mode(path):
    """No edge of the built-in full diagram passes through a mode box other than its two
    ends, their containers and what they hold, nor leaves the composite holding both ends
    (each edge sampled at 240 points, boxes shrunk or grown by 1 pt); the edges that no
    arc could keep so are routed."""
    from hybridteam.export import image
    from hybridteam.export.layout import Layout
    from hybridteam.export.route import container, inside, unrelated

    graph = diagram_graph(ht.load(EXAMPLES / path))
    layout = Layout(graph)
    edges, _notes = image._plan(layout, graph)
    messages = edges_of(graph, "message")
    drawn = layout.transitions + ([] if len(messages) > image.STUBS_AFTER else messages)
    through, out = [], []
    for (u, v, _d), edge in zip(drawn, edges, strict=False):
        if edge.loop:
            continue
        boxes = [(b.x + 1, b.y + 1, b.x + b.w - 1, b.y + b.h - 1) for b in unrelated(layout, u, v)]
        points = _drawn_points(edge)
        if inside(points, boxes).any():
            through.append((u, v))
        box = container(layout, u, v)
        if box is not None and not inside(points, [box], 1.0).all():
            out.append((u, v))  # it leaves the composite that holds both its ends
    assert through == [] and out == []
    assert any(e.path is not None for e in edges)  # some needed a route


def test_a_route_goes_around_a_box_in_its_way():
    from hybridteam.export.route import MARGIN, inside, route

    box = (40.0, 0.0, 60.0, 80.0)
    path = route((0.0, 40.0), (100.0, 40.0), [box], (0.0, -20.0, 100.0, 120.0))
    assert path is not None and path[0] == (0.0, 40.0) and path[-1] == (100.0, 40.0)
    seg = np.linspace(0, 1, 50)[:, None]
    points = np.concatenate(
        [np.asarray(a) + seg * (np.asarray(b) - np.asarray(a)) for a, b in itertools.pairwise(path)]
    )
    assert not inside(points, [box], MARGIN - 1.0).any()
    assert len(path) <= 8  # pulled straight: two bends a corner, not a 5 pt staircase
    assert (
        route((0.0, 40.0), (100.0, 40.0), [(30.0, -30.0, 70.0, 130.0)], (0.0, -20.0, 100.0, 120.0))
        is None
    )  # a wall across the bounds

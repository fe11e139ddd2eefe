"""Text renderers of the diagram graph, registered by name: DOT, Mermaid and PlantUML.

Each renderer is a function ``graph -> str | bytes`` in :data:`RENDERERS`; :func:`render`
looks one up by name so the CLI (and users) can add formats without touching this module.
Output is built in the graph's fixed order, so the same model always gives the same text and
a changed model gives a readable diff. Images (``svg``, ``png``) live in :mod:`.image` and
are imported lazily: asking for Mermaid text should not load matplotlib.

Mermaid and PlantUML cannot express every statechart detail; where they cannot, the text
stays valid and says less (history becomes ``(H)`` in the state's name, messages become
plain or dashed arrows between agents).
"""

from __future__ import annotations

import re
from collections.abc import Callable

import networkx as nx

from hybridteam.errors import did_you_mean, printable
from hybridteam.export.diagram import (
    agents,
    ancestors,
    children,
    edges_of,
    initial_child,
    is_composite,
    parent,
)
from hybridteam.export.style import FONT, text_color

Renderer = Callable[[nx.MultiDiGraph], str | bytes]
MESSAGE_COLOR = "#555555"
# words Mermaid's or PlantUML's grammar reads as keywords where a state id is expected
KEYWORDS = frozenset(
    {
        "as",
        "class",
        "classdef",
        "default",
        "direction",
        "end",
        "hide",
        "left",
        "note",
        "of",
        "right",
        "scale",
        "skinparam",
        "state",
        "title",
    }
)


def state_title(graph: nx.MultiDiGraph, node: str) -> str:
    """A composite's caption: agents name their plant, history shows as ``(H)``/``(H*)``."""
    data = graph.nodes[node]
    mark = {"shallow": " (H)", "deep": " (H*)"}.get(data.get("history", "none"), "")
    if data["kind"] == "agent":
        return f"{data['label']} ({data['plant']}){mark}"
    return data["name"] + mark


# ------------------------------------------------------------------ DOT


_LINE_BREAKS = re.compile("[\r\n\v\f\x1c\x1d\x1e\x85\u2028\u2029]")


def one_line(text: str) -> str:
    """``text`` with every line break (all that a parser may end a line at) a space: what a
    model names cannot start a line of its own in a text export (no injected statements)."""
    return _LINE_BREAKS.sub(" ", text)


def mermaid_text(text: str) -> str:
    """Text a model or a trace names, inert in any Mermaid diagram: on one line, no ``;``
    (ends a statement) or ``#`` (opens an entity, ``#lt;``), no ``%%`` (a comment, or with
    ``{`` an ``%%{init: …}%%`` directive that reconfigures the renderer), no ``<`` that
    could open an HTML tag (Mermaid draws labels as HTML) and no control character (the
    text may be printed on a terminal)."""
    text = printable(one_line(text)).replace(";", "\uff1b").replace("#", "\uff03")
    text = re.sub(r"%+", "%", text)
    return re.sub(r"<(?=[A-Za-z/!?])", "< ", text)


def plantuml_text(text: str) -> str:
    """Text a model or a trace names, inert in any PlantUML diagram: on one line (no
    ``!include`` or ``@enduml`` of its own), no ``<`` that opens a Creole tag (``<img:…>``
    reads a file or a URL), no ``[[`` link (a ``javascript:`` URL in the SVG) and no
    control character (the text may be printed on a terminal)."""
    text = re.sub(r"<(?=[A-Za-z/!?&$])", "< ", printable(one_line(text)))
    return text.replace("[[", "[ [")


def markdown_text(text: str) -> str:
    """Text read back from a file, inert in Markdown (a study's ``report.md``): on one line,
    HTML's ``&``, ``<`` and ``>`` as entities (renderers pass raw HTML through, a
    ``<script>`` included), ``[``, ``]`` and backticks escaped (no link, image or code span
    of its own), ``|`` escaped (a table cell's end) and no control character."""
    text = re.sub(r"([\\`\[\]|])", r"\\\1", printable(one_line(text)))
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def dot_quote(text: str) -> str:
    """A Graphviz double-quoted string: any id or label, newlines as centred line breaks."""
    text = text.replace("\\", "\\\\").replace('"', '\\"').replace("\r\n", "\n")
    return '"' + _LINE_BREAKS.sub(r"\\n", text) + '"'


def _attrs(**attrs: str | float | bool) -> str:
    parts = []
    for key, value in attrs.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        parts.append(f"{key}={dot_quote(text)}")
    return "[" + ", ".join(parts) + "]"


def pseudo_id(node: str) -> str:
    """DOT node of a composite's initial pseudostate (also the anchor of its cluster)."""
    return f"{node}/[*]"


def anchor_id(graph: nx.MultiDiGraph, node: str) -> str:
    """The DOT node an edge to or from ``node`` attaches to: itself, or its cluster's anchor."""
    if not is_composite(graph, node):
        return node
    return pseudo_id(node) if initial_child(graph, node) else f"{node}/[anchor]"


def _node(ident: str, pad: str, **attrs: str | float | bool) -> str:
    return f"{pad}{dot_quote(ident)} {_attrs(**attrs)};"


def _dot_block(graph: nx.MultiDiGraph, node: str, depth: int, out: list[str]) -> None:
    pad = "  " * depth
    data = graph.nodes[node]
    if not is_composite(graph, node):
        lines = [data["name"], data["dynamics"]]
        if data["invariant"]:
            lines.append(f"inv: {data['invariant']}")
        lines += data["behaviour"]
        color = data["color"]
        extra = {"peripheries": 2} if data["final"] else {}
        style = "rounded,filled" + (",dashed" if data["region"] else "")
        out.append(
            _node(
                node,
                pad,
                label="\n".join(x for x in lines if x),
                style=style,
                fillcolor=color,
                fontcolor=text_color(color),
                **extra,
            )
        )
        return
    style = "rounded,dashed" if data.get("region") else "rounded"
    out.append(f"{pad}subgraph {dot_quote('cluster_' + node)} {{")
    title = "\n".join([state_title(graph, node), *data.get("behaviour", ())])
    out.append(f"{pad}  graph {_attrs(label=title, style=style, color='#444444')};")
    if initial_child(graph, node):
        out.append(
            _node(
                pseudo_id(node),
                pad + "  ",
                shape="point",
                width=0.12,
                label="",
                style="filled",
                fillcolor="black",
            )
        )
    else:
        out.append(
            _node(
                anchor_id(graph, node),
                pad + "  ",
                shape="point",
                width=0.01,
                label="",
                style="invis",
            )
        )
    for child in children(graph, node):
        _dot_block(graph, child, depth + 1, out)
    out.append(f"{pad}}}")


def _dot_edge(
    graph: nx.MultiDiGraph, u: str, v: str, tail: str | None = None, **attrs: str | float | bool
) -> str:
    """An edge between two modes; clusters are reached through anchors and ltail/lhead.

    ``tail`` overrides the tail node (an initial pseudostate), which is never clipped.
    """
    if u != v:
        if tail is None and is_composite(graph, u) and u not in ancestors(graph, v):
            attrs["ltail"] = "cluster_" + u
        if is_composite(graph, v) and v not in ancestors(graph, u):
            attrs["lhead"] = "cluster_" + v
    start = dot_quote(tail or anchor_id(graph, u))
    tail_attrs = f" {_attrs(**attrs)}" if attrs else ""
    return f"  {start} -> {dot_quote(anchor_id(graph, v))}{tail_attrs};"


def to_dot(graph: nx.MultiDiGraph) -> str:
    """Graphviz text: one cluster per agent and per composite mode, leaves as coloured boxes."""
    name = graph.graph.get("name", "team")
    out = [
        f"digraph {dot_quote(name)} {{",
        "  graph "
        + _attrs(compound=True, fontname=FONT, label=name, labelloc="t", newrank=True, nodesep=0.4)
        + ";",
        f"  node {_attrs(fontname=FONT, fontsize=10, shape='box')};",
        f"  edge {_attrs(fontname=FONT, fontsize=9)};",
    ]
    for agent in agents(graph):
        _dot_block(graph, agent, 1, out)
    for node in graph.nodes:
        first = initial_child(graph, node) if is_composite(graph, node) else None
        if first:
            out.append(_dot_edge(graph, node, first, tail=pseudo_id(node), **{"class": "initial"}))
    for u, v, d in edges_of(graph, "transition"):
        out.append(_dot_edge(graph, u, v, label=d["label"], **{"class": "transition"}))
    for u, v, d in edges_of(graph, "message"):
        # constraint=false would keep messages from bending the ranks, but it trips
        # Graphviz's ranking with nested clusters ("trouble in init_rank"); newrank copes
        out.append(
            _dot_edge(
                graph,
                u,
                v,
                label=d["message"],
                style="dashed",
                color=MESSAGE_COLOR,
                fontcolor=MESSAGE_COLOR,
                **{"class": "message"},
            )
        )
    out.append("}")
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------ Mermaid and PlantUML


def state_ids(graph: nx.MultiDiGraph) -> dict[str, str]:
    """A unique, plain identifier per agent and mode: ``runner``, ``runner__Dock__Approach``.

    Both languages take ``[A-Za-z0-9_]`` ids safely (Mermaid stops an id at ``-`` or ``:``,
    PlantUML treats ``.`` as a namespace separator), so dotted paths become ``__``.
    """
    out: dict[str, str] = {}
    used: set[str] = set()
    for node, data in graph.nodes(data=True):
        raw = node if data["kind"] == "agent" else f"{data['agent']}__{data['path']}"
        base = re.sub(r"\W", "_", raw.replace(".", "__")) or "state"
        base += "_" if base.lower() in KEYWORDS else ""
        ident, k = base, 2
        while ident in used:
            ident, k = f"{base}_{k}", k + 1
        used.add(ident)
        out[node] = ident
    return out


def lca(graph: nx.MultiDiGraph, u: str, v: str) -> str:
    """The composite that owns a transition: the innermost container of both ends (a mode
    that contains the other end is left and re-entered, so it does not count)."""
    up_v = ancestors(graph, v)
    for node in ancestors(graph, u)[1:]:
        if node in up_v[1:]:
            return node
    return ancestors(graph, u)[-1]


class _StateText:
    """Shared walk of the hierarchy for the two PlantUML-like state languages.

    Every state is declared inside its parent's block; a transition is written inside the
    block of its owner (:func:`lca`) when ``nested_links`` is set, else inside its parent's
    block if both ends are siblings and at the top level otherwise. Mermaid needs the latter:
    older versions move a state into the block where a link mentions it.
    """

    divider = "--"
    message_arrow = "-->"
    nested_links = False

    def __init__(self, graph: nx.MultiDiGraph) -> None:
        self.graph = graph
        self.ids = state_ids(graph)
        self.local: dict[str | None, list[tuple]] = {}
        for u, v, d in edges_of(graph, "transition"):
            up = parent(graph, u)
            owner = (
                lca(graph, u, v)
                if self.nested_links
                else (up if up is not None and up == parent(graph, v) else None)
            )
            self.local.setdefault(owner, []).append((u, v, d))
        self.lines: list[str] = []

    def label(self, text: str) -> str:
        return one_line(text)

    def arrow(self, u: str, v: str, text: str, arrow: str = "-->") -> str:
        a = u if u == "[*]" else self.ids[u]
        b = v if v == "[*]" else self.ids[v]
        text = self.label(text)
        return f"{a} {arrow} {b} : {text}" if text.strip() else f"{a} {arrow} {b}"

    def endpoint(self, node: str, block: str | None) -> str:
        return node

    def link(self, u: str, v: str, text: str, block: str | None, arrow: str = "-->") -> str:
        """A link written in ``block``; an end the language cannot reach from there is drawn
        at a container instead, and the label names the real mode."""
        a, b = self.endpoint(u, block), self.endpoint(v, block)
        if a != u:
            text += f" (from {self.graph.nodes[u]['path']})"
        if b != v:
            text += f" (to {self.graph.nodes[v]['path']})"
        return self.arrow(a, b, text, arrow)

    def leaf(self, node: str, pad: str) -> None:
        data = self.graph.nodes[node]
        decl = f'{pad}state "{self.name(data["name"])}" as {self.ids[node]}'
        self.lines.append(decl + self.fill(data["color"]))
        for text in (
            data["dynamics"],
            data["invariant"] and f"inv {data['invariant']}",
            *data["behaviour"],
        ):
            if text:
                self.lines.append(f"{pad}{self.ids[node]} : {self.label(text)}")

    def fill(self, color: str) -> str:
        return ""

    def name(self, text: str) -> str:
        return text.replace('"', "'")

    def block(self, node: str, depth: int) -> None:
        pad = "    " * depth
        graph = self.graph
        if not is_composite(graph, node):
            self.leaf(node, pad)
            return
        title = self.name(state_title(graph, node))
        self.lines.append(f'{pad}state "{title}" as {self.ids[node]} {{')
        inner = pad + "    "
        kids = children(graph, node)
        if graph.nodes[node].get("mode_kind") == "and":
            for k, child in enumerate(kids):
                if k:
                    self.lines.append(inner + self.divider)
                self.block(child, depth + 1)  # no links here: they would cross regions
                if graph.nodes[child]["final"]:
                    self.lines.append(inner + self.arrow(child, "[*]", ""))
        else:
            first = initial_child(graph, node)
            if first:
                self.lines.append(inner + self.arrow("[*]", first, ""))
            for child in kids:
                self.block(child, depth + 1)
            for u, v, d in self.local.get(node, []):
                self.lines.append(inner + self.link(u, v, d["label"], node))
            for child in kids:
                if graph.nodes[child]["final"]:
                    self.lines.append(inner + self.arrow(child, "[*]", ""))
        self.lines.append(pad + "}")
        for text in graph.nodes[node].get("behaviour", ()):  # a composite's entry/exit
            self.lines.append(f"{pad}{self.ids[node]} : {self.label(text)}")

    def body(self) -> None:
        for agent in agents(self.graph):
            self.block(agent, 1)
        rest = self.local.get(None, [])
        if rest:
            self.lines.append(self.comment("transitions across levels"))
        for u, v, d in rest:
            self.lines.append("    " + self.link(u, v, d["label"], None))
        messages = edges_of(self.graph, "message")
        if messages:
            self.lines.append(self.comment("messages between agents"))
        for u, v, d in messages:
            self.lines.append("    " + self.message(u, v, d))

    def comment(self, text: str) -> str:
        return f"    %% {text}"

    def message(self, u: str, v: str, data: dict) -> str:
        return self.link(u, v, data["message"], None, self.message_arrow)


class _Mermaid(_StateText):
    """Mermaid ``stateDiagram-v2``.

    Its grammar ends a label at ``:``, ``;`` or a newline and reads ``#`` as a comment, so
    those become look-alike characters; a ``<`` that could open an HTML tag gets a space.
    """

    def label(self, text: str) -> str:
        return mermaid_text(text).replace(":", "\u2236").replace('"', "'")

    def name(self, text: str) -> str:
        return self.label(text)

    def message(self, u: str, v: str, data: dict) -> str:
        return self.arrow(u, v, f"{data['message']} (message)")

    def render(self) -> str:
        self.lines = [
            "stateDiagram-v2",
            f"    %% team {self.label(self.graph.graph.get('name', ''))}",
        ]
        self.body()
        colors: dict[str, list[str]] = {}
        for node, data in self.graph.nodes(data=True):
            if data["kind"] == "mode" and data["mode_kind"] == "leaf":
                colors.setdefault(data["color"], []).append(self.ids[node])
        for k, (color, ids) in enumerate(colors.items()):
            self.lines.append(f"    classDef mode{k} fill:{color},color:{text_color(color)}")
            self.lines.append(f"    class {','.join(ids)} mode{k}")
        return "\n".join(self.lines) + "\n"


class _PlantUML(_StateText):
    """PlantUML state diagram: ``||`` separates regions, messages are dashed arrows.

    PlantUML (up to at least 1.2020) refuses a link from outside a concurrent region to any
    state inside it, so such an end is drawn at the parallel mode, the label naming the mode
    really meant; links are written in their owner's block to need that as little as possible.
    """

    divider = "||"
    message_arrow = "-[dashed]->"
    nested_links = True

    def fill(self, color: str) -> str:
        return f" {color}"

    def label(self, text: str) -> str:
        return plantuml_text(text)

    def name(self, text: str) -> str:
        return plantuml_text(text).replace('"', "'")

    def comment(self, text: str) -> str:
        return f"    ' {text}"

    def endpoint(self, node: str, block: str | None) -> str:
        """The outermost parallel mode between ``block`` and ``node`` holding ``node``."""
        chain = ancestors(self.graph, node)
        if block is not None:
            chain = chain[: chain.index(block)]
        for up in reversed(chain[1:]):
            if self.graph.nodes[up].get("mode_kind") == "and":
                return up
        return node

    def render(self) -> str:
        self.lines = [
            "@startuml",
            "hide empty description",
            f"skinparam defaultFontName {FONT}",
            f"title {self.label(self.graph.graph.get('name', ''))}",
        ]
        self.body()
        self.lines.append("@enduml")
        return "\n".join(self.lines) + "\n"


def to_mermaid(graph: nx.MultiDiGraph) -> str:
    """Mermaid ``stateDiagram-v2`` text: composites nest, regions split by ``--``."""
    return _Mermaid(graph).render()


def to_plantuml(graph: nx.MultiDiGraph) -> str:
    """PlantUML ``@startuml`` state diagram text."""
    return _PlantUML(graph).render()


# ------------------------------------------------------------------ registry


def _image(fmt: str) -> Renderer:
    def draw(graph: nx.MultiDiGraph) -> str | bytes:
        from hybridteam.export import image  # matplotlib loads only when an image is asked for

        renderers: dict[str, Renderer] = {
            "svg": image.render_svg,
            "png": image.render_png,
            "pdf": image.render_pdf,
        }
        return renderers[fmt](graph)

    return draw


RENDERERS: dict[str, Renderer] = {
    "dot": to_dot,
    "mermaid": to_mermaid,
    "plantuml": to_plantuml,
    "svg": _image("svg"),
    "png": _image("png"),
    "pdf": _image("pdf"),
}


def register(name: str, fn: Renderer) -> None:
    """Make ``fn`` available as ``render(graph, name)`` (replacing any renderer of that name)."""
    if not name or not isinstance(name, str):
        raise ValueError("a renderer needs a non-empty name")
    RENDERERS[name] = fn


def render(graph: nx.MultiDiGraph, fmt: str) -> str | bytes:
    """Render the diagram graph in ``fmt``; text formats give ``str``, ``png`` gives bytes."""
    fn = RENDERERS.get(fmt)
    if fn is None:
        known = ", ".join(sorted(RENDERERS))
        hint = did_you_mean(fmt, RENDERERS)
        raise ValueError(
            f"unknown diagram format {fmt!r} (known: {known})" + (f"; {hint}" if hint else "")
        )
    return fn(graph)

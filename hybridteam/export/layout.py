"""The built-in layout of a state diagram: sizes and positions of every mode box.

Composites are labelled boxes holding their children, children stacked in layers found by a
breadth-first walk from the initial mode (so the default path reads top to bottom),
parallel regions side by side, agents in panels side by side, in rows no wider than a page.
Units are points, y points down. Deterministic: the same graph gives the same layout.
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass, field

import networkx as nx

from hybridteam.export.diagram import (
    agents,
    ancestors,
    children,
    edges_of,
    initial_child,
    is_composite,
)
from hybridteam.export.render import state_title

NAME_PT, SMALL_PT = 8.0, 6.5  # font sizes; layout units are points
GAP_X, GAP_Y, PAD, TITLE = 26.0, 34.0, 8.0, 15.0
ROW_MAX = 4  # boxes per row before a layer wraps
PANEL_GAP, WRAP = 80.0, 34
#: agents' panels go side by side up to this width (points), then wrap into a new row: three
#: robots side by side made a diagram 1,500 pt wide, whose text a page (the report's column
#: is 1,150 px, about 860 pt) shrank past reading
ROW_WIDTH = 900.0


def _text_width(lines: list[str], size: float) -> float:
    """Rough width of text in points (DejaVu Sans averages ~0.6 em per character)."""
    return max((len(s) for s in lines), default=0) * size * 0.6


def _wrap(text: str, width: int = WRAP) -> list[str]:
    """Lines of at most ``width`` characters; a rate such as ``@10 Hz`` stays in one piece."""
    text = re.sub(r"@(\S+) Hz", "@\\1\u00a0Hz", text)
    return textwrap.wrap(text, width, break_on_hyphens=False) if text else []


def behaviour_caption(graph: nx.MultiDiGraph, node: str) -> str:
    """A composite's entry and exit actions, on one line after its title in the title bar
    (its children fill the box below)."""
    return "   ".join(graph.nodes[node].get("behaviour", ()))


CAPTION_GAP = 8.0  # between a composite's title and its entry/exit actions (points)


@dataclass
class Box:
    """A mode's rectangle (points, y downwards); ``rows`` hold a composite's children."""

    node: str
    w: float = 0.0
    h: float = 0.0
    x: float = 0.0
    y: float = 0.0
    loop: float = 0.0  # room kept on the right for self-loops and their labels
    rows: list[list[Box]] = field(default_factory=list)
    gaps: list[float] = field(default_factory=list)  # below each row: room for edge labels
    row_gaps: list[float] = field(default_factory=list)  # between the boxes of each row
    lines: list[str] = field(default_factory=list)
    title_w: float = 0.0  # a composite's title bar: the width its name needs


class Layout:
    """Sizes and positions of every mode box of a team, agents side by side in rows."""

    def __init__(self, graph: nx.MultiDiGraph) -> None:
        self.graph = graph
        self.boxes: dict[str, Box] = {}
        self.transitions = edges_of(graph, "transition")
        self.loops: dict[str, list[str]] = {}
        for u, v, d in self.transitions:
            if u == v:
                self.loops.setdefault(u, []).append(d["label"])
        self.up = {n: ancestors(graph, n) for n in graph.nodes}
        self.panels = [self.measure(a) for a in agents(graph)]
        x, y, row_h, right = PAD, PAD + TITLE, 0.0, PAD
        for panel in self.panels:  # side by side, a new row where a page would end
            w = panel.w + panel.loop
            if x > PAD and x + w > ROW_WIDTH:
                x, y, row_h = PAD, y + row_h + PANEL_GAP, 0.0
            self.place(panel, x, y)
            right, row_h = max(right, x + w), max(row_h, panel.h)
            x += w + PANEL_GAP
        # rows: a lane beside the widest panel, where a message from the first row to the
        # third passes the second (routes stay inside the picture)
        lane = PANEL_GAP / 2 if y > PAD + TITLE else 0.0
        self.width = max(right + PAD + lane, 240.0)
        self.height = y + row_h + PAD

    # -------------------------------------------------------------- sizes
    def measure(self, node: str) -> Box:
        data = self.graph.nodes[node]
        box = Box(node)
        self.boxes[node] = box
        if node in self.loops:
            labels = [line for text in self.loops[node] for line in _wrap(text, 24)]
            box.loop = 26.0 + _text_width(labels, SMALL_PT)
        if not is_composite(self.graph, node):
            box.lines = (
                _wrap(data["dynamics"])
                + _wrap(f"inv: {data['invariant']}" if data["invariant"] else "")
                + [line for text in data["behaviour"] for line in _wrap(text)]
            )
            box.w = (
                max(
                    _text_width([data["name"]], NAME_PT) * 1.1,
                    _text_width(box.lines, SMALL_PT),
                    44.0,
                )
                + 2 * PAD
            )
            box.h = NAME_PT * 1.5 + len(box.lines) * SMALL_PT * 1.3 + PAD
            return box
        box.title_w = _text_width([state_title(self.graph, node)], NAME_PT) + 2 * PAD
        if behaviour_caption(self.graph, node):
            box.title_w += (
                _text_width([behaviour_caption(self.graph, node)], SMALL_PT) + CAPTION_GAP
            )
        kids = [self.measure(c) for c in children(self.graph, node)]
        if not kids:  # an agent without modes (possible when built in Python): an empty box
            box.w = box.title_w
            box.h = TITLE + 2 * PAD
            return box
        if data.get("mode_kind") == "and":
            box.rows = [kids]  # regions side by side
            inner_w = sum(k.w + k.loop for k in kids) + PAD * (len(kids) - 1)
            inner_h = max(k.h for k in kids)
        else:
            box.rows = self.layers(node, kids)
            box.gaps, box.row_gaps = self.label_room(node, box.rows)
            inner_w = max(
                sum(k.w + k.loop for k in row) + gap * (len(row) - 1)
                for row, gap in zip(box.rows, box.row_gaps, strict=True)
            )
            labels = [line for text in self.sibling_labels(node) for line in _wrap(text, 24)]
            widest = max(k.w for k in kids)
            inner_w = max(inner_w, widest + 2 * (_text_width(labels, SMALL_PT) + 6))
            inner_h = sum(max(k.h for k in row) for row in box.rows) + sum(box.gaps[:-1])
        box.w = max(inner_w + 2 * PAD + 14.0, box.title_w)  # 14: room for the initial dot
        box.h = inner_h + TITLE + 2 * PAD
        return box

    def label_room(self, node: str, rows: list[list[Box]]) -> tuple[list[float], list[float]]:
        """Room for the labels of edges between children of ``node``: below each row, the
        tallest label of an edge to the next row (labels sit half-way along an edge); within
        a row, the widest label of an edge between two of its boxes."""
        row_of = {k.node: i for i, row in enumerate(rows) for k in row}
        tall = [0] * len(rows)
        wide = [0.0] * len(rows)
        for u, v, d in self.transitions:
            a = next((n for n in self.up[u] if n in row_of), None)
            b = next((n for n in self.up[v] if n in row_of), None)
            if a is None or b is None or a == b:
                continue
            lines = _wrap(d["label"], 24)
            ra, rb = sorted((row_of[a], row_of[b]))
            if ra == rb:
                wide[ra] = max(wide[ra], _text_width(lines, SMALL_PT) + 12.0)
            elif rb == ra + 1:
                tall[ra] = max(tall[ra], len(lines))
        gaps = [max(GAP_Y, n * SMALL_PT * 1.25 + 16.0) for n in tall]
        return gaps, [max(GAP_X, w) for w in wide]

    def sibling_labels(self, node: str) -> list[str]:
        """Labels of transitions between different children of ``node`` (drawn inside it)."""
        found = []
        for u, v, d in self.transitions:
            a, b = self.up[u], self.up[v]
            if node in a[1:] and node in b[1:] and a[a.index(node) - 1] != b[b.index(node) - 1]:
                found.append(d["label"])
        return found

    def layers(self, node: str, kids: list[Box]) -> list[list[Box]]:
        """Children in breadth-first layers from the initial child, following transitions
        between the subtrees of siblings; unreached children start new layers in order."""
        index = {k.node: i for i, k in enumerate(kids)}
        succ: dict[str, list[str]] = {k.node: [] for k in kids}
        for u, v, _ in self.transitions:
            a = next((n for n in self.up[u] if n in index), None)
            b = next((n for n in self.up[v] if n in index), None)
            if a and b and a != b and b not in succ[a]:
                succ[a].append(b)
        layer: dict[str, int] = {}
        first = initial_child(self.graph, node)
        seeds = ([first] if first else []) + [k.node for k in kids]
        for seed in seeds:
            if seed in layer:
                continue
            layer[seed] = max(layer.values(), default=-1) + 1
            queue = [seed]
            while queue:
                cur = queue.pop(0)
                for nxt in succ[cur]:
                    if nxt not in layer:
                        layer[nxt] = layer[cur] + 1
                        queue.append(nxt)
        rows: list[list[Box]] = []
        for level in sorted(set(layer.values())):
            members = [k for k in kids if layer[k.node] == level]
            rows += [members[i : i + ROW_MAX] for i in range(0, len(members), ROW_MAX)]
        return rows

    # -------------------------------------------------------------- positions
    def place(self, box: Box, x: float, y: float) -> None:
        box.x, box.y = x, y
        if not box.rows:
            return
        and_mode = self.graph.nodes[box.node].get("mode_kind") == "and"
        cy = y + TITLE + PAD
        for i, row in enumerate(box.rows):
            gap = PAD if and_mode else box.row_gaps[i]
            row_w = sum(k.w + k.loop for k in row) + gap * (len(row) - 1)
            cx = x + 14.0 + PAD + (box.w - 14.0 - 2 * PAD - row_w) / 2
            for k in row:
                self.place(k, cx, cy + (0 if and_mode else (max(r.h for r in row) - k.h) / 2))
                cx += k.w + k.loop + gap
            cy += max(k.h for k in row) + (GAP_Y if and_mode else box.gaps[i])

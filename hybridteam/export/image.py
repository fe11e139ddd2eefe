"""State diagrams as SVG or PNG, with or without Graphviz.

When Graphviz's ``dot`` is on the PATH it lays out the DOT text of :mod:`.render` (the best
result). Nothing in hybridteam may require it, so without it (or if it fails) a small
built-in layout draws the same diagram with matplotlib: one panel per agent side by side,
composites as labelled boxes holding their children, children stacked in layers found by a
breadth-first walk from the initial mode (so the default path reads top to bottom),
parallel regions side by side with dashed borders, messages as dashed arrows between
panels. It is deterministic: same graph, same picture.
"""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import textwrap
from dataclasses import dataclass, field

import matplotlib as mpl
import networkx as nx
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch, FancyBboxPatch

from hybridteam.export.diagram import (
    agents,
    ancestors,
    children,
    edges_of,
    initial_child,
    is_composite,
)
from hybridteam.export.render import state_title, to_dot
from hybridteam.export.style import FONT, text_color

NAME_PT, SMALL_PT = 8.0, 6.5  # font sizes; layout units are points
GAP_X, GAP_Y, PAD, TITLE = 26.0, 34.0, 8.0, 15.0
ROW_MAX = 4  # boxes per row before a layer wraps
PANEL_GAP, WRAP = 80.0, 34
EDGE, MESSAGE = "#333333", "#777777"
DOT_TIMEOUT = 30.0


def _text_width(lines: list[str], size: float) -> float:
    """Rough width of text in points (DejaVu Sans averages ~0.6 em per character)."""
    return max((len(s) for s in lines), default=0) * size * 0.6


def _wrap(text: str, width: int = WRAP) -> list[str]:
    """Lines of at most ``width`` characters; a rate such as ``@10 Hz`` stays in one piece."""
    text = re.sub(r"@(\S+) Hz", "@\\1\u00a0Hz", text)
    return textwrap.wrap(text, width, break_on_hyphens=False) if text else []


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


class Layout:
    """Sizes and positions of every mode box of a team, agents side by side."""

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
        x = PAD
        for panel in self.panels:
            self.place(panel, x, PAD + TITLE)
            x += panel.w + panel.loop + PANEL_GAP
        self.width = max(x - PANEL_GAP + PAD, 240.0)
        self.height = max(p.h for p in self.panels) + 2 * PAD + TITLE

    # -------------------------------------------------------------- sizes
    def measure(self, node: str) -> Box:
        data = self.graph.nodes[node]
        box = Box(node)
        self.boxes[node] = box
        if node in self.loops:
            labels = [line for text in self.loops[node] for line in _wrap(text, 24)]
            box.loop = 26.0 + _text_width(labels, SMALL_PT)
        if not is_composite(self.graph, node):
            box.lines = _wrap(data["dynamics"]) + _wrap(
                f"inv: {data['invariant']}" if data["invariant"] else "")
            box.w = max(_text_width([data["name"]], NAME_PT) * 1.1,
                        _text_width(box.lines, SMALL_PT), 44.0) + 2 * PAD
            box.h = NAME_PT * 1.5 + len(box.lines) * SMALL_PT * 1.3 + PAD
            return box
        kids = [self.measure(c) for c in children(self.graph, node)]
        if not kids:  # an agent without modes (possible when built in Python): an empty box
            box.w = _text_width([state_title(self.graph, node)], NAME_PT) + 2 * PAD
            box.h = TITLE + 2 * PAD
            return box
        if data.get("mode_kind") == "and":
            box.rows = [kids]  # regions side by side
            inner_w = sum(k.w + k.loop for k in kids) + PAD * (len(kids) - 1)
            inner_h = max(k.h for k in kids)
        else:
            box.rows = self.layers(node, kids)
            box.gaps, box.row_gaps = self.label_room(node, box.rows)
            inner_w = max(sum(k.w + k.loop for k in row) + gap * (len(row) - 1)
                          for row, gap in zip(box.rows, box.row_gaps, strict=True))
            labels = [line for text in self.sibling_labels(node) for line in _wrap(text, 24)]
            widest = max(k.w for k in kids)
            inner_w = max(inner_w, widest + 2 * (_text_width(labels, SMALL_PT) + 6))
            inner_h = sum(max(k.h for k in row) for row in box.rows) + sum(box.gaps[:-1])
        title_w = _text_width([state_title(self.graph, node)], NAME_PT) + 2 * PAD
        box.w = max(inner_w + 2 * PAD + 14.0, title_w)  # 14: room for the initial dot
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
            rows += [members[i:i + ROW_MAX] for i in range(0, len(members), ROW_MAX)]
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


# ------------------------------------------------------------------ drawing


def _text(ax, x: float, y: float, s: str, **kw) -> None:
    ax.text(x, y, s, fontfamily=FONT, parse_math=False, **kw)


def _draw_box(ax, layout: Layout, box: Box, depth: int) -> None:
    data = layout.graph.nodes[box.node]
    dashed = bool(data.get("region"))
    style = "round,pad=0,rounding_size=7"
    if is_composite(layout.graph, box.node):
        shade = ("#FFFFFF", "#F4F4F4", "#EAEAEA", "#E0E0E0")[min(depth, 3)]
        ax.add_patch(FancyBboxPatch((box.x, box.y), box.w, box.h, boxstyle=style, fc=shade,
                                    ec="#444444", lw=1.0, ls="--" if dashed else "-"))
        _text(ax, box.x + PAD, box.y + 4, state_title(layout.graph, box.node), fontsize=NAME_PT,
              fontweight="bold", va="top", ha="left", color="#222222")
        first = initial_child(layout.graph, box.node)
        if first:
            kid = layout.boxes[first]
            cy = kid.y + min(kid.h / 2, 12.0)
            ax.add_patch(Circle((kid.x - 12, cy), 3.0, fc="black", ec="black"))
            ax.add_patch(FancyArrowPatch((kid.x - 9, cy), (kid.x, cy), arrowstyle="-|>",
                                         mutation_scale=7, lw=0.9, color="black"))
        for row in box.rows:
            for kid in row:
                _draw_box(ax, layout, kid, depth + 1)
        return
    color = data["color"]
    ink = text_color(color)
    ax.add_patch(FancyBboxPatch((box.x, box.y), box.w, box.h, boxstyle=style, fc=color,
                                ec="#222222", lw=1.0, ls="--" if dashed else "-"))
    if data["final"]:
        ax.add_patch(FancyBboxPatch((box.x + 2.5, box.y + 2.5), box.w - 5, box.h - 5,
                                    boxstyle="round,pad=0,rounding_size=5", fc="none",
                                    ec="#222222", lw=0.8))
    _text(ax, box.x + box.w / 2, box.y + PAD / 2 + 1, data["name"], fontsize=NAME_PT,
          fontweight="bold", ha="center", va="top", color=ink)
    if box.lines:
        _text(ax, box.x + box.w / 2, box.y + PAD / 2 + NAME_PT * 1.45, "\n".join(box.lines),
              fontsize=SMALL_PT, ha="center", va="top", color=ink, linespacing=1.15)


def _label(ax, x: float, y: float, text: str, color: str, **kw) -> None:
    if text:
        _text(ax, x, y, "\n".join(_wrap(text, 24)), fontsize=SMALL_PT, color=color,
              ha=kw.pop("ha", "center"), va=kw.pop("va", "center"), linespacing=1.1, zorder=5,
              bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
              **kw)


def _clip(box: Box, toward: tuple[float, float]) -> tuple[float, float]:
    """Where the segment from the box's centre to ``toward`` leaves the box."""
    cx, cy = box.x + box.w / 2, box.y + box.h / 2
    dx, dy = toward[0] - cx, toward[1] - cy
    t = min(box.w / 2 / abs(dx) if dx else float("inf"), box.h / 2 / abs(dy) if dy else
            float("inf"))
    t = min(t, 1.0)
    return cx + dx * t, cy + dy * t


def _ends(layout: Layout, u: str, v: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """Both ends of an edge on the boxes' borders; a composite that holds the other end is
    left from (or entered at) its title bar instead."""
    bu, bv = layout.boxes[u], layout.boxes[v]
    centre = {n: (b.x + b.w / 2, b.y + b.h / 2) for n, b in ((u, bu), (v, bv))}
    if u in layout.up[v]:
        centre[u] = (bu.x + bu.w / 2, bu.y + TITLE / 2)
        return centre[u], _clip(bv, centre[u])
    if v in layout.up[u]:
        centre[v] = (bv.x + bv.w / 2, bv.y + TITLE / 2)
        return _clip(bu, centre[v]), centre[v]
    return _clip(bu, centre[v]), _clip(bv, centre[u])


def _bezier(pa, pb, rad: float, t: float) -> tuple[float, float]:
    """Point at ``t`` of matplotlib's arc3 curve from ``pa`` to ``pb``: its control point is
    the chord's middle moved by rad * (-dy, dx) in these data coordinates (y points down)."""
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    cx, cy = (pa[0] + pb[0]) / 2 - rad * dy, (pa[1] + pb[1]) / 2 + rad * dx
    return ((1 - t) ** 2 * pa[0] + 2 * t * (1 - t) * cx + t * t * pb[0],
            (1 - t) ** 2 * pa[1] + 2 * t * (1 - t) * cy + t * t * pb[1])


def _bend(layout: Layout, u: str, v: str, pa, pb, base: float, message: bool) -> float:
    """The first curvature (from gentle to strong, either side) whose curve stays clear of
    boxes unrelated to the two ends: an edge skipping a layer must not cross a mode.

    The bulge is capped (messages span panels: a strong bend would leave the picture).
    """
    related = set(layout.up[u]) | set(layout.up[v])
    obstacles = [b for n, b in layout.boxes.items()
                 if n not in related and u not in layout.up[n] and v not in layout.up[n]]
    chord = max(((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2) ** 0.5, 1.0)
    cap = min(0.35, 200.0 / chord) if message else 160.0 / chord
    steps = [base] + [sign * (base + d) for d in (0.25, 0.5, 0.8, 1.1) for sign in (1, -1)]
    best, fewest = base, None
    for rad in [r for r in steps if abs(r) <= max(cap, base)]:
        hits = 0
        for k in range(1, 20):
            x, y = _bezier(pa, pb, rad, k / 20)
            hits += sum(b.x - 2 < x < b.x + b.w + 2 and b.y - 2 < y < b.y + b.h + 2
                        for b in obstacles)
        if hits == 0:
            return rad
        if fewest is None or hits < fewest:
            best, fewest = rad, hits
    return best


def _draw_edge(ax, layout: Layout, u: str, v: str, label: str, rad: float,
               message: bool) -> None:
    color = MESSAGE if message else EDGE
    pa, pb = _ends(layout, u, v)
    rad = _bend(layout, u, v, pa, pb, rad, message)
    ax.add_patch(FancyArrowPatch(pa, pb, connectionstyle=f"arc3,rad={rad}", arrowstyle="-|>",
                                 mutation_scale=9, lw=1.0, color=color, shrinkA=1, shrinkB=1,
                                 zorder=4, ls="--" if message else "-"))
    # the label sits on the curve (past the middle for messages, so two opposite messages
    # do not share a spot), on the outside of the bend
    mx, my = _bezier(pa, pb, rad, 0.7 if message else 0.5)
    ox, oy = -rad * (pb[1] - pa[1]), rad * (pb[0] - pa[0])
    if abs(ox) >= abs(oy):
        align = {"ha": "left" if ox > 0 else "right", "va": "center"}
        mx += 3 if ox > 0 else -3
    else:
        align = {"ha": "center", "va": "top" if oy > 0 else "bottom"}
    _label(ax, mx, my, label, color, fontstyle="italic" if message else "normal", **align)


def _draw_loop(ax, box: Box, label: str, k: int) -> None:
    x, cy = box.x + box.w, box.y + min(box.h / 2, 14.0)
    rad = -2.6 - 1.2 * k
    ax.add_patch(FancyArrowPatch((x, cy - 5), (x, cy + 5), connectionstyle=f"arc3,rad={rad}",
                                 arrowstyle="-|>", mutation_scale=8, lw=1.0, color=EDGE,
                                 shrinkA=0, shrinkB=0, zorder=4))
    _label(ax, x - rad * 5 + 6, cy + 10 * k, label, EDGE, ha="left")


def draw(graph: nx.MultiDiGraph, fmt: str, dpi: float = 150.0) -> bytes:
    """The built-in matplotlib drawing of the diagram graph as ``svg`` or ``png`` bytes."""
    layout = Layout(graph)
    w, h = layout.width, layout.height
    dpi = min(dpi, 5800.0 * 72.0 / max(w, h))  # keep the image under ~6000 px a side
    with mpl.rc_context({"svg.fonttype": "none", "font.family": FONT, "svg.hashsalt": "ht",
                         "path.simplify": False}):
        fig = Figure(figsize=(w / 72.0, h / 72.0), dpi=dpi)
        FigureCanvasAgg(fig)
        ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
        ax.set_aspect("equal")
        ax.axis("off")
        _text(ax, PAD, PAD, f"team {graph.graph.get('name', '')}", fontsize=NAME_PT + 1,
              fontweight="bold", va="top", ha="left")
        for panel in layout.panels:
            _draw_box(ax, layout, panel, 0)
        seen: dict[frozenset, int] = {}
        for u, v, d in layout.transitions + edges_of(graph, "message"):
            message = d["kind"] == "message"
            if u == v:
                k = seen.get(frozenset((u,)), 0)
                seen[frozenset((u,))] = k + 1
                _draw_loop(ax, layout.boxes[u], d["label"], k)
                continue
            k = seen.get(frozenset((u, v)), 0)
            seen[frozenset((u, v))] = k + 1
            rad = (0.18 if message else 0.12) + 0.18 * k
            _draw_edge(ax, layout, u, v, d["message"] if message else d["label"], rad, message)
        out = io.BytesIO()
        # "tight" grows the canvas to any label that reaches past the estimated layout
        fig.savefig(out, format=fmt, dpi=dpi, metadata=_metadata(fmt), bbox_inches="tight",
                    pad_inches=0.08)
        fig.clear()
    return out.getvalue()


def _metadata(fmt: str) -> dict[str, str | None]:
    """No dates or versions in the file, so the same diagram gives the same bytes."""
    if fmt == "svg":
        return {"Date": None, "Creator": None}
    if fmt == "pdf":
        return {"CreationDate": None, "ModDate": None, "Producer": None, "Creator": None}
    return {"Software": None}


def via_dot(graph: nx.MultiDiGraph, fmt: str) -> bytes | None:
    """Graphviz's rendering of the DOT text, or None when ``dot`` is missing or fails."""
    exe = shutil.which("dot")
    if exe is None:
        return None
    try:
        proc = subprocess.run([exe, f"-T{fmt}"], input=to_dot(graph).encode("utf-8"),
                              capture_output=True, timeout=DOT_TIMEOUT, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout if proc.returncode == 0 and proc.stdout else None


def render_svg(graph: nx.MultiDiGraph) -> str:
    """SVG text of the state diagram (Graphviz if available, else the built-in layout)."""
    data = via_dot(graph, "svg") or draw(graph, "svg")
    return data.decode("utf-8")


def render_png(graph: nx.MultiDiGraph) -> bytes:
    """PNG bytes of the state diagram (Graphviz if available, else the built-in layout)."""
    return via_dot(graph, "png") or draw(graph, "png")


def render_pdf(graph: nx.MultiDiGraph) -> bytes:
    """PDF bytes of the state diagram, vector (Graphviz if available, else the built-in
    layout)."""
    return via_dot(graph, "pdf") or draw(graph, "pdf")

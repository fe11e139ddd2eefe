"""State diagrams as SVG or PNG, with or without Graphviz.

When Graphviz's ``dot`` is on the PATH it lays out the DOT text of :mod:`.render` (the best
result). Nothing in hybridteam may require it, so without it (or if it fails) a small
built-in layout draws the same diagram with matplotlib: one panel per agent, side by side
in rows no wider than a page, composites as labelled boxes holding their children, children
stacked in layers found by a breadth-first walk from the initial mode (so the default path
reads top to bottom), parallel regions side by side with dashed borders, messages as
dashed arrows between panels (:mod:`.layout`). Edge labels are placed clear of boxes and
of each other, or become footnotes under the diagram (:mod:`.labels`). It is
deterministic: same graph, same picture.
"""

from __future__ import annotations

import io
import math
import shutil
import subprocess
from dataclasses import dataclass
from typing import Any

import matplotlib as mpl
import networkx as nx
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch, FancyBboxPatch
from matplotlib.path import Path as MplPath

from hybridteam.export.diagram import edges_of, initial_child, is_composite
from hybridteam.export.labels import Placer, Rect, text_size
from hybridteam.export.layout import (
    CAPTION_GAP,
    NAME_PT,
    PAD,
    SMALL_PT,
    TITLE,
    Box,
    Layout,
    _text_width,
    _wrap,
    behaviour_caption,
)
from hybridteam.export.render import state_title, to_dot
from hybridteam.export.route import along, bend, bezier, ends, rounded, route_edge
from hybridteam.export.style import FONT, text_color

EDGE, MESSAGE = "#333333", "#777777"
DOT_TIMEOUT = 30.0

# ------------------------------------------------------------------ drawing


def _text(ax, x: float, y: float, s: str, **kw) -> None:
    ax.text(x, y, s, fontfamily=FONT, parse_math=False, **kw)


def _draw_box(ax, layout: Layout, box: Box, depth: int) -> None:
    data = layout.graph.nodes[box.node]
    dashed = bool(data.get("region"))
    style = "round,pad=0,rounding_size=7"
    if is_composite(layout.graph, box.node):
        shade = ("#FFFFFF", "#F4F4F4", "#EAEAEA", "#E0E0E0")[min(depth, 3)]
        ax.add_artist(
            FancyBboxPatch(
                (box.x, box.y),
                box.w,
                box.h,
                boxstyle=style,
                fc=shade,
                ec="#444444",
                lw=1.0,
                ls="--" if dashed else "-",
            )
        )
        title = state_title(layout.graph, box.node)
        _text(
            ax,
            box.x + PAD,
            box.y + 4,
            title,
            fontsize=NAME_PT,
            fontweight="bold",
            va="top",
            ha="left",
            color="#222222",
        )
        if behaviour_caption(layout.graph, box.node):
            _text(
                ax,
                box.x + PAD + _text_width([title], NAME_PT) + CAPTION_GAP,
                box.y + 5,
                behaviour_caption(layout.graph, box.node),
                fontsize=SMALL_PT,
                va="top",
                ha="left",
                color="#222222",
            )
        first = initial_child(layout.graph, box.node)
        if first:
            kid = layout.boxes[first]
            cy = kid.y + min(kid.h / 2, 12.0)
            ax.add_artist(Circle((kid.x - 12, cy), 3.0, fc="black", ec="black"))
            ax.add_artist(
                FancyArrowPatch(
                    (kid.x - 9, cy),
                    (kid.x, cy),
                    arrowstyle="-|>",
                    mutation_scale=7,
                    lw=0.9,
                    color="black",
                )
            )
        for row in box.rows:
            for kid in row:
                _draw_box(ax, layout, kid, depth + 1)
        return
    color = data["color"]
    ink = text_color(color)
    ax.add_artist(
        FancyBboxPatch(
            (box.x, box.y),
            box.w,
            box.h,
            boxstyle=style,
            fc=color,
            ec="#222222",
            lw=1.0,
            ls="--" if dashed else "-",
        )
    )
    if data["final"]:
        ax.add_artist(
            FancyBboxPatch(
                (box.x + 2.5, box.y + 2.5),
                box.w - 5,
                box.h - 5,
                boxstyle="round,pad=0,rounding_size=5",
                fc="none",
                ec="#222222",
                lw=0.8,
            )
        )
    _text(
        ax,
        box.x + box.w / 2,
        box.y + PAD / 2 + 1,
        data["name"],
        fontsize=NAME_PT,
        fontweight="bold",
        ha="center",
        va="top",
        color=ink,
    )
    if box.lines:
        _text(
            ax,
            box.x + box.w / 2,
            box.y + PAD / 2 + NAME_PT * 1.45,
            "\n".join(box.lines),
            fontsize=SMALL_PT,
            ha="center",
            va="top",
            color=ink,
            linespacing=1.15,
        )


def _label(ax, x: float, y: float, lines: list[str], color: str, **kw) -> None:
    _text(
        ax,
        x,
        y,
        "\n".join(lines),
        fontsize=SMALL_PT,
        color=color,
        ha="center",
        va="center",
        linespacing=1.1,
        zorder=5,
        gid="edge-label",
        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
        **kw,
    )


@dataclass
class _Edge:
    """An edge ready to draw: its ends and bend, its label's text and centre."""

    pa: tuple[float, float]
    pb: tuple[float, float]
    rad: float
    message: bool
    lines: list[str]
    at: tuple[float, float]
    loop: bool = False
    path: list[tuple[float, float]] | None = None  # a routed polyline instead of an arc


def _spots(
    pa,
    pb,
    rad: float,
    ts: tuple[float, ...],
    step: float,
    path: list[tuple[float, float]] | None = None,
) -> list[tuple[float, float]]:
    """Candidate label centres: points of the curve (or the routed ``path``) at ``ts``,
    then beside it either side."""
    if path is not None:
        marks = along(path, ts)
    else:
        marks = []
        for t in ts:
            x, y = bezier(pa, pb, rad, t)
            x2, y2 = bezier(pa, pb, rad, min(t + 0.01, 1.0))
            marks.append(((x, y), (x2 - x, y2 - y)))
    out = []
    for k in (0, 1, -1, 2, -2, 3, -3):
        for (x, y), (tx, ty) in marks:
            norm = max((tx * tx + ty * ty) ** 0.5, 1e-9)
            out.append((x - ty / norm * k * step, y + tx / norm * k * step))
    return out


def _place(
    placer: Placer, text: str, spots: list[tuple[float, float]], more: list[tuple[float, float]]
) -> tuple[list[str], tuple[float, float]]:
    """The label's lines and centre: at the first free spot, else a footnote marker at the
    first free one of ``spots`` and ``more`` (denser, further out), else at the first."""
    lines = _wrap(text, 24)
    w, h = text_size(lines, SMALL_PT)
    at = placer.place(spots, w, h)
    if at is None:
        lines = [placer.footnote(text)]
        w, h = text_size(lines, SMALL_PT)
        at = placer.place([*spots, *more, *_spiral(*spots[0])], w, h) or spots[0]
    return lines, at


def _spiral(x: float, y: float) -> list[tuple[float, float]]:
    """Spots on rings of growing radius around (x, y): somewhere near, a marker fits."""
    return [
        (x + r * math.cos(a * math.pi / 8), y + r * math.sin(a * math.pi / 8))
        for r in range(8, 400, 6)
        for a in range(16)
    ]


def _blocked(layout: Layout) -> list[Rect]:
    """What a label must not cover: every mode box with text in it and composite titles."""
    out: list[Rect] = [(PAD, PAD, PAD + 200.0, PAD + TITLE)]  # the team's title
    for node, b in layout.boxes.items():
        if is_composite(layout.graph, node):
            out.append((b.x, b.y, b.x + b.title_w, b.y + TITLE))
        else:
            out.append((b.x, b.y, b.x + b.w, b.y + b.h))
    return out


#: More message links than this and each sending mode gets short labelled stubs instead of
#: arcs across the panels (a full protocol's dozens of arcs would cross every box)
STUBS_AFTER = 12


def _stubs(layout: Layout, graph: nx.MultiDiGraph, placer: Placer) -> list[_Edge]:
    """One short dashed arrow per sending mode and message, out of the side that faces
    the receivers, labelled ``message → receivers``."""
    groups: dict[tuple[str, str], list[str]] = {}
    for u, v, d in edges_of(graph, "message"):
        who = graph.nodes[v].get("agent", v)
        receivers = groups.setdefault((u, d["message"]), [])
        if who not in receivers:
            receivers.append(who)
    panel_x = {p.node: p.x for p in layout.panels}
    out: list[_Edge] = []
    count: dict[str, int] = {}
    for (u, message), receivers in groups.items():
        box = layout.boxes[u]
        k = count[u] = count.get(u, 0) + 1
        mine = panel_x.get(graph.nodes[u].get("agent", ""), box.x)
        right = sum(panel_x.get(r, 0.0) > mine for r in receivers) * 2 >= len(receivers)
        x = box.x + box.w if right else box.x
        y = box.y + box.h - 4.0 - 5.0 * (k - 1) % max(box.h - 8.0, 1.0)
        tip = (x + 18.0 if right else x - 18.0, y)
        text = f"{message} → {', '.join(receivers)}"
        w, _h = text_size(_wrap(text, 24), SMALL_PT)
        side = 1.0 if right else -1.0
        spots = [
            (tip[0] + side * (w / 2 + 2), y + dy)
            for dy in (0.0, *(s * j * 8.0 for j in range(1, 10) for s in (1, -1)))
        ]
        lines, at = _place(placer, text, spots, _spiral(*spots[0]))
        out.append(_Edge((x, y), tip, 0.0, True, lines, at))
    return out


def _plan(layout: Layout, graph: nx.MultiDiGraph) -> tuple[list[_Edge], list[str]]:
    """Every edge's geometry and label spot, and the labels that became footnotes."""
    placer = Placer(_blocked(layout))
    edges: list[_Edge] = []
    seen: dict[frozenset, int] = {}
    messages = edges_of(graph, "message")
    stubs = len(messages) > STUBS_AFTER
    for u, v, d in layout.transitions + ([] if stubs else messages):
        message = d["kind"] == "message"
        text = d["message"] if message else d["label"]
        k = seen.get(frozenset((u, v)), 0)
        seen[frozenset((u, v))] = k + 1
        if u == v:
            box = layout.boxes[u]
            x, cy = box.x + box.w, box.y + min(box.h / 2, 14.0)
            rad = -2.6 - 1.2 * k
            w, _h = text_size(_wrap(text, 24), SMALL_PT)
            spots = [
                (x - rad * 5 + 8 + w / 2, cy + dy)
                for dy in (10 * k, *(s * j * 9.0 for j in range(1, 12) for s in (1, -1)))
            ]
            more = [(x - rad * 5 + 14, cy + s * j * 5.0) for j in range(1, 40) for s in (1, -1)]
            lines, at = _place(placer, text, spots, more)
            edges.append(_Edge((x, cy - 5), (x, cy + 5), rad, False, lines, at, loop=True))
            continue
        pa, pb = ends(layout, u, v)
        rad, hits = bend(layout, u, v, pa, pb, (0.18 if message else 0.12) + 0.18 * k, message)
        path = route_edge(layout, u, v, pa, pb) if hits else None
        ts = (0.7, 0.6, 0.8, 0.5) if message else (0.5, 0.4, 0.6, 0.3, 0.7, 0.22, 0.78)
        dense = tuple(k / 20 for k in range(1, 20))
        lines, at = _place(
            placer, text, _spots(pa, pb, rad, ts, 9.0, path), _spots(pa, pb, rad, dense, 6.0, path)
        )
        edges.append(_Edge(pa, pb, rad, message, lines, at, path=path))
    if stubs:
        edges += _stubs(layout, graph, placer)
    return edges, placer.notes


def _draw_edge(ax, edge: _Edge) -> None:
    color = MESSAGE if edge.message else EDGE
    style: dict[str, Any] = {
        "arrowstyle": "-|>",
        "mutation_scale": 8 if edge.loop else 9,
        "lw": 1.0,
        "color": color,
        "zorder": 4,
        "ls": "--" if edge.message else "-",
    }
    if edge.path is not None:
        verts, codes = rounded(edge.path)
        ax.add_artist(FancyArrowPatch(path=MplPath(verts, codes), shrinkA=0, shrinkB=1, **style))
    else:
        ax.add_artist(
            FancyArrowPatch(
                edge.pa,
                edge.pb,
                connectionstyle=f"arc3,rad={edge.rad}",
                shrinkA=0 if edge.loop else 1,
                shrinkB=0 if edge.loop else 1,
                **style,
            )
        )
    _label(ax, *edge.at, edge.lines, color, fontstyle="italic" if edge.message else "normal")


def diagram_figure(graph: nx.MultiDiGraph, dpi: float = 150.0) -> Figure:
    """The built-in drawing of the diagram graph as a matplotlib figure (points as data
    units, y down): boxes, edges, labels clear of each other, footnotes below."""
    layout = Layout(graph)
    edges, notes = _plan(layout, graph)
    note_lines = [line for k, text in enumerate(notes, 1) for line in _wrap(f"({k}) {text}", 90)]
    w = layout.width
    h = layout.height + (len(note_lines) * SMALL_PT * 1.3 + 2 * PAD if note_lines else 0.0)
    dpi = min(dpi, 5800.0 * 72.0 / max(w, h))  # keep the image under ~6000 px a side
    fig = Figure(figsize=(w / 72.0, h / 72.0), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect("equal")
    ax.axis("off")
    _text(
        ax,
        PAD,
        PAD,
        f"team {graph.graph.get('name', '')}",
        fontsize=NAME_PT + 1,
        fontweight="bold",
        va="top",
        ha="left",
    )
    for panel in layout.panels:
        _draw_box(ax, layout, panel, 0)
    for edge in edges:
        _draw_edge(ax, edge)
    if note_lines:
        _text(
            ax,
            PAD,
            layout.height,
            "\n".join(note_lines),
            fontsize=SMALL_PT,
            va="top",
            ha="left",
            color=EDGE,
            linespacing=1.15,
            gid="footnotes",
        )
    return fig


def draw(graph: nx.MultiDiGraph, fmt: str, dpi: float = 150.0) -> bytes:
    """The built-in matplotlib drawing of the diagram graph as ``svg``/``png``/``pdf``."""
    with mpl.rc_context(
        {"svg.fonttype": "none", "font.family": FONT, "svg.hashsalt": "ht", "path.simplify": False}
    ):
        fig = diagram_figure(graph, dpi)
        out = io.BytesIO()
        # "tight" grows the canvas to any label that reaches past the estimated layout
        fig.savefig(
            out,
            format=fmt,
            dpi=fig.dpi,
            metadata=_metadata(fmt),
            bbox_inches="tight",
            pad_inches=0.08,
        )
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
        proc = subprocess.run(
            [exe, f"-T{fmt}"],
            input=to_dot(graph).encode("utf-8"),
            capture_output=True,
            timeout=DOT_TIMEOUT,
            check=False,
        )
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

"""Timeline of a run: who was in which mode when, with transitions and (close up) messages.

A lane per agent and per parallel region shows the deepest active modes as coloured bars, so
concurrent activity reads side by side; agents with composite modes get a thin row of their
top-level modes above, so "Dock" vs "Transport" stays visible over the Dock submodes. A
close-up (``window``) also draws every message as an arrow from send to receipt time, with
its latency, because in a close-up the interleaving of messages and mode changes is the point.

The drawing is computed first as :class:`TimelineData` — plain numbers, tested and exported
as CSV/JSON — and only then rendered, so what a test checks is what the figure shows.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from itertools import takewhile
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from hybridteam.errors import did_you_mean
from hybridteam.export.arrows import draw_messages, draw_mode_names, loss_text
from hybridteam.export.figures import DATA_FORMATS, figure_format, save_figure
from hybridteam.export.legend import legend_handles
from hybridteam.export.style import FONT, team_mode_colors
from hybridteam.export.verdicts import VIOLATION_COLOR, draw_violations
from hybridteam.trace import Table, Trace, write_atomic

MAIN_HEIGHT, TOP_HEIGHT, GAP = 0.8, 0.35, 0.35
#: a close-up's gaps between lanes hold two rows of message labels (see :mod:`.arrows`)
CLOSE_GAP = 0.7


@dataclass(frozen=True)
class Lane:
    """A horizontal row: an agent's modes, one parallel region, or the agent's top level."""

    agent: str
    region: str  # path of the region, "" for the agent's own lane
    label: str
    y: float  # centre, in data coordinates
    height: float = MAIN_HEIGHT
    top: bool = False  # the thin row of top-level modes


@dataclass(frozen=True)
class Bar:
    lane: int  # index into TimelineData.lanes
    mode: str
    label: str
    start: float
    end: float
    color: str


@dataclass(frozen=True)
class TransitionMark:
    """A transition drawn as a tick on its lane at time ``t``."""

    lane: int
    t: float
    source: str
    target: str


@dataclass(frozen=True)
class TimelineArrow:
    """A message copy drawn from its sender's lane at send time to its receiver's at
    receipt (a lost copy has no receipt)."""

    y_send: float
    y_recv: float
    t_send: float
    t_recv: float  # NaN when lost
    type: str
    latency: float  # seconds; NaN when lost
    lost: bool
    sender: str = ""
    receiver: str = ""
    socket: str = "control"


@dataclass
class TimelineData:
    """Everything the timeline draws, in data coordinates."""

    lanes: list[Lane]
    bars: list[Bar]
    marks: list[TransitionMark]
    arrows: list[TimelineArrow]
    span: tuple[float, float] = (0.0, 1.0)  # x limits
    window: tuple[float, float] | None = None
    lost: int = 0  # lost control messages of the instance (summarised without a window)
    dropped: int = 0  # lost data copies (a stream's; counted, marked only in a close-up)
    legend: dict[str, dict[str, str]] = field(default_factory=dict)  # agent -> path -> colour
    gap: float = GAP  # between lanes

    def to_json_dict(self) -> dict[str, Any]:
        """Plain lists of dicts; NaN (a lost message's receipt) becomes null."""
        return {
            key: [
                {
                    k: None if isinstance(v, float) and math.isnan(v) else v
                    for k, v in asdict(x).items()
                }
                for x in getattr(self, key)
            ]
            for key in ("lanes", "bars", "marks", "arrows")
        }

    def to_csv(self) -> str:  # the bars: what was active where, for a spreadsheet
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["lane", "agent", "region", "mode", "start", "end"])
        for b in self.bars:
            lane = self.lanes[b.lane]
            writer.writerow([b.lane, lane.agent, lane.region, b.mode, repr(b.start), repr(b.end)])
        return out.getvalue()


# ---------------------------------------------------------------------- model structure
def pick(table: Table, instance: int) -> Table:
    """Rows of one instance of an ensemble table."""
    return table.filter(np.asarray(table["instance"]) == instance)


def agent_meta(trace: Trace, agent: str) -> dict[str, Any]:
    """The agent's entry in the trace's meta (KeyError for a payload or unknown name)."""
    return {a["name"]: a for a in trace.meta["agents"]}[agent]


def mode_lanes(modes: list[dict[str, Any]]) -> dict[str, str]:
    """Each mode path -> the region lane it is drawn in ("" = the agent's lane).

    A region is a child of an ``and`` mode; a mode belongs to its innermost enclosing region
    (itself included), so nested parallel modes give nested lanes.
    """
    kinds = {m["path"]: m["kind"] for m in modes}
    regions = {p for p in kinds if "." in p and kinds.get(p.rsplit(".", 1)[0]) == "and"}
    return {p: region_of(p, regions) for p in kinds}


def region_of(path: str, regions: set[str]) -> str:
    parts = path.split(".") if path else []
    inside = [".".join(parts[:k]) for k in range(len(parts), 0, -1)]
    return next((p for p in inside if p in regions), "")


def drawn(kind: str | None) -> bool:
    """Deepest within its lane: a leaf, or a parallel mode (its children have own lanes)."""
    return kind in (None, "leaf", "and")


def team_colors(agents: list[dict[str, Any]]) -> dict[str, str]:
    """Mode colours of a trace's team (see :func:`style.team_mode_colors`)."""
    return team_mode_colors(
        [(m["path"], m["final"], m.get("role", "")) for m in meta.get("modes", [])]
        for meta in agents
    )


def select_agents(trace: Trace, names: list[str] | None) -> list[dict[str, Any]]:
    """The meta of the agents called ``names`` (all when None), in team order; an unknown
    name is a ValueError that suggests the closest."""
    every = trace.meta["agents"]
    if names is None:
        return every
    known = [a["name"] for a in every]
    for name in names:
        if name not in known:
            hint = did_you_mean(name, known)
            raise ValueError(
                f"no agent '{name}' in this trace (agents: {', '.join(known)})"
                + (f"; {hint}" if hint else "")
            )
    return [a for a in every if a["name"] in names]


def end_time(trace: Trace, instance: int) -> float:
    """When the instance ended: its outcome time, else the last recorded event or sample."""
    outcomes = getattr(trace, "diagnostics", trace.outcomes)
    o = outcomes[instance] if instance < len(outcomes) else {}
    t = max(
        [
            float(o.get("t") or 0.0) if isinstance(o, dict) else 0.0,
            *pick(trace.intervals, instance)["end"].tolist(),
        ]
    )
    t = t if t > 0 or not len(trace.sample_times) else float(trace.sample_times[-1])
    return t if t > 0 else float(trace.meta.get("duration") or 1.0)


def _phase_changes(intervals: Table, agent: str, window: tuple[float, float]) -> bool:
    """Whether more than one top-level mode of ``agent`` is active within ``window``
    (``intervals``: one instance's)."""
    iv = intervals.where(agent=agent)
    shown = (
        (np.asarray(iv["depth"]) == 1)
        & (np.asarray(iv["start"], float) <= window[1])
        & (np.asarray(iv["end"], float) >= window[0])
    )
    return len(set(np.asarray(iv["mode"])[shown].tolist())) > 1


def common_ancestor(a: str, b: str) -> str:
    """The innermost mode containing both paths (a transition lives there); "" = top."""
    pairs = zip(a.split("."), b.split("."), strict=False)
    same = takewhile(lambda pair: pair[0] == pair[1], pairs)
    return ".".join(x for x, _ in same) if a else b


# ---------------------------------------------------------------------- data
def timeline_data(
    trace: Trace,
    instance: int = 0,
    window: tuple[float, float] | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> TimelineData:
    """What the timeline of ``instance`` shows, optionally restricted to ``window`` and to
    some ``agents`` (in team order; colours stay those of the whole team).

    ``top``: the thin row of an agent's top-level modes above its lane. By default (None)
    only for agents with more than one top-level mode besides final leaves (``Dock`` then
    ``Transport``), where it says which phase the submodes below belong to; otherwise it
    would repeat the lane below (a final ``Arrived`` leaf shows in the lane itself). True
    draws it for every agent with nested modes.
    """
    lanes: list[Lane] = []
    index: dict[tuple[str, str, bool], int] = {}
    colors = team_colors(trace.meta["agents"])
    chosen = select_agents(trace, agents)
    cursor = 0.0
    gap = GAP if window is None else CLOSE_GAP
    iv = pick(trace.intervals, instance)
    for meta in chosen:
        modes = meta.get("modes", [])
        lane_of = mode_lanes(modes)
        regions = sorted({r for r in lane_of.values() if r}, key=[m["path"] for m in modes].index)
        composite = any(
            lane_of[m["path"]] == "" and drawn(m["kind"]) and m["depth"] > 1 for m in modes
        )
        if top is None:  # phases: more than one top-level mode, a final leaf aside
            composite &= (
                sum(m["depth"] == 1 and not (m["final"] and m["kind"] == "leaf") for m in modes) > 1
            )
            if window is not None:  # a close-up: only if the phase changes within it
                composite &= _phase_changes(iv, meta["name"], window)
        elif not top:
            composite = False
        rows = [("", True)] * composite + [("", False)] + [(r, False) for r in regions]
        for region, is_top in rows:
            h = TOP_HEIGHT if is_top else MAIN_HEIGHT
            label = (
                f"{meta['name']} (top)"
                if is_top
                else f"{meta['name']} / {region}"
                if region
                else meta["name"]
            )
            index[(meta["name"], region, is_top)] = len(lanes)
            lanes.append(Lane(meta["name"], region, label, cursor - h / 2, h, is_top))
            cursor -= h + gap

    tr = pick(trace.transitions, instance)
    bars: list[Bar] = []
    marks: list[TransitionMark] = []
    legend: dict[str, dict[str, str]] = {}  # agent -> {mode path: colour}
    # modes the legend names: a stay entered and left at the same instant is a sliver no
    # reader can find, so its mode is named only if it also stays somewhere (a final mode
    # reached as the run ends is zero-length too, and named)
    used: set[tuple[str, str]] = set()
    t_end = end_time(trace, instance)
    for meta in chosen:
        name = meta["name"]
        kinds = {m["path"]: m["kind"] for m in meta.get("modes", [])}
        lane_of = mode_lanes(meta.get("modes", []))
        mine = iv.where(agent=name)
        if window is not None:  # a close-up: only the stays it shows (numpy, not a loop)
            st, en = np.asarray(mine["start"], float), np.asarray(mine["end"], float)
            mine = mine.filter(
                ((st < window[1]) & (en > window[0]))
                | ((window[0] <= st) & (st == en) & (en <= window[1]))
            )
        mine = mine.filter(np.lexsort((mine["depth"], mine["start"])))
        for mode, depth, start, end in zip(
            mine["mode"].tolist(),
            mine["depth"].tolist(),
            mine["start"].tolist(),
            mine["end"].tolist(),
            strict=True,
        ):
            color, label = colors.get(mode, "#BBBBBB"), mode.rsplit(".", 1)[-1]
            keys = [(name, lane_of.get(mode, ""), False)] if drawn(kinds.get(mode)) else []
            keys += [(name, "", True)] if depth == 1 and (name, "", True) in index else []
            bars += [Bar(index[key], mode, label, start, end, color) for key in keys]
            if keys and (end > start or end >= t_end):  # not entered and left at once
                used.add((name, mode))
        lane_regions, mine_tr = set(lane_of.values()) - {""}, tr.where(agent=name)
        if window is not None:
            at = np.asarray(mine_tr["t"], float)
            mine_tr = mine_tr.filter((window[0] <= at) & (at <= window[1]))
        marks += [
            TransitionMark(
                index[(name, region_of(common_ancestor(a, b), lane_regions), False)], t, a, b
            )
            for t, a, b in zip(
                mine_tr["t"].tolist(),
                mine_tr["source"].tolist(),
                mine_tr["target"].tolist(),
                strict=True,
            )
        ]
        for path in kinds:  # the legend follows the agent's model order, not the run
            if (name, path) in used:
                legend.setdefault(name, {})[path] = colors.get(path, "#BBBBBB")

    arrows: list[TimelineArrow] = []
    msgs = pick(trace.messages, instance)
    if len(msgs):  # copies still in flight when the run ended were not lost by the network
        msgs = msgs.filter(msgs["reason"] != "run ended")
    gone = (msgs["status"] == "lost") if len(msgs) else np.zeros(0, bool)
    on_data = (msgs["socket"].astype(str) == "data") if len(msgs) else np.zeros(0, bool)
    lost, dropped = int(np.sum(gone & ~on_data)), int(np.sum(gone & on_data))
    ys = {lane.agent: lane.y for lane in lanes if not lane.top and not lane.region}
    if len(msgs):  # the copies with an arrow: sent or received inside a close-up's window;
        # with no window only lost control messages are marked (a stream to a rate-limited
        # receiver drops thousands of copies, which would hide the lanes)
        sent = np.asarray(msgs["t_send"], float)
        got = np.where(gone, np.nan, np.asarray(msgs["t_recv"], float))
        msgs = msgs.filter(
            (
                ((window[0] <= sent) & (sent <= window[1]))
                | ((window[0] <= got) & (got <= window[1]))
            )
            if window is not None
            else gone & ~on_data
        )
    for m in msgs:
        if m.sender not in ys or m.receiver not in ys:
            continue
        is_lost = m.status == "lost"
        t_recv = math.nan if is_lost or m.t_recv is None else float(m.t_recv)
        arrows.append(
            TimelineArrow(
                ys[m.sender],
                ys[m.receiver],
                float(m.t_send),
                t_recv,
                m.type,
                t_recv - m.t_send,
                is_lost,
                m.sender,
                m.receiver,
                str(m.socket),
            )
        )
    span = window if window is not None else (0.0, end_time(trace, instance))
    return TimelineData(
        lanes, bars, marks, arrows, span, window, lost=lost, dropped=dropped, legend=legend, gap=gap
    )


# ---------------------------------------------------------------------- drawing
def timeline_figure(
    trace: Trace,
    instance: int = 0,
    window: tuple[float, float] | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> tuple[Figure, TimelineData]:
    """The timeline as a matplotlib figure (Agg canvas) and the data it shows."""
    data = timeline_data(trace, instance, window, agents, top)
    extent = sum(lane.height + data.gap for lane in data.lanes)
    with rc_context({"font.family": FONT}):
        fig = Figure(figsize=(11.0, 1.4 + 0.55 * extent), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        draw_timeline(fig, ax, data, trace, instance)
    return fig, data


def draw_timeline(
    fig: Figure, ax: Any, data: TimelineData, trace: Trace, instance: int, extra: Sequence[Any] = ()
) -> None:
    """Draw ``data`` on ``ax``; ``extra``: legend entries of what a caller draws on top
    (an overlay's marks), after the timeline's own."""
    t0, t1 = data.span
    width = max(t1 - t0, 1e-9)
    groups: dict[tuple[int, str], list[tuple[float, float]]] = defaultdict(list)
    for b in data.bars:  # zero-length intervals (a final mode at the end) stay visible
        groups[(b.lane, b.color)].append((b.start, max(b.end - b.start, width * 0.002)))
    per_lane = np.bincount([b.lane for b in data.bars], minlength=len(data.lanes))
    for (lane_i, color), spans in groups.items():
        lane = data.lanes[lane_i]  # white separators, unless so dense they would wash out
        ax.broken_barh(
            spans,
            (lane.y - lane.height / 2, lane.height),
            facecolors=color,
            edgecolors="white",
            linewidth=0.4 if per_lane[lane_i] < 300 else 0,
            gid=f"bars:{lane_i}",
        )
    # labels where they fit: estimate from the axes width in pixels
    px_per_s = ax.get_position().width * fig.get_figwidth() * fig.dpi / width
    draw_mode_names(ax, fig, data, px_per_s)
    if data.marks:  # ticks across the lower edge of the lane, all in one collection
        lo = np.array(
            [data.lanes[m.lane].y - data.lanes[m.lane].height / 2 - 0.1 for m in data.marks]
        )
        ax.vlines(
            [m.t for m in data.marks],
            lo,
            lo + 0.22,
            colors="black",
            linewidth=0.7,
            gid="transitions",
        )
    draw_messages(ax, data, 7 * 0.62 * fig.dpi / 72 / px_per_s)
    violated = draw_violations(ax, trace, instance, (t0, t1))
    pad = 0.0 if data.window else 0.01 * width
    ax.set_xlim(t0 - pad, t1 + pad)
    first, last = data.lanes[0], data.lanes[-1]
    ax.set_ylim(last.y - last.height / 2 - 0.2, first.y + first.height / 2 + 0.2)
    ax.set_yticks([lane.y for lane in data.lanes], [lane.label for lane in data.lanes])
    for tick, lane in zip(ax.get_yticklabels(), data.lanes, strict=True):
        tick.set(fontsize=7 if lane.top else 9, color="#555555" if lane.top else "black")
    ax.set_xlabel("time (s)")
    ax.grid(axis="x", color="#DDDDDD", linewidth=0.6)
    ax.set_axisbelow(True)
    title = str(trace.meta.get("team", "")) + (f" — instance {instance}" if trace.n > 1 else "")
    ax.set_title(
        title
        + (f" — {data.window[0]:g} s to {data.window[1]:g} s" if data.window else loss_text(data))
    )
    handles, heads = legend_handles(data.legend)
    if violated:
        handles.append(
            Line2D([], [], color=VIOLATION_COLOR, linestyle="--", label="requirement violated")
        )
    handles += extra
    if handles:
        box = ax.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            fontsize=8,
            frameon=False,
            ncol=1 + len(handles) // 30,
            handlelength=1.4,
        )
        for k in heads:
            box.get_texts()[k].set_fontweight("bold")


# ---------------------------------------------------------------------- files
def write_timeline(
    trace: Trace,
    path: str | os.PathLike,
    instance: int = 0,
    window: tuple[float, float] | None = None,
    data_path: str | os.PathLike | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> Path:
    """Write the timeline (.png/.svg) and, when ``data_path`` is given, its data (.csv/.json)."""
    figure_format(path)
    kind = None if data_path is None else figure_format(data_path, DATA_FORMATS)
    fig, data = timeline_figure(trace, instance, window, agents, top)
    try:
        save_figure(fig, path)
    finally:
        fig.clear()
    if data_path is not None:
        text = data.to_csv() if kind == "csv" else json.dumps(data.to_json_dict(), allow_nan=False)
        write_atomic(Path(data_path), text)
    return Path(path)

"""A recorded run drawn over its model's replay: where the robots and the model differ.

``hybridteam check --conformance`` says in words where a log first leaves the model; these
views show it. The timeline gives every agent two lanes, the log's modes above the model's
(the replay conformance computes, :mod:`hybridteam.logs.conformance`), in the same colours,
so a shifted or missing transition reads as bars that stop lining up; the first divergence
is a line across that agent's two lanes, labelled with its time and both modes. The plot
draws over the logged paths the model's replay (dashed) and, for a robot whose log has its
commands, its plant driven by those commands (dotted, :mod:`hybridteam.logs.commanded`),
and joins each to the log where they are farthest apart, labelled with the distance and
the time: the two deviations the conformance report gives.

Both are the ordinary views (:mod:`.timeline`, :mod:`.trajectories`) of the log with the
model added, so everything else (colours, legend, requirement violations, the scene) is
what a reader of those views already knows.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from hybridteam.export.figures import figure_format, save_figure
from hybridteam.export.scene import planar_agents, pose, scene_extent
from hybridteam.export.style import FONT, HALO, PALETTE
from hybridteam.export.timeline import (
    Lane,
    TimelineData,
    draw_timeline,
    end_time,
    timeline_data,
)
from hybridteam.export.trajectories import trajectory_figure

if TYPE_CHECKING:
    from hybridteam.logs.commanded import PoseDeviation
    from hybridteam.logs.conformance import Conformance

#: the first divergence's line and label (not the requirement violations' red)
DIVERGENCE_COLOR = "#6A1B9A"
#: the model's paths: dashed, over the logged ones in the same colour
MODEL_STYLE = {"linestyle": (0, (4, 2.5)), "linewidth": 1.3, "alpha": 0.9}
#: the plants under the logged commands: dotted, in the same colour
COMMANDED_STYLE = {"linestyle": (0, (1, 1.6)), "linewidth": 1.6, "alpha": 0.95}
#: the largest deviation from the plant under the logged commands (the replay's is purple)
COMMANDED_COLOR = "#B71C1C"
SIDES = ("log", "model")


# ---------------------------------------------------------------------- timeline
def overlay_timeline_data(
    result: Conformance,
    window: tuple[float, float] | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> TimelineData:
    """The timeline of the log and of the model's replay, interleaved: per agent its
    lanes of the log, then the same lanes of the model (labelled ``A — log``,
    ``A — model``). Bars and transition ticks are each side's own; message arrows are
    the log's (the model's sends went nowhere: the replay gives each agent the log's
    arrivals)."""
    sides = (
        timeline_data(result.log, result.instance, window, agents, top),
        timeline_data(result.model, 0, window, agents, top),
    )
    lanes: list[Lane] = []
    moved: list[dict[int, int]] = [{}, {}]  # per side: its lane index -> the merged one
    cursor = 0.0
    gap = sides[0].gap
    names = list(dict.fromkeys(lane.agent for lane in sides[0].lanes))
    for name in names:
        for k, (side, data) in enumerate(zip(SIDES, sides, strict=True)):
            for i, lane in enumerate(data.lanes):
                if lane.agent != name:
                    continue
                moved[k][i] = len(lanes)
                lanes.append(
                    dataclasses.replace(
                        lane, label=f"{lane.label} — {side}", y=cursor - lane.height / 2
                    )
                )
                cursor -= lane.height + (gap if k == 1 and _last(data, i) else 0.12)
    bars = [
        dataclasses.replace(b, lane=moved[k][b.lane])
        for k, data in enumerate(sides)
        for b in data.bars
    ]
    marks = [
        dataclasses.replace(m, lane=moved[k][m.lane])
        for k, data in enumerate(sides)
        for m in data.marks
    ]
    by_agent = {
        old.agent: lanes[moved[0][i]].y  # an arrow joins the log's main lanes
        for i, old in enumerate(sides[0].lanes)
        if not old.top and not old.region
    }
    arrows = [
        dataclasses.replace(a, y_send=by_agent[a.sender], y_recv=by_agent[a.receiver])
        for a in sides[0].arrows
    ]
    legend = {
        a: {**sides[1].legend.get(a, {}), **sides[0].legend.get(a, {})}
        for a in names
        if a in sides[0].legend or a in sides[1].legend
    }
    span = (
        window
        if window is not None
        else (0.0, max(end_time(result.log, result.instance), end_time(result.model, 0)))
    )
    return TimelineData(
        lanes,
        bars,
        marks,
        arrows,
        span,
        window,
        lost=sides[0].lost,
        dropped=sides[0].dropped,
        legend=legend,
        gap=gap,
    )


def _last(data: TimelineData, i: int) -> bool:
    """Whether lane ``i`` is its agent's last: the gap between agents follows it."""
    return i + 1 == len(data.lanes) or data.lanes[i + 1].agent != data.lanes[i].agent


def overlay_timeline_figure(
    result: Conformance,
    window: tuple[float, float] | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> tuple[Figure, TimelineData]:
    """The overlaid timeline as a figure (Agg canvas), and the data it draws."""
    data = overlay_timeline_data(result, window, agents, top)
    extent = sum(lane.height + data.gap for lane in data.lanes)
    with rc_context({"font.family": FONT}):
        fig = Figure(figsize=(11.0, 1.7 + 0.55 * extent), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        diverged = _mark_divergence(ax, data, result)
        entry = (
            [Line2D([], [], color=DIVERGENCE_COLOR, linewidth=2.0, label="first divergence")]
            if diverged is not None
            else []
        )
        draw_timeline(fig, ax, data, result.log, result.instance, entry)
        if top is not None:  # room for the label above the first agent's lanes
            low, high = ax.get_ylim()
            ax.set_ylim(low, max(high, top + 0.3))
        ax.set_title(
            f"{result.log.meta.get('team', '')} — log against model\n{_verdict(result)}",
            fontsize=10,
        )
    return fig, data


def _verdict(result: Conformance) -> str:
    first = result.first
    if first is None:
        return (
            f"conformant: every mode sequence is the model's, each transition within "
            f"{result.tolerance:g} s"
        )
    return (
        f"first divergence at t={first.t:.6g} s, {first.agent}: model in "
        f"{first.expected}, log in {first.observed}"
    )


def _mark_divergence(ax: Any, data: TimelineData, result: Conformance) -> float | None:
    """A line across the diverging agent's lanes at the first divergence, labelled
    ``t=…: model X, log Y`` above them (to its left near the right edge); the top of the
    line, where the label sits, or None when nothing is drawn."""
    first = result.first
    t0, t1 = data.span
    mine = [lane for lane in data.lanes if lane.agent == (first and first.agent)]
    if first is None or not t0 <= first.t <= t1 or not mine:  # --agents, --window
        return None
    top = max(lane.y + lane.height / 2 for lane in mine) + 0.1
    bottom = min(lane.y - lane.height / 2 for lane in mine) - 0.1
    ax.plot(
        [first.t, first.t],
        [bottom, top],
        color=DIVERGENCE_COLOR,
        linewidth=2.0,
        zorder=9,
        gid="divergence",
        path_effects=HALO,
    )
    right = first.t > t0 + 0.6 * (t1 - t0)
    short = (first.expected.rsplit(".", 1)[-1], first.observed.rsplit(".", 1)[-1])
    ax.annotate(
        f"t={first.t:.6g} s: model {short[0]}, log {short[1]}",
        (first.t, top),
        xytext=(-4 if right else 4, 1),
        textcoords="offset points",
        ha="right" if right else "left",
        va="bottom",
        fontsize=8,
        fontweight="bold",
        color=DIVERGENCE_COLOR,
        zorder=10,
        gid="divergence-label",  # (a box: message arrows cross this height)
        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.9},
    )
    return top


def write_overlay_timeline(
    result: Conformance,
    path: str | os.PathLike,
    window: tuple[float, float] | None = None,
    agents: list[str] | None = None,
    top: bool | None = None,
) -> Path:
    """Write :func:`overlay_timeline_figure` (.png, .svg or .pdf by extension)."""
    figure_format(path)
    fig, _ = overlay_timeline_figure(result, window, agents, top)
    try:
        return save_figure(fig, path)
    finally:
        fig.clear()


# ---------------------------------------------------------------------- plot
def overlay_plot_figure(
    result: Conformance,
    xlim: tuple[float, float] | None = None,
    ylim: tuple[float, float] | None = None,
    size: tuple[float, float] | None = None,
) -> Figure:
    """The log's trajectories (:func:`~.trajectories.trajectory_figure`) with each planar
    robot's model path dashed and its plant under the logged commands dotted over its own
    (where the log has its commands), and the largest deviation from each marked: a
    segment from the logged position to the other's at that time, labelled with the
    distance (the replay's label above its logged end, the commands' below). The plane's
    limits (unless given) cover the log's scene, the model's paths and the commanded
    ones."""
    log, model = result.log, result.model
    order = planar_agents(log)
    agents = [a for a in order if a in model.samples]
    commanded = {
        a.agent: a.commanded for a in result.agents if a.agent in agents and a.commanded is not None
    }
    if agents and (xlim is None or ylim is None):
        lx0, lx1, ly0, ly1 = scene_extent(log, result.instance)
        mx0, mx1, my0, my1 = scene_extent(model, 0)
        xs, ys = [lx0, lx1, mx0, mx1], [ly0, ly1, my0, my1]
        for path in commanded.values():
            xs += [float(path.xy[:, 0].min()), float(path.xy[:, 0].max())]
            ys += [float(path.xy[:, 1].min()), float(path.xy[:, 1].max())]
        xlim = xlim or (min(xs), max(xs))
        ylim = ylim or (min(ys), max(ys))

    def draw_model(ax: Any) -> None:
        for a in agents:
            color = PALETTE[order.index(a) % len(PALETTE)]
            p = pose(model, a, 0)
            ax.plot(
                p[:, 0],
                p[:, 1],
                color=color,
                zorder=4.5,
                gid=f"model-path:{a}",
                label=f"{a} (model)",
                **MODEL_STYLE,
            )
            if a in commanded:
                xy = commanded[a].xy
                ax.plot(
                    xy[:, 0],
                    xy[:, 1],
                    color=color,
                    zorder=4.6,
                    gid=f"commanded-path:{a}",
                    label=f"{a} (under logged commands)",
                    **COMMANDED_STYLE,
                )
        # the replay's segment wider, under the commands' one: where the two are the
        # same segment (a logged pose off both), its colour still shows round the other
        marks = (
            (
                "deviation",
                result.replay_deviation,
                DIVERGENCE_COLOR,
                3.2,
                6,
                "largest deviation, log to model",
            ),
            (
                "commanded-deviation",
                result.deviation,
                COMMANDED_COLOR,
                1.4,
                -13,
                "largest deviation, log to logged commands",
            ),
        )
        for gid, deviation, color, width, above, label in marks:
            marked = [(a, w) for a in agents if (w := deviation(a)) is not None and _marked(w)]
            for k, (a, worst) in enumerate(marked):
                (x0, y0), (x1, y1) = worst.logged, worst.model
                ax.plot(
                    [x0, x1],
                    [y0, y1],
                    color=color,
                    linewidth=width,
                    zorder=9,
                    marker="o",
                    markersize=3.5,
                    gid=f"{gid}:{a}",
                    label="_" if k else label,
                )
                # at the segment's middle: inside the plane, where its ends may be at
                # the edge (a label there would cross the frame)
                ax.annotate(
                    f"{worst.distance:.3g} m at t={worst.t:.4g} s",
                    ((x0 + x1) / 2, (y0 + y1) / 2),
                    xytext=(6, above),
                    textcoords="offset points",
                    fontsize=7.5,
                    fontweight="bold",
                    color=color,
                    path_effects=HALO,
                    zorder=10,
                    gid=f"{gid}-label:{a}",
                )

    fig = trajectory_figure(
        log, result.instance, xlim=xlim, ylim=ylim, size=size, overlay=draw_model
    )
    fig.suptitle(
        f"{log.meta.get('team', '')} — log (solid), model (dashed), plant under "
        "the logged commands (dotted)"
        if commanded
        else f"{log.meta.get('team', '')} — log (solid) against model (dashed)"
    )
    return fig


def _marked(worst: PoseDeviation | None) -> bool:
    """Whether a deviation is drawn: one of exactly 0 has nothing to point at."""
    return worst is not None and worst.distance > 0


def write_overlay_plot(
    result: Conformance,
    path: str | os.PathLike,
    xlim: tuple[float, float] | None = None,
    ylim: tuple[float, float] | None = None,
    size: tuple[float, float] | None = None,
) -> Path:
    """Write :func:`overlay_plot_figure` (.png, .svg or .pdf by extension)."""
    figure_format(path)
    fig = overlay_plot_figure(result, xlim, ylim, size)
    try:
        return save_figure(fig, path, tight=size is None)
    finally:
        fig.clear()

"""Where the robots went: paths in the plane, or state against time for flow plants.

For planar agents (state with x and y) a reader wants the geometry — paths, the robot's
footprint and heading every so often, the world it moved in, the payload it carried — and
where along the path the mode changed; those points are numbered in time order across the
team ("1R", "2A", ...) so a figure and a timeline can be read together. Flow agents have no
geometry, so each state component is drawn against time, coloured by the active mode.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.typing import LineStyleType

from hybridteam.export.figures import save_figure
from hybridteam.export.scene import (
    COLLISION_MARK,
    collision_marks,
    draw_guides,
    draw_payloads,
    draw_world,
    flow_agents,
    moved,
    payload_names,
    planar_agents,
    pose,
    scene_extent,
    scene_of,
)
from hybridteam.export.style import FONT, HALO, PALETTE
from hybridteam.export.timeline import (
    agent_meta,
    drawn,
    end_time,
    mode_lanes,
    pick,
    team_colors,
)
from hybridteam.trace import Table, Trace

MAX_NUMBERS = 120  # beyond this, numbered labels only on every k-th change (legibility)
#: labels of changes at one spot stack upwards; past this many, one "…" stands for the rest
#: (a Zeno run's last bounces would otherwise stack a column of labels off the plot)
MAX_STACK = 3
LINESTYLES: tuple[LineStyleType, ...] = ("solid", "dashed", "dashdot", "dotted")


# ---------------------------------------------------------------------- what is what
def main_lane_intervals(trace: Trace, instance: int, agent: str) -> Table:
    """Intervals of the modes drawn in the agent's own lane, sorted by start: the agent's
    "current mode" for plots that colour by mode."""
    meta = agent_meta(trace, agent)
    kinds = {m["path"]: m["kind"] for m in meta.get("modes", [])}
    lanes = mode_lanes(meta.get("modes", []))
    iv = pick(trace.intervals, instance).where(agent=agent)
    keep = np.array([lanes.get(m, "") == "" and drawn(kinds.get(m)) for m in iv["mode"]], bool)
    iv = iv.filter(keep) if len(iv) else iv
    return iv.filter(np.argsort(iv["start"], kind="stable"))


def letters(names: Sequence[str]) -> dict[str, str]:
    """First letter of each name, upper case; longer prefixes only where two would clash."""
    out: dict[str, str] = {}
    if all(len(n) <= 3 for n in names) and len({n.upper() for n in names}) == len(names):
        return {n: n.upper() for n in names}  # short names (R1, R2) are their own labels
    for name in names:
        k = 1
        while k < len(name) and any(v == name[:k].upper() for v in out.values()):
            k += 1
        out[name] = name[:k].upper()
    return out


def start_label(name: str, letter: str) -> str:
    """A robot's start: ``0S: scout2``. The letter is what the numbered changes use; two
    Scouts' letters (``S``, ``SC``) say which is which only next to the name."""
    return f"0{letter}" if letter == name.upper() else f"0{letter}: {name}"


def collision_labels(
    hits: Sequence[tuple[float, float, float, str]], near: float
) -> list[tuple[float, float, str]]:
    """One label per spot where collisions happened: ``(x, y, "1.8 s")``, or where several
    happened within ``near`` of the first one there (two robots clipping the same door
    jamb, seconds apart), ``"3.8 s lead, 5.8 s tail"``, since labels drawn at one spot hide
    each other. ``hits``: ``(t, x, y, who)`` in time order."""
    spots: list[tuple[float, float, list[tuple[float, str]]]] = []
    for t, x, y, who in hits:
        for sx, sy, group in spots:
            if math.hypot(x - sx, y - sy) <= near:
                group.append((t, who))
                break
        else:
            spots.append((x, y, [(t, who)]))
    return [
        (
            x,
            y,
            f"{group[0][0]:.3g} s"
            if len(group) == 1
            else ", ".join(f"{t:.3g} s {who}" for t, who in group),
        )
        for x, y, group in spots
    ]


START_ROW = 10.0  # points between stacked start labels (8 pt bold text)


def start_rows(ax: Any, starts: Sequence[tuple[float, float, str, str]]) -> list[int]:
    """The row under its start each start label takes (0: 12 pt below it), so that labels
    of robots starting side by side, which name their robots now and are long, do not
    overprint each other: a label moves a row down while it would overlap one placed
    before it. Sizes are estimated before layout, from the axes' share of the figure at
    equal aspect (about 0.6 em per character of 8 pt bold)."""
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    box = ax.get_position()
    w_in, h_in = ax.get_figure().get_size_inches()
    per_pt = max(
        (x1 - x0) / max(box.width * w_in * 72.0, 1.0),
        (y1 - y0) / max(box.height * h_in * 72.0, 1.0),
    )  # metres per point
    placed: list[tuple[float, float, float]] = []  # left, right, top (points)
    rows = []
    for x, y, text, _color in starts:
        left = x / per_pt - 6.0
        right = left + 0.6 * 8.0 * len(text)
        row = 0
        while any(
            left < r and lo < right and abs(y / per_pt - 12.0 - START_ROW * row - top) < START_ROW
            for lo, r, top in placed
        ):
            row += 1
        placed.append((left, right, y / per_pt - 12.0 - START_ROW * row))
        rows.append(row)
    return rows


def nice_step(span: float, count: int = 10) -> float:
    """A round spacing (1, 2, 2.5, 5 x 10^k) giving about ``count`` footprints per run."""
    raw = max(span, 1e-9) / count
    mag = 10 ** math.floor(math.log10(raw))
    return min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=10 * mag)


def footprint_indices(times: np.ndarray, valid: np.ndarray, every: float) -> np.ndarray:
    """First sample at or after t0, t0 + every, ... while the agent is alive (valid)."""
    if not valid.any():
        return np.zeros(0, int)
    t_valid = times[valid]
    marks = np.arange(t_valid[0], t_valid[-1] + every * 1e-9, every)
    idx = np.clip(np.searchsorted(t_valid, marks), 0, len(t_valid) - 1)
    return np.unique(np.flatnonzero(valid)[idx])


def mode_changes(
    trace: Trace, instance: int, agents: Sequence[str], modes: Sequence[str] | None
) -> list[tuple[float, int, str, str, int]]:
    """(t, step, agent, target, number) of the numbered points, in time order.

    Default: when the team plays protocol roles, every change of role (a leadership change:
    the numbers of the architecture paper's Figs. 7, 8, 11); otherwise every transition into
    a leaf (the start, numbered 0, is not one). With ``modes``: transitions whose source or
    target is one of those paths or lies inside one.
    """
    tr = pick(trace.transitions, instance)
    out = []
    metas = {a: agent_meta(trace, a).get("modes", []) for a in agents}
    leaves = {a: {m["path"] for m in ms if m["kind"] == "leaf"} for a, ms in metas.items()}
    roles = {a: {m["path"]: m["role"] for m in ms if m.get("role")} for a, ms in metas.items()}
    by_role = not modes and any(roles.values())

    def role(agent: str, path: str) -> str | None:
        while path:
            if path in roles[agent]:
                return roles[agent][path]
            path = path.rpartition(".")[0]
        return None

    def inside(path: str) -> bool:
        return any(path == m or path.startswith(m + ".") for m in modes or ())

    for row in tr:
        if row.agent not in leaves or row.cause == "init":
            continue
        if by_role:
            before, after = role(row.agent, row.source), role(row.agent, row.target)
            selected = before is not None and after is not None and before != after
        elif modes:
            selected = inside(row.source) or inside(row.target)
        else:
            selected = row.target in leaves[row.agent]
        if selected:
            out.append(
                (
                    row.t,
                    row.step,
                    row.agent,
                    row.target,
                    role(row.agent, row.target) if by_role else None,
                )
            )
    order = {a: k for k, a in enumerate(agents)}
    if out:  # by time, step, then team order; stable, as a sort on that key would be
        rank = np.lexsort(([order[r[2]] for r in out], [r[1] for r in out], [r[0] for r in out]))
        out = [out[k] for k in rank]
    return _numbered(out) if by_role else [(*r[:4], k) for k, r in enumerate(out, 1)]


def _numbered(changes: list) -> list[tuple[float, int, str, str, int]]:
    """Number role changes per hand-over, as the architecture paper does: a robot taking the
    ``lead`` role starts number k, and the robot that gave it up (its change just before)
    shares k — so a request reads 1X (new leader) and 1L (old leader), not 1 and 2."""
    numbers = [0] * len(changes)
    count = 0
    pending: list[int] = []
    for k, (*_, new_role) in enumerate(changes):
        if new_role == "lead":
            count += 1
            numbers[k] = count
            for j in pending:
                numbers[j] = count
            pending = []
        else:
            pending.append(k)
    for j in pending:  # gave up the lead and nobody has taken it (yet)
        numbers[j] = count + 1
    return [(*c[:4], n) for c, n in zip(changes, numbers, strict=True)]


# ---------------------------------------------------------------------- planar
def draw_planar(
    ax: Any,
    trace: Trace,
    instance: int,
    every: float | None,
    modes: Sequence[str] | None,
    limits: tuple[float, float, float, float] | None = None,
    overlay: Callable[[Any], None] | None = None,
) -> None:
    """The planar robots' paths, poses, mode changes and world on ``ax``. ``overlay``:
    what another view draws on the plane (a model's paths over a log's), called before
    the legend is made, which lists its artists that have labels after the robots."""
    agents = planar_agents(trace)
    times = trace.sample_times
    scene = scene_of(trace)
    draw_world(ax, scene)
    poses = {a: pose(trace, a, instance) for a in agents}
    pts = np.concatenate([p[:, :2] for p in poses.values()]) if poses else np.zeros((0, 2))
    pts = pts[~np.isnan(pts).any(axis=1)]
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 1.0
    every = every or nice_step(end_time(trace, instance), 10)
    letter = letters(agents)
    all_idx = np.zeros(0, int)
    starts: list[tuple[float, float, str, str]] = []  # x, y, label, colour
    for k, a in enumerate(agents):
        p, color = poses[a], PALETTE[k % len(PALETTE)]
        valid = ~np.isnan(p[:, 0])
        ax.plot(p[:, 0], p[:, 1], color=color, linewidth=1.4, label=a, zorder=4, gid=f"path:{a}")
        foot = scene.footprints.get(a)
        radius = foot.radius if foot else None
        idx = footprint_indices(times, valid, every)
        all_idx = np.union1d(all_idx, idx)
        idx = moved(p, idx, 0.25 * float(radius) if radius else 0.01 * extent)
        xy = p[idx, :2]
        heading = np.c_[np.cos(p[idx, 2]), np.sin(p[idx, 2])]
        if radius:
            ax.add_collection(
                EllipseCollection(
                    np.full(len(idx), 2 * radius),
                    np.full(len(idx), 2 * radius),
                    0.0,
                    units="xy",
                    offsets=xy,
                    offset_transform=ax.transData,
                    facecolors="none",
                    edgecolors=color,
                    linewidths=0.8,
                    zorder=5,
                    gid=f"footprints:{a}",
                )
            )
            heads = np.stack([xy, xy + float(radius) * heading], 1)
            ax.add_collection(
                LineCollection(
                    heads,  # type: ignore[arg-type]  # an (n, 2, 2) array
                    colors=color,
                    linewidths=1.0,
                    zorder=5,
                    gid=f"headings:{a}",
                )
            )
        else:
            # no footprint size known: a small pose triangle pointing along the heading, which
            # cannot be mistaken for a piece of path (a heading line could)
            size = 0.018 * max(extent, 1e-9)
            side = np.c_[-heading[:, 1], heading[:, 0]]
            tri = np.stack(
                [
                    xy + size * heading,
                    xy - 0.6 * size * heading + 0.55 * size * side,
                    xy - 0.6 * size * heading - 0.55 * size * side,
                ],
                1,
            )
            ax.add_collection(
                PolyCollection(
                    tri,  # type: ignore[arg-type]  # an (n, 3, 2) array
                    facecolors=color,
                    edgecolors="white",
                    linewidths=0.4,
                    alpha=0.9,
                    zorder=5,
                    gid=f"footprints:{a}",
                )
            )
        if valid.any():
            x0, y0 = p[np.flatnonzero(valid)[0], :2]
            ax.plot([x0], [y0], marker="s", color=color, markersize=5, zorder=6)
            starts.append((float(x0), float(y0), start_label(a, letter[a]), color))
    draw_guides(ax, scene, instance, agents)
    draw_payloads(ax, trace, instance, all_idx)
    changes = mode_changes(trace, instance, agents, modes)
    stride = max(1, math.ceil(len(changes) / MAX_NUMBERS))
    at = np.full((len(changes), 2), np.nan)
    who = np.array([c[2] for c in changes], dtype=object)
    when = np.array([c[0] for c in changes], dtype=float)
    for a in agents:  # positions at the change times, one interpolation per agent
        rows = np.flatnonzero(who == a)
        valid = ~np.isnan(poses[a][:, 0])
        if rows.size and valid.any():
            ts = when[rows]
            at[rows] = np.c_[
                np.interp(ts, times[valid], poses[a][valid, 0]),
                np.interp(ts, times[valid], poses[a][valid, 1]),
            ]
    placed: list[tuple[float, float]] = []
    tol = 0.015 * max(extent, 1e-9)
    crowded = False
    for k, ((_t, _step, a, _target, n), (x, y)) in enumerate(zip(changes, at, strict=True)):
        if k % stride == 0 and not np.isnan(x):  # labels at one spot stack upwards
            near = sum(abs(x - px) < tol and abs(y - py) < tol for px, py in placed)
            placed.append((x, y))
            if near > MAX_STACK:
                continue
            crowded |= near == MAX_STACK
            ax.annotate(
                f"{n}{letter[a]}" if near < MAX_STACK else "…",
                (x, y),
                xytext=(4, 4 + 9 * near),
                textcoords="offset points",
                fontsize=7.5,
                color="#111111",
                path_effects=HALO,
                zorder=8,
                gid="change",
            )
    if len(at):
        ax.scatter(at[:, 0], at[:, 1], s=10, color="#111111", zorder=7, gid="changes")
    hits = collision_marks(trace, instance)
    if hits:  # over the paths and the change numbers: the thing a reader must not miss
        ax.plot(
            [h[1] for h in hits], [h[2] for h in hits], zorder=9, gid="collisions", **COLLISION_MARK
        )
        x0, x1, y0, y1 = limits or scene_extent(trace, instance)
        for x, y, text in collision_labels(hits, 0.02 * max(x1 - x0, y1 - y0)):
            ax.annotate(
                text,
                (x, y),
                xytext=(6, -11),
                textcoords="offset points",
                fontsize=7.5,
                color=COLLISION_MARK["color"],
                path_effects=HALO,
                zorder=9,
                gid="collision-label",
            )
    if overlay is not None:
        overlay(ax)
    x0, x1, y0, y1 = limits or scene_extent(trace, instance)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")  # the limits stay: the box takes the shape
    for (x, y, text, color), row in zip(starts, start_rows(ax, starts), strict=True):
        ax.annotate(
            text,
            (x, y),
            xytext=(-6, -12 - START_ROW * row),
            textcoords="offset points",
            fontsize=8,
            fontweight="bold",
            color=color,
            path_effects=HALO,
            zorder=7,
            gid="start",
        )
    ax.grid(color="#E0E0E0", linewidth=0.6)
    unit = scene.unit
    ax.set_xlabel(f"x ({unit})" if unit else "x")
    ax.set_ylabel(f"y ({unit})" if unit else "y")
    if agents:
        # "best" scans every plotted point: fine for a short run, seconds for a long one
        # outside the plot, never over a path or a wall: below a wide scene, beside a tall one
        handles = _legend(ax, trace, every, bool(len(at)), bool(hits))
        if wide(limits or scene_extent(trace, instance)):  # the layout makes room below
            ax.figure.legend(
                handles=handles, loc="outside lower center", fontsize=7.5, frameon=False, ncol=3
            )
        else:
            ax.legend(
                handles=handles,
                loc="upper left",
                bbox_to_anchor=(1.01, 1.0),
                fontsize=7.5,
                frameon=False,
            )
    notes = [f"numbers shown on every {_ordinal(stride)} mode change"] if stride > 1 else []
    if crowded:
        notes.append(f"where changes crowd one spot, the first {MAX_STACK} and …")
    if notes:
        ax.text(0.01, 0.01, "; ".join(notes), transform=ax.transAxes, fontsize=7, color="#666666")


def _ordinal(k: int) -> str:
    """2nd, 3rd, 11th, 21st, ..."""
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def wide(limits: tuple[float, float, float, float]) -> bool:
    """Whether a scene is wider than tall enough to take its legend below, not beside."""
    return (limits[3] - limits[2]) < 0.6 * (limits[1] - limits[0])


def _legend(ax: Any, trace: Trace, every: float, changes: bool, hits: bool) -> list[Any]:
    """Robots and guide paths as drawn, then what the marks mean: the start (0X), the
    numbered mode changes (1X: the first, by robot X), collisions, footprints and payload
    snapshots (every so many seconds), obstacles and walls — each only if the plot has
    it."""
    handles, _ = ax.get_legend_handles_labels()
    grey = "#555555"
    handles.append(
        Line2D(
            [],
            [],
            marker="s",
            color=grey,
            linestyle="none",
            markersize=4,
            label="0X: start of robot X",
        )
    )
    if changes:
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                color="#111111",
                linestyle="none",
                markersize=3,
                label="nX: n-th mode change, by robot X",
            )
        )
    if hits:
        handles.append(
            Line2D(
                [],
                [],
                **{**COLLISION_MARK, "markersize": 9},
                label="first collision of each robot or payload, its time",
            )
        )
    scene = scene_of(trace)
    sized = [a in scene.footprints for a in planar_agents(trace)]
    if any(sized):
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                markerfacecolor="none",
                color=grey,
                linestyle="none",
                markersize=7,
                label=f"footprint and heading, every {every:g} s",
            )
        )
    if not all(sized):
        handles.append(
            Line2D(
                [],
                [],
                marker=">",
                color=grey,
                linestyle="none",
                markersize=5,
                label=f"pose (no footprint), every {every:g} s",
            )
        )
    for k, name in enumerate(payload_names(trace)):
        handles.append(
            Patch(
                facecolor=PALETTE[(k + 5) % len(PALETTE)],
                alpha=0.35,
                edgecolor="#333333",
                label=f"{name}, every {every:g} s",
            )
        )
    if scene.obstacles:
        handles.append(Patch(facecolor="#9A9A9A", edgecolor=grey, label="obstacle"))
    if scene.walls:
        handles.append(Line2D([], [], color="#222222", linewidth=2.5, label="wall"))
    return handles


# ---------------------------------------------------------------------- flow
def draw_flow(ax: Any, trace: Trace, instance: int, agent: str) -> None:
    """Each state component against time, segment by segment in the active mode's colour."""
    times = trace.sample_times
    meta = agent_meta(trace, agent)
    colors = team_colors(trace.meta["agents"])
    iv = main_lane_intervals(trace, instance, agent)
    starts, mode_of = iv["start"], iv["mode"]
    s = trace.samples[agent][:, instance]
    tr = pick(trace.transitions, instance).where(agent=agent)
    ts = np.sort(tr["t"][tr["cause"] != "init"])
    used: dict[str, str] = {}
    if len(times) > 1 and len(starts):
        runs = mode_runs(times, s, starts, ts)
        for k, name in enumerate(meta["state"]):
            y = s[:, k]
            lines = [np.c_[times[a : b + 1], y[a : b + 1]] for a, b, _ in runs]
            ax.add_collection(
                LineCollection(
                    lines,
                    colors=[colors.get(mode_of[m], "#777777") for _, _, m in runs],
                    linewidths=1.4,
                    zorder=3,
                    linestyles=LINESTYLES[k % len(LINESTYLES)],
                    gid=f"state:{name}",
                )
            )
        for _, _, m in runs:
            used[mode_of[m]] = colors.get(mode_of[m], "#777777")
    if len(ts):
        ax.vlines(
            ts,
            0,
            1,
            transform=ax.get_xaxis_transform(),
            colors="#888888",
            linestyles="dotted",
            linewidth=0.7,
            zorder=1,
            gid="transitions",
        )
    ax.autoscale_view()
    ax.set_xlim(float(times[0]) if len(times) else 0.0, end_time(trace, instance))
    ax.set_ylabel(", ".join(meta["state"]))
    ax.set_title(agent, fontsize=10, loc="left")
    ax.grid(color="#E8E8E8", linewidth=0.6)
    handles = [
        Line2D([], [], color=c, linewidth=2, label=m)
        for m, c in sorted(
            used.items(), key=lambda mc: list(colors).index(mc[0]) if mc[0] in colors else 0
        )
    ]
    if len(meta["state"]) > 1:  # components differ by line style, modes by colour
        handles += [
            Line2D(
                [],
                [],
                color="#444444",
                linewidth=1.2,
                label=name,
                linestyle=LINESTYLES[k % len(LINESTYLES)],
            )
            for k, name in enumerate(meta["state"])
        ]
    if handles:
        ax.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            fontsize=8,
            frameon=False,
            title="modes / state" if len(meta["state"]) > 1 else "modes",
        )


def mode_runs(
    times: np.ndarray, s: np.ndarray, starts: np.ndarray, switches: np.ndarray
) -> list[tuple[int, int, int]]:
    """(first, last sample, interval) of each stretch sampled in one mode interval.

    A segment between two samples with a transition strictly between them is not drawn: the
    state may jump there (a reset) and a straight line would invent values; the gap is one
    sample period wide. Stretches are whole polylines so dash patterns read as one line.
    """
    mid = (times[:-1] + times[1:]) / 2
    key = np.clip(np.searchsorted(starts, mid, side="right") - 1, 0, len(starts) - 1)
    alive = ~(np.isnan(s[:-1]).any(axis=1) | np.isnan(s[1:]).any(axis=1))
    crossed = np.searchsorted(switches, times[1:], side="left") > np.searchsorted(
        switches, times[:-1], side="right"
    )
    key = np.where(alive & ~crossed, key, -1)
    edges = np.flatnonzero(np.diff(key)) + 1
    runs = []
    for a, b in zip(np.r_[0, edges], np.r_[edges, len(key)], strict=True):
        if key[a] >= 0:
            runs.append((int(a), int(b), int(key[a])))  # segments a..b-1 = samples a..b
    return runs


# ---------------------------------------------------------------------- figure and file
def trajectory_figure(
    trace: Trace,
    instance: int = 0,
    every: float | None = None,
    modes: Sequence[str] | None = None,
    xlim: tuple[float, float] | None = None,
    ylim: tuple[float, float] | None = None,
    size: tuple[float, float] | None = None,
    overlay: Callable[[Any], None] | None = None,
) -> Figure:
    """Planar agents in one equal-aspect plot; flow agents one time plot each below it.

    ``every``: seconds between drawn footprints (default: about ten along the run);
    ``modes``: the mode paths whose changes are numbered (default: every leaf transition);
    ``xlim``, ``ylim``: the planar plot's limits (default: the scene, see
    :func:`~.scene.scene_extent`); ``size``: the figure's width and height in inches
    (default: 8 wide, as tall as the scene's shape asks); ``overlay``: drawn on the
    planar plot before its legend (see :func:`draw_planar`).
    """
    planar, flows = planar_agents(trace), flow_agents(trace)
    limits = None
    width = size[0] if size else 8.0
    if planar:
        x0, x1, y0, y1 = scene_extent(trace, instance)
        limits = (*(xlim or (x0, x1)), *(ylim or (y0, y1)))
        if ylim is None:
            limits = room_below_starts(trace, instance, limits, width - 1.2)
    aspect = (limits[3] - limits[2]) / max(limits[1] - limits[0], 1e-12) if limits else 0.5
    # the planar axes' width: the figure's, less the y labels and a legend at the side
    axes_w = width - 1.2 - (0.0 if limits is None or wide(limits) else 2.4)
    legend_h = 0.0 if limits is None or not wide(limits) else 0.55  # three rows below
    planar_height = axes_w * float(np.clip(aspect, 0.12, 1.6)) + 0.45 + legend_h if planar else 0.0
    heights = ([max(planar_height, 2.0)] if planar else []) + [1.8] * len(flows)
    with rc_context({"font.family": FONT}):
        fig = Figure(figsize=(width, size[1] if size else 0.45 + max(sum(heights), 2.0)), dpi=100)
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(max(len(heights), 1), 1, height_ratios=heights or [1])
        row = 0
        if planar:
            draw_planar(fig.add_subplot(grid[0]), trace, instance, every, modes, limits, overlay)
            row = 1
        for k, agent in enumerate(flows):
            ax = fig.add_subplot(grid[row + k])
            draw_flow(ax, trace, instance, agent)
            if k == len(flows) - 1:
                ax.set_xlabel("time (s)")
        title = str(trace.meta.get("team", ""))
        if trace.n > 1:
            title += f" — instance {instance}"
        fig.suptitle(title)
        fig.set_layout_engine("constrained")
    return fig


def room_below_starts(
    trace: Trace, instance: int, limits: tuple[float, float, float, float], axes_w: float
) -> tuple[float, float, float, float]:
    """``limits`` with the bottom lowered where a start label (12 pt under its start, about
    18 pt to its lower edge) would cross the plot's lower edge, and the axis strike through
    it: robots that start on the scene's lowest line (a flat scene's). ``axes_w``: the
    plot's width in inches, which at equal aspect sets the points per metre."""
    x0, x1, y0, y1 = limits
    firsts = []
    for a in planar_agents(trace):
        y = pose(trace, a, instance)[:, 1]
        if (~np.isnan(y)).any():
            firsts.append(float(y[~np.isnan(y)][0]))
    if not firsts:
        return limits
    side = axes_w * 72.0  # points across the plot; at most 1.6 times that tall
    per_pt = max((x1 - x0) / side, (y1 - y0) / (1.6 * side))
    below = min(firsts) - 18.0 * per_pt
    return (x0, x1, min(y0, below), y1)


def write_trajectories(trace: Trace, path: str | os.PathLike, instance: int = 0, **kw: Any) -> Path:
    """Write :func:`trajectory_figure` as .png or .svg (chosen by the extension)."""
    fig = trajectory_figure(trace, instance, **kw)
    try:
        return save_figure(fig, path, tight=kw.get("size") is None)
    finally:
        fig.clear()

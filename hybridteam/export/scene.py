"""The scene of a planar run: the world it moved in and the payloads it carried.

Shared by the trajectory plot and the animation: what is a robot and what is a load in a
trace, the walls, obstacles, regions and guide paths, payload outlines at their poses, and
the extent of all of it, which both views fit their axes to. What is drawn of the world is
the trace's typed :class:`~hybridteam.world.scene.SceneDescription` (:func:`scene_of`),
which the world components described.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.patches import Circle, Polygon

from hybridteam.export.style import PALETTE
from hybridteam.export.timeline import agent_meta
from hybridteam.trace import Trace
from hybridteam.world.scene import (
    DEFAULT_PAYLOAD_SHAPE,
    CircleObstacle,
    CollisionMark,
    PayloadShape,
    SceneDescription,
    WallObstacle,
)


# ---------------------------------------------------------------------- what is what
def scene_of(trace: Trace) -> SceneDescription:
    """What the trace says the views draw of its world (its components' descriptions)."""
    return SceneDescription.from_meta(trace.meta)


def payload_names(trace: Trace) -> list[str]:
    """The payloads the trace has pose samples of, in declaration order."""
    return [p for p in scene_of(trace).payloads if p in trace.samples]


def planar_agents(trace: Trace) -> list[str]:
    """Agents with x and y in their state (payloads excluded: they are drawn as loads)."""
    payloads = set(payload_names(trace))
    return [
        a["name"]
        for a in trace.meta["agents"]
        if a["name"] not in payloads and {"x", "y"} <= set(a["state"])
    ]


def flow_agents(trace: Trace) -> list[str]:
    """Agents without a position: drawn as state against time (agents with no state at
    all, such as an operator, are not drawn)."""
    payloads = set(payload_names(trace))
    return [
        a["name"]
        for a in trace.meta["agents"]
        if a["name"] not in payloads and a["state"] and not {"x", "y"} <= set(a["state"])
    ]


def pose(trace: Trace, name: str, instance: int) -> np.ndarray:
    """(K, 3) x, y, theta of an agent or payload (theta 0 when its state has none)."""
    try:
        states = agent_meta(trace, name)["state"]
    except KeyError:
        states = ["x", "y", "theta"]
    s = trace.samples[name][:, instance]
    out = np.zeros((len(s), 3))
    for k, key in enumerate(("x", "y", "theta")):
        if key in states:
            out[:, k] = s[:, states.index(key)]
        else:
            out[:, k] = np.where(np.isnan(s[:, 0]), np.nan, 0.0)
    return out


# ---------------------------------------------------------------------- world and payloads
def draw_world(ax: Any, scene: SceneDescription) -> None:
    """Walls, obstacles and labelled regions, under everything else."""
    for region in scene.regions:
        pts = np.asarray(region.outline, float)
        ax.add_patch(
            Polygon(
                pts,
                closed=True,
                facecolor="#F2E6B8",
                edgecolor="#C8B46A",
                alpha=0.6,
                zorder=0,
                gid="region",
            )
        )
        if region.label:
            cx, cy = pts.mean(axis=0)
            ax.text(
                cx,
                cy,
                region.label,
                ha="center",
                va="center",
                fontsize=8,
                color="#7A6A2A",
                zorder=1,
                gid="region-label",
            )
    thin = []
    for ob in scene.obstacles or ():
        style = {
            "facecolor": "#9A9A9A",
            "edgecolor": "#555555",
            "zorder": 1.8,  # over the grid
            "gid": "obstacle",
        }
        if isinstance(ob, CircleObstacle):
            ax.add_patch(Circle((ob.x, ob.y), ob.r, **style))
        elif isinstance(ob, WallObstacle):  # no thickness: a heavy grey stroke
            thin.append(np.asarray((ob.start, ob.end), float))
        else:
            ax.add_patch(Polygon(np.asarray(ob.corners, float), closed=True, **style))
    if thin:
        ax.add_collection(
            LineCollection(
                thin,
                colors="#9A9A9A",
                linewidths=4.0,
                zorder=1.8,
                capstyle="round",
                gid="obstacle-walls",
            )
        )
    walls = np.asarray(scene.walls, float).reshape(-1, 4)
    if len(walls):
        ax.add_collection(
            LineCollection(
                walls.reshape(-1, 2, 2),  # type: ignore[arg-type]  # an (n, 2, 2) array
                colors="#222222",
                linewidths=2.5,
                zorder=2,
                gid="walls",
            )
        )


def draw_guides(ax: Any, scene: SceneDescription, instance: int, agents: Sequence[str]) -> None:
    """Planned paths of ``instance`` (:class:`~hybridteam.world.scene.GuidePath`), dashed
    in the agent's colour."""
    for entry in scene.paths_of(instance):
        if entry.agent not in agents:
            continue
        pts = np.asarray(entry.points, float)
        color = PALETTE[list(agents).index(entry.agent) % len(PALETTE)]
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            color=color,
            linewidth=0.9,
            linestyle=(0, (4, 3)),
            alpha=0.8,
            zorder=3,
            label=f"{entry.agent} guide path",
            gid=f"guide:{entry.agent}",
        )


#: how a collision is marked, in the trajectories and the animation alike
COLLISION_MARK: dict[str, Any] = {
    "marker": "*",
    "markersize": 13,
    "color": "#CC0000",
    "markeredgecolor": "white",
    "markeredgewidth": 0.8,
    "linestyle": "none",
}


def collision_marks(trace: Trace, instance: int) -> list[tuple[float, float, float, str]]:
    """(t, x, y, who) of where each robot, pair of robots or payload first collided in
    ``instance``, in time order (``world.collisions``, recorded by the obstacles component
    under ``on_collision: warn`` or ``outcome``): a run told to go on through collisions
    shows where they were, not only a list in the summary."""
    marks: tuple[CollisionMark, ...] = scene_of(trace).collisions_of(instance)
    return sorted((c.t, c.x, c.y, c.who) for c in marks)


def scene_extent(trace: Trace, instance: int) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) of everything the planar plot draws: walls, obstacles, regions,
    guide paths, the robots' paths with their footprints, and the payloads' outlines. The
    axes are fitted to it, so a narrow corridor fills the plot instead of a square around
    it (equal aspect would otherwise widen the shorter side to the figure's shape)."""
    scene = scene_of(trace)
    pts = [np.asarray(scene.walls, float).reshape(-1, 2)]
    for ob in scene.obstacles or ():
        if isinstance(ob, CircleObstacle):
            pts.append(np.array([[ob.x - ob.r, ob.y - ob.r], [ob.x + ob.r, ob.y + ob.r]]))
        else:
            corners = (ob.start, ob.end) if isinstance(ob, WallObstacle) else ob.corners
            pts.append(np.asarray(corners, float).reshape(-1, 2))
    for region in scene.regions:
        pts.append(np.asarray(region.outline, float).reshape(-1, 2))
    for entry in scene.paths_of(instance):
        pts.append(np.asarray(entry.points, float).reshape(-1, 2))
    for a in planar_agents(trace):
        xy = pose(trace, a, instance)[:, :2]
        xy = xy[np.isfinite(xy).all(axis=1)]
        foot = scene.footprints.get(a)
        r = foot.radius if foot else 0.0
        if len(xy):  # rounding is monotone: min(x - r) is min(x) - r, exactly
            pts += [xy.min(axis=0)[None] - r, xy.max(axis=0)[None] + r]
    for name in payload_names(trace):
        p = pose(trace, name, instance)
        p = p[np.isfinite(p).all(axis=1)]
        pts.append(payload_outline(payload_shape(trace, name), *p.T).reshape(-1, 2))
    lows, highs = [], []
    for piece in pts:  # each piece's corners: no copy of every point into one array
        piece = piece[np.isfinite(piece).all(axis=1)]
        if len(piece):
            lows.append(piece.min(axis=0))
            highs.append(piece.max(axis=0))
    if not lows:
        return (-1.0, 1.0, -1.0, 1.0)
    (x0, y0), (x1, y1) = np.min(lows, axis=0), np.max(highs, axis=0)
    span = max(x1 - x0, y1 - y0, 1e-9)
    pad_x, pad_y = max(0.04 * (x1 - x0), 0.005 * span), max(0.04 * (y1 - y0), 0.005 * span)
    return (float(x0 - pad_x), float(x1 + pad_x), float(y0 - pad_y), float(y1 + pad_y))


def payload_shape(trace: Trace, name: str) -> PayloadShape:
    """A payload's shape from the trace (a 0.3 m box where the trace does not say)."""
    return scene_of(trace).payloads.get(name, DEFAULT_PAYLOAD_SHAPE)


def payload_outline(shape: PayloadShape, x: Any, y: Any, th: Any) -> np.ndarray:
    """Corners of a payload shape at a pose, ``(4, 2)``, or at K poses given as arrays,
    ``(K, 4, 2)`` (a bar is a thin rectangle)."""
    w, d = shape.size
    cx, cy = np.array([-w, w, w, -w]) / 2, np.array([-d, -d, d, d]) / 2
    x, y, th = (np.asarray(v, float)[..., None] for v in (x, y, th))
    c, s = np.cos(th), np.sin(th)
    return np.stack([cx * c - cy * s + x, cx * s + cy * c + y], -1)


def moved(
    p: np.ndarray, indices: np.ndarray, step: float, turn: float = math.radians(15.0)
) -> np.ndarray:
    """Of the poses at ``indices``, those where the body has moved by more than ``step`` or
    turned by more than ``turn`` since the last one kept: a robot that waits 13 s while the
    team docks is drawn once, not as a pile of identical footprints."""
    keep: list[int] = []
    for i in indices.tolist():
        if keep:
            last = p[keep[-1]]
            dist = math.hypot(p[i, 0] - last[0], p[i, 1] - last[1])
            dth = abs((p[i, 2] - last[2] + math.pi) % (2 * math.pi) - math.pi)
            if not (dist > step or dth > turn):
                continue
        keep.append(i)
    return np.array(keep, int)


def draw_payloads(ax: Any, trace: Trace, instance: int, indices: np.ndarray) -> None:
    for k, name in enumerate(payload_names(trace)):
        p = pose(trace, name, instance)
        ok = indices[~np.isnan(p[indices, 0])] if len(indices) else indices
        shape = payload_shape(trace, name)
        ok = moved(p, ok, 0.15 * min(shape.measures))
        polys = payload_outline(shape, *p[ok].T)
        color = PALETTE[(k + 5) % len(PALETTE)]
        ax.add_collection(
            PolyCollection(
                polys,  # type: ignore[arg-type]  # an (n, k, 2) array
                facecolors=color,
                edgecolors="#333333",
                alpha=0.35,
                linewidths=0.6,
                zorder=3,
                gid=f"payload:{name}",
            )
        )
        ax.plot(p[:, 0], p[:, 1], color=color, linewidth=0.8, linestyle="dotted", zorder=3)

"""Where the built-in diagram's edges go: their ends, arcs, and routes around mode boxes.

Most edges of a diagram join neighbouring layers and a gentle arc serves them. An edge that
skips a layer, or a message between panels, may find every arc through some unrelated box;
it is then routed: a shortest path on a grid of free points (5 pt apart, obstacles grown
by a margin) inside the innermost composite that holds both ends, found by Dijkstra
(scipy's csgraph), then pulled straight wherever a straight segment clears every obstacle,
and drawn with rounded corners. Deterministic, like the rest of the layout.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from hybridteam.export.layout import TITLE, Box, Layout
from hybridteam.world.geometry import segments_intersect

Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (points, y down)
Point = tuple[float, float]
STEP = 5.0  # grid spacing, points
MARGIN = 6.0  # how far a route keeps from a box


def inside(points: ArrayLike, rects: list[Rect], grow: float = 0.0) -> np.ndarray:
    """Per point, whether it lies strictly inside any rectangle grown by ``grow``."""
    p = np.asarray(points, float).reshape(-1, 2)
    if not rects:
        return np.zeros(len(p), bool)
    r = np.asarray(rects, float)
    x, y = p[:, :1], p[:, 1:]
    hit = (r[:, 0] - grow < x) & (x < r[:, 2] + grow) & (r[:, 1] - grow < y) & (y < r[:, 3] + grow)
    return np.logical_or.reduce(hit, axis=1)


def _grown_edges(rects: list[Rect], grow: float) -> np.ndarray:
    """The four sides of every rectangle grown by ``grow``: ``(4 r, 4)`` segments."""
    r = np.asarray(rects, float)
    x0, y0, x1, y1 = r[:, 0] - grow, r[:, 1] - grow, r[:, 2] + grow, r[:, 3] + grow
    return np.concatenate(
        [np.c_[x0, y0, x1, y0], np.c_[x1, y0, x1, y1], np.c_[x1, y1, x0, y1], np.c_[x0, y1, x0, y0]]
    )


def _clear_to(
    a: Point, ends: list[Point], rects: list[Rect], grow: float, edges: np.ndarray
) -> np.ndarray:
    """Whether each segment from ``a`` to one of ``ends`` stays out of every grown
    rectangle (touching its border is allowed only at a distance: the rectangles are
    grown); ``edges`` are their sides (:func:`_grown_edges`). Every segment is tested in
    one batch, each as it would be alone."""
    if not rects:
        return np.ones(len(ends), bool)
    segs = np.array([[a[0], a[1], b[0], b[1]] for b in ends], float).reshape(-1, 4)
    crossed = segments_intersect(segs, edges).any(axis=1)
    return (
        ~crossed
        & ~inside(np.array([a]), rects, grow)[0]
        & ~inside(np.array(ends, float), rects, grow)
    )


def route(pa: Point, pb: Point, obstacles: list[Rect], bounds: Rect) -> list[Point] | None:
    """A polyline from ``pa`` to ``pb`` clear of ``obstacles`` (by :data:`MARGIN`) within
    ``bounds``, or None when the grid finds no way through."""
    x0, y0, x1, y1 = bounds
    nx_, ny_ = max(int((x1 - x0) // STEP), 2), max(int((y1 - y0) // STEP), 2)
    xs = x0 + (np.arange(nx_) + 0.5) * (x1 - x0) / nx_
    ys = y0 + (np.arange(ny_) + 0.5) * (y1 - y0) / ny_
    gx, gy = np.meshgrid(xs, ys)
    pts = np.c_[gx.ravel(), gy.ravel()]
    free = ~inside(pts, obstacles, MARGIN)
    start, goal = _nearest(pts, free, pa), _nearest(pts, free, pb)
    if start is None or goal is None:
        return None
    graph = _grid_graph(ny_, nx_, free, (x1 - x0) / nx_, (y1 - y0) / ny_)
    # (scipy-stubs types indices as an array only; scipy documents one int as well)
    dist, pred = dijkstra(
        graph,
        indices=start,  # type: ignore[call-overload]
        return_predecessors=True,
    )
    if not math.isfinite(dist[goal]):
        return None
    cells = [goal]
    while cells[-1] != start:
        cells.append(int(pred[cells[-1]]))
    path = [tuple(pts[c]) for c in reversed(cells)]
    return [pa, *_straighten(path, obstacles), pb]


def _nearest(pts: np.ndarray, free: np.ndarray, p: Point) -> int | None:
    if not free.any():
        return None
    d = np.hypot(pts[:, 0] - p[0], pts[:, 1] - p[1])
    d[~free] = np.inf
    return int(np.argmin(d))


def _grid_graph(ny: int, nx: int, free: np.ndarray, dx: float, dy: float) -> coo_matrix:
    """8-neighbour links between free grid points, weighted by their distance."""
    idx = np.arange(ny * nx).reshape(ny, nx)
    rows, cols, w = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = idx[max(0, -di) : ny - max(0, di), max(0, -dj) : nx - max(0, dj)]
        b = idx[max(0, di) : ny - max(0, -di) or None, max(0, dj) : nx - max(0, -dj) or None]
        a, b = a.ravel(), b.ravel()
        ok = free[a] & free[b]
        rows.append(a[ok])
        cols.append(b[ok])
        w.append(np.full(ok.sum(), math.hypot(di * dy, dj * dx)))
    r, c, ww = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    return coo_matrix((np.r_[ww, ww], (np.r_[r, c], np.r_[c, r])), shape=(ny * nx, ny * nx))


def _straighten(path: list[Point], obstacles: list[Rect]) -> list[Point]:
    """Keep a grid point only where the straight segment past it would hit an obstacle:
    from each kept point, on to the farthest later point it sees (all of them tested in
    one batch), or the next one."""
    grow = MARGIN - 0.5
    edges = _grown_edges(obstacles, grow) if obstacles else np.zeros((0, 4))
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        later = path[i + 2 :]
        seen = (
            np.flatnonzero(_clear_to(path[i], later, obstacles, grow, edges))
            if later
            else np.zeros(0, int)
        )
        j = i + 2 + int(seen[-1]) if seen.size else i + 1
        out.append(path[j])
        i = j
    return out


def along(points: list[Point], ts: tuple[float, ...]) -> list[tuple[Point, Point]]:
    """Points at fractions ``ts`` of a polyline's length, each with its unit direction."""
    p = np.asarray(points, float)
    seg = np.diff(p, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.r_[0.0, np.cumsum(length)]
    out = []
    for t in ts:
        s = t * cum[-1]
        k = min(int(np.searchsorted(cum, s, "right")) - 1, len(seg) - 1)
        f = (s - cum[k]) / length[k] if length[k] > 0 else 0.0
        at = p[k] + f * seg[k]
        d = seg[k] / max(length[k], 1e-9)
        out.append(((float(at[0]), float(at[1])), (float(d[0]), float(d[1]))))
    return out


def rounded(points: list[Point], radius: float = 6.0) -> tuple[list[Point], list[np.uint8]]:
    """Vertices and matplotlib Path codes of the polyline with quadratic corners."""
    from matplotlib.path import Path

    verts, codes = [points[0]], [Path.MOVETO]
    for k in range(1, len(points) - 1):
        prev, corner, nxt = (np.asarray(points[j], float) for j in (k - 1, k, k + 1))
        a, b = prev - corner, nxt - corner
        r = min(radius, np.hypot(*a) / 2, np.hypot(*b) / 2)
        p = corner + a / max(np.hypot(*a), 1e-9) * r
        q = corner + b / max(np.hypot(*b), 1e-9) * r
        verts += [tuple(p), tuple(corner), tuple(q)]
        codes += [Path.LINETO, Path.CURVE3, Path.CURVE3]
    verts.append(points[-1])
    codes.append(Path.LINETO)
    return verts, codes


# ------------------------------------------------------------------ edges of a layout
def _clip(box: Box, toward: tuple[float, float]) -> tuple[float, float]:
    """Where the segment from the box's centre to ``toward`` leaves the box."""
    cx, cy = box.x + box.w / 2, box.y + box.h / 2
    dx, dy = toward[0] - cx, toward[1] - cy
    t = min(
        box.w / 2 / abs(dx) if dx else float("inf"), box.h / 2 / abs(dy) if dy else float("inf")
    )
    t = min(t, 1.0)
    return cx + dx * t, cy + dy * t


def ends(layout: Layout, u: str, v: str) -> tuple[tuple[float, float], tuple[float, float]]:
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


def bezier(pa, pb, rad: float, t: float) -> tuple[float, float]:
    """Point at ``t`` of matplotlib's arc3 curve from ``pa`` to ``pb``: its control point is
    the chord's middle moved by rad * (-dy, dx) in these data coordinates (y points down)."""
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    cx, cy = (pa[0] + pb[0]) / 2 - rad * dy, (pa[1] + pb[1]) / 2 + rad * dx
    return (
        (1 - t) ** 2 * pa[0] + 2 * t * (1 - t) * cx + t * t * pb[0],
        (1 - t) ** 2 * pa[1] + 2 * t * (1 - t) * cy + t * t * pb[1],
    )


def unrelated(layout: Layout, u: str, v: str) -> list[Box]:
    """The boxes an edge from ``u`` to ``v`` must not cross: all but the two ends, their
    containers and what they contain."""
    related = set(layout.up[u]) | set(layout.up[v])
    return [
        b
        for n, b in layout.boxes.items()
        if n not in related and u not in layout.up[n] and v not in layout.up[n]
    ]


def bend(layout: Layout, u: str, v: str, pa, pb, base: float, message: bool) -> tuple[float, int]:
    """The first curvature (from gentle to strong, either side) whose curve stays clear of
    boxes unrelated to the two ends and inside the box holding both, and how many of its
    sample points still break that (0 when none; the edge is then routed instead).

    The bulge is capped (messages span panels: a strong bend would leave the picture).
    """
    rects = [(b.x, b.y, b.x + b.w, b.y + b.h) for b in unrelated(layout, u, v)]
    box = container(layout, u, v)
    chord = max(((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2) ** 0.5, 1.0)
    cap = min(0.35, 200.0 / chord) if message else 160.0 / chord
    steps = [base] + [sign * (base + d) for d in (0.25, 0.5, 0.8, 1.1) for sign in (1, -1)]
    best, fewest = base, None
    for rad in [r for r in steps if abs(r) <= max(cap, base)]:
        points = [bezier(pa, pb, rad, k / 64) for k in range(1, 64)]
        hits = int(inside(points, rects, 2.0).sum())
        if box is not None:
            hits += int((~inside(points, [box], -2.0)).sum())
        if hits == 0:
            return rad, 0
        if fewest is None or hits < fewest:
            best, fewest = rad, hits
    return best, fewest or 0


def container(layout: Layout, u: str, v: str) -> Rect | None:
    """The innermost box holding both ends of an edge (None between agents' panels)."""
    common = next((n for n in layout.up[u] if n in layout.up[v]), None)
    if common is None:
        return None
    b = layout.boxes[common]
    return (b.x, b.y, b.x + b.w, b.y + b.h)


def route_edge(layout: Layout, u: str, v: str, pa, pb) -> list[tuple[float, float]] | None:
    """A polyline around the unrelated boxes, inside the innermost box holding both ends
    (the whole picture for a message between panels); it keeps off the ends' own boxes
    (unless one holds the other) and the container's title."""
    rect = lambda b: (b.x, b.y, b.x + b.w, b.y + b.h)  # noqa: E731
    obstacles = [rect(b) for b in unrelated(layout, u, v)]
    for a, other in ((u, v), (v, u)):
        if a not in layout.up[other]:
            obstacles.append(rect(layout.boxes[a]))
    common = next((n for n in layout.up[u] if n in layout.up[v]), None)
    if common is None:
        bounds = (0.0, 0.0, layout.width, layout.height)
    else:
        box = layout.boxes[common]
        bounds = rect(box)
        if common not in (u, v):
            obstacles.append((box.x, box.y, box.x + box.title_w, box.y + TITLE))
    return route(pa, pb, obstacles, bounds)

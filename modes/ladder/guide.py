"""Guide paths: where each robot would like to go, ignoring its partner (paper Sec. 3.1).

A guide path is a cardinal spline through a few control points, resampled to equally
spaced points (160 in the paper). The start, the goal and the two control points on the
edges of the corner square are the paper's; ``alpha`` slides the corner points from the
inner walls (0) to the outer walls (1). The paper shows more control points without
placing them, so two more are optional: on the centre line, ``approach`` before the
corner's entry edge and after its exit edge, so the path runs straight down the middle
until it nears the turn. The spline's ``tension`` is not given either (0 is the
Catmull-Rom spline). Both are in :class:`~hybridteam.modes.ladder.params.Settings`.

Everything is vectorized over n robots, with per-instance work kept elementwise (or in a
per-instance loop), so a path does not depend on the other paths in the batch.
"""

from __future__ import annotations

import numpy as np

from hybridteam.world.geometry import Corridor

#: Spline samples per control-point interval before resampling by arclength.
DENSE_PER_INTERVAL = 64


def alpha_to_across(alpha: np.ndarray, width: float, inset: float) -> np.ndarray:
    """Map alpha (0 inner .. 1 outer) to a fraction of the width, keeping ``inset`` clear."""
    a = np.asarray(alpha, dtype=float)
    return (inset + a * (width - 2.0 * inset)) / width


def control_points(
    corridor: Corridor,
    start: np.ndarray,
    goal: np.ndarray,
    alpha: np.ndarray,
    *,
    approach: float | None = None,
    inset: float = 0.0,
) -> np.ndarray:
    """Control points ``(n, K, 2)`` of n guide paths from ``start`` to ``goal`` (each (n, 2)).

    Order: start, [approach point], corner entry point, corner exit point,
    [departure point], goal. Approach/departure points are on the centre line, ``approach``
    before the entry edge and after the exit edge (omitted when ``approach`` is None).
    """
    start = np.asarray(start, dtype=float).reshape(-1, 2)
    goal = np.asarray(goal, dtype=float).reshape(-1, 2)
    n = start.shape[0]
    alpha = np.broadcast_to(np.asarray(alpha, dtype=float), (n,))
    entry = corridor.corner_entry_point(alpha_to_across(alpha, corridor.width_in, inset))
    exit_ = corridor.corner_exit_point(alpha_to_across(alpha, corridor.width_out, inset))
    points = [start]
    if approach is not None:
        mid_in = corridor.inner_vertex - 0.5 * corridor.width_in * corridor.direction_out
        points.append(np.broadcast_to(mid_in - approach * corridor.direction_in, (n, 2)))
    points += [entry, exit_]
    if approach is not None:
        mid_out = corridor.inner_vertex + 0.5 * corridor.width_out * corridor.direction_in
        points.append(np.broadcast_to(mid_out + approach * corridor.direction_out, (n, 2)))
    points.append(goal)
    return np.stack(points, axis=1)


def cardinal_spline(
    points: np.ndarray, tension: float = 0.0, per_interval: int = DENSE_PER_INTERVAL
) -> np.ndarray:
    """Dense samples ``(n, (K-1) * per_interval + 1, 2)`` of cardinal splines through points.

    Hearn & Baker's form: with ``s = (1 - tension) / 2`` the tangent at P_k is
    ``s (P_{k+1} - P_{k-1})``; the end points are repeated as their own neighbours.
    """
    p = np.asarray(points, dtype=float)
    ext = np.concatenate([p[:, :1], p, p[:, -1:]], axis=1)
    s = 0.5 * (1.0 - tension)
    u = np.arange(per_interval, dtype=float) / per_interval
    u2, u3 = u * u, u * u * u
    w0 = -s * u3 + 2.0 * s * u2 - s * u
    w1 = (2.0 - s) * u3 + (s - 3.0) * u2 + 1.0
    w2 = (s - 2.0) * u3 + (3.0 - 2.0 * s) * u2 + s * u
    w3 = s * u3 - s * u2
    pieces = []
    for k in range(p.shape[1] - 1):
        a, b, c, d = (ext[:, k + j, None, :] for j in range(4))
        pieces.append(w0[:, None] * a + w1[:, None] * b + w2[:, None] * c + w3[:, None] * d)
    pieces.append(p[:, -1:, :])
    return np.concatenate(pieces, axis=1)


def resample(polyline: np.ndarray, count: int) -> np.ndarray:
    """``count`` points equally spaced by arclength along each polyline ``(n, M, 2)``."""
    poly = np.asarray(polyline, dtype=float)
    out = np.empty((poly.shape[0], count, 2))
    for i, line in enumerate(poly):
        d = line[1:] - line[:-1]
        cum = np.concatenate([[0.0], np.cumsum(np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]))])
        at = cum[-1] * (np.arange(count, dtype=float) / (count - 1))
        out[i, :, 0] = np.interp(at, cum, line[:, 0])
        out[i, :, 1] = np.interp(at, cum, line[:, 1])
        out[i, 0], out[i, -1] = line[0], line[-1]
    return out


def guide_paths(
    corridor: Corridor,
    start: np.ndarray,
    goal: np.ndarray,
    alpha: np.ndarray,
    *,
    count: int = 160,
    tension: float = 0.0,
    approach: float | None = None,
    inset: float = 0.0,
) -> np.ndarray:
    """Guide paths ``(n, count, 2)`` for n robots: spline through the control points, resampled."""
    pts = control_points(corridor, start, goal, alpha, approach=approach, inset=inset)
    return resample(cardinal_spline(pts, tension), count)

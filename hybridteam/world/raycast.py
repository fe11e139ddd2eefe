"""Ray casting: the distance along each of many rays to the first wall or disk it meets.

A range sensor answers "how far is the first thing along this beam?". The XR4000 carries
rings of 24 infrared and 24 sonar sensors, the Nomad Scout a ring of 16 sonars; a team of
such robots simulated as an ensemble of m instances fires ``m x beams`` rays at every
sensing instant, so :func:`cast` is vectorized over instances, rays and obstacles at once
(no Python loop over any of them; only over fixed-size blocks of rays, which bounds the
``rays x obstacles`` temporaries and keeps them in cache).

Obstacles come in two shapes. Walls and polygonal obstacles are *segments* ``(s, 4)``
(``x0, y0, x1, y1``, the format of :mod:`hybridteam.world.geometry`; a polygon is its
:func:`polygon_edges`), static and shared by every instance. Round things — other robots,
posts — are *circles* ``(c, 3)`` (``x, y, radius``), either shared or given per instance
``(m, c, 3)`` because robots are where each instance's simulation put them. A circle row of
NaN is no obstacle, so instances with different numbers of neighbours fit one array.

Conventions a caller can rely on:

- Tests are closed: a ray that grazes a segment end or is tangent to a circle hits it, and
  a ray starting on a segment (or inside a circle) reads 0, so a sensor pressed against a
  wall never sees through it.
- A ray collinear with a segment hits it where it first meets it; a ray parallel to a
  segment and off its line misses it. Zero-length segments are points.
- Only elementwise arithmetic, ``sqrt`` and comparisons act on ray/obstacle pairs, and the
  reduction is a minimum, so an instance's readings do not depend on the rest of the batch.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from hybridteam.arrays import every, filled
from hybridteam.world.geometry import as_segments

__all__ = ["Targets", "cast", "cast_at"]

#: A segment within this angle (radians, as a sine) of a ray is treated as parallel to it:
#: beyond it the crossing point is too ill-conditioned to locate, so a near-collinear
#: segment is hit where it first comes within this tolerance of the ray's line.
_EPS_PARALLEL = 1e-9
#: Slack on "the crossing lies within the segment" (a fraction of its length), so a ray
#: through the shared corner of two walls cannot slip between them by rounding.
_EPS_ALONG = 1e-10
#: Relative rounding slack of a cross product of coordinates (a few ulps, generously).
_ROUNDING = 1e-14
#: Ray/obstacle pairs evaluated per block: big enough to amortize the ~40 numpy calls of a
#: block, small enough (256 KB per scratch array) to stay near the cache.
_BLOCK = 1 << 15


def as_circles(circles: np.ndarray | list | None, m: int) -> np.ndarray:
    """Circles as ``(c, 3)`` (shared) or ``(m, c, 3)`` (per instance); None is no circles."""
    if circles is None:
        return np.zeros((0, 3))
    circ = np.asarray(circles, dtype=float)
    if circ.ndim == 1:
        circ = circ[None, :]
    if circ.shape[-1] != 3 or circ.ndim not in (2, 3) or (circ.ndim == 3 and circ.shape[0] != m):
        raise ValueError(f"circles must have shape (c, 3) or ({m}, c, 3), got {circ.shape}")
    return circ


class _Scratch:
    """Scratch arrays reused by every block of one :func:`cast` call, and by later calls
    with the same block shape in this thread (:func:`_scratch`).

    Allocating the kernels' ten temporaries afresh for each block makes glibc hand the freed
    heap top back to the kernel and fault it in again on the next block: three times slower
    on small batches. Views are contiguous ``(rows, cols)`` windows of flat buffers, kept
    per shape: a single run casts the same few shapes thousands of times, and building ten
    views costs as much as a third of a small cast. The kernels write every element they
    read, so what a previous call left in them never shows.
    """

    def __init__(self, rows: int, cols: int) -> None:
        self.floats = np.empty((7, rows * cols))
        self.flags = np.empty((3, rows * cols), dtype=bool)
        self._views: dict[tuple[int, int], list[np.ndarray]] = {}

    def views(self, rows: int, cols: int) -> list[np.ndarray]:
        got = self._views.get((rows, cols))
        if got is None:
            n = rows * cols
            got = self._views[(rows, cols)] = [
                a[:n].reshape(rows, cols) for a in (*self.floats, *self.flags)
            ]
        return got


_kept = threading.local()


def _scratch(rows: int, cols: int) -> _Scratch:
    """This thread's scratch for blocks of ``rows`` rays by ``cols`` obstacles (a handful
    of shapes per run; the oldest are dropped past 16)."""
    kept: dict[tuple[int, int], _Scratch] = _kept.__dict__.setdefault("by_shape", {})
    got = kept.get((rows, cols))
    if got is None:
        if len(kept) >= 16:
            del kept[next(iter(kept))]
        got = kept[(rows, cols)] = _Scratch(rows, cols)
    return got


def _prepare(seg: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per-segment columns of the kernel, computed once per call."""
    ax, ay = seg[:, 0], seg[:, 1]
    ex, ey = seg[:, 2] - ax, seg[:, 3] - ay
    length = np.sqrt(ex * ex + ey * ey)
    return ax, ay, ex, ey, length, _ROUNDING * (np.abs(ax) + np.abs(ay) + length)


def _segment_hits(
    ox: np.ndarray,
    oy: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    seg: tuple[np.ndarray, ...],
    scratch: _Scratch,
) -> np.ndarray:
    """Distance along each of B unit rays to the first of S segments: ``(B,)``, inf if none.

    With ``w`` from the ray's origin to a segment's start ``a`` and ``e`` the segment's
    vector, the crossing ``o + t u = a + s e`` has ``t = (w x e) / (u x e)`` and
    ``s = (w x u) / (u x e)``; ``s`` is tested without dividing, on numerators over the
    positive denominator ``|u x e|``. The slack adds a bound on the rounding in ``w x u``
    (the start's offset from the ray's line), so a ray aimed exactly at a segment's end
    point hits it even when the segment is tiny next to its distance. Parallel pairs
    (``|u x e|`` tiny, including zero-length segments) are rare and handled apart, by
    projecting both ends onto the ray. ``seg`` comes from :func:`_prepare`.
    """
    ax, ay, ex, ey, length, mag = seg
    wx, wy, den, tn, sn, size, tmp, parallel, hit, test = scratch.views(ox.size, ax.size)
    ray_mag = _ROUNDING * (np.abs(ox) + np.abs(oy))
    ox, oy, ux, uy = ox[:, None], oy[:, None], ux[:, None], uy[:, None]
    np.subtract(ax, ox, out=wx)
    np.subtract(ay, oy, out=wy)
    np.multiply(ux, ey, out=den)
    den -= np.multiply(uy, ex, out=tmp)
    np.multiply(wx, ey, out=tn)
    tn -= np.multiply(wy, ex, out=tmp)
    np.multiply(wx, uy, out=sn)
    sn -= np.multiply(wy, ux, out=tmp)
    np.abs(den, out=size)
    np.less_equal(size, _EPS_PARALLEL * length, out=parallel)
    np.sign(den, out=den)
    tn *= den
    sn *= den
    slack = np.multiply(size, _EPS_ALONG, out=den)
    slack += ray_mag[:, None]
    slack += mag
    np.greater_equal(tn, np.multiply(slack, -length, out=tmp), out=hit)  # t >= 0
    hit &= np.greater_equal(sn, np.negative(slack, out=tmp), out=test)  # s >= 0
    slack += size
    hit &= np.less_equal(sn, slack, out=test)  # s <= 1
    hit &= np.logical_not(parallel, out=test)
    # divided only where it hits (|u x e| > 0 there, and t is bounded by the geometry),
    # so no error state is needed (a context costs about 2 µs a call)
    dist = np.divide(tn, size, out=tn, where=hit)
    np.copyto(dist, np.inf, where=np.logical_not(hit, out=test))  # non-hits -> inf
    rows, cols = np.nonzero(parallel)
    if rows.size:
        pwx, pwy, pux, puy = wx[rows, cols], wy[rows, cols], ux[rows, 0], uy[rows, 0]
        near = pwx * pux + pwy * puy  # projection of the start
        far = near + (ex[cols] * pux + ey[cols] * puy)  # ... and of the end
        near, far = np.minimum(near, far), np.maximum(near, far)
        # A near-parallel segment spans _EPS_PARALLEL * length across the ray's line; a
        # point obstacle has no length, so only the rounding slack lets a ray touch it.
        slack = _EPS_PARALLEL * length[cols] + ray_mag[rows] + mag[cols]
        off_line = np.abs(pwx * puy - pwy * pux)  # the start's distance from it
        touch = (off_line <= slack) & (far >= -slack)
        dist[rows, cols] = np.where(touch, near, np.inf)
    # a start just behind the ray's origin reads 0 (np.minimum.reduce: ndarray.min's own
    # reduction, without its Python-level wrapper)
    return np.maximum(np.minimum.reduce(dist, axis=1), 0.0)


def _circle_hits(
    ox: np.ndarray,
    oy: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    circ: np.ndarray,
    scratch: _Scratch,
) -> np.ndarray:
    """Distance along each of B unit rays to the first of C circles: ``(B,)``, inf if none.

    ``circ`` is ``(C, 3)`` or ``(B, C, 3)``. The near root of ``t^2 + 2 b t + c = 0`` is
    taken as ``c / (-b + sqrt(b^2 - c))`` (no cancellation when the circle is close); an
    origin inside or on a circle reads 0; a NaN row compares false everywhere: no obstacle.
    """
    cx, cy, r = circ[..., 0], circ[..., 1], circ[..., 2]
    wx, wy, b, c, disc, t, tmp, ahead, miss, test = scratch.views(ox.size, cx.shape[-1])
    ux, uy = ux[:, None], uy[:, None]
    np.subtract(ox[:, None], cx, out=wx)
    np.subtract(oy[:, None], cy, out=wy)
    np.multiply(wx, ux, out=b)
    b += np.multiply(wy, uy, out=tmp)
    np.multiply(wx, wx, out=c)
    c += np.multiply(wy, wy, out=tmp)
    c -= r * r
    np.multiply(b, b, out=disc)
    disc -= c
    np.less(b, 0.0, out=ahead)
    ahead &= np.greater_equal(disc, 0.0, out=test)
    ahead &= np.greater(c, 0.0, out=test)
    np.logical_not(ahead, out=miss)
    np.copyto(disc, 0.0, where=miss)
    disc = np.sqrt(disc, out=disc)
    disc -= b
    np.divide(c, disc, out=t, where=ahead)  # -b > 0 there: disc > 0, no error state
    np.copyto(t, np.inf, where=miss)
    np.copyto(t, 0.0, where=np.less_equal(c, 0.0, out=test))
    return np.minimum.reduce(t, axis=1)


def cast(
    origins: np.ndarray,
    directions: np.ndarray,
    segments: np.ndarray | list | None,
    circles: np.ndarray | list | None = None,
    max_range: float | np.ndarray = np.inf,
) -> np.ndarray:
    """Distance from each ray's origin to the first segment or circle it meets: ``(m, k)``.

    ``origins`` and ``directions`` are ``(m, k, 2)`` (m instances of k rays; directions need
    not be unit length, but must not be zero). ``segments`` is ``(s, 4)`` shared walls,
    ``circles`` ``(c, 3)`` shared or ``(m, c, 3)`` per instance. Rays that meet nothing
    within ``max_range`` (a scalar or anything broadcastable to ``(m, k)``) read
    ``max_range``.
    """
    o = np.asarray(origins, dtype=float)
    d = np.asarray(directions, dtype=float)
    if o.ndim != 3 or o.shape[2] != 2 or d.shape != o.shape:
        raise ValueError(
            f"origins and directions must both have shape (m, k, 2), got {o.shape} and {d.shape}"
        )
    return cast_at(o, d, Targets.of(segments, circles, o.shape[0]), max_range)


@dataclass(frozen=True)
class Targets:
    """What rays are cast against, prepared once: a component whose walls do not move
    builds it at its start rather than at every reading (the per-segment columns cost as
    much as the casting itself on a handful of rays)."""

    segments: tuple[np.ndarray, ...]  # the kernel's per-segment columns (:func:`_prepare`)
    circles: np.ndarray  # (c, 3) shared or (m, c, 3) per instance

    @classmethod
    def of(
        cls,
        segments: np.ndarray | list | None,
        circles: np.ndarray | list | None = None,
        m: int = 0,
    ) -> Targets:
        """Walls and circles as :func:`cast` takes them (circles per instance: ``m``)."""
        seg = np.zeros((0, 4)) if segments is None else as_segments(segments)
        return cls(_prepare(seg), as_circles(circles, m))


def cast_at(
    o: np.ndarray, d: np.ndarray, targets: Targets, max_range: float | np.ndarray = np.inf
) -> np.ndarray:
    """:func:`cast` on float arrays ``(m, k, 2)`` already checked, against prepared
    ``targets``: the same distances, bit for bit."""
    m, k, _ = o.shape
    circ = targets.circles
    norm = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])
    fine = (norm > 0.0) & (norm < np.inf)  # NaN fails both
    if not every(fine):
        raise ValueError("ray directions must be finite and non-zero")
    ox, oy = o[..., 0].ravel(), o[..., 1].ravel()
    ux, uy = (d[..., 0] / norm).ravel(), (d[..., 1] / norm).ravel()
    out = filled(m * k, np.inf)
    prepared = targets.segments
    n_seg, n_circ = prepared[0].size, circ.shape[-2]
    if circ.ndim == 3 and n_circ:
        owner = np.repeat(np.arange(m), k)  # instance of each flattened ray
    step = max(1, min(m * k, _BLOCK // max(1, n_seg, n_circ)))
    scratch = _scratch(step, max(1, n_seg, n_circ))
    for start in range(0, m * k, step):
        rays = slice(start, start + step)
        args = (ox[rays], oy[rays], ux[rays], uy[rays])
        if n_seg:
            out[rays] = _segment_hits(*args, prepared, scratch)
        if n_circ:
            rows = circ if circ.ndim == 2 else circ[owner[rays]]
            out[rays] = np.minimum(out[rays], _circle_hits(*args, rows, scratch))
    return np.minimum(out.reshape(m, k), max_range)

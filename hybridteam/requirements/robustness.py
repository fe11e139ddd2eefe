"""STL temporal operators on sampled signals: robustness, vectorized over instances.

Arrays are ``(n, K)``: instances by grid points. ``t`` holds each instance's grid,
strictly increasing and padded at the end with ``+inf`` where an instance's grid is
shorter (a ``(K,)`` grid is shared by all rows). At grid point ``t_i`` of a row, with
``W_i = {j : t_i + a <= t_j <= t_i + b}`` (the sums rounded in float64, as any other
code that looks at a window computes them; on a grid like ``k * 0.1`` an edge can then
miss a sample one ulp away, so a caller wanting slack widens ``[a, b]`` itself):

- ``always``:     ``min { rho_j : j in W_i }``
- ``eventually``: ``max { rho_j : j in W_i }``
- ``until``:      ``max over j in W_i of min(psi_j, min { phi_k : i <= k < j })``

``until`` is rtamt's discrete-time semantics (``phi until[a,b] psi``, offline): phi must
hold from ``t_i`` itself (not from ``t_i + a``) up to, *not including*, the point where psi
is taken; with ``a > 0`` the points before the window still constrain phi. The tests use
rtamt as the oracle.

Finite traces: a window is cut at the end of the row's valid grid, and an empty window
gives the identity of the reduction: ``+inf`` for always, ``-inf`` for eventually and
until (no point to take psi at). rtamt pads a trace the same way, so near the end these
values mean "nothing left to check" (always) or "cannot be witnessed any more" (the
others), not a verdict about the unobserved future. Padding positions get NaN. ``b``
may be ``inf`` (the rest of the row); ``a`` must be finite.

Why these algorithms: windows vary per point (grids are irregular), so each point's
window is an index range found by one exact search. min and max are idempotent, so a
sparse table answers any range with two overlapping power-of-two blocks. until composes
the maps ``x -> max(psi_j, min(phi_j, x))``, which is associative but not idempotent:
its table is walked in disjoint blocks (binary lifting), ``O(log span)`` per point for
any ``b``. Tables are built per chunk of rows so memory stays near ``chunk_bytes``
(:data:`CHUNK_BYTES` unless a caller says otherwise).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

#: Working memory per chunk of rows (tables, search keys), the operators' default
#: ``chunk_bytes``: the results do not depend on it, only how many rows a table holds.
CHUNK_BYTES = 48 << 20

Reduce = np.ufunc  # np.minimum or np.maximum


def always(
    t: np.ndarray,
    rho: np.ndarray,
    a: float = 0.0,
    b: float = math.inf,
    *,
    chunk_bytes: int = CHUNK_BYTES,
) -> np.ndarray:
    """Robustness of ``always[a, b] phi`` given ``rho`` = robustness of phi (tables built
    ``chunk_bytes`` of rows at a time)."""
    return _window(t, rho, a, b, np.minimum, math.inf, chunk_bytes)


def eventually(
    t: np.ndarray,
    rho: np.ndarray,
    a: float = 0.0,
    b: float = math.inf,
    *,
    chunk_bytes: int = CHUNK_BYTES,
) -> np.ndarray:
    """Robustness of ``eventually[a, b] phi`` given ``rho`` = robustness of phi."""
    return _window(t, rho, a, b, np.maximum, -math.inf, chunk_bytes)


def until(
    t: np.ndarray,
    rho1: np.ndarray,
    rho2: np.ndarray,
    a: float = 0.0,
    b: float = math.inf,
    *,
    chunk_bytes: int = CHUNK_BYTES,
) -> np.ndarray:
    """Robustness of ``phi until[a, b] psi`` (``rho1`` = phi's, ``rho2`` = psi's).

    With ``[lo, hi)`` the window's index range, ``min phi[i, j) = min(min phi[i, lo),
    min phi[lo, j))`` for every ``j >= lo``, so the result is ``min(M_i, V_i)``: ``M_i``
    the range minimum of phi before the window, ``V_i`` the until from ``lo`` inside it.
    """
    a, b = _check_window(a, b)
    t, (phi, psi) = _check_signals(t, rho1, rho2)
    lo, hi, valid = _bounds(t, a, b, phi.shape[0], chunk_bytes)
    phi, psi = _blank(phi, valid, math.inf), _blank(psi, valid, -math.inf)
    out = _until_from(phi, psi, lo, hi, chunk_bytes)
    if a > 0:
        start = np.broadcast_to(np.arange(phi.shape[1]), phi.shape)
        np.minimum(out, _range_reduce(phi, start, lo, np.minimum, math.inf, chunk_bytes), out=out)
    out[~valid] = np.nan
    return out


def _window(
    t: np.ndarray,
    rho: np.ndarray,
    a: float,
    b: float,
    op: Reduce,
    identity: float,
    chunk_bytes: int,
) -> np.ndarray:
    a, b = _check_window(a, b)
    t, (rho,) = _check_signals(t, rho)
    lo, hi, valid = _bounds(t, a, b, rho.shape[0], chunk_bytes)
    x = _blank(rho, valid, identity)
    if np.isinf(x).all():  # a Boolean signal (+-inf): count the deciding values instead
        out = _count_reduce(x, None if a == 0 else lo, hi, identity)
    elif math.isinf(b):  # every window runs to the row's end: one suffix scan, O(K) a row
        out = _suffix_reduce(x, lo, op, identity)
    else:
        out = _range_reduce(x, lo, hi, op, identity, chunk_bytes)
    out[~valid] = np.nan
    return out


def _count_reduce(
    x: np.ndarray, lo: np.ndarray | None, hi: np.ndarray, identity: float
) -> np.ndarray:
    """min (``identity`` +inf) or max (-inf) over ``x[r, lo:hi]`` when every value is
    +-inf: the window holds the other infinity iff it counts one; one prefix sum a row.
    ``lo`` None: each window starts at its own point."""
    n, k = x.shape
    counts = np.zeros((n, k + 1), np.int64)
    np.cumsum(x != identity, axis=1, out=counts[:, 1:])
    before = (
        counts[:, :k] if lo is None else np.take_along_axis(counts, np.broadcast_to(lo, (n, k)), 1)
    )
    decided = np.take_along_axis(counts, np.broadcast_to(hi, (n, k)), 1) > before
    return np.where(decided, -identity, identity)


def _suffix_reduce(x: np.ndarray, lo: np.ndarray, op: Reduce, identity: float) -> np.ndarray:
    """``op`` over ``x[r, lo:]`` per point (pads already hold ``identity``)."""
    n, k = x.shape
    suffix = np.full((n, k + 1), identity)
    suffix[:, :k] = op.accumulate(x[:, ::-1], axis=1)[:, ::-1]
    return np.take_along_axis(suffix, np.broadcast_to(lo, (n, k)), axis=1)


def _check_window(a: float, b: float) -> tuple[float, float]:
    try:
        a, b = float(a), float(b)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"bad window [{a!r}, {b!r}]: bounds must be numbers") from exc
    if math.isnan(a) or math.isnan(b) or not 0 <= a < math.inf or b < a:
        raise ValueError(f"bad window [{a}, {b}]: need 0 <= a <= b, a finite, b <= inf")
    return a, b


def _check_signals(t: np.ndarray, *rhos: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Float arrays, with the shapes and the grid checked (NaN, order, padding)."""
    arrays = [np.asarray(r, dtype=float) for r in rhos]
    shape = arrays[0].shape
    if len(shape) != 2:
        raise ValueError(f"signals must be (n, K) arrays, got shape {shape}")
    for other in arrays[1:]:
        if other.shape != shape:
            raise ValueError(f"signals of shapes {shape} and {other.shape} differ")
    t = np.asarray(t, dtype=float)
    if t.shape not in (shape, shape[1:]):
        raise ValueError(f"times of shape {t.shape} do not match signals of shape {shape}")
    grid = np.atleast_2d(t)
    if not np.all(grid > -np.inf):
        raise ValueError("times must not be NaN or -inf")
    if np.any((grid[:, 1:] <= grid[:, :-1]) & np.isfinite(grid[:, 1:])):
        raise ValueError(
            "times must increase strictly along a row, padded at its end with +inf only"
        )
    return t, arrays


def _blank(x: np.ndarray, valid: np.ndarray, identity: float) -> np.ndarray:
    """``x`` with padding set to ``identity``: pads may hold anything, even NaN."""
    return x if valid.all() else np.where(valid, x, identity)


def _chunks(n: int, row_bytes: int, chunk_bytes: int) -> Iterator[slice]:
    step = max(1, chunk_bytes // max(1, row_bytes))
    for r0 in range(0, n, step):
        yield slice(r0, min(n, r0 + step))


def _bounds(
    t: np.ndarray, a: float, b: float, n: int, chunk_bytes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point, its window ``[lo, hi)`` in row indices, and the valid (non-pad) mask."""
    valid = np.isfinite(t)
    if t.ndim == 1:  # one grid for all rows: search it once
        length = valid.sum()
        lo = np.minimum(np.searchsorted(t, t + a, "left"), length)
        hi = np.minimum(np.searchsorted(t, t + b, "right"), length)
        shape = (n, t.size)
        return (
            np.broadcast_to(lo, shape),
            np.broadcast_to(hi, shape),
            np.broadcast_to(valid, shape),
        )
    length = valid.sum(axis=1, keepdims=True)  # pads get empty windows [length, length)
    if a == 0:  # on a strictly increasing row, t_i's own index is where [t_i, ...) starts
        lo = np.minimum(np.arange(t.shape[1]), length)
    else:
        lo = np.minimum(_count_before(t, t + a, True, chunk_bytes), length)
    hi = (
        np.minimum(_count_before(t, t + b, False, chunk_bytes), length)
        if math.isfinite(b)
        else np.broadcast_to(length, t.shape)
    )
    return lo, hi, valid


def _count_before(t: np.ndarray, q: np.ndarray, strict: bool, chunk_bytes: int) -> np.ndarray:
    """Per row, how many ``t_j`` are ``< q_i`` (strict) or ``<= q_i``: a row-wise
    ``searchsorted`` without a loop over rows. Both rows are sorted, so a stable argsort
    of their concatenation is one merge (timsort finds the two runs); query ``i`` lands
    at ``i`` plus the count. Ties go to whichever half comes first. Exact, unlike one
    flat search with a float offset per row, which would round nearby times together."""
    n, k = t.shape
    out = np.empty((n, k), np.intp)
    for rows in _chunks(n, 64 * k, chunk_bytes):
        m = rows.stop - rows.start
        halves = [q[rows], t[rows]] if strict else [t[rows], q[rows]]
        order = np.argsort(np.concatenate(halves, axis=1), axis=1, kind="stable")
        is_query = order < k if strict else order >= k
        at = np.flatnonzero(is_query).reshape(m, k)  # in query order: the sort is stable
        out[rows] = at - (np.arange(m) * 2 * k)[:, None] - np.arange(k)
    return out


def _range_reduce(
    x: np.ndarray, lo: np.ndarray, hi: np.ndarray, op: Reduce, identity: float, chunk_bytes: int
) -> np.ndarray:
    """``op`` over ``x[r, lo:hi]`` per point (``identity`` where empty), by a sparse table:
    level ``l`` holds ``op`` over ``x[j : j + 2**l]``; a range of length ``s`` is the
    union of the two blocks of level ``floor(log2 s)`` at its two ends."""
    n, k = x.shape
    out = np.full((n, k), identity)
    levels = int((hi - lo).max(initial=0)).bit_length()
    for rows in _chunks(n, 8 * levels * k, chunk_bytes) if levels else ():
        m = rows.stop - rows.start
        table = np.empty((levels, m, k))
        table[0] = x[rows]
        for lv in range(1, levels):
            h = 1 << (lv - 1)
            op(table[lv - 1, :, :-h], table[lv - 1, :, h:], out=table[lv, :, :-h])
            table[lv, :, k - h :] = table[lv - 1, :, k - h :]  # cut blocks: never queried
        start, stop = lo[rows], hi[rows]
        empty = stop <= start
        level = np.frexp(np.maximum(stop - start, 1))[1] - 1  # floor(log2(span)), exactly
        base = level * (m * k) + np.arange(m)[:, None] * k
        left = np.take(table, base + np.where(empty, 0, start))
        right = np.take(table, base + np.where(empty, 0, stop - (1 << level)))
        out[rows] = np.where(empty, identity, op(left, right))
    return out


def _until_from(
    phi: np.ndarray, psi: np.ndarray, lo: np.ndarray, hi: np.ndarray, chunk_bytes: int
) -> np.ndarray:
    """``max over lo <= j < hi of min(psi_j, min phi[lo, j))`` per point, ``-inf`` where
    empty. This is ``(F_lo o ... o F_{hi-1})(-inf)`` with ``F_j(x) = max(psi_j,
    min(phi_j, x))``; maps ``x -> max(p, min(q, x))`` compose as ``(p1, q1) o (p2, q2) =
    (max(p1, min(q1, p2)), min(q1, q2))``. Level ``l`` of the table composes
    ``[j, j + 2**l)``; a range is walked as disjoint blocks, largest first."""
    n, k = phi.shape
    span = hi - lo
    out = np.full((n, k), -np.inf)
    levels = int(span.max(initial=0)).bit_length()
    if levels == 0:
        return out
    for rows in _chunks(n, 16 * levels * k, chunk_bytes):
        m = rows.stop - rows.start
        p, q = np.empty((levels, m, k)), np.empty((levels, m, k))
        p[0], q[0] = psi[rows], phi[rows]
        for lv in range(1, levels):
            h = 1 << (lv - 1)
            np.minimum(q[lv - 1, :, :-h], p[lv - 1, :, h:], out=p[lv, :, :-h])
            np.maximum(p[lv - 1, :, :-h], p[lv, :, :-h], out=p[lv, :, :-h])
            np.minimum(q[lv - 1, :, :-h], q[lv - 1, :, h:], out=q[lv, :, :-h])
            p[lv, :, k - h :], q[lv, :, k - h :] = p[lv - 1, :, k - h :], q[lv - 1, :, k - h :]
        acc_p, acc_q = out[rows], np.full((m, k), np.inf)
        pos, todo = lo[rows].copy(), span[rows]
        row_base = np.arange(m)[:, None] * k
        for lv in reversed(range(levels)):
            step = (todo >> lv) & 1 == 1
            at = lv * (m * k) + row_base + np.where(step, pos, 0)
            new_p = np.maximum(acc_p, np.minimum(acc_q, np.take(p, at)))
            acc_p = np.where(step, new_p, acc_p)
            if lv:  # the last block's q is never needed
                acc_q = np.where(step, np.minimum(acc_q, np.take(q, at)), acc_q)
                pos += np.where(step, 1 << lv, 0)
        out[rows] = acc_p
    return out

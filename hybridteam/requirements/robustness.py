"""STL temporal operators on sampled signals: robustness, vectorized over instances.

Every array is ``(n, K)``: instances by grid points; ``t`` holds each instance's grid
(increasing; padded at the end with ``inf`` where an instance's grid is shorter; a
``(K,)`` grid is shared by all rows). At grid point ``t_i`` of a row:

- ``always``:     min { rho_j : t_j in [t_i + a, t_i + b] }
- ``eventually``: max { rho_j : t_j in [t_i + a, t_i + b] }
- ``until``:      max over j with t_j in [t_i + a, t_i + b] of
  min(psi_j, min { phi_k : i <= k < j })  — phi up to, not including, the point where psi
  is taken: rtamt's discrete-time semantics (its ``precedes`` operation), which the tests
  use as the oracle.

Finite traces: a window is cut at the end of the row's grid. An empty window gives the
identity of the reduction: ``+inf`` for always, ``-inf`` for eventually and until.
Results at padding positions are NaN. ``b`` may be ``inf``.

always/eventually answer each window with a sparse-table range minimum (two lookups per
point, ``O(K log K)`` work per row), in row chunks that bound the table's memory; until
uses a backward recursion for unbounded windows and one pass per index offset otherwise.
"""

from __future__ import annotations

import math

import numpy as np

_CHUNK_BYTES = 48 << 20  # the sparse table's memory per chunk of rows


def _grid(t: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    t = np.asarray(t, float)
    if t.ndim == 1:
        t = np.broadcast_to(t, shape)
    if t.shape != shape:
        raise ValueError(f"times of shape {t.shape} do not match signals of shape {shape}")
    return t


def _check(rho: np.ndarray, a: float, b: float) -> np.ndarray:
    rho = np.asarray(rho, float)
    if rho.ndim != 2:
        raise ValueError(f"signals must be (n, K), got shape {rho.shape}")
    if math.isnan(a) or math.isnan(b) or not math.isfinite(a) or a < 0 or b < a:
        raise ValueError(f"bad window [{a}, {b}]: need 0 <= a <= b, a finite")
    return rho


def _bounds(t: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point, the window's index range [lo, hi) and the row's valid length."""
    n, k = t.shape
    length = np.isfinite(t).sum(axis=1)
    lo = np.empty((n, k), np.intp)
    hi = np.empty((n, k), np.intp)
    for r in range(n):  # one C search per row; rows are few compared to points
        g = t[r, : length[r]]
        full = t[r]
        with np.errstate(invalid="ignore"):
            lo[r] = np.searchsorted(g, full + a, "left")
            hi[r] = np.searchsorted(g, full + b, "right") if math.isfinite(b) else length[r]
    return lo, hi, length


def _window_min(t: np.ndarray, rho: np.ndarray, a: float, b: float) -> np.ndarray:
    n, k = rho.shape
    lo, hi, length = _bounds(t, a, b)
    out = np.full((n, k), np.inf)
    levels = max(1, int(np.log2(max(k, 1))) + 1)
    step = max(1, _CHUNK_BYTES // max(1, 8 * k * levels))
    for r0 in range(0, n, step):
        rows = slice(r0, min(n, r0 + step))
        table = [np.where(np.arange(k) < length[rows, None], rho[rows], np.inf)]
        while (1 << len(table)) <= k:
            half = 1 << (len(table) - 1)
            prev = table[-1]
            table.append(np.minimum(prev[:, :-half], prev[:, half:]))
        start, stop = lo[rows], hi[rows]
        span = stop - start
        got = np.full(start.shape, np.inf)
        ok = span > 0
        level = np.zeros(start.shape, np.intp)
        level[ok] = np.floor(np.log2(span[ok])).astype(np.intp)
        for j, tab in enumerate(table):
            sel = ok & (level == j)
            if not sel.any():
                continue
            rr = np.nonzero(sel)[0]
            left = tab[rr, start[sel]]
            right = tab[rr, stop[sel] - (1 << j)]
            got[sel] = np.minimum(left, right)
        out[rows] = got
    out[~np.isfinite(t)] = np.nan
    return out


def always(t: np.ndarray, rho: np.ndarray, a: float = 0.0, b: float = math.inf) -> np.ndarray:
    """Robustness of ``always[a, b]`` at every grid point (see the module docstring)."""
    rho = _check(rho, a, b)
    return _window_min(_grid(t, rho.shape), rho, a, b)


def eventually(t: np.ndarray, rho: np.ndarray, a: float = 0.0, b: float = math.inf
               ) -> np.ndarray:
    """Robustness of ``eventually[a, b]``: the window maximum (``-always(-rho)``)."""
    rho = _check(rho, a, b)
    return -_window_min(_grid(t, rho.shape), -rho, a, b)


def until(t: np.ndarray, phi: np.ndarray, psi: np.ndarray, a: float = 0.0,
          b: float = math.inf) -> np.ndarray:
    """Robustness of ``until[a, b](phi, psi)`` (see the module docstring)."""
    phi, psi = _check(phi, a, b), _check(psi, a, b)
    if phi.shape != psi.shape:
        raise ValueError(f"phi {phi.shape} and psi {psi.shape} differ in shape")
    t = _grid(t, phi.shape)
    n, k = phi.shape
    valid = np.isfinite(t)
    if not math.isfinite(b):
        return _until_unbounded(t, phi, psi, a, valid)
    lo, hi, _ = _bounds(t, a, b)
    out = np.full((n, k), -np.inf)
    running = np.full((n, k), np.inf)  # min of phi over [i, i + d)
    idx = np.arange(k)
    for d in range(int((hi - idx).max(initial=0))):
        j = idx + d
        inside = (j < k)
        jj = np.minimum(j, k - 1)
        in_window = inside[None, :] & (jj[None, :] >= lo) & (jj[None, :] < hi)
        cand = np.minimum(psi[:, jj], running)
        out = np.where(in_window, np.maximum(out, cand), out)
        running = np.minimum(running, np.where(inside[None, :], phi[:, jj], np.inf))
    out[~valid] = np.nan
    return out


def _until_unbounded(t: np.ndarray, phi: np.ndarray, psi: np.ndarray, a: float,
                     valid: np.ndarray) -> np.ndarray:
    """``b = inf``: U0 (window [0, inf)) by the backward recursion
    ``U0_i = max(psi_i, min(phi_i, U0_{i+1}))``; then for ``a > 0`` the window starts at
    the first point p with ``t_p >= t_i + a``: ``min(min phi[i, p), U0_p)``."""
    n, k = phi.shape
    phi_v = np.where(valid, phi, np.inf)
    psi_v = np.where(valid, psi, -np.inf)
    u0 = np.full((n, k + 1), -np.inf)
    for i in range(k - 1, -1, -1):
        u0[:, i] = np.maximum(psi_v[:, i], np.minimum(phi_v[:, i], u0[:, i + 1]))
    if a == 0:
        out = u0[:, :k].copy()
    else:
        lo, _, _ = _bounds(t, a, math.inf)
        before = _prefix_window_min(t, phi_v, lo)
        out = np.minimum(before, np.take_along_axis(u0, lo, axis=1))
    out[~valid] = np.nan
    return out


def _prefix_window_min(t: np.ndarray, phi: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """min of phi over [i, stop_i) per point (``+inf`` where empty), by the sparse table
    of :func:`_window_min` on index windows."""
    n, k = phi.shape
    # an index window [i, stop_i) is the time window [t_i, t_{stop_i}) : reuse the table
    # on a grid of indices, where [a, b] in "time" is [0, stop_i - i - 1]
    out = np.full((n, k), np.inf)
    idx = np.arange(k)
    span = stop - idx[None, :]
    for d in np.unique(span[span > 0]).tolist():
        sel = span == d
        win = _window_min(np.broadcast_to(idx.astype(float), (n, k)), phi, 0.0, d - 1.0)
        out[sel] = win[sel]
    return out

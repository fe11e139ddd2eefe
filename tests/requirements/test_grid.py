"""The ensemble time grid against the per-instance construction it replaces: each row is
the sorted union of the samples up to the instance's end and its own instants, and the
row-wise searches equal ``np.searchsorted`` on each row."""

from __future__ import annotations

import numpy as np
import pytest

from hybridteam.requirements.grid import Grid


def _rows(st, ends, inst, times):
    rows = []
    for i, end in enumerate(ends):
        g = np.unique(np.concatenate([st[st <= end], times[inst == i]]))
        rows.append(g[np.isfinite(g) & (g <= end)])
    return rows


@pytest.mark.parametrize("seed", range(8))
def test_rows_and_searches_equal_the_per_instance_construction(seed):
    rng = np.random.default_rng(seed)
    n, s = int(rng.integers(1, 7)), int(rng.integers(0, 30))
    st = np.round(np.cumsum(rng.uniform(0.1, 1.0, s)), 1)  # extras hit samples, too
    st = np.unique(st)
    ends = np.round(rng.uniform(0, st[-1] + 1 if s else 5, n), 1)
    m = int(rng.integers(0, 40))
    inst = rng.integers(0, n, m)
    times = np.round(rng.uniform(-1, ends.max() + 1, m), 1)
    times[rng.random(m) < 0.1] = np.inf
    grid = Grid(st, ends, inst, times)
    want = _rows(st, ends, inst, times)
    assert grid.t.shape == (n, max(len(g) for g in want))
    for i, g in enumerate(want):
        assert np.array_equal(grid.t[i, : len(g)], g)
        assert np.all(np.isinf(grid.t[i, len(g) :]))
    qi = rng.integers(0, n, 60)
    qt = np.concatenate(
        [
            np.round(rng.uniform(-1, ends.max() + 1, 30), 1),
            grid.t[qi[30:], 0] if grid.t.shape[1] else np.zeros(30),
        ]
    )
    for side in ("left", "right"):
        got = grid.search(qi, qt, side)
        assert got.tolist() == [
            int(np.searchsorted(want[i], q, side)) for i, q in zip(qi, qt, strict=True)
        ]
    at = grid.locate(qi, qt)
    for i, q, p in zip(qi, qt, at, strict=True):
        assert p == (int(np.searchsorted(want[i], q)) if q in want[i] else -1)


def test_interpolation_is_linear_between_data_and_held_beyond():
    grid = Grid(np.array([0.0, 1.0, 2.0]), np.array([3.0]), np.array([0, 0]), np.array([0.25, 3.0]))
    assert grid.t.tolist() == [[0.0, 0.25, 1.0, 2.0, 3.0]]
    values = np.array([[2.0, np.nan, 4.0, 8.0, np.nan]])
    out = grid.interpolate(~np.isnan(values), values)
    assert out.tolist() == [[2.0, 2.5, 4.0, 8.0, 8.0]]


def test_the_last_record_at_a_grid_point_wins():
    grid = Grid(np.array([0.0, 1.0]), np.array([1.0, 1.0]), np.array([1]), np.array([0.5]))
    # records in the order taken: two at (0, 1.0), two at (1, 0.5), one off the grid
    rows, cols, which = grid.last_records(
        np.array([0, 1, 0, 1, 1]), np.array([1.0, 0.5, 1.0, 0.5, 0.7])
    )
    got = sorted(zip(rows.tolist(), cols.tolist(), which.tolist(), strict=True))
    assert got == [(0, 1, 2), (1, 1, 3)]

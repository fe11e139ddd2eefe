"""The earliest scheduled instants of each instance, read once per engine iteration.

``Ensemble.instants`` holds every source of scheduled instants, one row per source: rows
``at`` (the event queue, the end of the run, ``after:`` deadlines: instants where
transitions may fire) and rows ``tick`` (stream copies, law ticks). At every iteration the
simulator needs, per instance, the earliest of all of them (where its step ends) and the
earliest of each kind (which kinds the step reached). The sources do not move between the
start of a step and its arrival (only the discrete phase and the instant's bookkeeping
reschedule them), so the three are read together at the start of the step.

For a few instances (a single run's one) the three reductions cost their dispatch, a few
microseconds each for one number, so they are computed on Python floats, by numpy's rules:
``np.minimum`` propagates a NaN, ``np.fmin`` skips it, so both give the same values
(``tests/engine/test_schedule.py`` compares them). A tie between ``0.0`` and ``-0.0`` may keep
either sign (numpy's own reductions keep one or the other depending on the array's
length); the engine only compares these times, or takes the larger of the earliest and
the clock, which keeps the clock's zero on a tie, so no sign reaches a result.
"""

from __future__ import annotations

import numpy as np

#: Up to this many instances the earliest instants are found on Python floats.
FEW = 4


def earliest(instants: np.ndarray, n_at: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(first, first_at, first_tick)`` per instance (column) of ``instants``:
    ``np.minimum.reduce`` over every row, and ``np.fmin.reduce`` over the first ``n_at``
    rows and over the others (a NaN source is skipped: no time reaches it)."""
    if instants.shape[1] > FEW:
        return (
            np.minimum.reduce(instants, axis=0),
            np.fmin.reduce(instants[:n_at], axis=0),
            np.fmin.reduce(instants[n_at:], axis=0),
        )
    first, first_at, first_tick = [], [], []
    for col in instants.T.tolist():
        first.append(_minimum(col))
        first_at.append(_fmin(col, 0, n_at))
        first_tick.append(_fmin(col, n_at, len(col)))
    out = np.array(first + first_at + first_tick).reshape(3, -1)  # one array, three rows
    return out[0], out[1], out[2]


def _minimum(col: list[float]) -> float:
    """``np.minimum.reduce`` of ``col``: NaN if any is, else the least."""
    m = col[0]
    for v in col:
        if v != v:
            return v
        if not m < v:
            m = v
    return m


def _fmin(col: list[float], lo: int, hi: int) -> float:
    """``np.fmin.reduce`` of ``col[lo:hi]``: the least that is not NaN; NaN if all are."""
    m = col[lo]
    for i in range(lo + 1, hi):
        v = col[i]
        if m != m or v < m:
            m = v
    return m

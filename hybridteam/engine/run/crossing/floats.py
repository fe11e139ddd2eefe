"""A single run's crossing search on Python floats.

A single run's search reads one row at each checkpoint and trial point, where each numpy
call costs its dispatch (about 1 µs) for one number. Where every atom (and the guard or
invariant judged) has a float form (:attr:`hybridteam.expr.Atom.row`,
:attr:`hybridteam.expr.Expression.row`), these functions do what
:mod:`~hybridteam.engine.run.crossing.search`'s array versions do with the same IEEE
operations on the same doubles, so they give the same truths, states and times
(``tests/engine/test_row_form.py`` runs the examples both ways).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.compile.compiled import Row
from hybridteam.engine.run.step import AgentStep

if TYPE_CHECKING:
    from hybridteam.dynamics import rk
    from hybridteam.engine.run.state import AgentState


def context_row(st: AgentState, sub: int, x: list[float], t: float) -> Row:
    """Instance ``sub``'s context on floats at state ``x`` and time ``t`` (its time in a
    mode is set by whoever reads one: :func:`_at`)."""
    return Row(x, st.v[sub].tolist(), st.p[sub].tolist(), t, t)


class DenseRow:
    """A single run's flowing row on its step's dense output, read on floats:
    :meth:`at_tau` is its context ``tau`` after the step start, with ``theta = tau / h``
    for the interpolant and ``t = t0 + tau`` (what ``step.dense_reader`` and the array
    search compute)."""

    __slots__ = ("at", "dense", "row", "span", "t0")

    def __init__(self, st: AgentState, sub: int, s: rk.Step, at: int, t0: float) -> None:
        h = float(s.h[at])
        self.span = h if h > 0 else 1.0  # (as dense_reader's: a zero-length step reads its start)
        self.at, self.dense, self.t0 = at, s.dense_row, t0
        self.row = context_row(st, sub, [], t0)

    def at_tau(self, tau: float) -> Row:
        row = self.row
        row.x = self.dense(tau / self.span, self.at)
        row.t = self.t0 + tau
        return row


def truths_one(st: AgentState, sub: int, x: list[float], t: float) -> np.ndarray:
    """Every watched atom's truth for instance ``sub`` at state ``x`` and time ``t``, as
    ``search.watch_truth`` gives them for one row: ``(atoms, 1)``."""
    return np.array(_truths(st, context_row(st, sub, x, t), st.entry[sub].tolist()), bool)[:, None]


def _truths(st: AgentState, row: Row, entry: list[float]) -> list[bool]:
    """Every watched atom's truth at ``row`` (each timed in its own mode)."""
    return [w.atom.row(_at(row, entry[w.mode]))[0] for w in st.ca.watches]  # type: ignore[misc]  # (row_watches: all have one)


def check_truths_one(
    st: AgentState,
    idx: np.ndarray,
    x_end: np.ndarray,
    step: AgentStep,
    thetas: np.ndarray,
    start: np.ndarray,
    h: np.ndarray,
    t0: np.ndarray,
    t1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``crossing._check_truths`` for a single run's one flowing row whose atoms all have a
    float form: the checkpoints' states off the dense output row by row, and every atom's truth
    there and at the end, on Python floats. The operations of the array version (``tau =
    theta h``, ``theta = tau / h`` for the interpolant, ``t = t0 + tau``, the atom's
    comparison) on the same doubles: the same truths, states and times."""
    s = step.rk_step
    assert s is not None and step.rk_pos is not None
    sub = int(idx[0])
    entry = st.entry[sub].tolist()
    reader = DenseRow(st, sub, s, int(step.rk_pos[0]), float(t0[0]))
    hh = float(h[0])
    xs, ts, truths = [], [], []
    for th in thetas[1:-1].tolist():
        row = reader.at_tau(float(th) * hh)
        xs.append(row.x)
        ts.append(row.t)
        truths.append(_truths(st, row, entry))
    row = reader.row  # (the same context, now at the step's end)
    row.x, row.t = x_end[0].tolist(), float(t1[0])
    truths.append(_truths(st, row, entry))
    out = np.empty((thetas.size, len(st.ca.watches), 1), bool)
    out[0] = start
    out[1:, :, 0] = truths
    return out, np.array(xs, dtype=float).reshape(len(xs), -1), np.array(ts, dtype=float)


def _at(row: Row, entered: float) -> Row:
    """``row`` with the time in the mode entered at ``entered``."""
    row.t_in = row.t - entered
    return row


def relevant_one(
    st: AgentState, idx: np.ndarray, keep: np.ndarray, points: list[tuple[np.ndarray, np.ndarray]]
) -> None:
    """``crossing._relevant`` for a single run whose guards and invariants have float forms:
    the same judgements (a lone flip matters where its guard is true, its invariant false,
    at the end of its sub-interval) on Python floats."""
    watches = st.ca.watches
    sub = int(idx[0])
    entry = st.entry[sub].tolist()
    row = context_row(st, sub, [], 0.0)
    flips = keep[:, :, 0].tolist()  # (the flips as found: keep changes below)
    for k, flipped in enumerate(flips):
        x, t = points[k + 1]
        row.t, read = float(t[0]), False
        for w, watch in enumerate(watches):
            if not flipped[w] or watch.observer:
                continue
            if any(
                flipped[v]
                for v, other in enumerate(watches)
                if v != w and other.owner is watch.owner
            ):
                continue
            if not read:
                row.x, read = x[0].tolist(), True
            row.t_in = row.t - entry[watch.mode]
            if bool(watch.owner.row(row)) == watch.invariant:  # type: ignore[union-attr, misc]  # (owner_matters on floats)
                keep[k, w, 0] = False

"""A single run's crossing search on Python floats.

A single run's search reads one row at each checkpoint and trial point, where each numpy
call costs its dispatch (about 1 µs) for one number. Where every atom (and the guard or
invariant judged) has a float form (:attr:`hybridteam.expr.Atom.row`,
:attr:`hybridteam.expr.Expression.row`), these functions do what :mod:`.crossing`'s array
versions do with the same IEEE operations on the same doubles, so they give the same
truths, states and times (``tests/test_row_form.py`` runs the examples both ways).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.compiled import Row
from hybridteam.engine.step import AgentStep

if TYPE_CHECKING:
    from hybridteam.engine.state import AgentState


def truths_one(st: AgentState, sub: int, x: list[float], t: float) -> np.ndarray:
    """Every watched atom's truth for instance ``sub`` at state ``x`` and time ``t``, as
    ``crossing.watch_truth`` gives them for one row: ``(atoms, 1)``."""
    row = Row(x, st.v[sub].tolist(), st.p[sub].tolist(), t, 0.0)
    entry = st.entry[sub].tolist()
    return np.array([[w.atom.row(_at(row, entry[w.mode]))[0]] for w in st.ca.watches], bool)


def check_truths_one(st: AgentState, idx: np.ndarray, x_end: np.ndarray, step: AgentStep,
                     thetas: np.ndarray, start: np.ndarray, h: np.ndarray, t0: np.ndarray,
                     t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``crossing._check_truths`` for a single run's one flowing row whose atoms all have a
    float form: the checkpoints' states off the dense output row by row, and every atom's truth
    there and at the end, on Python floats. The operations of the array version (``tau =
    theta h``, ``theta = tau / h`` for the interpolant, ``t = t0 + tau``, the atom's
    comparison) on the same doubles: the same truths, states and times."""
    s = step.rk_step
    assert s is not None and step.rk_pos is not None
    at = int(step.rk_pos[0])
    span = float(s.h[at])
    span = span if span > 0 else 1.0  # (as dense_reader's)
    hh, t_start, sub = float(h[0]), float(t0[0]), int(idx[0])
    entry = st.entry[sub].tolist()
    row = Row([], st.v[sub].tolist(), st.p[sub].tolist(), t_start, t_start)
    watches = [(w.atom.row, entry[w.mode]) for w in st.ca.watches]
    xs, ts, truths = [], [], []
    points = [(float(th) * hh, None) for th in thetas[1:-1].tolist()]
    points.append((None, float(t1[0])))
    for tau, t_end in points:
        if t_end is None:
            row.x = s.dense_row(tau / span, at)
            row.t = t = t_start + tau
            xs.append(row.x)
            ts.append(t)
        else:
            row.x, row.t = x_end[0].tolist(), t_end
        truths.append([both(_at(row, entered))[0] for both, entered in watches])
    out = np.empty((thetas.size, len(watches), 1), bool)
    out[0] = start
    out[1:, :, 0] = truths
    return out, np.array(xs, dtype=float).reshape(len(xs), -1), np.array(ts, dtype=float)


def _at(row: Row, entered: float) -> Row:
    """``row`` with the time in the mode entered at ``entered``."""
    row.t_in = row.t - entered
    return row


def relevant_one(st: AgentState, idx: np.ndarray, keep: np.ndarray,
                 points: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """``crossing._relevant`` for a single run whose guards and invariants have float forms:
    the same judgements (a lone flip matters where its guard is true, its invariant false,
    at the end of its sub-interval) on Python floats."""
    watches = st.ca.watches
    sub = int(idx[0])
    entry = st.entry[sub].tolist()
    row = Row([], st.v[sub].tolist(), st.p[sub].tolist(), 0.0, 0.0)
    flips = keep[:, :, 0].tolist()  # (the flips as found: keep changes below)
    for k, flipped in enumerate(flips):
        x, t = points[k + 1]
        row.t, read = float(t[0]), False
        for w, watch in enumerate(watches):
            if not flipped[w] or watch.observer:
                continue
            if any(flipped[v] for v, other in enumerate(watches)
                   if v != w and other.owner is watch.owner):
                continue
            if not read:
                row.x, read = x[0].tolist(), True
            row.t_in = row.t - entry[watch.mode]
            if bool(watch.owner.row(row)) == watch.invariant:  # (owner_matters on floats)
                keep[k, w, 0] = False

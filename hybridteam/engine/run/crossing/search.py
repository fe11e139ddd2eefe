"""Locating guard and invariant crossings inside an integration step.

A compound guard can only change truth where one of its comparisons (atoms) changes sign,
so the engine watches atoms, not whole guards: a ball passing through a thin band flips
``h < 0.51`` and then ``h > 0.49``, each once, even when the whole band is crossed within one
step. Within a step each atom is checked at its ends and at ``crossing_checks`` interior
points (dense output for Runge–Kutta, the exact flow for kinematic plants); the first
sub-interval where it flips is then narrowed by a vectorized Illinois (modified regula falsi)
search. Every trial point is computed by re-integrating from the step start — the exact arc
for kinematic plants, one fresh Runge–Kutta step for flows — rather than interpolated, so the
event time is as accurate as a step, not as the interpolant.

The search keeps a bracket ``[a, b]`` with the atom's original truth at ``a`` and the flipped
truth at ``b`` and returns ``b``: the state handed to the discrete phase is always on the new
side of the boundary, within ``event_tol`` seconds of the crossing.

All of this runs inside :meth:`Simulator.run <hybridteam.engine.run.simulator.Simulator.run>`,
which ignores floating-point errors for the whole run (a secant through equal margins is
NaN, and is replaced): the search sets no error state of its own, a cost per trial.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Container
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, filled, gather, some, where_true
from hybridteam.engine.compile.compiled import Ctx
from hybridteam.engine.run.crossing.floats import check_truths_one, relevant_one, truths_one
from hybridteam.engine.run.crossing.segment import Segment, owner_matters
from hybridteam.engine.run.step import AgentStep, state_at
from hybridteam.floatpaths import FLOAT_PATHS

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble

#: Pass foregone flips without locating them (:func:`_foregone`). The public switch of
#: that shortcut: False locates every flip, the reference the shortcut must give bit for
#: bit (``tests/engine/test_foregone.py`` compares the two and reads :class:`.costs.Costs`).
SKIP_FOREGONE = True


def watch_truth(
    ens: Ensemble, a: int, idx: np.ndarray, x: np.ndarray, t: np.ndarray, full: bool = False
) -> np.ndarray:
    """Truth of every watched atom of agent ``a`` at state ``x`` (rows) for instances idx
    (``full``: they are every instance, in order, so gathers can be views)."""
    st = ens.states[a]
    if idx.size == 1 and st.ca.row_watches and FLOAT_PATHS.on:  # a single run's: on floats
        return truths_one(st, int(idx[0]), x[0].tolist(), float(t[0]))
    out = np.empty((len(st.ca.watches), idx.size), bool)
    sel = slice(None) if full else idx
    v, p = gather(st.v, sel), gather(st.p, sel)
    ctx: Ctx | None = None
    mode = -1
    for w, watch in enumerate(st.ca.watches):
        if watch.mode != mode:
            mode = watch.mode
            # (its time in the mode computed where an atom reads it: most do not)
            ctx = Ctx(x, v, p, t, since=(st.entry[:, mode], sel))
        out[w] = watch.atom.truth(ctx)  # assignment broadcasts scalars
    return out


def find_crossings(
    ens: Ensemble,
    idx: np.ndarray,
    x_end: list[np.ndarray],
    steps: list[AgentStep],
    sampled: Container[int] = (),
) -> tuple[np.ndarray | None, list[np.ndarray | None], dict[int, Segment]]:
    """Earliest located crossing time (relative to the step start) per instance of ``idx``.

    ``x_end[a]`` is agent ``a``'s state at the end of the step for those instances.
    Returns ``inf`` where nothing relevant crossed (None when no atom flipped at all, so
    nothing was searched), each agent's atom truths at the end of the step (None for
    agents without watched atoms), which stay valid where nothing crossed, and each
    searched agent's :class:`Segment`, whose
    :meth:`~Segment.true_state` reads the states its trial points computed, so the engine
    need not integrate to the crossing again. Updates nothing.

    ``sampled``: agents whose plant is external (:mod:`.plant`), which have no arc to
    search: skipped here (truths None), their atoms sampled by the simulator instead.
    """
    best = best_lo = None  # made when some atom flipped (most steps: none did)
    thetas = ens.thetas
    end_truths: list[np.ndarray | None] = []
    searched: dict[int, Segment] = {}
    for a, st in enumerate(ens.states):
        if not st.ca.watches or a in sampled:
            end_truths.append(None)
            continue
        end, flips = _flips(ens, a, idx, x_end[a], steps[a], thetas)
        end_truths.append(end)  # None: no atom watched, nothing to refresh
        if flips is None:
            continue
        if best is None or best_lo is None:
            best, best_lo = filled(idx.size, np.inf), filled(idx.size, np.inf)
        seg = _search(ens, a, idx, steps[a], thetas, *flips, best, best_lo)
        if seg is not None:
            searched[a] = seg
    return best, end_truths, searched


def _flips(
    ens: Ensemble, a: int, idx: np.ndarray, x_end: np.ndarray, step: AgentStep, thetas: np.ndarray
) -> tuple[np.ndarray | None, tuple[np.ndarray, np.ndarray] | None]:
    """Agent ``a``'s atom truths at the step's end, and — where some watched atom flipped
    in a way that can matter — which sub-intervals of the step it flipped in and the truths
    at their ends: ``(relevant (K, nw, m), truths (K + 1, nw, m))``, else None.

    Atoms are evaluated at the step's ends and at ``crossing_checks`` interior points (all
    instances' checkpoints in one batch, off the dense output or the exact arc).

    Where no atom is watched in any of these instances, none is evaluated and the truths
    returned are None: an atom's stored truth is read only where it is watched, and it is
    evaluated afresh whenever a transition makes it watched (``Simulator._instant``). For
    the same reason only the instances with some atom watched are evaluated; the others
    keep their stored truths (an ensemble whose members left their guarded modes at
    different times pays for those still in one). Rows are independent, so an evaluated
    row's truths do not depend on which others are evaluated with it.
    """
    st = ens.states[a]
    full = idx.size == ens.n  # idx is every instance (the live ones, sorted)
    sel = slice(None) if full else idx
    watched = st.watched[:, sel]  # (nw, m)
    if not some(watched):
        return None, None
    m = idx.size
    h, t0 = ens.h[sel], ens.t0[sel]  # (views while every instance is live: read only)
    t1 = t0 + h
    start = st.truth[:, sel]
    pos = where_true(np.logical_or.reduce(watched, axis=0))  # rows with some atom watched
    part = pos.size < m
    checks = thetas.size - 2
    if checks == 0:
        if part:
            end = start.copy()
            end[:, pos] = watch_truth(ens, a, idx[pos], x_end[pos], t1[pos])
        else:
            end = watch_truth(ens, a, idx, x_end, t1, full)
        if not some(watched & (end != start)):
            return end, None
        all_truths = np.stack([start, end])
        x_checks: np.ndarray | None = None
        t_checks: np.ndarray | None = None
    else:
        all_truths, x_checks, t_checks = _check_truths(
            ens, a, idx, x_end, step, thetas, pos, part, start, h, t0, t1
        )
        end = all_truths[-1]
    flips = all_truths[1:] != all_truths[:-1]  # (K, nw, m)
    flips &= watched
    if not some(flips):
        return end, None
    points: list[tuple[np.ndarray, np.ndarray]] = [(step.x0, t0)]
    for c in range(checks):
        span = slice(c * pos.size, (c + 1) * pos.size)
        assert x_checks is not None and t_checks is not None  # (checks > 0)
        if part:  # rows not evaluated stay at the start: no flip there, never read
            x_c, t_c = step.x0.copy(), t0.copy()
            x_c[pos], t_c[pos] = x_checks[span], t_checks[span]
            points.append((x_c, t_c))
        else:
            points.append((x_checks[span], t_checks[span]))
    points.append((x_end, t1))
    return end, (_relevant(ens, a, idx, flips, points), all_truths)


def _check_truths(
    ens: Ensemble,
    a: int,
    idx: np.ndarray,
    x_end: np.ndarray,
    step: AgentStep,
    thetas: np.ndarray,
    pos: np.ndarray,
    part: bool,
    start: np.ndarray,
    h: np.ndarray,
    t0: np.ndarray,
    t1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Atom truths at the step's start (``start``), its interior checkpoints and its end:
    ``(K + 1, nw, m)``, with the checkpoints' states and times (rows ``pos`` of each, in
    checkpoint order). The checkpoints and the end are evaluated in one batch: rows are
    independent, so each row's truths are what it gets alone, for one evaluation of the
    atoms instead of two (at a single run's size each array operation costs its dispatch,
    about 1 µs, for one number). Rows not in ``pos`` keep their start truths."""
    k, checks = pos.size, thetas.size - 2
    if (
        idx.size == 1
        and ens.states[a].ca.row_watches
        and step.rk_step is not None
        and step.rk[0]
        and FLOAT_PATHS.on
    ):
        return check_truths_one(ens.states[a], idx, x_end, step, thetas, start, h, t0, t1)
    rows = np.concatenate([pos] * checks)
    tau = thetas[1:-1].repeat(k) * h[rows]
    x_checks = state_at(ens, a, idx[rows], tau, step, dense=True, rows=rows)
    t_checks = t0[rows] + tau
    n_ck = rows.size
    xs = np.empty((n_ck + k, x_end.shape[1]))
    xs[:n_ck], xs[n_ck:] = x_checks, x_end[pos] if part else x_end
    ts = np.empty(n_ck + k)
    ts[:n_ck], ts[n_ck:] = t_checks, t1[pos] if part else t1
    truths = watch_truth(ens, a, np.concatenate([idx[pos] if part else idx] * (checks + 1)), xs, ts)
    nw = truths.shape[0]
    out = np.empty((checks + 2, nw, idx.size), bool)
    out[0] = start
    if part:
        out[1:] = start
        out[1:, :, pos] = truths.reshape(nw, checks + 1, k).transpose(1, 0, 2)
    else:
        out[1:] = truths.reshape(nw, checks + 1, k).transpose(1, 0, 2)
    return out, x_checks, t_checks


def _search(
    ens: Ensemble,
    a: int,
    idx: np.ndarray,
    step: AgentStep,
    thetas: np.ndarray,
    relevant: np.ndarray,
    truths: np.ndarray,
    best: np.ndarray,
    best_lo: np.ndarray,
) -> Segment | None:
    """Locate agent ``a``'s relevant flips, lowering ``best`` (the earliest crossing per
    instance over all agents so far) and ``best_lo`` (the bracket's lower end) in place.
    Returns the segment searched on (its true states), or None if nothing was searched.

    A located crossing that does not matter (:meth:`Segment.matters`: the guard false, or
    the invariant true, just past it) does not stop the run. The search goes on past it:
    to the atom's next relevant sub-interval, and, for every watched atom whose truth just
    past the crossing differs from its truth at the sub-interval's end, to the rest of that
    sub-interval (a flip the sub-interval's ends could not show: the ball's impact after
    its apex, in one sub-interval that starts with ``h <= 0`` already true).
    """
    first = np.argmax(relevant, axis=0)  # (nw, m): first relevant sub-interval
    has = np.logical_or.reduce(relevant, axis=0)
    # atoms in order of their first sub-interval: the earliest crossing is found first and
    # later atoms only need one probe to show they do not cross before it
    order = sorted(
        range(relevant.shape[1]),
        key=lambda w: float(first[w][has[w]].min()) if some(has[w]) else 9.0,
    )
    # (atom, rows, sub-interval, bracket start or None for the sub-interval's, its truth)
    todo: deque = deque()
    for w in order:
        cand = where_true(has[w])
        if cand.size:
            todo.append((w, cand, first[w, cand], None, None))
    seg: Segment | None = None
    while todo:
        w, cand, k, lo, truth_lo = todo.popleft()
        if seg is None:
            seg = Segment(ens, a, idx, step)
        dropped = _locate_atom(
            seg, w, cand, k, lo, truth_lo, thetas, relevant, truths, best, best_lo
        )
        if dropped is not None:
            _search_on(ens, a, seg, w, *dropped, relevant, truths, todo)
    return seg


def _locate_atom(
    seg: Segment,
    w: int,
    cand: np.ndarray,
    k: np.ndarray,
    lo: np.ndarray | None,
    truth_lo: np.ndarray | None,
    thetas: np.ndarray,
    relevant: np.ndarray,
    truths: np.ndarray,
    best: np.ndarray,
    best_lo: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Locate atom ``w``'s first flip in sub-interval ``k`` of each row of ``cand`` (from
    ``lo``, with truth ``truth_lo`` there; None: from the sub-interval's start), lowering
    ``best`` and ``best_lo`` where it is earlier and matters. Returns the rows where it did
    not matter, their sub-intervals, crossing times and the states just past them (see
    :meth:`Segment.judge`; None if none; NaN where the flip was known not to matter
    without locating it, see :func:`_foregone`)."""
    # a lone atom's flip searched from its sub-interval's start was judged by _relevant
    judged = lo is None and seg.st.ca.lone_watches[w]
    from_start = lo is None
    if lo is None:
        lo, truth_lo = thetas[k] * seg.h[cand], truths[k, w, cand]
    assert truth_lo is not None  # (given with lo)
    hi = thetas[k + 1] * seg.h[cand]
    known = np.isfinite(best[cand])
    if some(known):
        # crossing later than the best so far (original truth still at best_lo)?
        rows = cand[known]
        probe = np.minimum(best_lo[rows], hi[known])
        dense = seg.evaluator(w, rows, dense=True)
        later = dense(np.arange(rows.size), probe)[0] == truth_lo[known]
        later |= best_lo[rows] <= lo[known]
        keep = np.ones(cand.size, bool)
        keep[where_true(known)[later]] = False
        # (the bracket is not cut at best_lo: each row's result must not depend on which
        # atoms other instances searched first, so an instance of an ensemble and a single
        # run agree bit for bit)
        cand, k, lo, hi, truth_lo = cand[keep], k[keep], lo[keep], hi[keep], truth_lo[keep]
        if cand.size == 0:
            return None
    skip = (
        _foregone(seg, w, cand, k, truth_lo, relevant)
        if SKIP_FOREGONE and from_start and not judged
        else None
    )
    costs = seg.ens.costs
    if judged:
        costs.located += cand.size
        tau_lo, tau = seg.locate(w, cand, lo, hi, truth_lo)
        matters, past = np.ones(cand.size, bool), None
    elif skip is not None and some(skip):
        tau_lo, tau = filled(cand.size, np.nan), filled(cand.size, np.nan)
        matters = np.zeros(cand.size, bool)
        past = np.full((cand.size, seg.step.x0.shape[1]), np.nan)
        go = where_true(~skip)
        costs.located += go.size
        if go.size:
            tau_lo[go], tau[go], matters[go], past[go] = seg.judge(
                w, cand[go], lo[go], hi[go], truth_lo[go]
            )
    else:
        costs.located += cand.size
        tau_lo, tau, matters, past = seg.judge(w, cand, lo, hi, truth_lo)
    better = matters & (tau < best[cand])
    best[cand[better]] = tau[better]
    best_lo[cand[better]] = tau_lo[better]
    if every(matters):
        return None
    assert past is not None
    return cand[~matters], k[~matters], tau[~matters], past[~matters]


def _foregone(
    seg: Segment,
    w: int,
    cand: np.ndarray,
    k: np.ndarray,
    truth_lo: np.ndarray,
    relevant: np.ndarray,
) -> np.ndarray | None:
    """Rows of ``cand`` whose flip of atom ``w`` in sub-interval ``k`` need not be located:
    what locating it would lead to is already known.

    The atom is a conjunct of its guard and flips to false: just past the flip the guard
    is false, so the crossing does not matter (as :meth:`Segment.matters` would find). A
    crossing that does not matter is searched past (:func:`_search_on`): the atom's later
    sub-intervals, which need no crossing time, and the rest of this one for each watched
    atom whose truth just past it differs from its truth at the sub-interval's end. That
    rest is empty where every other watched atom of the row is searched in this
    sub-interval from its start anyway: the atom itself is false at the sub-interval's end
    as just past the flip (it is searched from the start because its truths at the ends
    differ).
    The flips just after a bounce (``h <= 0`` turning false a picosecond after the impact
    was located on its far side) are such flips: the search then costs one location a
    bounce, not two. The run's results are those of locating them."""
    watch = seg.st.ca.watches[w]
    if not watch.conjunct or watch.invariant or watch.observer:
        return None
    others = relevant[k, :, cand] | ~seg.st.watched[:, seg.idx[cand]].T  # (rows, atoms)
    others[:, w] = True
    return truth_lo & np.logical_and.reduce(others, axis=1)


def _search_on(
    ens: Ensemble,
    a: int,
    seg: Segment,
    w: int,
    rows: np.ndarray,
    k: np.ndarray,
    tau: np.ndarray,
    past: np.ndarray,
    relevant: np.ndarray,
    truths: np.ndarray,
    todo: deque,
) -> None:
    """Queue what is left to search past atom ``w``'s crossings at ``tau`` that did not
    matter (rows ``rows``, in their sub-intervals ``k``, states ``past`` there), as
    :func:`_search` describes.

    Another atom whose sub-interval is searched from its start anyway is not searched
    again from ``tau``: that search finds its first flip, and goes on from there if the
    flip does not matter. So every crossing is located from one bracket whatever order
    the atoms are searched in (an order that depends on the other instances), and an
    instance of an ensemble gives a single run's results bit for bit.
    """
    later = relevant[:, w, rows].copy()  # (K, rows)
    later[np.arange(later.shape[0])[:, None] <= k] = False
    again = where_true(np.logical_or.reduce(later, axis=0))
    if again.size:
        todo.append((w, rows[again], np.argmax(later[:, again], axis=0), None, None))
    found = ~np.isnan(tau)  # (NaN: not located, nothing ahead; see _foregone)
    if not every(found):
        rows, k, tau, past = rows[found], k[found], tau[found], past[found]
        if rows.size == 0:
            return
    st = ens.states[a]
    sub = seg.idx[rows]
    now = watch_truth(ens, a, sub, past, seg.t0[rows] + tau)
    for v in range(now.shape[0]):
        ahead = (now[v] != truths[k + 1, v, rows]) & st.watched[v, sub]
        if v != w:
            ahead &= ~relevant[k, v, rows]
        ahead = where_true(ahead)
        if ahead.size:
            todo.append((v, rows[ahead], k[ahead], tau[ahead], now[v, ahead]))


def _relevant(
    ens: Ensemble,
    a: int,
    idx: np.ndarray,
    flips: np.ndarray,
    points: list[tuple[np.ndarray, np.ndarray]],
) -> np.ndarray:
    """Keep only flips that can matter, so a run does not stop at every one of them.

    If atom ``w`` is the only atom of its guard (invariant) that flipped inside a
    sub-interval, the guard's truth right after the flip equals its truth at the end of
    that sub-interval. A guard false there was not enabled by the flip (a ball's apex flips
    ``v < 0`` while ``h <= 0`` is false); an invariant true there was not violated.
    """
    st = ens.states[a]
    watches = st.ca.watches
    keep = flips.copy()
    if idx.size == 1 and st.ca.row_owners and FLOAT_PATHS.on:
        relevant_one(st, idx, keep, points)
        return keep
    for k in range(flips.shape[0]):
        x, t = points[k + 1]
        for w, watch in enumerate(watches):
            cols = where_true(flips[k, w])
            if cols.size == 0 or watch.observer:  # a requirement's crossing always matters
                continue
            shared = np.zeros(cols.size, bool)
            for v, other in enumerate(watches):
                if v != w and other.owner is watch.owner:
                    shared |= flips[k, v, cols]
            rows = cols[~shared]
            if rows.size == 0:
                continue
            keep[k, w, rows[~owner_matters(st, w, idx[rows], x[rows], t[rows])]] = False
    return keep

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

All of this runs inside :meth:`Simulator.run <hybridteam.engine.simulator.Simulator.run>`,
which ignores floating-point errors for the whole run (a secant through equal margins is
NaN, and is replaced): the search sets no error state of its own, a cost per trial.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, filled, some, spread, where_true
from hybridteam.dynamics import rk
from hybridteam.engine.compiled import Ctx
from hybridteam.engine.drivers import derivative
from hybridteam.engine.step import AgentStep, state_at

if TYPE_CHECKING:
    from hybridteam.engine.ensemble import Ensemble

MAX_ITER = 200

Evaluator = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``ev(positions, tau) -> (truth, margin)`` of one atom for some of a search's candidates."""


def watch_truth(ens: Ensemble, a: int, idx: np.ndarray, x: np.ndarray,
                t: np.ndarray, full: bool = False) -> np.ndarray:
    """Truth of every watched atom of agent ``a`` at state ``x`` (rows) for instances idx
    (``full``: they are every instance, in order, so gathers can be views)."""
    st = ens.states[a]
    out = np.empty((len(st.ca.watches), idx.size), bool)
    sel = slice(None) if full else idx
    v, p = st.v[sel], st.p[sel]
    ctx: Ctx | None = None
    mode = -1
    for w, watch in enumerate(st.ca.watches):
        if watch.mode != mode:
            mode = watch.mode
            ctx = Ctx(x, v, p, t, t - st.entry[sel, mode])
        out[w] = watch.atom.truth(ctx)  # assignment broadcasts scalars
    return out


def find_crossings(ens: Ensemble, idx: np.ndarray, x_end: list[np.ndarray],
                   steps: list[AgentStep]) -> tuple[np.ndarray, list[np.ndarray | None], dict]:
    """Earliest located crossing time (relative to the step start) per instance of ``idx``.

    ``x_end[a]`` is agent ``a``'s state at the end of the step for those instances.
    Returns ``inf`` where nothing relevant crossed, and each agent's atom truths at the end
    of the step (None for agents without watched atoms), which stay valid where nothing
    crossed, and the true states computed at trial times ({agent: {(row, tau): x}}) so
    the engine need not integrate to the crossing again. Updates nothing.
    """
    best = filled(idx.size, np.inf)
    best_lo = filled(idx.size, np.inf)
    thetas = ens.thetas
    end_truths: list[np.ndarray | None] = []
    cache: dict[int, dict] = {}
    for a, st in enumerate(ens.states):
        if not st.ca.watches:
            end_truths.append(None)
            continue
        end, flips = _flips(ens, a, idx, x_end[a], steps[a], thetas)
        end_truths.append(end)  # None: no atom watched, nothing to refresh
        if flips is None:
            continue
        seg = _search(ens, a, idx, steps[a], thetas, *flips, best, best_lo)
        if seg is not None:
            cache[a] = seg.true_states
    return best, end_truths, cache


def _flips(ens: Ensemble, a: int, idx: np.ndarray, x_end: np.ndarray, step: AgentStep,
           thetas: np.ndarray
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
    h, t0 = ens.h[idx], ens.t0[idx]
    t1 = t0 + h
    start = st.truth[:, sel]
    pos = where_true(np.logical_or.reduce(watched, axis=0))  # rows with some atom watched
    part = pos.size < m
    if part:
        end = start.copy()
        end[:, pos] = watch_truth(ens, a, idx[pos], x_end[pos], t1[pos])
    else:
        end = watch_truth(ens, a, idx, x_end, t1, full)
    truths = [start]
    checks = thetas.size - 2
    if checks == 0 and not some(watched & (end != start)):
        return end, None
    points: list[tuple[np.ndarray, np.ndarray]] = [(step.x0, t0)]
    if checks:
        k = pos.size
        rows = np.concatenate([pos] * checks)
        tau = thetas[1:-1].repeat(k) * h[rows]
        x_all = state_at(ens, a, idx[rows], tau, step, dense=True, rows=rows)
        t_all = t0[rows] + tau
        tr_all = watch_truth(ens, a, idx[rows], x_all, t_all)
        for c in range(checks):
            span = slice(c * k, (c + 1) * k)
            if part:  # rows not evaluated stay at the start: no flip there, never read
                x_c, t_c, tr_c = step.x0.copy(), t0.copy(), start.copy()
                x_c[pos], t_c[pos], tr_c[:, pos] = x_all[span], t_all[span], tr_all[:, span]
                points.append((x_c, t_c))
                truths.append(tr_c)
            else:
                points.append((x_all[span], t_all[span]))
                truths.append(tr_all[:, span])
    points.append((x_end, t1))
    truths.append(end)
    all_truths = np.stack(truths)  # (K + 1, nw, m)
    flips = all_truths[1:] != all_truths[:-1]
    flips &= watched
    if not some(flips):
        return end, None
    return end, (_relevant(ens, a, idx, flips, points), all_truths)


def _search(ens: Ensemble, a: int, idx: np.ndarray, step: AgentStep, thetas: np.ndarray,
            relevant: np.ndarray, truths: np.ndarray, best: np.ndarray, best_lo: np.ndarray
            ) -> _Segment | None:
    """Locate agent ``a``'s relevant flips, lowering ``best`` (the earliest crossing per
    instance over all agents so far) and ``best_lo`` (the bracket's lower end) in place.
    Returns the segment searched on (its true states), or None if nothing was searched."""
    h = ens.h[idx]
    first = np.argmax(relevant, axis=0)  # (nw, m): first relevant sub-interval
    has = relevant.any(axis=0)
    # atoms in order of their first sub-interval: the earliest crossing is found first and
    # later atoms only need one probe to show they do not cross before it
    order = sorted(range(relevant.shape[1]),
                   key=lambda w: float(first[w][has[w]].min()) if some(has[w]) else 9.0)
    seg: _Segment | None = None
    for w in order:
        cand = where_true(has[w])
        if cand.size == 0:
            continue
        if seg is None:
            seg = _Segment(ens, a, idx, step)
        k = first[w, cand]
        lo = thetas[k] * h[cand]
        hi = thetas[k + 1] * h[cand]
        truth_lo = truths[k, w, cand]
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
            cand, lo, hi, truth_lo = cand[keep], lo[keep], hi[keep], truth_lo[keep]
            if cand.size == 0:
                continue
        tau_lo, tau = seg.locate(w, cand, lo, hi, truth_lo)
        better = tau < best[cand]
        best[cand[better]] = tau[better]
        best_lo[cand[better]] = tau_lo[better]
    return seg


def _relevant(ens: Ensemble, a: int, idx: np.ndarray, flips: np.ndarray,
              points: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Keep only flips that can matter, so a run does not stop at every one of them.

    If atom ``w`` is the only atom of its guard (invariant) that flipped inside a
    sub-interval, the guard's truth right after the flip equals its truth at the end of
    that sub-interval. A guard false there was not enabled by the flip (a ball's apex flips
    ``v < 0`` while ``h <= 0`` is false); an invariant true there was not violated.
    """
    st = ens.states[a]
    watches = st.ca.watches
    keep = flips.copy()
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
            sub = idx[rows]
            ctx = Ctx(x[rows], st.v[sub], st.p[sub], t[rows],
                      t[rows] - st.entry[sub, watch.mode])
            value = spread(watch.owner(ctx), rows.shape)
            keep[k, w, rows[value if watch.invariant else ~value]] = False
    return keep


class _Segment:
    """Agent ``a``'s motion over the current step, for the instances being searched.

    Built once per step and agent: the dense-output coefficients and the derivative of the
    flowing instances are prepared once, so each trial point costs a handful of array
    operations.
    """

    def __init__(self, ens: Ensemble, a: int, idx: np.ndarray, step: AgentStep) -> None:
        self.ens, self.a, self.idx, self.step = ens, a, idx, step
        self.st = ens.states[a]
        self.t0 = ens.t0[idx]
        self.tol = np.maximum(ens.settings.event_tol,
                              4 * np.finfo(float).eps * np.abs(self.t0 + ens.h[idx]))
        self.has_rk = some(step.rk)
        self.true_states: dict[tuple[int, float], np.ndarray] = {}

    def evaluator(self, w: int, rows: np.ndarray, dense: bool) -> Evaluator:
        """``ev(pos, tau) -> (truth, margin)`` for the candidates ``rows[pos]``.

        Everything a trial point needs is gathered once per search: start states and
        inputs (kinematic plants), dense-output coefficients, or the derivative of the
        flowing instances; true states computed here are remembered so the engine does not
        integrate to the crossing a second time.
        """
        st, sub = self.st, self.idx[rows]
        watch = st.ca.watches[w]
        atom, plant = watch.atom, st.ca.plant
        x0, u = self.step.x0[rows], self.step.u[rows]
        v, p, t0 = st.v[sub], st.p[sub], self.t0[rows]
        entry = st.entry[sub, watch.mode]
        is_rk = self.step.rk[rows]
        any_rk = self.has_rk and some(is_rk)
        ens, a = self.ens, self.a
        derivs: dict[bytes, object] = {}

        def state(pos: np.ndarray, tau: np.ndarray) -> np.ndarray:
            if not any_rk:
                return plant.propagate(x0[pos], u[pos], tau)
            if dense:
                return state_at(ens, a, sub[pos], tau, self.step, rows=rows[pos], dense=True)
            out = np.empty((pos.size, x0.shape[1]))
            flow = is_rk[pos]
            if not every(flow):
                ex = pos[~flow]
                out[~flow] = plant.propagate(x0[ex], u[ex], tau[~flow])
            fp = pos[flow]
            key = fp.tobytes()
            if key not in derivs:
                derivs[key] = derivative(ens, a, sub[fp])
            step = rk.step(derivs[key], t0[fp], x0[fp], tau[flow],  # type: ignore[arg-type]
                           ens.settings.rtol, ens.settings.atol, estimate=False)
            out[flow] = step.x1
            for r, tt, x in zip(rows[fp].tolist(), tau[flow].tolist(), step.x1, strict=True):
                self.true_states[(r, tt)] = x
            return out

        def ev(pos: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t = t0[pos] + tau
            ctx = Ctx(state(pos, tau), v[pos], p[pos], t, t - entry[pos])
            truth, margin = atom.truth_and_margin(ctx)
            # (read only: the search copies what it keeps)
            return spread(truth, tau.shape), spread(np.asarray(margin, dtype=float), tau.shape)

        return ev

    def locate(self, w: int, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray,
               truth_lo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Final bracket ``(lo, hi)`` of atom ``w``'s crossing, on the exact flow.

        Kinematic plants are searched directly on their closed form. For Runge–Kutta
        flows the search first runs on the step's dense output (no derivative evaluations).
        The interpolant's error is smooth, so one Newton correction from the *true* margin
        at that estimate (slope from the interpolant) lands within the tolerance; two true
        steps confirm the bracket. Where they do not, the bracket is widened a
        thousandfold at a time until confirmed, and finished on true steps.
        """
        tol = self.tol[rows]
        exact = self.evaluator(w, rows, dense=False)
        if not self.has_rk or not some(self.step.rk[rows]):
            return _illinois(exact, lo, hi, truth_lo, tol)
        span_lo, span_hi = lo.copy(), hi.copy()
        dense = self.evaluator(w, rows, dense=True)
        everyone = np.arange(rows.size)
        _, g = _illinois(dense, lo.copy(), hi.copy(), truth_lo, tol)
        d = np.maximum(1e-6 * (span_hi - span_lo), 8 * tol)
        a_, b_ = np.maximum(span_lo, g - d), np.minimum(span_hi, g + d)
        both = dense(np.concatenate([everyone, everyone]), np.concatenate([b_, a_]))[1]
        slope = (both[: rows.size] - both[rows.size:]) / (b_ - a_)  # rows are independent
        m_g = exact(everyone, g)[1]
        g1 = g - m_g / slope
        guess = np.where(np.isfinite(g1) & (g1 > span_lo) & (g1 < span_hi), g1, g)
        new_lo, new_hi = span_lo.copy(), span_hi.copy()
        m_lo = filled(rows.size, np.nan)
        m_hi = filled(rows.size, np.nan)
        todo = np.arange(rows.size)
        # half a tolerance either side of the guess, less the rounding of guess -/+ width:
        # a first bracket that confirms is then at most tol wide, final without a third
        # true step (at tol = 1e-12 and guesses of order 1, rounding alone made it
        # 1.0001 tol, and the search paid one more step to halve it)
        width = 0.5 * tol - np.spacing(np.abs(guess) + tol)
        for _ in range(6):
            if todo.size == 0:
                break
            a_ = np.maximum(span_lo[todo], guess[todo] - width[todo])
            b_ = np.minimum(span_hi[todo], guess[todo] + width[todo])
            tt, mm = exact(np.concatenate([todo, todo]), np.concatenate([a_, b_]))  # one step
            ta, tb, ma, mb = tt[: todo.size], tt[todo.size:], mm[: todo.size], mm[todo.size:]
            ok = (ta == truth_lo[todo]) & (tb != truth_lo[todo])
            sel = todo[ok]
            new_lo[sel], new_hi[sel], m_lo[sel], m_hi[sel] = a_[ok], b_[ok], ma[ok], mb[ok]
            todo = todo[~ok]
            width = width * 1000.0
        return _illinois(exact, new_lo, new_hi, truth_lo, tol, m_lo=m_lo, m_hi=m_hi)


def _illinois(ev: Evaluator, lo: np.ndarray, hi: np.ndarray, truth0: np.ndarray,
              tol: np.ndarray, m_lo: np.ndarray | None = None, m_hi: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Narrow ``[lo, hi]`` (original truth at lo, flipped at hi) to ``tol``; return it.

    Regula falsi with the Anderson–Björck correction. Trial points are kept at least half
    a tolerance inside the bracket: when the crossing sits at an end (a strict comparison
    starting exactly on its boundary, or a margin of 1e-12 at one end) the next trial
    collapses the bracket at once instead of crawling. A bisection replaces the secant
    whenever three rounds failed to halve the bracket, which bounds the worst case.
    """
    size = lo.size
    everyone = np.arange(size)
    if m_lo is None or some(np.isnan(m_lo)):
        need = everyone if m_lo is None else where_true(np.isnan(m_lo))
        m_lo = np.empty(size) if m_lo is None else m_lo
        m_hi = np.empty(size) if m_hi is None else m_hi
        # both ends in one evaluation (rows are independent: the same values as two)
        ends = ev(np.concatenate([need, need]), np.concatenate([lo[need], hi[need]]))[1]
        m_lo[need], m_hi[need] = ends[: need.size], ends[need.size:]
    ma, mb = m_lo, m_hi
    assert mb is not None
    kept = np.zeros(size, np.int8)  # +1: hi survived last round, -1: lo survived
    slow = np.zeros(size, np.int8)  # rounds in a row that did not halve the bracket
    for _ in range(MAX_ITER):
        open_ = where_true(hi - lo > tol)
        if open_.size == 0:
            break
        # while every bracket is open (a single run's one bracket, mostly), views, not copies
        k: slice | np.ndarray = slice(None) if open_.size == size else open_
        a_, b_, fa, fb, tl = lo[k], hi[k], ma[k], mb[k], tol[k]
        width = b_ - a_
        c = b_ - fb * width / (fb - fa)  # (the run ignores floating-point errors)
        c = np.where(np.isfinite(c) & (slow[k] < 3), c, 0.5 * (a_ + b_))
        c = np.minimum(np.maximum(c, a_ + 0.5 * tl), b_ - 0.5 * tl)  # np.clip's values
        tc, mc = ev(open_, c)
        to_lo = tc == truth0[k]  # c has the original truth: it becomes the new lo
        scale = np.where(to_lo, 1 - mc / fa, 1 - mc / fb)
        new_lo, new_hi = np.where(to_lo, c, a_), np.where(to_lo, b_, c)
        slow[k] = np.where(new_hi - new_lo > 0.5 * width, slow[k] + 1, 0)
        survivor = np.where(to_lo, np.int8(1), np.int8(-1))
        again = kept[k] == survivor
        # Anderson–Björck: the end that survives again has its value scaled by
        # 1 - f(c)/f(replaced end) (0.5 when that is not positive), which pulls the next
        # secant across the root instead of creeping from one side as regula falsi does
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, 0.5)
        new_ma = np.where(to_lo, mc, np.where(again, scale * fa, fa))
        mb[k] = np.where(to_lo, np.where(again, scale * fb, fb), mc)
        ma[k], lo[k], hi[k] = new_ma, new_lo, new_hi
        kept[k] = survivor
    return lo, hi

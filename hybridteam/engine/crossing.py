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
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.compiled import Ctx

if TYPE_CHECKING:
    from hybridteam.engine.simulator import Simulator

MAX_ITER = 200


def _truth_margin(sim: Simulator, a: int, w: int, idx: np.ndarray, x: np.ndarray,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    st = sim.states[a]
    watch = st.ca.watches[w]
    ctx = Ctx(x, st.v[idx], st.p[idx], t, t - st.entry[idx, watch.mode])
    truth = np.broadcast_to(watch.atom.truth(ctx), idx.shape)
    margin = np.broadcast_to(watch.atom.margin(ctx), idx.shape)
    return truth, np.array(margin, dtype=float)


def watch_truth(sim: Simulator, a: int, idx: np.ndarray, x: np.ndarray,
                t: np.ndarray) -> np.ndarray:
    """Truth of every watched atom of agent ``a`` at state ``x`` (rows) for instances idx."""
    st = sim.states[a]
    out = np.zeros((len(st.ca.watches), idx.size), bool)
    for w, watch in enumerate(st.ca.watches):
        ctx = Ctx(x, st.v[idx], st.p[idx], t, t - st.entry[idx, watch.mode])
        out[w] = np.broadcast_to(watch.atom.truth(ctx), idx.shape)
    return out


def find_crossings(sim: Simulator, idx: np.ndarray, x_end: list[np.ndarray],
                   steps: list[dict]) -> np.ndarray:
    """Earliest located crossing time (relative to the step start) per instance of ``idx``.

    ``x_end[a]`` is agent ``a``'s state at the end of the step for those instances;
    returns ``inf`` where nothing relevant crossed. Updates nothing.
    """
    h = sim.h[idx]
    t0 = sim.t0[idx]
    best = np.full(idx.size, np.inf)
    checks = sim.settings.crossing_checks
    thetas = [0.0] + [(k + 1) / (checks + 1) for k in range(checks)] + [1.0]
    for a, st in enumerate(sim.states):
        ca = st.ca
        if not ca.watches:
            continue
        watched = st.active[np.ix_(idx, [w.mode for w in ca.watches])].T  # (nw, m)
        if not watched.any():
            continue
        truths = [st.truth[:, idx]]
        points: list[tuple[np.ndarray, np.ndarray]] = [(steps[a]["x0"], t0)]
        for theta in thetas[1:]:
            if theta == 1.0:
                x_th = x_end[a]
            else:
                x_th = sim.state_at(a, idx, np.full(idx.size, theta) * h, steps[a],
                                    dense=True)
            t_th = t0 + theta * h
            points.append((x_th, t_th))
            truths.append(watch_truth(sim, a, idx, x_th, t_th))
        flips = np.stack([watched & (truths[k] != truths[k - 1])
                          for k in range(1, len(truths))])  # (K, nw, m)
        if not flips.any():
            continue
        relevant = _relevant(sim, a, idx, flips, points)
        first = np.argmax(relevant, axis=0)  # (nw, m): first relevant sub-interval
        has = relevant.any(axis=0)
        for w in range(len(ca.watches)):
            cand = np.flatnonzero(has[w])
            if cand.size == 0:
                continue
            k = first[w, cand]
            lo = np.asarray(thetas)[k] * h[cand]
            hi = np.asarray(thetas)[k + 1] * h[cand]
            truth_lo = np.stack(truths)[k, w, cand]
            tau = _locate(sim, a, w, idx[cand], lo, hi, truth_lo, steps[a], cand)
            best[cand] = np.minimum(best[cand], tau)
    return best


def _relevant(sim: Simulator, a: int, idx: np.ndarray, flips: np.ndarray,
              points: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Keep only flips that can matter, so a run does not stop at every one of them.

    If atom ``w`` is the only atom of its guard (invariant) that flipped inside a
    sub-interval, the guard's truth right after the flip equals its truth at the end of
    that sub-interval. A guard false there was not enabled by the flip (a ball's apex flips
    ``v < 0`` while ``h <= 0`` is false); an invariant true there was not violated.
    """
    st = sim.states[a]
    watches = st.ca.watches
    keep = flips.copy()
    for k in range(flips.shape[0]):
        x, t = points[k + 1]
        for w, watch in enumerate(watches):
            cols = np.flatnonzero(flips[k, w])
            if cols.size == 0:
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
            value = np.broadcast_to(watch.owner(ctx), rows.shape)
            keep[k, w, rows[value if watch.invariant else ~value]] = False
    return keep


def _locate(sim: Simulator, a: int, w: int, sub: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            truth0: np.ndarray, step: dict, cand: np.ndarray) -> np.ndarray:
    """Crossing time within ``[lo, hi]``: on the exact flow, cheaply where possible.

    Kinematic plants are searched directly on their closed form. For Runge–Kutta flows the
    search first runs on the step's dense output (no derivative evaluations), then a narrow
    bracket around that estimate is confirmed with true steps — widened a thousandfold at a
    time while the interpolant's error exceeds it — and finished on true steps. Few true
    steps are needed, and the answer is as accurate as a direct search.
    """
    if not step["rk"][cand].any():
        return _illinois(sim, a, w, sub, lo, hi, truth0, step, cand, dense=False)
    guess = _illinois(sim, a, w, sub, lo.copy(), hi.copy(), truth0, step, cand, dense=True)
    t0 = sim.t0[sub]
    tol = np.maximum(sim.settings.event_tol, 4 * np.finfo(float).eps * np.abs(t0 + hi))
    new_lo, new_hi = lo.copy(), hi.copy()
    todo = np.arange(sub.size)
    width = 4 * tol
    for _ in range(6):
        if todo.size == 0:
            break
        a_ = np.maximum(lo[todo], guess[todo] - width[todo])
        b_ = np.minimum(hi[todo], guess[todo] + width[todo])
        ta = _probe(sim, a, w, sub, a_, todo, step, cand)
        tb = _probe(sim, a, w, sub, b_, todo, step, cand)
        ok = (ta == truth0[todo]) & (tb != truth0[todo])
        new_lo[todo[ok]], new_hi[todo[ok]] = a_[ok], b_[ok]
        todo = todo[~ok]
        width = width * 1000.0
    return _illinois(sim, a, w, sub, new_lo, new_hi, truth0, step, cand, dense=False)


def _probe(sim: Simulator, a: int, w: int, sub: np.ndarray, tau: np.ndarray,
           rows: np.ndarray, step: dict, cand: np.ndarray) -> np.ndarray:
    x = sim.state_at(a, sub[rows], tau, step, rows=cand[rows])
    return _truth_margin(sim, a, w, sub[rows], x, sim.t0[sub[rows]] + tau)[0]


def _illinois(sim: Simulator, a: int, w: int, sub: np.ndarray, lo: np.ndarray,
              hi: np.ndarray, truth0: np.ndarray, step: dict, cand: np.ndarray, *,
              dense: bool) -> np.ndarray:
    """Narrow ``[lo, hi]`` (original truth at lo, flipped at hi) to ``event_tol``.

    Trial points are kept at least half a tolerance inside the bracket: when the crossing
    sits at an end (a strict comparison starting exactly on its boundary, or a margin of
    1e-12 at one end) the next trial collapses the bracket at once instead of crawling.
    A bisection replaces the secant whenever two rounds failed to halve the bracket.
    """
    t0 = sim.t0[sub]
    tol = np.maximum(sim.settings.event_tol, 4 * np.finfo(float).eps * np.abs(t0 + hi))

    def at(tau: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = sim.state_at(a, sub[rows], tau, step, rows=cand[rows], dense=dense)
        return _truth_margin(sim, a, w, sub[rows], x, t0[rows] + tau)

    everyone = np.arange(sub.size)
    _, ma = at(lo, everyone)
    _, mb = at(hi, everyone)
    kept = np.zeros(sub.size, np.int8)  # +1: hi survived last round, -1: lo survived
    slow = np.zeros(sub.size, np.int8)  # rounds in a row that did not halve the bracket
    for _ in range(MAX_ITER):
        open_ = np.flatnonzero(hi - lo > tol)
        if open_.size == 0:
            break
        a_, b_, fa, fb, tl = lo[open_], hi[open_], ma[open_], mb[open_], tol[open_]
        width = b_ - a_
        with np.errstate(all="ignore"):
            c = b_ - fb * width / (fb - fa)
        c = np.where(np.isfinite(c) & (slow[open_] < 2), c, 0.5 * (a_ + b_))
        c = np.clip(c, a_ + 0.5 * tl, b_ - 0.5 * tl)
        tc, mc = at(c, open_)
        to_lo = tc == truth0[open_]  # c has the original truth: it becomes the new lo
        lo[open_] = np.where(to_lo, c, a_)
        hi[open_] = np.where(to_lo, b_, c)
        slow[open_] = np.where(hi[open_] - lo[open_] > 0.5 * width, slow[open_] + 1, 0)
        survivor = np.where(to_lo, 1, -1).astype(np.int8)
        again = kept[open_] == survivor
        # Illinois: an end that survives twice in a row has its value halved
        ma[open_] = np.where(to_lo, mc, np.where(again, 0.5 * fa, fa))
        mb[open_] = np.where(to_lo, np.where(again, 0.5 * fb, fb), mc)
        kept[open_] = survivor
    return hi

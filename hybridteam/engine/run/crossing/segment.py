"""One step's motion for a crossing search, and the bracket narrowing on it.

:class:`Segment` holds an agent's motion over the current step for the instances being
searched (dense output, start states, the derivative of the flowing ones) and answers what
:mod:`~hybridteam.engine.run.crossing.search` asks of a trial time: an atom's truth and
margin, off the dense output or as accurate as a step, the state there, whether a crossing
there matters. :func:`~.illinois.illinois` narrows a bracket to the event tolerance.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, filled, gather, some, spread, where_true
from hybridteam.dynamics import rk
from hybridteam.engine.compile.compiled import Ctx, Row
from hybridteam.engine.run.crossing.floats import DenseRow
from hybridteam.engine.run.crossing.illinois import Evaluator, OneEvaluator, illinois, illinois_one
from hybridteam.engine.run.drivers import derivative
from hybridteam.engine.run.step import AgentStep, dense_reader, state_at
from hybridteam.floatpaths import FLOAT_PATHS

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.state import AgentState


def owner_matters(
    st: AgentState, w: int, sub: np.ndarray, x: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """Whether the guard that atom ``w`` of ``st``'s agent belongs to is true (its
    invariant false) at states ``x`` and times ``t`` of instances ``sub``: where a flip of
    the atom there can matter."""
    watch = st.ca.watches[w]
    ctx = Ctx(
        x,
        gather(st.v, sub),
        gather(st.p, sub),
        t,
        t - st.entry[:, watch.mode][sub],
        q=(st.active, sub),
    )
    assert watch.owner is not None  # (a requirement's observer has none and is not judged)
    value = spread(watch.owner(ctx), sub.shape)
    return ~value if watch.invariant else value


class Segment:
    """Agent ``a``'s motion over the current step, for the instances being searched.

    Built once per step and agent: the dense-output coefficients and the derivative of the
    flowing instances are prepared once, so each trial point costs a handful of array
    operations.
    """

    def __init__(self, ens: Ensemble, a: int, idx: np.ndarray, step: AgentStep) -> None:
        self.ens, self.a, self.idx, self.step = ens, a, idx, step
        self.st = ens.states[a]
        self.t0, self.h = ens.t0[idx], ens.h[idx]
        self.tol = np.maximum(
            ens.settings.event_tol, 4 * np.finfo(float).eps * np.abs(self.t0 + self.h)
        )
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
        x0, u = gather(self.step.x0, rows), gather(self.step.u, rows)
        v, p, t0 = gather(st.v, sub), gather(st.p, sub), self.t0[rows]
        entry = st.entry[:, watch.mode][sub]
        is_rk = self.step.rk[rows]
        any_rk = self.has_rk and some(is_rk)
        ens, a = self.ens, self.a
        derivs: dict[bytes, rk.Derivative] = {}
        # one candidate (a single run's search): its trial points need no gathering
        alone = rows.size == 1
        # state_at's dense read, its lookups done once
        flowing = dense_reader(self.step, rows) if dense and any_rk and every(is_rk) else None

        def state(pos: np.ndarray, tau: np.ndarray) -> np.ndarray:
            if not any_rk:
                return plant.propagate(gather(x0, pos), gather(u, pos), tau)
            if dense:
                if flowing is not None:
                    return flowing(tau, None if alone and pos.size == 1 else pos)
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
            step = rk.step(
                derivs[key],
                t0[fp],
                x0[fp],
                tau[flow],
                ens.settings.rtol,
                ens.settings.atol,
                estimate=False,
            )
            ens.costs.true_steps += 1
            out[flow] = step.x1
            for r, tt, x in zip(rows[fp].tolist(), tau[flow].tolist(), step.x1, strict=True):
                self.true_states[(r, tt)] = x
            return out

        def ev(pos: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            if alone and pos.size == 1:
                t = t0 + tau
                ctx = Ctx(state(pos, tau), v, p, t, t - entry)
            else:
                t = t0[pos] + tau
                ctx = Ctx(state(pos, tau), v[pos], p[pos], t, t - entry[pos])
            truth, margin = atom.truth_and_margin(ctx)
            # (read only: the search copies what it keeps)
            return spread(truth, tau.shape), spread(np.asarray(margin, dtype=float), tau.shape)

        return ev

    def _one(self, w: int, rows: np.ndarray) -> _One | None:
        """What a float search of atom ``w`` reads for a search with one candidate
        (``rows``, a single run's) whose row flows and whose atom has a float form
        (:attr:`~hybridteam.expr.Atom.row`); else None."""
        watch = self.st.ca.watches[w]
        s = self.step.rk_step
        pos = self.step.rk_pos  # (set with rk_step)
        if (
            rows.size != 1
            or watch.atom.row is None
            or s is None
            or pos is None
            or not self.step.rk[rows[0]]
            or not FLOAT_PATHS.on
        ):
            return None
        return _One(self, watch, s, int(pos[rows[0]]), int(rows[0]))

    def dense_one(self, w: int, rows: np.ndarray) -> OneEvaluator | None:
        """``one(tau) -> (truth, margin)`` of atom ``w`` on the dense output, on Python
        floats, where :meth:`_one` allows (else None).

        The same operations as :meth:`evaluator`'s dense ``ev`` (``theta = tau / h``, the
        interpolant row by row, ``t = t0 + tau``, the atom's comparison and difference)
        on the same doubles: the same bits, without the dozen numpy calls per trial point
        that cost a single run's search more than the arithmetic."""
        one = self._one(w, rows)
        return None if one is None else one.atom

    def matters(self, w: int, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Whether atom ``w``'s crossing at ``tau`` (just past it) matters for ``rows``: its
        guard is true there, or its invariant false; a requirement's always does.

        ``search._relevant`` rules out most flips that do not matter before any search, from
        the truths at the end of the sub-interval; not those that share their sub-interval
        with another atom of the same guard. A ball's apex (``v < 0`` flips while ``h <= 0``
        is false) shares one with the impact when a step spans both: without this the run
        would stop at every apex for nothing.
        """
        watch = self.st.ca.watches[w]
        if watch.observer or watch.owner is None:
            return np.ones(rows.size, bool)
        return owner_matters(
            self.st, w, self.idx[rows], self.true_state(rows, tau), self.t0[rows] + tau
        )

    def true_state(self, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The state ``tau`` after the step start for ``rows`` (as accurate as a step), from
        the trial points' states where the search computed it; the others are computed and
        kept."""
        known = [self.true_states.get(key) for key in zip(rows.tolist(), tau.tolist(), strict=True)]
        miss = np.array([x is None for x in known], bool)
        out = np.empty((rows.size, self.step.x0.shape[1]))
        for i in where_true(~miss).tolist():
            out[i] = known[i]
        if some(miss):
            r = rows[miss]
            x = state_at(self.ens, self.a, self.idx[r], tau[miss], self.step, rows=r)
            out[miss] = x
            for key, xi in zip(zip(r.tolist(), tau[miss].tolist(), strict=True), x, strict=True):
                self.true_states[key] = xi
        return out

    def judge(
        self, w: int, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, truth_lo: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Locate atom ``w``'s crossing for ``rows`` where it matters: ``(tau_lo, tau,
        matters, x)``, with ``x`` the state just past each crossing that does not matter
        (where the search goes on from; NaN where it matters).

        Whether a flip matters is judged first on the step's dense output, as the truths
        at the checkpoints that found the flip were. A flip whose guard is false there
        (invariant true) does not matter, and its place on the dense output is where the
        search goes on: locating it on true steps (two Runge–Kutta steps) would only
        move that place by the interpolant's error. Every other flip is located on true
        steps, from the same dense estimate, and judged again on the true state. (A ball's
        apex shares its sub-interval with the impact and is such a flip; so are most
        flips that do not matter, the others being ruled out before any search.)
        Kinematic rows and requirements' atoms (whose crossings always matter) are
        located directly. Rows are independent: each gets what it gets alone.
        """
        watch = self.st.ca.watches[w]
        if (
            rows.size == 1
            and not watch.observer
            and watch.owner is not None
            and watch.owner.row is not None
        ):
            one = self._one(w, rows)
            if one is not None:
                return self._judge_one(one, w, rows, lo, hi, truth_lo)
        n, d = rows.size, self.step.x0.shape[1]
        tau_lo, tau = np.empty(n), np.empty(n)
        matters = np.ones(n, bool)
        x = np.full((n, d), np.nan)
        flows = self.step.rk[rows] if self.has_rk else np.zeros(n, bool)
        if watch.observer or watch.owner is None:
            flows = np.zeros(n, bool)
        if not every(flows):
            ex = where_true(~flows)
            tau_lo[ex], tau[ex] = self.locate(w, rows[ex], lo[ex], hi[ex], truth_lo[ex])
            matters[ex] = self.matters(w, rows[ex], tau[ex])
            self._fill_true(x, ex, rows, tau, matters)
        fl = where_true(flows)
        if fl.size == 0:
            return tau_lo, tau, matters, x
        r = rows[fl]
        d_lo, d_hi = illinois(
            self.evaluator(w, r, dense=True),
            lo[fl].copy(),
            hi[fl].copy(),
            truth_lo[fl],
            self.tol[r],
            one=self.dense_one(w, r),
        )
        x_d = dense_reader(self.step, r)(d_hi)
        on_dense = owner_matters(self.st, w, self.idx[r], x_d, self.t0[r] + d_hi)
        out = where_true(~on_dense)  # judged on the dense output: not located further
        tau_lo[fl[out]], tau[fl[out]], x[fl[out]] = d_lo[out], d_hi[out], x_d[out]
        matters[fl[out]] = False
        go = where_true(on_dense)
        if go.size:
            at = fl[go]
            tau_lo[at], tau[at] = self.locate(
                w, rows[at], lo[at], hi[at], truth_lo[at], on_dense=(d_lo[go], d_hi[go])
            )
            matters[at] = self.matters(w, rows[at], tau[at])
            self._fill_true(x, at, rows, tau, matters)
        return tau_lo, tau, matters, x

    def _judge_one(
        self,
        one: _One,
        w: int,
        rows: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        truth_lo: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`judge` for a single run's one flowing candidate whose atom and guard (or
        invariant) have float forms: the dense search and the judgement on floats, the
        same operations as the array version's on the same doubles (the same bits)."""
        a, b = illinois_one(
            one.atom, float(lo[0]), float(hi[0]), bool(truth_lo[0]), float(self.tol[rows[0]])
        )
        row = one.at_tau(b)
        watch = one.watch
        if bool(watch.owner.row(row)) == watch.invariant:  # does not matter on the dense output
            return np.array([a]), np.array([b]), np.zeros(1, bool), np.array([row.x], float)
        tau_lo, tau = self.locate(
            w, rows, lo, hi, truth_lo, on_dense=(np.array([a]), np.array([b]))
        )
        matters = self.matters(w, rows, tau)
        x = np.full((1, self.step.x0.shape[1]), np.nan)
        self._fill_true(x, np.zeros(1, np.intp), rows, tau, matters)
        return tau_lo, tau, matters, x

    def _fill_true(
        self, x: np.ndarray, at: np.ndarray, rows: np.ndarray, tau: np.ndarray, matters: np.ndarray
    ) -> None:
        """Fill ``x[at]`` with the true states ``tau`` after the start where the located
        crossing does not matter (the trial points computed them)."""
        need = at[~matters[at]]
        if need.size:
            x[need] = self.true_state(rows[need], tau[need])

    def locate(
        self,
        w: int,
        rows: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        truth_lo: np.ndarray,
        on_dense: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Final bracket ``(lo, hi)`` of atom ``w``'s crossing, on the exact flow.

        Kinematic plants are searched directly on their closed form. For Runge–Kutta
        flows the search first runs on the step's dense output (no derivative evaluations),
        to a bracket at most a tolerance wide (``on_dense``, where :meth:`judge` found it
        already) whose upper end is ``g``. One true step then computes the states at ``g``
        and half a tolerance either side of the bracket's middle: where those two confirm
        the bracket (the interpolant was that accurate, as a polynomial flow's is), it is
        final. Elsewhere, the interpolant's error being smooth, one Newton correction from
        the true margin at ``g`` (slope from the interpolant) lands within the tolerance,
        and a second true step confirms the bracket around it. Where that does not, the
        bracket is widened a thousandfold at a time until confirmed, and finished on true
        steps.
        """
        tol = self.tol[rows]
        exact = self.evaluator(w, rows, dense=False)
        if not self.has_rk or not some(self.step.rk[rows]):
            return illinois(exact, lo, hi, truth_lo, tol)
        span_lo, span_hi = lo.copy(), hi.copy()
        one = self.dense_one(w, rows)
        # (a single run's dense search runs on floats: no array evaluator to gather)
        dense = self.evaluator(w, rows, dense=True) if one is None else _unused
        n = rows.size
        everyone = np.arange(n)
        g_lo, g = (
            on_dense
            if on_dense is not None
            else illinois(dense, lo.copy(), hi.copy(), truth_lo, tol, one=one)
        )
        mid = 0.5 * (g_lo + g)
        # half a tolerance either side of a guess, less the rounding of guess -/+ width: a
        # bracket that confirms is then at most tol wide, final without another true step
        # (at tol = 1e-12 and guesses of order 1, rounding alone made it 1.0001 tol, and
        # the search paid one more step to halve it)
        width = 0.5 * tol - np.spacing(np.abs(mid) + tol)
        a_, b_ = np.maximum(span_lo, mid - width), np.minimum(span_hi, mid + width)
        tt, mm = exact(np.concatenate([everyone] * 3), np.concatenate([g, a_, b_]))  # one step
        if n == 1:  # a single run's bracket that confirms is final (what illinois returns)
            _, t_a, t_b = tt.tolist()
            if t_a == truth_lo[0] and t_b != truth_lo[0] and not b_[0] - a_[0] > tol[0]:
                return a_, b_
        ok = (tt[n : 2 * n] == truth_lo) & (tt[2 * n :] != truth_lo)
        new_lo, new_hi = span_lo.copy(), span_hi.copy()
        m_lo, m_hi = filled(n, np.nan), filled(n, np.nan)
        new_lo[ok], new_hi[ok], m_lo[ok], m_hi[ok] = (
            a_[ok],
            b_[ok],
            mm[n : 2 * n][ok],
            mm[2 * n :][ok],
        )
        todo = where_true(~ok)
        if todo.size == 0:
            return illinois(exact, new_lo, new_hi, truth_lo, tol, m_lo=m_lo, m_hi=m_hi)
        d = np.maximum(1e-6 * (span_hi - span_lo), 8 * tol)
        a_, b_ = np.maximum(span_lo, g - d), np.minimum(span_hi, g + d)
        if one is not None:
            both = np.array([one(float(b_[0]))[1], one(float(a_[0]))[1]])
        else:
            both = dense(np.concatenate([everyone, everyone]), np.concatenate([b_, a_]))[1]
        slope = (both[:n] - both[n:]) / (b_ - a_)  # rows are independent
        g1 = g - mm[:n] / slope
        guess = np.where(np.isfinite(g1) & (g1 > span_lo) & (g1 < span_hi), g1, g)
        width = 0.5 * tol - np.spacing(np.abs(guess) + tol)
        for _ in range(6):
            if todo.size == 0:
                break
            a_ = np.maximum(span_lo[todo], guess[todo] - width[todo])
            b_ = np.minimum(span_hi[todo], guess[todo] + width[todo])
            tt, mm = exact(np.concatenate([todo, todo]), np.concatenate([a_, b_]))  # one step
            ta, tb, ma, mb = tt[: todo.size], tt[todo.size :], mm[: todo.size], mm[todo.size :]
            ok = (ta == truth_lo[todo]) & (tb != truth_lo[todo])
            sel = todo[ok]
            new_lo[sel], new_hi[sel], m_lo[sel], m_hi[sel] = a_[ok], b_[ok], ma[ok], mb[ok]
            todo = todo[~ok]
            width = width * 1000.0
        return illinois(exact, new_lo, new_hi, truth_lo, tol, m_lo=m_lo, m_hi=m_hi)


def _unused(pos: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The array evaluator of a search that runs on floats: never called."""
    raise AssertionError("a search with a float evaluator evaluated on arrays")


class _One:
    """A single run's flowing row on the dense output (:class:`~.floats.DenseRow`) with one
    watched atom, read on floats: the context timed in the atom's mode, and its truth and
    margin."""

    __slots__ = ("entered", "reader", "watch")

    def __init__(self, seg: Segment, watch, s: rk.Step, at: int, r: int) -> None:
        sub = int(seg.idx[r])
        self.watch, self.entered = watch, float(seg.st.entry[sub, watch.mode])
        self.reader = DenseRow(seg.st, sub, s, at, float(seg.t0[r]))

    def at_tau(self, tau: float) -> Row:
        """The row's context ``tau`` after the step start, off the dense output."""
        row = self.reader.at_tau(tau)
        row.t_in = row.t - self.entered
        return row

    def atom(self, tau: float) -> tuple[bool, float]:
        return self.watch.atom.row(self.at_tau(tau))

"""Running drivers: inputs from laws and expressions, derivatives for the integrator, and
the zero-order hold of sampled laws.

These are the only places user laws are called. A law is given all instances that share it
at once (an ensemble of a thousand robots under one law is one call), and its output is
checked for shape and saturated to the actuator limits.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import all_finite, count_true, distinct, every, gather, some, where_true
from hybridteam.dynamics import rk
from hybridteam.dynamics.plants import saturate
from hybridteam.engine.compile.compiled import CAgent, Ctx, Driver
from hybridteam.engine.run.numerics import stop_broken_inputs
from hybridteam.errors import ModelError

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


def evaluate_driver(ca: CAgent, drv: Driver, ctx: Ctx) -> np.ndarray:
    """Plant inputs from a law or ``inputs:`` expressions, saturated to the limits."""
    m = ctx.x.shape[0]
    if drv.kind == "zero":
        return np.zeros((m, len(ca.plant.input_names)))
    if drv.inputs is not None:
        u = np.empty((m, len(drv.inputs)))
        for j, e in enumerate(drv.inputs):
            u[:, j] = e(ctx)
    else:
        u = _call_law(ca, drv, ctx, m)
    bounds = ca.bounds
    return u if bounds is None else saturate(u, *bounds)


def _call_law(ca: CAgent, drv: Driver, ctx: Ctx, m: int) -> np.ndarray:
    """The law's inputs, shape-checked. A law that fails or returns the wrong shape is a
    :class:`ModelError` at its binding, with what went wrong (``HYBRIDTEAM_DEBUG=1``
    re-raises the law's own exception instead, for its traceback)."""
    name = drv.law.name  # type: ignore[union-attr]  # (called for a law's drivers only)
    try:
        u = np.asarray(drv.law.fn(ca.law_context(ctx, drv)), dtype=float)  # type: ignore[union-attr]  # (ditto)
    except Exception as exc:
        if os.environ.get("HYBRIDTEAM_DEBUG"):
            raise
        detail = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        raise ModelError(
            (*drv.where, "use"),
            f"law '{name}' of agent '{ca.name}' failed: {type(exc).__name__}: {detail}",
        ) from exc
    expected = (m, len(ca.plant.input_names))
    if u.shape != expected:
        raise ModelError(
            (*drv.where, "use"),
            f"law '{name}' of agent '{ca.name}' returned "
            f"shape {u.shape}, expected {expected} (inputs "
            f"{', '.join(ca.plant.input_names)})",
        )
    return u


def derivative(ens: Ensemble, a: int, idx: np.ndarray) -> rk.Derivative:
    """``f(t, x)`` for agent ``a``'s instances ``idx`` under their current drivers."""
    st = ens.states[a]
    ca, plant = st.ca, st.ca.plant
    fixed_names = ca.fixed_names
    drv = st.driver[idx]
    v, p, entry = gather(st.v, idx), gather(st.p, idx), gather(st.entry, idx)
    # what does not change from one stage to the next is gathered once, per driver group
    groups = []
    # (one instance, a single run's: its one driver, without sorting out groups)
    drivers = [drv.item(0)] if drv.size == 1 else distinct(drv) if drv.size else []
    for d in drivers:
        D = ca.drivers[d]
        rows = where_true(drv == d) if drv.size > 1 else drv
        sel: slice | np.ndarray = slice(None) if rows.size == drv.size else rows
        entered = entry[:, D.owner][sel] if D.owner >= 0 and D.reads_t_in else None
        v_g, p_g = v[sel], p[sel]
        flows = []  # (column, expression or None, its value where it reads no state or time)
        for j, expr in enumerate(D.flow or ()):
            if expr is not None:
                fixed = expr.names <= fixed_names  # the same at every stage: evaluated once
                # (a fixed flow reads no state and no time: evaluated without them)
                value = expr(Ctx(None, v_g, p_g, None)) if fixed else None  # type: ignore[arg-type]
                flows.append((j, None if fixed else expr, value))
        groups.append(
            (
                D,
                sel,
                v_g,
                p_g,
                entered,
                None if st.inbox is None else st.inbox.view(idx[sel]),
                flows,
            )
        )
    whole = len(groups) == 1 and isinstance(groups[0][1], slice)

    def f(tt: np.ndarray, xx: np.ndarray) -> np.ndarray:
        out = np.zeros(xx.shape)
        for D, sel, v_g, p_g, entered, e, flows in groups:
            # (one group of every row, the common case: the arrays themselves, not views)
            tr, xr = (tt, xx) if whole else (tt[sel], xx[sel])
            # (t_in_mode is t where nothing reads it)
            ctx = Ctx(xr, v_g, p_g, tr, None if entered is None else tr - entered, e=e)
            if D.kind == "flow":
                for j, expr, value in flows:
                    out[sel, j] = value if expr is None else expr(ctx)
            elif plant.input_names:
                out[sel] = plant.derivative(ctx.x, evaluate_driver(ca, D, ctx))
        return out

    return f


def next_ticks(t: np.ndarray, period: float) -> np.ndarray:
    """The first tick ``k * period`` strictly after each time of ``t`` (``k`` whole).

    For a few times (a single run's) this is computed on Python floats: the array version's
    five operations cost their dispatch, about 1 µs each, for one number. ``math.floor`` of
    a finite float is that float's integer value, exactly, so both give the same bits."""
    if t.size <= 4:
        out = []
        for ti in t.tolist():
            q = ti / period
            if not math.isfinite(q):
                break  # math.floor refuses inf and NaN: the array version answers
            kf = float(math.floor(q)) + 1.0
            tick = kf * period
            out.append(tick if tick > ti else (kf + 1.0) * period)
        else:
            return np.array(out)
    k = np.floor(t / period) + 1
    nxt = k * period
    late = nxt <= t  # round-off put the k-th tick at or before t: the next one
    if some(late):
        nxt[late] = (k[late] + 1) * period
    return nxt


def sample_laws(ens: Ensemble, a: int, live: np.ndarray, changed: np.ndarray) -> None:
    """Evaluate held (sampled) inputs at ticks and where the law's mode was just entered.

    Instances are grouped by driver with boolean masks over the whole ensemble: in the
    common case every instance ticks under the same law, and the law sees all of them
    at once without any gathering.
    """
    st = ens.states[a]
    ca = st.ca
    if not ca.plant.input_names or live.size == 0:
        return
    t_all = ens.t
    if live.size == ens.n:
        due = t_all >= st.next_tick
    else:
        due = np.zeros(ens.n, bool)
        due[live] = t_all[live] >= st.next_tick[live]
    fresh: np.ndarray | None = None
    if changed.size and st.single_driver >= 0 and not some(due):
        # no tick: under one sampled law everywhere, only an instance whose law's mode
        # was entered at this instant samples (a message arrival's instant: none)
        D = ca.drivers[st.single_driver]
        if D.kind == "sampled" and not some(st.entry[changed, D.owner] == t_all[changed]):
            return
    if changed.size:
        fresh = np.zeros(ens.n, bool)
        fresh[changed] = True
        due |= fresh
    n_due = count_true(due)  # (once: with one driver and no entry, also whether all are due)
    if n_due == 0:
        return
    # the drivers in charge, in index order (one, usually, everywhere: no gathering then)
    single = st.single_driver >= 0
    for d in [st.single_driver] if single else distinct(st.driver[due]):
        D = ca.drivers[d]
        # (a copy only where it may be narrowed below: to the instances just entered)
        mine = (due if fresh is None else due.copy()) if single else due & (st.driver == d)
        if D.kind == "continuous":
            st.next_tick[mine] = np.inf
            continue
        if D.kind == "sampled" and fresh is not None:
            # re-sample on a tick, or when the law's mode was (re)entered just now (without
            # fresh instances, ``due`` holds only ticks)
            entered = fresh & (st.entry[:, D.owner] == t_all)
            mine &= entered | (t_all >= st.next_tick)
            if not some(mine):
                continue
        everyone = n_due == ens.n if mine is due else every(mine)
        rows = slice(None) if everyone else where_true(mine)
        t = t_all[rows]
        # (nothing entered at this instant: held inputs are still what their modes' entries
        # gave; only the next ticks are scheduled)
        if not (D.held and fresh is None):
            ctx = st.ctx(rows, t, D.owner, law=D.inputs is None, lazy=True)
            u = evaluate_driver(ca, D, ctx)
            st.u[rows] = u
            if not all_finite(u):
                where = np.arange(ens.n)[rows] if isinstance(rows, slice) else rows
                stop_broken_inputs(ens, a, where, u)
        if D.kind == "sampled":
            st.next_tick[rows] = next_ticks(t, D.period)
        else:
            st.next_tick[rows] = np.inf

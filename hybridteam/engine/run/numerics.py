"""Numerical failure is an outcome, not a hang: ``numerical_error`` and ``stiff``.

A flow that divides by zero, takes the root of a negative number or overflows, or a law
that returns NaN, makes a state or an input stop being a finite number; from then on the
integrator's error estimate is NaN and the step-size control can no longer make progress.
A flow that is stiff or oscillates far faster than the run's time scale drives the step
size toward zero, so the run would take practically forever. Both are diagnosed where they
happen and end only the instances concerned, with a message naming the agent, its mode,
the quantity and the time; the rest of an ensemble runs on.

The step-size floor is ``simulation.min_step`` when given, else ``1e-6`` of the duration
(a run that needs a million Runge–Kutta steps per agent takes minutes and is almost always
a modelling mistake; a model that really needs it says so with ``min_step``), and never
below what floating point can resolve at the current time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import all_finite, some

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.step import AgentStep

#: the default floor of the Runge–Kutta step, as a fraction of the run's duration
MIN_STEP_FRACTION = 1e-6


def step_floor(ens: Ensemble, t: np.ndarray) -> np.ndarray:
    """The smallest Runge–Kutta step allowed at times ``t``."""
    floor = ens.settings.min_step
    if floor is None:
        floor = MIN_STEP_FRACTION * max(ens.t_end, 1e-300)
    return np.maximum(floor, 16 * np.finfo(float).eps * np.abs(t))


def _leaf(ens: Ensemble, a: int, i: int) -> str:
    return ", ".join(ens.states[a].leaf_paths(i)) or "(root)"


def _driver_text(ens: Ensemble, a: int, i: int, column: int | None) -> str:
    """What drives agent ``a`` in instance ``i``: the flow of one state, or the law."""
    st = ens.states[a]
    drv = st.ca.drivers[int(st.driver[i])]
    names = st.ca.plant.state_names
    if drv.kind == "flow" and drv.flow is not None:
        cols = [column] if column is not None else range(len(names))
        return "flow " + ", ".join(
            f"{names[c]}: {e.source if (e := drv.flow[c]) else '0'}" for c in cols
        )
    if drv.law is not None:
        return f"law '{drv.law.name}'"
    if drv.inputs is not None:
        return "inputs: " + ", ".join(
            f"{n}: {e.source}" for n, e in zip(st.ca.plant.input_names, drv.inputs, strict=True)
        )
    return drv.kind


def stop_broken_states(
    ens: Ensemble,
    idx: np.ndarray,
    sel: slice | np.ndarray,
    t1: np.ndarray,
    x_end: list[np.ndarray],
    steps: list[AgentStep],
) -> None:
    """End with ``numerical_error`` the instances where a flow's derivative at the step's
    start, or the state a step produced, is not a finite number; they stay at the step's
    start (their last finite state). Runge–Kutta results that are not finite were already
    rejected (a smaller step may do), so what is left here is beyond any step size."""
    if all(all_finite(xe) for xe in x_end) and not any(
        s.start_bad is not None and some(s.start_bad) for s in steps
    ):
        return  # the usual case, in a few reductions
    accepted = ens.h[sel] > 0
    bad = np.zeros(idx.size, bool)
    for a in range(len(ens.states)):
        step = steps[a]
        start = step.start_bad if step.start_bad is not None else np.zeros(idx.size, bool)
        rows = ~bad & (start | (accepted & ~np.isfinite(x_end[a]).all(axis=1)))
        for r in np.flatnonzero(rows).tolist():
            _report_state(
                ens, a, int(idx[r]), step, r, x_end[a][r], float(t1[idx[r]]), bool(start[r])
            )
        bad |= rows
    if some(bad):
        back = idx[bad]
        t1[back] = ens.t[back]
        ens.h[back] = 0.0
        for a in range(len(ens.states)):
            x_end[a][bad] = steps[a].x0[bad]


def _report_state(
    ens: Ensemble,
    a: int,
    i: int,
    step: AgentStep,
    r: int,
    x: np.ndarray,
    t_to: float,
    at_start: bool,
) -> None:
    names = ens.states[a].ca.plant.state_names
    if at_start:
        assert step.rk_step is not None and step.rk_pos is not None
        k0 = step.rk_step.k[0][step.rk_pos[r]]
        col = int(np.flatnonzero(~np.isfinite(k0))[0])
        what = f"the derivative of state '{names[col]}' is {k0[col]}"
    else:
        col = int(np.flatnonzero(~np.isfinite(x))[0])
        what = f"state '{names[col]}' became {x[col]} in the step to t={t_to!r}"
    ens.finish(
        np.array([i]),
        "numerical_error",
        lambda i: (
            f"agent '{ens.cteam.agents[a].name}' in mode '{_leaf(ens, a, i)}' at "
            f"t={ens.when(i)}: {what} ({_driver_text(ens, a, i, col)})"
        ),
    )


def stop_collapsed_steps(
    ens: Ensemble, idx: np.ndarray, steps: list[AgentStep], rows: np.ndarray
) -> np.ndarray:
    """End with ``stiff`` the instances among ``idx[rows]`` whose Runge–Kutta step size
    fell below the floor (or stopped being a number); the agent named is the one with the
    largest error estimate. Returns the rows ended."""
    failed = rows[~(ens.h_rk[idx[rows]] >= step_floor(ens, ens.t[idx[rows]]))]
    for r in failed.tolist():
        i = int(idx[r])
        errs = [
            -1.0 if s.err is None else float(np.nan_to_num(s.err[r], nan=np.inf)) for s in steps
        ]
        a = int(np.argmax(errs))
        size = float(ens.h_rk[i])
        limit = float(step_floor(ens, ens.t[i : i + 1])[0])
        ens.finish(
            np.array([i]),
            "stiff",
            lambda i, a=a, size=size, limit=limit: (  # type: ignore[misc]  # default-bound lambda
                f"agent '{ens.cteam.agents[a].name}' in mode '{_leaf(ens, a, i)}' at "
                f"t={ens.when(i)}: the integrator's step size fell to {size:.3g} s, below "
                f"{limit:.3g} s ({_driver_text(ens, a, i, None)}): the flow changes too fast for "
                f"a run of {ens.t_end:g} s (it is stiff, oscillates, or blows up, or the run is "
                "far longer than its time scale); simulation.min_step sets the smallest step "
                "allowed"
            ),
        )
    return failed


def stop_broken_inputs(ens: Ensemble, a: int, rows: np.ndarray, u: np.ndarray) -> None:
    """End with ``numerical_error`` the instances ``rows`` where agent ``a``'s law or input
    expressions gave a value that is not a finite number (``u``: their inputs)."""
    ca = ens.cteam.agents[a]
    for k in np.flatnonzero(~np.isfinite(u).all(axis=1)).tolist():
        i = int(rows[k])
        col = int(np.flatnonzero(~np.isfinite(u[k]))[0])
        value = u[k, col]
        ens.finish(
            np.array([i]),
            "numerical_error",
            lambda i, col=col, value=value: (  # type: ignore[misc]  # default-bound lambda
                f"agent '{ca.name}' in mode '{_leaf(ens, a, i)}' at t={ens.when(i)}: input "
                f"'{ca.plant.input_names[col]}' is {value} ({_driver_text(ens, a, i, None)})"
            ),
        )

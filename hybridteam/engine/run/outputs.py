"""Output samples: the trace's regular time grid, recorded without stopping the run there.

Samples that fall inside a step are read off the step (dense output for flows, the exact
arc for kinematic plants); samples at the step's end are taken after its instant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, gather, some, where_true
from hybridteam.engine.run.step import AgentStep, state_at

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


def interpolate_samples(
    ens: Ensemble, idx: np.ndarray, t1: np.ndarray, steps: list[AgentStep]
) -> None:
    """Record output samples that fall strictly inside this step, without stopping there.

    Outputs do not constrain the integrator: flows are read off the step's dense
    output, kinematic plants off their exact arcs, all samples of a step in one call.
    Samples exactly at the step's end are taken after that instant's discrete steps,
    by :func:`record_samples`.
    """
    upcoming = ens.next_out if idx.size == ens.n else ens.next_out[idx]
    if not some(upcoming < t1):  # the next sample of each is not before t1
        return
    first = ens.out_k[idx]
    last = np.searchsorted(ens.sample_times, t1, side="left")  # samples < t1
    count = np.maximum(last - first, 0)
    rows = np.repeat(np.arange(idx.size), count)
    k = np.repeat(first, count) + (
        np.arange(rows.size) - np.repeat(np.cumsum(count) - count, count)
    )
    due = idx[rows]
    tau = ens.sample_times[k] - ens.t0[due]
    for a, st in enumerate(ens.states):
        x = state_at(ens, a, due, tau, steps[a], rows=rows, dense=True)
        ens.rec.sample(k, due, st.ca.name, x)
    moved = idx[count > 0]
    ens.out_k[moved] = last[count > 0]
    ens.next_out[moved] = ens.sample_after[ens.out_k[moved]]


def record_samples(
    ens: Ensemble, idx: np.ndarray, taken: tuple[np.ndarray, dict[str, np.ndarray]] | None
) -> None:
    """Record the output samples due at the current time of instances ``idx``, after the
    instant's discrete steps. ``taken``: the world's series as this instant's snapshot
    read them, ``(instances, values)`` (None: none), the same values for the same
    instances."""
    due = (
        where_true(ens.t >= ens.next_out)
        if idx.size == ens.n
        else idx[ens.t[idx] >= ens.next_out[idx]]
    )
    if due.size == 0:
        return
    world = (
        taken[1]
        if taken is not None and taken[0].shape == due.shape and every(taken[0] == due)
        else ens.world.sample(due)
    )
    if due.size == 1:  # a single run's sample: its row by Python ints, no index arrays
        i = due.item(0)
        k = ens.out_k.item(i)
        for st in ens.states:
            ens.rec.sample_one(k, i, st.ca.name, st.x[i])
        for name, values in world.items():
            ens.rec.sample_one(k, i, name, values[0])
        ens.out_k[i] = k + 1
        ens.next_out[i] = ens.sample_after[k + 1]
        return
    ks = ens.out_k[due]
    for st in ens.states:
        ens.rec.sample(ks, due, st.ca.name, gather(st.x, due))
    for name, values in world.items():
        ens.rec.sample(ks, due, name, values)
    ens.out_k[due] += 1
    ens.next_out[due] = ens.sample_after[ens.out_k[due]]

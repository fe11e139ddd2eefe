"""End-of-instant checks that can end an instance: ``stuck``, ``ok``, ``deadlock``.

``stuck``: an active mode's invariant is false and no transition took the instance out.
The run's end: the agents of the team's end rule (by default every agent but a protocol's
operators, which stand by forever) are all in final modes — or, with ``when: any``, one
of them is — and the outcome is the first named by their final modes, else ``ok``.
``deadlock``: nothing is pending (no
event, message, timer, stream) and every agent either is final or waits for a trigger, so no
discrete step can ever happen again (never concluded in a live run, where a datagram may
still arrive). Each outcome carries a message naming agents, modes,
guards or triggers, and the time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, filled, some, spread

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


def check_instances(ens: Ensemble, idx: np.ndarray, config: np.ndarray | None = None) -> None:
    """Invariants (``stuck``), the end rule (a final mode's outcome, else ``ok``), nothing
    can happen (``deadlock``), for the instances ``idx`` where something happened.

    ``config``: the instances whose configuration (active modes) changed at this instant
    (None: any of ``idx``). The end rule reads only the active modes, so it can newly hold
    only there: elsewhere it was false when the configuration last changed, or the
    instance would have ended then. A deadlock needs nothing pending, which a running
    stream or a component that raises events rules out: where neither check can fire,
    the modes are not read at all (most of a streaming team's instants)."""
    if idx.size == 0:
        return
    for st in ens.states:
        ca = st.ca
        for m in ca.invariant_modes:
            sel = idx[st.active[:, m.index][idx] & ~ens.done[idx]]
            if sel.size == 0:
                continue
            assert m.invariant is not None  # (an invariant mode's)
            ok = spread(m.invariant(st.ctx(sel, ens.t[sel], m.index)), sel.shape)
            bad = sel[~ok]
            if bad.size:
                ens.finish(
                    bad,
                    "stuck",
                    lambda i, ca=ca, m=m: (  # type: ignore[misc]  # default-bound lambda
                        f"agent '{ca.name}' in mode '{m.path}' at t={ens.when(i)}: invariant "
                        f"'{m.invariant_text}' is false and no transition out is enabled"
                    ),
                )
    if not ens.may_end_early:
        return
    idx = idx[~ens.done[idx]]
    if idx.size == 0:
        return
    # periodic stream sends are pending messages too: a robot that still talks is not stalled
    pending = ens.queue.pending(idx) | np.isfinite(ens.streams.next[idx]) | ens.world.raises
    if ens.network.outlet is not None:  # live: a datagram may always still arrive
        pending = filled(idx.size, True, bool)
    if config is None:
        ending = filled(idx.size, True, bool)
    else:
        ending = np.zeros(ens.n, bool)
        ending[config] = True
        ending = ending[idx]
    look = ending | ~pending
    if not some(look):
        return
    if not every(look):
        idx, pending, ending = idx[look], pending[look], ending[look]
    cteam = ens.cteam
    all_final = filled(idx.size, True, bool)
    ends = np.zeros(idx.size, bool) if cteam.end_any else filled(idx.size, True, bool)
    waiting = filled(idx.size, True, bool)
    someone_waits = np.zeros(idx.size, bool)
    for a, st in enumerate(ens.states):
        ca = st.ca
        act = st.active[idx]
        leaf_act = act[:, ca.leaves]
        final = np.logical_and.reduce(~leaf_act | ca.final_leaves, axis=1)
        all_final &= final
        if a in cteam.ending:
            ends = ends | final if cteam.end_any else ends & final
        eventless = np.logical_or.reduce(act & ca.has_eventless, axis=1)
        trig = np.logical_or.reduce(act & ca.has_triggered, axis=1)
        waiting &= final | (~eventless & trig & ~np.isfinite(ens.timer[a][idx]))
        someone_waits |= ~final & trig
    fin = idx[ends & ending]
    if fin.size:
        text = _end_text(ens)
        for kind, group in final_outcomes(ens, fin).items():
            ens.finish(group, kind, lambda i: text)
    stalled = idx[~all_final & waiting & someone_waits & ~pending]
    if stalled.size:
        ens.finish(stalled, "deadlock", lambda i: deadlock_text(ens, i))


def _end_text(ens: Ensemble) -> str:
    cteam = ens.cteam
    if len(cteam.ending) == len(cteam.agents) and not cteam.end_any:
        return "every agent reached a final mode"
    if cteam.team.end.agents is None:
        ops = ", ".join(f"'{a.name}'" for a in cteam.team.agents if a.operator)
        return f"every agent reached a final mode (operators are not waited for: {ops})"
    names = ", ".join(f"'{cteam.agents[a].name}'" for a in cteam.ending)
    if cteam.end_any:
        return (
            f"one of {names} reached a final mode"
            if len(cteam.ending) > 1
            else f"{names} reached a final mode"
        )
    return (
        f"{names} reached final modes (the end rule)"
        if len(cteam.ending) > 1
        else f"{names} reached a final mode (the end rule)"
    )


def final_outcomes(ens: Ensemble, idx: np.ndarray) -> dict[str, np.ndarray]:
    """Instances ``idx`` (at their end) grouped by outcome: the ``outcome`` of the first
    active final mode that names one, among the agents that end the run in agent order,
    else ``ok``."""
    kind = np.full(idx.size, "ok", dtype=object)
    named = np.zeros(idx.size, bool)
    for st in (ens.states[a] for a in ens.cteam.ending):
        for m, name in enumerate(st.ca.outcome):
            if name is not None:
                hit = ~named & st.active[:, m][idx]
                kind[hit] = name
                named |= hit
    return {k: idx[kind == k] for k in dict.fromkeys(kind.tolist())}


def deadlock_text(ens: Ensemble, i: int) -> str:
    parts = []
    for st in ens.states:
        ca = st.ca
        waits = sorted(
            {
                on
                for m in ca.modes
                if st.active[i, m.index]
                for j in m.outgoing
                if (on := ca.transitions[j].on)
            }
        )
        if waits:
            parts.append(
                f"agent '{ca.name}' in {', '.join(st.leaf_paths(i))} waits for {', '.join(waits)}"
            )
    return f"nothing pending at t={ens.when(i)}: " + "; ".join(parts)

"""The discrete phase: everything that happens at one instant, in micro-steps.

At an instant ``t`` an instance takes micro-steps ``(t, 0), (t, 1), ...`` (superdense time)
until it is quiescent. In each micro-step, if any urgent transition (guard and/or ``after``,
no trigger) is enabled in some agent, every agent takes its enabled urgent transitions;
otherwise the first pending event (scenario, message, local) is dispatched (it wakes the
transitions on its name and, if dotted, on its prefixes: :meth:`.CAgent.waiting`). Within an
agent, transitions are considered in precedence order (higher ``priority``, then by the
team's rule outer before inner or, ``inner_first``, inner before outer, then declaration
order: :func:`.transitions.compile_transitions`) and a transition is blocked by a
higher-precedence one that fires
and conflicts with it (:func:`.transitions.conflict`): one on the same mode, one whose exit
set overlaps its own, or one that exits its source. So parallel regions step together, and
an outer transition that leaves its mode pre-empts everything inside it. A transition
without a target exits nothing: it blocks, and is blocked by, only transitions that leave
its source (or share it); under the default rule one inside it on the same event fires
too, after it (under ``inner_first`` one fired from inside a source blocks it, as SCXML
takes one transition per active leaf).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import gather, some, spread, where_true
from hybridteam.engine.run.actions import exit_actions, run_actions
from hybridteam.engine.run.events import MESSAGE, TIMER

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CAgent
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.state import AgentState


def discrete_phase(ens: Ensemble, idx: np.ndarray) -> None:
    """Run micro-steps for instances ``idx`` (all at their current time) until quiescent."""
    if idx.size == 0:  # (a law's tick only: nothing may fire, no event is due)
        return
    ens.micro[idx] = 0
    active = idx
    # instances whose last micro-step only consumed an event that changed nothing the
    # urgent guards read (no transition fired): their urgent transitions are still all
    # disabled, so they are not evaluated again (unless a guard may change on its own:
    # AgentState.urgent_volatile)
    quiet = np.zeros(ens.n, bool)
    recheck = ens.urgent_volatile
    while active.size:
        fired = np.zeros(ens.n, bool)
        urgent = active[~quiet[active]] if not recheck else active
        for ag, st in zip(ens.cteam.agents, ens.states, strict=True):
            if ag.eventless:
                sel = urgent[~ens.done[urgent]]
                fired[sel] |= select_and_fire(ens, ag, st, sel, ag.eventless, None)
        took = fired.copy()  # where a transition fired (events consumed join fired below)
        rest = active[~fired[active] & ~ens.done[active]]
        inert: list[int] = []  # instances whose event this micro-step nobody waited for
        if rest.size:
            for (kind, agent, name), members in ens.queue.pop_due(rest, ens.t).items():
                inst = np.array([i for i, _ in members], np.intp)
                fired[inst] = True  # consuming an event is a micro-step, taken or not
                ag, st = ens.cteam.agents[agent], ens.states[agent]
                msg = None
                if kind == TIMER:
                    live = ~ens.done[inst]
                    ens.reliable.on_timer(
                        inst[live],
                        agent,
                        [p for (_, p), ok in zip(members, live, strict=True) if ok],
                    )
                    continue
                # an event nobody waits for is dropped, as in statecharts
                waiting = ag.waiting(name)
                if kind == MESSAGE and not waiting:
                    # its receipt (rate limit, the protocol's screen, the record) is all it
                    # does: no transition waits for it (a stream copy's usual case)
                    for i, p in members:
                        ens.network.receive_one(i, float(ens.t[i]), p, screen=ens.screen)
                    if not recheck and len(members) <= FEW_INERT:
                        inert += [i for i, _ in members]
                    continue
                if kind == MESSAGE:
                    payloads = [p for _, p in members]
                    keep = (
                        ens.network.receive(inst, ens.t[inst], payloads, screen=ens.screen)
                        & ~ens.done[inst]
                    )
                    inst = inst[keep]
                    msg = message_fields([p for p, k in zip(payloads, keep, strict=True) if k])
                else:
                    inst = inst[~ens.done[inst]]
                cause = f"{'message' if kind == MESSAGE else 'event'}:{name}"
                took[inst] |= select_and_fire(ens, ag, st, inst, waiting, cause, msg)
            for i in inert:
                _more_inert(ens, i)
        quiet = fired & ~took
        stepped = active[fired[active]]
        ens.changed[stepped] = True
        ens.micro[stepped] += 1
        over = stepped[ens.micro[stepped] >= ens.settings.zeno.max_steps_per_instant]
        if over.size:
            ens.finish(
                over,
                "zeno",
                lambda i: (
                    f"{ens.settings.zeno.max_steps_per_instant} discrete steps at "
                    f"t={ens.when(i)} without time advancing; last: {ens.last_step_text(i)}"
                ),
            )
        active = stepped[~ens.done[stepped]]
        if not recheck and active.size:
            # a quiet instance with no event left due would only find that out next round
            # (its urgent transitions are not evaluated again): it is quiescent now
            active = active[~(quiet[active] & (ens.queue.next[active] > ens.t[active]))]


#: Up to this many instances, messages nobody waits for are taken a run at a time
#: (:func:`_more_inert`); more take their micro-steps in rounds, one array pass each.
FEW_INERT = 4


def _more_inert(ens: Ensemble, i: int) -> None:
    """Instance ``i`` just consumed a message nobody waits for: take its next due events
    now while they are such messages too, each a micro-step of its own.

    What the next rounds of :func:`discrete_phase` would do for ``i``, without the rounds:
    a message nobody waits for fires no transition, so ``i`` is quiet and (no urgent guard
    reading stream estimates) its urgent transitions are not evaluated again; the round
    pops its next due event, delivers it (rate limits, the protocol's screen, the record)
    and counts a micro-step. So the same messages are delivered in the same order, and
    the count stops where the Zeno limit would end the instance. A streaming team's
    arrival instants (a copy from each teammate at once) take one round, not one per copy.
    """
    if ens.done[i]:  # (a receipt ends no instance: checked once)
        return
    t = float(ens.t[i])
    agents = ens.cteam.agents

    def inert(a: int, name: str) -> bool:
        return not agents[a].waiting(name)

    # (the round that consumed the first one counts its micro-step: taken + 1 of them)
    room = ens.settings.zeno.max_steps_per_instant - int(ens.micro[i]) - 1
    taken = 0
    while taken < room:
        got = ens.queue.pop_message(i, t, inert)
        if got is None:
            break
        ens.network.receive_one(i, t, got[1], screen=ens.screen)
        taken += 1
    ens.micro[i] += taken


def message_fields(messages: list) -> dict[str, np.ndarray]:
    """The triggering messages' fields as arrays over the instances receiving them."""
    out = {
        "sender": np.array([m.sender for m in messages], float),
        "t_send": np.array([m.t_send for m in messages], float),
    }
    for name in messages[0].fields if messages else ():
        out[name] = np.array([m.fields.get(name, np.nan) for m in messages], float)
    return out


def _rows(msg: dict[str, np.ndarray] | None, rows: np.ndarray) -> dict[str, np.ndarray] | None:
    return None if msg is None else {k: v[rows] for k, v in msg.items()}


def select_and_fire(
    ens: Ensemble,
    ag: CAgent,
    st: AgentState,
    idx: np.ndarray,
    candidates: list[int],
    cause: str | None,
    msg: dict[str, np.ndarray] | None = None,
) -> np.ndarray:
    """Fire, in each instance of ``idx``, the enabled candidates that are not pre-empted.

    ``msg`` holds the fields of the message being dispatched (aligned with ``idx``).
    """
    fired = np.zeros(idx.size, bool)
    if idx.size == 0 or not candidates:
        return fired
    t = ens.t[idx]
    enabled: dict[int, np.ndarray] = {}
    # one gather says which candidates' sources are active anywhere, so the loop below
    # visits only those (most of an agent's transitions leave modes it is not in)
    act = gather(st.active, idx).take(ag.transition_sources[candidates], 1)
    for c in where_true(np.logical_or.reduce(act, axis=0)).tolist():
        j = candidates[c]
        tr = ag.transitions[j]
        e = act[:, c].copy()
        if tr.after is not None:
            e &= t >= st.deadline[:, tr.after_slot][idx]
        if tr.guard is not None and some(e):
            sub = idx[e]
            ctx = st.ctx(sub, ens.t[sub], tr.source, _rows(msg, where_true(e)))
            e[e] = spread(tr.guard(ctx), sub.shape)
        if some(e):
            enabled[j] = e
    if not enabled:
        return fired
    chosen: dict[int, np.ndarray] = {}
    for j in sorted(enabled):
        e = enabled[j]
        for k in ag.transitions[j].conflicts.tolist():
            if k in chosen:
                e = e & ~chosen[k]
        if some(e):
            chosen[j] = e
    for j, e in chosen.items():
        tr = ag.transitions[j]
        reason = cause or ("after" if tr.after is not None else "guard")
        fire(ens, ag, st, j, idx[e], reason, _rows(msg, where_true(e)))
        fired |= e
    return fired


def fire(
    ens: Ensemble,
    ag: CAgent,
    st: AgentState,
    j: int,
    sub: np.ndarray,
    cause: str,
    msg: dict[str, np.ndarray] | None = None,
) -> None:
    """Exit (innermost first, with the modes' exit actions), act, enter (outermost first,
    with their entry actions) — for transition ``j`` in instances ``sub``."""
    tr = ag.transitions[j]
    if not tr.internal:
        if ag.mode_actions:
            exit_actions(ens, ag, st, tr.exit_root, sub, tr.exit_inside)
        st.exit(tr.exit_root, sub, ens.t, ens.rec, tr.exit_inside)
    if tr.actions:
        run_actions(ens, ag, st, tr.actions, sub, st.ctx(sub, ens.t[sub], tr.source, msg), msg)
    if not tr.internal:
        for a, b in tr.carry:  # same role: the body resumes (see compiler._role_carry)
            st.last[:, b][sub] = tr.carry_map[st.last[:, a][sub]]  # type: ignore[index]
        st.enter(tr.entry, sub, ens.t, deep=bool(tr.carry))  # type: ignore[arg-type]
        for b, slot_a, slot_b in tr.carry_timers:
            on = sub[st.active[:, b][sub]]
            st.deadline[:, slot_b][on] = st.deadline[:, slot_a][on]
    ens.rec.transition(ag.index, j, sub, ens.t[sub], ens.micro[sub], cause)
    ens.reconfigured[sub] = True
    ens.last_fired[sub] = ag.index * 1_000_000 + j
    _zeno_window(ens, ag, st, sub)


def _zeno_window(ens: Ensemble, ag: CAgent, st: AgentState, sub: np.ndarray) -> None:
    """Too many transitions of one agent within a short window: a Zeno run, stop it."""
    bad = ens.zeno.fired(ag.index, sub, ens.t[sub])
    if bad.size:
        z = ens.settings.zeno
        ens.finish(
            bad,
            "zeno",
            lambda i: (
                f"agent '{ag.name}' took {z.max_transitions + 1} transitions within {z.window:g} s "
                f"up to t={ens.when(i)}; last: {ens.last_step_text(i)}"
            ),
        )

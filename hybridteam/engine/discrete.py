"""The discrete phase: everything that happens at one instant, in micro-steps.

At an instant ``t`` an instance takes micro-steps ``(t, 0), (t, 1), ...`` (superdense time)
until it is quiescent. In each micro-step, if any urgent transition (guard and/or ``after``,
no trigger) is enabled in some agent, every agent takes its enabled urgent transitions;
otherwise the first pending event (scenario, message, local) is dispatched. Within an agent,
transitions are considered in precedence order (higher ``priority``, then outer before inner,
then declaration order) and a transition is blocked by any higher-precedence transition that
fires and exits an overlapping part of the mode tree, so parallel regions step together while
an outer transition pre-empts everything inside it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.compiled import REPLY
from hybridteam.engine.events import LOCAL, MESSAGE, TIMER

if TYPE_CHECKING:
    from hybridteam.engine.compiled import CAction, CAgent, Ctx
    from hybridteam.engine.simulator import Simulator
    from hybridteam.engine.state import AgentState


def discrete_phase(sim: Simulator, idx: np.ndarray) -> None:
    """Run micro-steps for instances ``idx`` (all at their current time) until quiescent."""
    sim.micro[idx] = 0
    active = idx
    while active.size:
        fired = np.zeros(sim.n, bool)
        for ag, st in zip(sim.cteam.agents, sim.states, strict=True):
            if ag.eventless:
                sel = active[~sim.done[active]]
                fired[sel] |= select_and_fire(sim, ag, st, sel, ag.eventless, None)
        rest = active[~fired[active] & ~sim.done[active]]
        if rest.size:
            for (kind, agent, name), members in sim.queue.pop_due(rest, sim.t).items():
                inst = np.array([i for i, _ in members], np.intp)
                fired[inst] = True  # consuming an event is a micro-step, taken or not
                ag, st = sim.cteam.agents[agent], sim.states[agent]
                msg = None
                if kind == TIMER:
                    live = ~sim.done[inst]
                    sim.reliable.on_timer(inst[live], agent,
                                          [p for (_, p), ok in zip(members, live, strict=True)
                                           if ok])
                    continue
                if kind == MESSAGE:
                    payloads = [p for _, p in members]
                    keep = sim.network.receive(inst, sim.t[inst], payloads,
                                               screen=sim.screen) & ~sim.done[inst]
                    inst = inst[keep]
                    msg = message_fields([p for p, k in zip(payloads, keep, strict=True) if k])
                else:
                    inst = inst[~sim.done[inst]]
                # an event nobody waits for is dropped, as in statecharts
                cause = f"{'message' if kind == MESSAGE else 'event'}:{name}"
                select_and_fire(sim, ag, st, inst, ag.triggered.get(name, []), cause, msg)
        stepped = active[fired[active]]
        sim.changed[stepped] = True
        sim.micro[stepped] += 1
        over = stepped[sim.micro[stepped] >= sim.settings.zeno.max_steps_per_instant]
        if over.size:
            sim.finish(over, "zeno", lambda i: (
                f"{sim.settings.zeno.max_steps_per_instant} discrete steps at "
                f"t={sim.when(i)} without time advancing; last: {sim.last_step_text(i)}"))
        active = stepped[~sim.done[stepped]]


def message_fields(messages: list) -> dict[str, np.ndarray]:
    """The triggering messages' fields as arrays over the instances receiving them."""
    out = {"sender": np.array([m.sender for m in messages], float),
           "t_send": np.array([m.t_send for m in messages], float)}
    for name in messages[0].fields if messages else ():
        out[name] = np.array([m.fields.get(name, np.nan) for m in messages], float)
    return out


def _rows(msg: dict[str, np.ndarray] | None, rows: np.ndarray) -> dict[str, np.ndarray] | None:
    return None if msg is None else {k: v[rows] for k, v in msg.items()}


def select_and_fire(sim: Simulator, ag: CAgent, st: AgentState, idx: np.ndarray,
                    candidates: list[int], cause: str | None,
                    msg: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Fire, in each instance of ``idx``, the enabled candidates that are not pre-empted.

    ``msg`` holds the fields of the message being dispatched (aligned with ``idx``).
    """
    fired = np.zeros(idx.size, bool)
    if idx.size == 0 or not candidates:
        return fired
    t = sim.t[idx]
    enabled: dict[int, np.ndarray] = {}
    for j in candidates:
        tr = ag.transitions[j]
        e = st.active[idx, tr.source]
        if not e.any():
            continue
        if tr.after is not None:
            e &= t >= st.deadline[idx, tr.after_slot]
        if tr.guard is not None and e.any():
            sub = idx[e]
            ctx = st.ctx(sub, sim.t[sub], tr.source, _rows(msg, np.flatnonzero(e)))
            e[e] = np.broadcast_to(tr.guard(ctx), sub.shape)
        if e.any():
            enabled[j] = e
    if not enabled:
        return fired
    chosen: dict[int, np.ndarray] = {}
    for j in sorted(enabled):
        e = enabled[j]
        for k in ag.transitions[j].conflicts.tolist():
            if k in chosen:
                e = e & ~chosen[k]
        if e.any():
            chosen[j] = e
    for j, e in chosen.items():
        tr = ag.transitions[j]
        reason = cause or ("after" if tr.after is not None else "guard")
        fire(sim, ag, st, j, idx[e], reason, _rows(msg, np.flatnonzero(e)))
        fired |= e
    return fired


def fire(sim: Simulator, ag: CAgent, st: AgentState, j: int, sub: np.ndarray,
         cause: str, msg: dict[str, np.ndarray] | None = None) -> None:
    """Exit, act, enter — for transition ``j`` in instances ``sub``."""
    tr = ag.transitions[j]
    ctx = st.ctx(sub, sim.t[sub], tr.source, msg)
    if not tr.internal:
        st.exit(tr.exit_root, sub, sim.t, sim.rec)
    for act in tr.actions:
        if act.kind == "assign":
            kind, col = act.target  # type: ignore[misc]
            value = np.broadcast_to(act.expr(ctx), sub.shape).astype(float)  # type: ignore[misc]
            if kind == "x":
                st.x[sub, col] = value
                ctx.x[:, col] = value
            else:
                st.v[sub, col] = value
                ctx.v[:, col] = value
        elif act.kind == "raise":
            sim.queue.push(sub, sim.t[sub], LOCAL, ag.index, act.name)
        else:
            _send(sim, ag, act, sub, ctx, msg)
    if not tr.internal:
        for a, b in tr.carry:  # same role: the body resumes (see compiler._role_carry)
            st.last[sub, b] = tr.carry_map[st.last[sub, a]]  # type: ignore[index]
        st.enter_path(tr.entry_path, sub, sim.t, deep=bool(tr.carry))
        for b, slot_a, slot_b in tr.carry_timers:
            on = sub[st.active[sub, b]]
            st.deadline[on, slot_b] = st.deadline[on, slot_a]
    sim.rec.transition(ag.index, j, sub, sim.t[sub], sim.micro[sub], cause)
    sim.last_fired[sub] = ag.index * 1_000_000 + j
    _zeno_window(sim, ag, st, sub)


def _send(sim: Simulator, ag: CAgent, act: CAction, sub: np.ndarray, ctx: Ctx,
          msg: dict[str, np.ndarray] | None) -> None:
    """A ``send`` action: plain datagrams, or through the acknowledged layer when the
    message type's protocol asks for acks; priority ranks same-instant arrivals."""
    fields = {k: np.broadcast_to(e(ctx), sub.shape).copy() for k, e in act.fields.items()}
    to: int | np.ndarray | None = act.to
    if act.to_expr is not None:
        to = np.rint(np.broadcast_to(act.to_expr(ctx), sub.shape)).astype(np.intp)
    elif to == REPLY:
        to = msg["sender"].astype(np.intp) if msg is not None else None
    policy = ag.policies.get(act.name)
    rank = None
    if policy is not None and policy.priority is not None:
        rank = -np.broadcast_to(policy.priority(ctx), sub.shape).astype(float)
    if policy is not None and policy.acknowledged:
        timeout = np.broadcast_to(policy.timeout(ctx), sub.shape)  # type: ignore[misc]
        retries = np.broadcast_to(policy.retries(ctx), sub.shape)  # type: ignore[misc]
        sim.reliable.send(sub, ag.index, to, act.socket, act.name, fields, timeout, retries,
                          rank)
    else:
        sim.network.send(sub, sim.t[sub], ag.index, to, act.socket, act.name, fields,
                         rank=rank)


def _zeno_window(sim: Simulator, ag: CAgent, st: AgentState, sub: np.ndarray) -> None:
    """Too many transitions of one agent within a short window: a Zeno run, stop it."""
    ring, ptr = sim.zeno_ring[ag.index], sim.zeno_ptr[ag.index]
    pos = ptr[sub]
    old = ring[sub, pos]
    ring[sub, pos] = sim.t[sub]
    ptr[sub] = (pos + 1) % ring.shape[1]
    bad = sub[(sim.t[sub] - old) <= sim.settings.zeno.window]
    if bad.size:
        z = sim.settings.zeno
        sim.finish(bad, "zeno", lambda i: (
            f"agent '{ag.name}' took {z.max_transitions + 1} transitions within {z.window:g} s "
            f"up to t={sim.when(i)}; last: {sim.last_step_text(i)}"))

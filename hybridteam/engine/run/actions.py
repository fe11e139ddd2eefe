"""Running compiled actions: a transition's ``do:`` and its modes' entry and exit lists.

Assignments are sequential (each reads the values the earlier ones wrote), a ``raise``
queues a local event for later in the same instant, a send goes to the network or the
acknowledged layer. A transition runs, in order: the exit actions of the modes it leaves,
innermost first (reverse document order, so regions in reverse too); its own actions; the
entry actions of the modes it enters, outermost first (document order). A team that
declares no entry or exit actions never looks for them (``CAgent.mode_actions``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import spread
from hybridteam.engine.compile.compiled import REPLY
from hybridteam.engine.compile.values import require
from hybridteam.engine.run.events import LOCAL

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CAction, CAgent, Ctx
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.state import AgentState


def run_actions(
    ens: Ensemble,
    ag: CAgent,
    st: AgentState,
    actions: list[CAction],
    sub: np.ndarray,
    ctx: Ctx,
    msg: dict[str, np.ndarray] | None,
) -> None:
    """Run ``actions`` in instances ``sub`` (``ctx``: their context, kept up to date by
    the assignments; ``msg``: the triggering message's fields, if any)."""
    for act in actions:
        if act.kind == "assign":
            kind, col = act.target  # type: ignore[misc]  # (an assignment has both)
            value = spread(act.expr(ctx), sub.shape).astype(float)  # type: ignore[misc]  # (ditto)
            if kind == "x":
                st.x[:, col][sub] = value
                ctx.x[:, col] = value
            else:
                st.v[:, col][sub] = value
                ctx.v[:, col] = value
        elif act.kind == "raise":
            ens.queue.push(sub, ens.t[sub], LOCAL, ag.index, act.name)
        else:
            _send(ens, ag, act, sub, ctx, msg)


def exit_actions(
    ens: Ensemble, ag: CAgent, st: AgentState, root: int, sub: np.ndarray, inside: bool = False
) -> None:
    """The exit actions of the active modes of ``root``'s subtree (about to be exited;
    ``inside``: below ``root`` only), innermost first."""
    modes = ag.modes[root].subtree[1:] if inside else ag.modes[root].subtree
    for m in modes[::-1].tolist():
        mode = ag.modes[m]
        if mode.on_exit:
            sel = sub[st.active[:, m][sub]]
            if sel.size:
                run_actions(ens, ag, st, mode.on_exit, sel, st.ctx(sel, ens.t[sel], m), None)


def entry_actions(ens: Ensemble, ag: CAgent, st: AgentState, m: int, sub: np.ndarray) -> None:
    """Mode ``m``'s entry actions in instances ``sub``, which just entered it (called by
    :meth:`.AgentState.activate` before the mode's delays are armed, so they may read what
    the actions set)."""
    mode = ag.modes[m]
    if mode.on_entry and sub.size:
        run_actions(ens, ag, st, mode.on_entry, sub, st.ctx(sub, ens.t[sub], m), None)


def _send(
    ens: Ensemble,
    ag: CAgent,
    act: CAction,
    sub: np.ndarray,
    ctx: Ctx,
    msg: dict[str, np.ndarray] | None,
) -> None:
    """A ``send`` action: plain datagrams, or through the acknowledged layer when the
    message type's protocol asks for acks; priority ranks same-instant arrivals."""
    fields = {k: spread(e(ctx), sub.shape).copy() for k, e in act.fields.items()}
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
        wait, tries = policy.timeout, policy.retries
        assert wait is not None and tries is not None  # (an acknowledged message's policy)
        timeout = require(
            np.broadcast_to(wait(ctx), sub.shape),
            (*policy.where, "timeout"),
            "the ack timeout",
            wait.source,
            low=0.0,
            open_low=True,
            instances=sub,
        )
        retries = require(
            np.broadcast_to(tries(ctx), sub.shape),
            (*policy.where, "retries"),
            "the number of retries",
            tries.source,
            low=0.0,
            instances=sub,
        )
        ens.reliable.send(sub, ag.index, to, act.socket, act.name, fields, timeout, retries, rank)
    else:
        ens.network.send(sub, ens.t[sub], ag.index, to, act.socket, act.name, fields, rank=rank)

"""Timing settings that cannot work, found before a run: warnings with locations.

A team whose acknowledgements time out before a reply could arrive, whose robots give up
waiting for an answer while their request is still being resent, or whose receivers are
sent more messages than their rate limit lets them take, still runs, and usually ends
``ok``: every handover fails, or whole senders are never heard. These checks evaluate the
settings on the team's own parameter values (a study may vary them; the engine's range
checks still apply per instance) and say what happens and what would work.
"""

from __future__ import annotations

import re

import numpy as np

from hybridteam.engine.compile.compiled import CAgent, CTeam, Ctx
from hybridteam.engine.compile.settings import default_parameters, evaluate_setting
from hybridteam.errors import ModelError
from hybridteam.model import Team

_NAME = re.compile(r"[A-Za-z_]\w*$")


def timing_warnings(team: Team, cteam: CTeam) -> list[ModelError]:
    """Every timing warning of a compiled team."""
    return ack_timeouts(team, cteam) + answer_timeouts(team, cteam) + rate_limits(team, cteam)


def _value(expr, ctx: Ctx) -> float:
    return float(np.asarray(expr(ctx), float).reshape(-1)[0])


def _context(ca: CAgent) -> Ctx:
    """One instance of the agent at its defaults (settings read parameters only)."""
    return Ctx(
        np.zeros((1, len(ca.plant.state_names))),
        np.zeros((1, len(ca.var_index))),
        ca.param_defaults[None, :],
        np.zeros(1),
    )


def ack_timeouts(team: Team, cteam: CTeam) -> list[ModelError]:
    """Acknowledged messages whose timeout is no longer than a round trip to a receiver
    (latency and jitter, there and back, with the team's own values): every one would be
    resent, and after its retries reported undeliverable, though nothing is lost."""
    params, net = default_parameters(team), team.network
    ways: dict[int, float] = {}  # one way's latency and jitter, by link settings

    def way(s: str, r: str) -> float:
        spec = net.links.get((s, r), net.default)
        if id(spec) not in ways:
            ways[id(spec)] = float(
                evaluate_setting(spec.latency, params, 1)[0]
                + evaluate_setting(spec.jitter, params, 1)[0]
            )
        return ways[id(spec)]

    linked: dict[str, set[str]] = {}  # the agents each agent has a link of its own with
    for s, r in net.links:
        linked.setdefault(s, set()).add(r)
        linked.setdefault(r, set()).add(s)
    agents = [a.name for a in team.agents]
    order = {name: k for k, name in enumerate(agents)}
    out: list[ModelError] = []
    for agent, ca in zip(team.agents, cteam.agents, strict=True):
        ctx = _context(ca)
        timeouts = [
            (name, _value(pol.timeout, ctx))
            for name, pol in ca.policies.items()
            if pol.timeout is not None
        ]
        if not timeouts:
            continue
        # every other agent without a link of its own with this one is reached over the
        # default link both ways: the first of them stands for all (a team of thousands
        # would otherwise cost a round trip per pair)
        own = linked.get(agent.name, set())
        plain = next((o for o in agents if o != agent.name and o not in own), None)
        others = sorted(
            (own - {agent.name}) | ({plain} if plain else set()),
            key=lambda o: order.get(o, len(agents)),
        )
        trips = {o: way(agent.name, o) + way(o, agent.name) for o in others if o in order}
        if not trips:
            continue
        worst = max(trips, key=trips.__getitem__)
        short: dict[float, list[str]] = {}  # timeout -> the messages resent that soon
        for name, timeout in timeouts:
            if timeout <= trips[worst]:
                short.setdefault(timeout, []).append(name)
        for timeout, names in short.items():
            out.append(
                ModelError(
                    agent.where,
                    f"agent '{agent.name}' resends "
                    f"{', '.join(names)} after {timeout:g} s without an "
                    f"acknowledgement, but a round trip to '{worst}' takes up "
                    f"to {trips[worst]:g} s (latency and jitter, both ways): "
                    "every copy would be sent again and, after its retries, "
                    "reported undeliverable",
                    hint=f"make the ack timeout longer than {trips[worst]:g} s "
                    f"({_suggest(team, trips[worst])})",
                    at_key=True,
                )
            )
    return out


def _suggest(team: Team, trip: float) -> str:
    """An ack timeout that works, as an agent parameter: an expression of the team's
    latency (and jitter) parameters when the network names them, so it follows a study."""
    net = team.network.default
    terms = [str(s) for s in (net.latency, net.jitter) if isinstance(s, str) and _NAME.match(s)]
    if terms and not isinstance(net.latency, (int, float)):
        trip_text = terms[0] if len(terms) == 1 else f"({' + '.join(terms)})"
        return f"e.g. the agent's parameters: {{ack_timeout: 2 * {trip_text} + 0.05}}"
    return f"e.g. ack_timeout: {2 * trip + 0.05:g}"


def answer_timeouts(team: Team, cteam: CTeam) -> list[ModelError]:
    """Modes that wait ``after: d`` for an answer to an acknowledged message sent on entry,
    with d no longer than that message's retries take (timeout × (retries + 1)): a message
    that needs its retries is given up on (in the role-assignment protocol: the operator is
    called) while the reliable layer is still resending it."""
    out: list[ModelError] = []
    for agent, ca in zip(team.agents, cteam.agents, strict=True):
        ctx = _context(ca)
        short: dict[tuple[float, float, str], list[str]] = {}  # (wait, span, after) -> waits
        for tr in ca.transitions:
            sends = [a.name for a in tr.actions if a.kind == "send"]
            for name in sends if not tr.internal else []:
                pol = ca.policies.get(name)
                if pol is None or pol.timeout is None or pol.retries is None:
                    continue
                span = _value(pol.timeout, ctx) * (_value(pol.retries, ctx) + 1)
                for wait in ca.transitions:
                    if wait.source == tr.target and wait.after is not None and not wait.on:
                        d = _value(wait.after, ctx)
                        if d <= span:
                            key = (d, span, wait.after.source)
                            short.setdefault(key, []).append(
                                f"{name} in '{ca.modes[tr.target].path}'"
                            )
        for (d, span, after), waits in short.items():
            out.append(
                ModelError(
                    agent.where,
                    f"agent '{agent.name}' waits {d:g} s (after: {after}) for an "
                    f"answer to {', '.join(dict.fromkeys(waits))}, but it resends them until "
                    f"{span:g} s (ack timeout × (retries + 1)): a message that needs its "
                    "retries is given up on before they are done",
                    hint=f"make the wait longer than {span:g} s, or resend sooner",
                    at_key=True,
                )
            )
    return out


def rate_limits(team: Team, cteam: CTeam) -> list[ModelError]:
    """Receivers whose rate limit is below what the streams send them: most copies are
    dropped and, without jitter, copies arrive in the same order every period, so a
    receiver that takes the first may never hear a later sender at all."""
    limits = team.network.rate_limits
    if not limits:
        return []
    params, net = default_parameters(team), team.network
    index = {a.name: k for k, a in enumerate(team.agents)}
    out: list[ModelError] = []
    for receiver, per_socket in limits.items():
        if receiver not in index:
            continue  # an error, reported by the compiler
        for socket, limit in per_socket.items():
            incoming: dict[str, float] = {}
            for sender in cteam.agents:
                if sender.name == receiver:
                    continue
                ctx = _context(sender)
                for cs in sender.streams:
                    if socket in ("*", cs.socket):
                        incoming[sender.name] = incoming.get(sender.name, 0.0) + 1.0 / _value(
                            cs.period, ctx
                        )
            total = sum(incoming.values())
            if total <= float(limit) + 1e-9:
                continue
            jitter = max(
                float(
                    evaluate_setting(net.links.get((s, receiver), net.default).jitter, params, 1)[0]
                )
                for s in incoming
            )
            what = ", ".join(f"{s} {r:g}" for s, r in incoming.items())
            lost = 100 * (1 - float(limit) / total)
            text = (
                f"'{receiver}' takes at most {float(limit):g} {socket} messages per second "
                f"but streams send it {total:g} ({what}): at least {lost:.0f} % of the "
                "copies are dropped"
            )
            if jitter == 0:
                text += (
                    "; with no jitter they arrive in the same order every period, so "
                    "a later sender may never be heard"
                )
            out.append(
                ModelError(
                    (*net.where, "rate_limits", receiver, socket),
                    text,
                    hint="raise the limit, lower the stream rate, or add "
                    "jitter so every sender gets through"
                    if jitter == 0
                    else None,
                    at_key=True,
                )
            )
    return out

"""Compiling what protocols add to agents: message policies, streams, estimate names.

Kept apart from :mod:`~hybridteam.engine.compile.compiler` (modes and transitions): a team without
protocols never touches this, and the names a protocol introduces are defined in one place —
``est_<type>_<field>``, ``est_<type>_age``, ``est_<type>_sender`` for stream estimates,
``id_<agent>`` for agent indices (what ``msg_sender`` and ``to: <expression>`` use), and,
in a stream's fields, the held inputs ``u_<input>`` and the plant-neutral velocities
``vel_x``, ``vel_y``, ``vel_theta``, ``vel_forward`` (:func:`velocity_symbols`).
"""

from __future__ import annotations

from collections import ChainMap
from collections.abc import MutableMapping

import numpy as np

from hybridteam.dynamics.plants import Plant
from hybridteam.engine.compile.compiled import CAgent, CPolicy, CStream
from hybridteam.engine.compile.scope import Collector, resolve_mode
from hybridteam.errors import ModelError, did_you_mean
from hybridteam.model import Send, Team


def stream_fields(team: Team) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for agent in team.agents:
        for s in agent.streams:
            have = out.setdefault(s.message, [])
            have += [f for f in s.fields if f not in have]
    return out


def team_symbols(team: Team) -> dict:
    """Names every agent's expressions can read besides its own state and parameters."""
    syms: dict = {}
    for k, agent in enumerate(team.agents):
        syms[f"id_{agent.name}"] = lambda c, k=k: np.float64(k)
    for type_, fields in stream_fields(team).items():
        syms[f"est_{type_}_sender"] = lambda c, T=type_: c.e.sender(T).astype(float)
        syms[f"est_{type_}_age"] = lambda c, T=type_: c.t - c.e.sent(T)
        for f in fields:
            syms[f"est_{type_}_{f}"] = lambda c, T=type_, f=f: c.e.field(T, f)
    return syms


def check_messages(team: Team) -> list[ModelError]:
    """Sends of undeclared message fields, reserved names, and sockets that disagree."""
    errors: list[ModelError] = []
    if "ack" in team.messages:
        errors.append(
            ModelError(
                team.messages["ack"].where, "'ack' is reserved for acknowledgements", at_key=True
            )
        )
    for agent in team.agents:
        for _, mode in agent.root.walk():
            for tr in mode.transitions:
                for act in tr.actions:
                    if not isinstance(act, Send):
                        continue
                    spec = team.messages.get(act.message)
                    if spec is None or not spec.fields:
                        continue
                    for f in act.fields:
                        if f not in spec.fields:
                            errors.append(
                                ModelError(
                                    (*act.where, "fields", f),
                                    f"message '{spec.name}' has no field '{f}'",
                                    hint=did_you_mean(f, spec.fields),
                                    at_key=True,
                                )
                            )
    return errors


def attach(ca: CAgent, team: Team, syms: MutableMapping, paths: list[str], col: Collector) -> None:
    """Give a compiled agent its message policies and its streams."""
    agent = team.agents[ca.index]
    sends = {
        act.message
        for _, mode in agent.root.walk()
        for tr in mode.transitions
        for act in tr.actions
        if isinstance(act, Send)
    }
    for name, spec in team.messages.items():
        if name not in sends:  # how a message is sent matters only to its senders
            continue
        own = Collector()  # a sender without the names its policy reads: say who and why
        pol = CPolicy()
        if spec.priority not in (0, 0.0, "0"):
            pol.priority = own.expr(spec.priority, syms, (*spec.where, "priority"))
        if spec.ack is not None:
            pol.timeout = own.expr(spec.ack.timeout, syms, (*spec.ack.where, "timeout"))
            pol.retries = own.expr(spec.ack.retries, syms, (*spec.ack.where, "retries"))
            pol.where = spec.ack.where
            pol.dedupe = spec.ack.dedupe
        ca.policies[name] = pol
        for err in own.errors:
            what = (
                {"timeout": "ack timeout", "retries": "ack retries"}.get(
                    str(err.path[-1]), str(err.path[-1])
                )
                if err.path
                else "policy"
            )
            col.fail(
                agent.where,
                f"agent '{ca.name}' sends '{name}', whose {what} cannot be "
                f"evaluated for it: {err.message}",
                "give the agent that parameter "
                f"(parameters:), or make it a member of the protocol that declares "
                f"'{name}'" + (f" ({spec.protocol})" if spec.protocol else ""),
            )
    usyms = ChainMap(
        {
            **velocity_symbols(ca.plant),
            **{f"u_{n}": (lambda c, j=j: c.u[:, j]) for j, n in enumerate(ca.plant.input_names)},
        },
        syms,
    )
    for s in agent.streams:
        modes = []
        for k, name in enumerate(s.while_):
            m, matches = resolve_mode(name, paths)
            if m is None:
                col.fail(
                    (*s.where, "while", k),
                    f"unknown mode '{name}' in agent '{ca.name}'"
                    if not matches
                    else f"mode name '{name}' is ambiguous: {', '.join(matches)}",
                    None
                    if matches
                    else did_you_mean(name, [p.rsplit(".", 1)[-1] for p in paths if p]),
                )
                continue
            modes.append(m)
        rate = col.expr(s.rate, syms, (*s.where, "rate"))
        given = {f: col.expr(e, usyms, (*s.where, "fields", f)) for f, e in s.fields.items()}
        fields = {f: e for f, e in given.items() if e is not None}
        if rate is None or len(fields) < len(given):
            continue
        ca.streams.append(
            CStream(
                s.message,
                s.socket,
                _reciprocal(rate),
                fields,
                modes,
                where=s.where,
                rate_text=str(s.rate),
                fixed_rate=rate.names <= ca.param_index.keys(),
            )
        )


VELOCITY_NAMES = ("vel_x", "vel_y", "vel_theta", "vel_forward")


def velocity_symbols(plant: Plant) -> dict:
    """``vel_x``, ``vel_y``, ``vel_theta``: the world-frame rates of x, y, theta under the
    held input (the plant's ``derivative``), and ``vel_forward`` = vel_x cos(theta) +
    vel_y sin(theta), the speed along the heading.

    ``u_<input>`` name a plant's own inputs, so a stream written with them (``v: u_v``)
    works for one kind of robot only; these names mean the same for a unicycle and a
    holonomic base, so one protocol serves a team of both. Plants without inputs (flows,
    operators) or without a planar pose report zero.
    """
    if not plant.input_names or not {"x", "y", "theta"} <= set(plant.state_names):

        def zero(c):
            return np.zeros(c.x.shape[0])

        return dict.fromkeys(VELOCITY_NAMES, zero)
    ix, iy, ith = (plant.state_names.index(n) for n in ("x", "y", "theta"))

    def forward(c):
        d, th = plant.derivative(c.x, c.u), c.x[:, ith]
        return d[:, ix] * np.cos(th) + d[:, iy] * np.sin(th)

    return {
        "vel_x": lambda c: plant.derivative(c.x, c.u)[:, ix],
        "vel_y": lambda c: plant.derivative(c.x, c.u)[:, iy],
        "vel_theta": lambda c: plant.derivative(c.x, c.u)[:, ith],
        "vel_forward": forward,
    }


def _reciprocal(rate):
    def period(ctx):
        return 1.0 / rate(ctx)

    return period

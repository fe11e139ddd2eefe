"""Counterexamples in words: each step of a path as the message, timer or event it is,
with the mode changes it caused."""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Graph
from hybridteam.verify.machine import State


def _fields(c) -> str:
    shown = [f"{k}={v:g}" for k, v in c.fields if k != "id"]
    return f" ({', '.join(shown)})" if shown else ""


def step_text(sk: Skeleton, parent: State, choice: tuple) -> str:
    names = [ca.name for ca in sk.original.agents]
    kind = choice[0]
    if kind in ("deliver", "lose", "dup"):
        c = parent.inflight[choice[1]]
        what = {"deliver": "arrives", "lose": "is lost", "dup": "is duplicated"}[kind]
        ident = f" #{c.msg_id}" if c.msg_id >= 0 else ""
        return f"{names[c.sender]} -> {names[c.receiver]}: {c.type}{ident}{_fields(c)} {what}"
    if kind == "timer":
        e = parent.outbox[choice[1]]
        waiting = ", ".join(names[r] for r in e.waiting)
        act = "resends it" if e.retries_left > 0 else "gives up (undeliverable)"
        return (
            f"{names[e.sender]}: ack timeout of {e.type} #{e.msg_id} (no ack from {waiting}): {act}"
        )
    if kind == "scenario":
        _, agent, name = sk.original.scenario[parent.cursor]
        return f"scenario: {names[agent]} raises {name}"
    if kind == "world":
        return f"world: {names[choice[1]]} gets {choice[2]}"
    if kind == "time":
        tr = sk.original.agents[choice[1]].transitions[choice[2]]
        why = f"after {tr.after.source}" if tr.after is not None else f"'{tr.guard_text}'"
        return f"{names[choice[1]]}: {tr.text} ({why})"
    return str(choice)


def leaves(sk: Skeleton, s: State) -> list[list[str]]:
    return agent_leaves(sk, s.agents)


def agent_leaves(sk: Skeleton, agents: tuple) -> list[list[str]]:
    """Each agent's active leaf modes, from a state's agents entry alone."""
    out = []
    for ca, (config, _) in zip(sk.original.agents, agents, strict=True):
        act = np.frombuffer(config[: len(ca.modes)], np.uint8).astype(bool)
        out.append([ca.modes[m].path for m in ca.leaves.tolist() if act[m]])
    return out


def changes(sk: Skeleton, before: State, after: State) -> list[str]:
    names = [ca.name for ca in sk.original.agents]
    out = []
    for a, (x, y) in enumerate(zip(leaves(sk, before), leaves(sk, after), strict=True)):
        if x != y:
            out.append(f"{names[a]}: {', '.join(x)} -> {', '.join(y)}")
    return out


def describe(
    sk: Skeleton,
    g: Graph,
    path: list[int],
    mark: tuple[int, str] | None = None,
    times: list[float] | None = None,
) -> list[str]:
    """One line per step (with its mode changes indented below); ``mark`` = (k, text)
    puts a line of text after step k (0: before the first); ``times``: the moments a
    replay gave the steps, shown before each."""
    lines = [
        "initial: "
        + "; ".join(
            f"{ca.name} in {', '.join(modes)}"
            for ca, modes in zip(sk.original.agents, leaves(sk, g.states[path[0]]), strict=True)
        )
    ]
    if mark is not None and mark[0] == 0:
        lines.append(mark[1])
    for k, (a, b) in enumerate(pairwise(path), start=1):
        choice = g.edge_choice(a, b, ("?",))
        at = f"t={times[k]:.6f} s  " if times and k < len(times) else ""
        lines.append(f"{k:3d}. {at}" + step_text(sk, g.states[a], choice))
        lines += [f"       {c}" for c in changes(sk, g.states[a], g.states[b])]
        if mark is not None and mark[0] == k:
            lines.append(mark[1])
    return lines

"""A skeleton path as steps a replay can schedule and check (:mod:`~hybridteam.verify.replay`).

:func:`follow` re-runs the path on a raw machine (the engine's own message ids, copies in
sending order) to give every copy an identity — the n-th copy of its type on its link —
and to note what each step arms: acknowledged messages (with their ack timeouts) and
``after:`` timeouts (with their delays). :func:`bounds` turns that into the timing the
engine imposes (:mod:`~hybridteam.verify.schedule`).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Graph, active_of, other_answers
from hybridteam.verify.machine import Copy, Machine, State
from hybridteam.verify.paths import step_text
from hybridteam.verify.schedule import Bound


@dataclass
class PathStep:
    """One step of a path, with what a replay needs to schedule and to check it."""

    kind: str  # initial, deliver, lose, dup, timer, scenario, world, time
    text: str
    active: frozenset  # (agent name, mode path) of every active mode after the step
    copies: tuple  # identities (sender, receiver, type, n) of the control copies it sends
    outbox: dict = field(default_factory=dict)  # (sender, id) -> ack timeout, after it
    armed: tuple = ()  # (agent, transition, delay) of the after: timeouts it arms
    key: tuple | None = None  # deliver/lose/dup: (sender, receiver, type, n) of the copy
    agent: int = -1  # time/world: whose transition; scenario: who gets the event
    event: str = ""  # scenario: the event
    transition: int = -1  # time: which transition
    entry: tuple | None = None  # timer: (sender, id) of the message
    sent_at: int = -1  # timer: the step that last sent the message
    timeout: float = 0.0  # timer: the message's ack timeout

    @property
    def sends(self) -> Counter:
        """(sender, receiver, type) of the copies it sends, counted."""
        return Counter(c[:3] for c in self.copies)


def follow(sk: Skeleton, g: Graph, path: list[int], m: Machine) -> list[PathStep]:
    """The steps of ``path`` with the identity of every copy (which send of its link and
    type it is), found by re-running the path with the engine's own message ids on ``m``
    (a raw machine of capacity 1)."""
    names = [ca.name for ca in sk.original.agents]
    raw = m.initial()
    count: Counter = Counter()
    ident: list[tuple] = []

    def keys(copies) -> tuple:
        """Identities for newly sent copies: the n-th copy of its type on its link."""
        new = []
        for c in copies:
            link = (names[c.sender], names[c.receiver], c.type)
            new.append((*link, count[link]))
            count[link] += 1
        ident.extend(new)
        return tuple(new)

    steps = [
        PathStep(
            "initial",
            "initial",
            _active(sk, raw),
            keys(raw.inflight),
            _outbox(raw),
            _armed(m, m.armed0),
        )
    ]
    sent_at = {(e.sender, e.msg_id): 0 for e in raw.outbox}
    for a, b in pairwise(path):
        choice = g.edge_choice(a, b)
        assert choice is not None, "a path follows the graph's edges"
        rc, nxt = _match(m, raw, g.states[a], choice, g.states[b])
        step = PathStep(
            rc[0], step_text(sk, g.states[a], choice), _active(sk, nxt), (), _outbox(nxt)
        )
        if rc[0] in ("deliver", "lose", "dup"):
            step.key = ident[rc[1]]
            if rc[0] == "dup":
                ident.append(step.key)
            else:
                del ident[rc[1]]
        elif rc[0] == "timer":
            e = raw.outbox[rc[1]]
            step.entry = (e.sender, e.msg_id)
            step.sent_at, step.timeout = sent_at[step.entry], e.timeout
        elif rc[0] == "scenario":
            _, step.agent, step.event = sk.original.scenario[raw.cursor]
        elif rc[0] in ("time", "world"):
            step.agent = rc[1]
            step.transition = rc[2] if rc[0] == "time" else -1
        if rc[0] not in ("lose", "dup"):
            step.copies = keys(nxt.inflight[len(ident) :])
            step.armed = _armed(m)
        for e in nxt.outbox:  # a new acknowledged message: its timer starts here
            if (e.sender, e.msg_id) not in sent_at:
                sent_at[(e.sender, e.msg_id)] = len(steps)
        if step.entry is not None and step.copies:  # resent: the timer starts again
            sent_at[step.entry] = len(steps)
        steps.append(step)
        raw = nxt
    return steps


def _active(sk: Skeleton, s: State) -> frozenset:
    out = set()
    for a, ca in enumerate(sk.original.agents):
        act = active_of(s, a, len(ca.modes))
        out |= {
            (ca.name, ca.modes[k].path) for k in np.flatnonzero(act).tolist() if ca.modes[k].path
        }  # the root is not a mode of the trace
    return frozenset(out)


def _outbox(s: State) -> dict:
    return {(e.sender, e.msg_id): e.timeout for e in s.outbox}


def _armed(m: Machine, rows: list[np.ndarray] | None = None) -> tuple:
    """(agent, transition, delay) of each after: timeout the last step armed: the
    machine's clock stands at 0, so an armed deadline is the delay itself."""
    out = []
    for a, st in enumerate(m.ens.states):
        row = st.deadline[0] if rows is None else rows[a]
        for j in st.ca.after:
            d = float(row[st.ca.transitions[j].after_slot])
            if math.isfinite(d) and d >= 0:
                out.append((a, j, d))
    return tuple(out)


def _same(x: Copy, y: Copy) -> bool:
    """The same copy up to message ids (raw ids against canonical ones)."""

    def strip(c: Copy) -> tuple:
        return (*c[:4], tuple(f for f in c.fields if f[0] != "id"))

    return strip(x) == strip(y)


def _match(
    m: Machine, raw: State, parent: State, choice: tuple, child: State
) -> tuple[tuple, State]:
    """The choice on the raw state whose successor is ``child`` in canonical form, and
    that successor; identical copies are tried oldest first."""
    kind = choice[0]
    if kind in ("deliver", "lose", "dup"):
        c = parent.inflight[choice[1]]
        options = [(kind, j) for j, r in enumerate(raw.inflight) if _same(r, c)]
    elif kind == "timer":
        e = parent.outbox[choice[1]]
        options = [
            ("timer", j)
            for j, r in enumerate(raw.outbox)
            if r._replace(msg_id=0) == e._replace(msg_id=0)
        ]
    else:
        options = [choice]
    for option in options:
        tapes: list[tuple] = [()]
        while tapes:
            tape = tapes.pop(0)
            r = m.run([(raw, option, tape)])[0]
            if m.canonical(r.state) == child:
                return option, r.state
            tapes += other_answers(tape, r.reads)
    raise AssertionError(f"the path's step {choice} cannot be followed")  # a bug: say so


def bounds(sk: Skeleton, steps: list[PathStep], gap: float) -> list[Bound]:
    """The timing the engine imposes on the path (see :mod:`~hybridteam.verify.schedule`), with
    ``gap`` between consecutive steps."""
    names = [ca.name for ca in sk.original.agents]
    n = len(steps) - 1
    out = []
    for k in range(1, n + 1):
        s = steps[k]
        if s.kind in ("lose", "dup"):  # decided when the copy was sent: no moment of its own
            out.append(Bound(k - 1, k, 0.0, 0.0, f"step {k} takes no time"))
        else:
            out.append(Bound(k - 1, k, gap, math.inf, f"step {k} comes after step {k - 1}"))
        if s.kind == "timer":
            out.append(
                Bound(
                    s.sent_at,
                    k,
                    s.timeout,
                    s.timeout,
                    f"the ack timeout at step {k} expires {s.timeout:g} s after "
                    f"step {s.sent_at} sent the message",
                )
            )
    for k in range(n + 1):  # timers the path does not take must not expire while armed
        for entry, timeout in steps[k].outbox.items():
            if (
                k
                and entry in steps[k - 1].outbox
                and not (steps[k].entry == entry and steps[k].copies)
            ):
                continue  # armed earlier
            e = next(
                (
                    j
                    for j in range(k + 1, n + 1)
                    if entry not in steps[j].outbox or steps[j].entry == entry
                ),
                None,
            )
            if e is not None and steps[e].entry == entry:
                continue  # it expires at step e: the bound above
            what = f"{names[entry[0]]}'s message #{entry[1]} (sent at step {k})"
            out.append(
                Bound(
                    k,
                    n if e is None else e,
                    -math.inf,
                    timeout - gap,
                    f"{what} is not settled by the path's end"
                    if e is None
                    else f"{what} is settled at step {e}, before its ack timeout ({timeout:g} s)",
                )
            )
    ca_of = sk.original.agents
    for k in range(n + 1):
        for a, j, d in steps[k].armed:
            tr = ca_of[a].transitions[j]
            source = (names[a], ca_of[a].modes[tr.source].path)
            for e in range(k + 1, n + 1):
                s = steps[e]
                if s.kind == "time" and (s.agent, s.transition) == (a, j):
                    exact = tr.guard is None
                    out.append(
                        Bound(
                            k,
                            e,
                            d,
                            d if exact else math.inf,
                            f"{names[a]}'s 'after {d:g} s' ({tr.text}) fires at "
                            f"step {e}, entered at step {k}",
                        )
                    )
                    break
                if source not in s.active or any((b, i) == (a, j) for b, i, _ in s.armed):
                    out.append(
                        Bound(
                            k,
                            e,
                            -math.inf,
                            d - gap,
                            f"{names[a]} leaves {source[1]} (step {e}) before its "
                            f"'after {d:g} s' (entered at step {k})",
                        )
                    )
                    break
            else:
                out.append(
                    Bound(
                        k,
                        n,
                        -math.inf,
                        d - gap,
                        f"{names[a]}'s 'after {d:g} s' ({tr.text}) does not fire by the path's end",
                    )
                )
    return out

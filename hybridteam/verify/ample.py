"""Partial-order reduction over independent deliveries (``--por ample``).

Two copies in flight to different receivers arrive in either order with the same result:
each arrival changes only its receiver (its modes and variables, its outbox and duplicate
filter) and adds copies. Exploring both orders of every such pair multiplies the states
by the interleavings of independent exchanges. From a state, :meth:`Ample.choose` picks
one copy ``c`` (to receiver ``r``) whose fates — it arrives, is lost, is duplicated —
form an *ample set* that keeps every verdict:

- **independence** (C1): on no path from the state that leaves ``c`` alone can anything
  happen to ``r``: no other copy to ``r`` is in flight, ``r`` has no timeout, world or
  scenario event to come and nothing awaiting acks, nobody has a message to ``r``
  awaiting acks, and no agent that may act before ``c`` arrives can send to ``r`` — the
  agents that may act are closed under "may send to" (the sends of the modes each can
  still reach, a broadcast to everyone), and an agent that answers ``to: sender`` could
  answer ``r`` only for a copy from ``r`` already in flight to it;
- **visibility** (C2): no checked invariant or response property reads ``r`` (its modes,
  roles or variables; ``count_in_role`` reads every agent with the role); ``deadlock``
  needs none (dead ends are kept exactly by such sets);
- **the cycle proviso** (C3): a state whose ample successors include one already stored
  is expanded fully (:func:`~.explore.explore`), so every cycle of the reduced graph has a
  fully expanded state and no choice is put off for ever.

Only with the timing under which arrivals have no other effect: ``--ack-timing bounded``
(a retransmission timer waits while its copies fly), ``--timeouts any`` (an ``after:``
does not wait for the network to settle) and ``--order any``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hybridteam.engine.compile.compiled import CAgent
from hybridteam.engine.run.reliable import ACK
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Options, active_of
from hybridteam.verify.machine import State
from hybridteam.verify.properties import Property, Unsupported, truth

FATES = ("deliver", "lose", "dup")


@dataclass(frozen=True)
class Sends:
    """Whom an agent may still send to from one configuration."""

    to: frozenset[int]  # named receivers (``to: b``)
    everyone: bool  # a broadcast, or a receiver computed from variables
    replies: bool  # ``to: sender``


@dataclass
class Ample:
    """Ample sets of one team's skeleton (see the module docstring)."""

    sk: Skeleton
    visible: frozenset[int]  # agents some checked property reads
    _sends: dict[tuple[int, bytes], Sends] = field(default_factory=dict, repr=False)

    def choose(self, s: State, choices: list[tuple]) -> list[tuple] | None:
        """An ample subset of ``choices`` (the state's), or None: all of them. The subset
        is every choice of one agent (the one with the fewest that qualifies)."""
        mine: dict[int, list[tuple]] = {}
        for ch in choices:
            owner = self._owner(s, ch)
            if owner is not None:
                mine.setdefault(owner, []).append(ch)
        best: list[tuple] | None = None
        for r, own in sorted(mine.items()):
            if (
                r not in self.visible
                and len(own) < len(choices)
                and (best is None or len(own) < len(best))
                and self._alone(s, choices, r)
            ):
                best = own
        return best

    @staticmethod
    def _owner(s: State, ch: tuple) -> int | None:
        """The agent a choice happens to, where it may be in an ample set: the receiver of
        a copy (not an ack) that arrives, is lost or duplicated; the agent of a
        time-driven transition or a world event. None for the rest."""
        kind = ch[0]
        if kind in FATES:
            c = s.inflight[ch[1]]
            return None if c.type == ACK else c.receiver
        if kind in ("time", "world"):
            return ch[1]
        return None

    def _alone(self, s: State, choices: list[tuple], r: int) -> bool:
        """Whether nothing can happen to ``r`` but its own choices until one of them is
        taken."""
        if any(e.sender == r or r in e.waiting for e in s.outbox):
            return False
        scenario = self.sk.original.scenario
        if any(agent == r for _, agent, _ in scenario[s.cursor :]):
            return False
        if any(c.type == ACK and c.receiver == r for c in s.inflight):
            return False
        acting: set[int] = set()
        for ch in choices:
            owner = self._owner(s, ch)
            if owner is not None:
                acting.add(owner)
            elif ch[0] == "timer":
                acting.add(s.outbox[ch[1]].sender)
        acting.discard(r)
        acting |= {agent for _, agent, _ in scenario[s.cursor :]}
        acting |= {c.receiver for c in s.inflight}  # acks among them
        acting.discard(r)
        todo = list(acting)
        while todo:
            a = todo.pop()
            sends = self.sends(s, a)
            if sends.everyone:
                return False
            if sends.replies and any(
                c.sender == r and c.receiver == a and c.type != ACK for c in s.inflight
            ):
                return False
            for b in sends.to - acting:
                if b == r:
                    return False
                acting.add(b)
                todo.append(b)
        return True

    def sends(self, s: State, a: int) -> Sends:
        """Whom agent ``a`` may send to from its configuration in ``s`` on (the sends of
        every transition from a mode it is in or can still reach, and of those modes'
        entry and exit actions)."""
        key = (a, s.agents[a][0])
        found = self._sends.get(key)
        if found is None:
            ca = self.sk.original.agents[a]
            modes = _reachable(ca, np.flatnonzero(active_of(s, a, len(ca.modes))).tolist())
            to: set[int] = set()
            everyone = replies = False
            actions = [x for tr in ca.transitions if tr.source in modes for x in tr.actions]
            actions += [x for m in modes for x in (*ca.modes[m].on_entry, *ca.modes[m].on_exit)]
            for x in actions:
                if x.kind != "send":
                    continue
                if x.to_expr is not None or x.to is None:
                    everyone = True
                elif x.to < 0:
                    replies = True
                else:
                    to.add(x.to)
            found = self._sends[key] = Sends(frozenset(to), everyone, replies)
        return found


def _reachable(ca: CAgent, active: list[int]) -> set[int]:
    """The modes active now or enterable later: closed under the transitions out of them
    (each target with its subtree, a history may restore any of it, and its ancestors)."""
    modes = set(active)
    todo = list(active)
    while todo:
        m = todo.pop()
        for j in ca.modes[m].outgoing:
            tr = ca.transitions[j]
            for t in tr.targets or ([] if tr.internal else [tr.target]):
                new = set(ca.modes[t].subtree.tolist()) | {t}
                p = ca.modes[t].parent
                while p >= 0:
                    new.add(p)
                    p = ca.modes[p].parent
                for x in new - modes:
                    modes.add(x)
                    todo.append(x)
    return modes


class _Reads:
    """A stand-in for the explored states' signals that records which agents a formula
    reads (every branch of it is evaluated)."""

    shape = (1, 1)

    def __init__(self, sk: Skeleton) -> None:
        self.names = {ca.name: a for a, ca in enumerate(sk.original.agents)}
        self.agents: set[int] = set()

    def in_modes(self, agent: str, modes: list[int]) -> np.ndarray:
        self.agents.add(self.names[agent])
        return np.zeros(self.shape, bool)

    def variable(self, agent: str, j: int) -> np.ndarray:
        self.agents.add(self.names[agent])
        return np.zeros(self.shape)

    def param(self, agent: str, name: str) -> np.ndarray:
        return np.zeros(self.shape)  # a constant

    def team_param(self, name: str) -> np.ndarray:
        return np.zeros(self.shape)

    def __getattr__(self, name: str):
        raise Unsupported(name)  # time, state, series, events: not checked anyway


def ample(sk: Skeleton, props: list[Property], opts: Options) -> Ample | None:
    """Ample sets for ``sk`` checking ``props`` under ``opts``, or None where the options'
    timing makes arrivals depend on each other (see the module docstring)."""
    if opts.ack_timing != "bounded" or opts.timeouts != "any" or opts.order != "any":
        return None
    reads = _Reads(sk)
    for p in props:
        for node in (p.phi, p.psi) if p.kind in ("invariant", "response") else ():
            if node is not None:
                try:
                    truth(node, reads)  # type: ignore[arg-type]  # (records the reads)
                except Unsupported:
                    reads.agents |= set(range(len(sk.original.agents)))
    return Ample(sk, frozenset(reads.agents))

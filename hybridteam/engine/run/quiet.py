"""Quiet copies: stream copies whose arrival no instant needs.

An instant at every copy's arrival (a step ending there, the world, the discrete phase,
the laws' and streams' bookkeeping, the checks) is what made a jittered team cost twice
its jitter-free twin: jitter spreads the copies of one send over as many instants as it
has receivers. Yet most copies only write an estimate that nothing reads before the
receiver's next law tick. A copy is *quiet* when, for its receiver and its type:

- no transition of the receiver waits for the message (it fires nothing);
- no agent watches a guard or invariant atom that reads an estimate, and no urgent guard
  reads one (a copy changes neither a located crossing nor an urgent transition);
- none of the receiver's drivers is read between ticks with an estimate in it: its laws
  are sampled (at ticks and mode entries, which are instants) or zero, and a flow reads
  no estimate;
- every world component judges robots at their sensing instants only
  (``WorldComponent.sensing_instants_only``), and while some robot the world may judge
  senses at every instant (no control period: ``next_tick`` infinite) the instance holds
  nothing (its copies' arrivals are sensing instants for that robot);
- it arrives after the instant it is sent at (a copy without latency arrives within its
  send's instant, where a law whose mode was entered then samples again and reads it);
- something else keeps the instance from a deadlock (a running stream, or a component
  that raises events): the last copy in flight of a stalled team is where its deadlock is
  found, so while nothing streams the copies are instants again.

A quiet copy is held apart from the event queue (:meth:`.events.EventQueue.take_held`):
no step ends at it. At the next instant of its instance, before anything there, it is
received at its own arrival time — the same rate limit, protocol screen, estimate and
message-table row, in the same order, as when its arrival was an instant of its own; a
copy arriving exactly at that instant joins the instant's events in the queue's order.
What changes is only where steps end: a kinematic plant's arc over a control period is
one arc rather than one per copy (states differ from the split steps' by round-off), and a
requirement's snapshots are taken at the instants that remain (a component's series hold
their last reading between sensing instants, so theirs are the same values).

A live run, a replay and the verifier never hold copies (their clocks, outlets and
scripts see every event as it comes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import NO_INDEX
from hybridteam.engine.run.state import reads_estimates

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CAgent
    from hybridteam.engine.run.ensemble import Ensemble


def quiet_pairs(ens: Ensemble) -> frozenset[tuple[int, str]]:
    """The ``(receiving agent, stream type)`` pairs whose copies are quiet (see the module
    docstring); empty where the team streams nothing or some estimate is watched."""
    inbox = ens.states[0].inbox if ens.states else None
    if inbox is None:
        return frozenset()
    if any(st.watch_estimates or st.urgent_volatile for st in ens.states):
        return frozenset()
    if not all(type(c).sensing_instants_only for c in ens.world.components):
        return frozenset()
    return frozenset(
        (st.ca.index, type_)
        for st in ens.states
        if _reads_estimates_at_ticks(st.ca)
        for type_ in inbox.fields
        if not st.ca.waiting(type_)
    )


def _reads_estimates_at_ticks(ca: CAgent) -> bool:
    """Whether agent ``ca``'s drivers read estimates only where an instant is (sampled laws
    and inputs, zero inputs, a flow whose expressions name no estimate)."""
    for d in ca.drivers:
        if d.kind == "continuous":
            return False
        if d.kind == "flow" and any(e is not None and reads_estimates(e) for e in d.flow or ()):
            return False
    return True


class QuietCopies:
    """The held copies' side of the loop: which pairs are quiet, where an instance holds
    them, and their receipt at the next instant."""

    def __init__(self, ens: Ensemble) -> None:
        self.ens = ens
        ens.queue.quiet = quiet_pairs(ens)
        #: the agents a world component may judge (those with a state): an instance
        #: holds no copy while one of them senses at every instant
        self.judged = [st for st in ens.states if st.ca.plant.state_names] if ens.world.any else []
        self.raises = ens.world.raises

    @property
    def any(self) -> bool:
        """Whether some copy may be held."""
        return bool(self.ens.queue.quiet)

    def receive(self, idx: np.ndarray) -> np.ndarray:
        """Receive the held copies that arrived before the current time of instances
        ``idx`` (at an instant, before anything there); returns the instances where a
        copy arrived exactly now (it joined their events: their discrete phase runs)."""
        ens = self.ens
        queue = ens.queue
        if idx.size == 1:
            i = idx.item(0)
            if not queue.held_next.item(i) <= ens.t.item(i):
                return NO_INDEX
            due = [i]
        else:
            due = idx[queue.held_next[idx] <= ens.t[idx]].tolist()
        now: list[int] = []
        for i in due:
            t = ens.t.item(i)
            for entry in queue.take_held(i, t):
                ens.network.receive_one(i, entry[0], entry[6], screen=ens.screen)
            if queue.next.item(i) <= t:
                now.append(i)
        return np.array(now, np.intp) if now else NO_INDEX

    def refresh(self, config: np.ndarray) -> None:
        """Where the configuration changed: an instance holds copies while every robot
        the world may judge has a control period and something keeps it from a deadlock
        (a running stream, a component that raises events); where it stops holding, the
        copies held so far join its queue."""
        ens = self.ens
        queue = ens.queue
        for i in config.tolist():
            holds = (self.raises or ens.streams.next.item(i) < np.inf) and all(
                st.next_tick.item(i) < np.inf for st in self.judged
            )
            if holds:
                queue.holding[i] = True
            elif queue.holding[i]:
                queue.wake(i)

    def close(self) -> None:
        """At the end of the run: copies that arrived before an instance's last time (one
        ended between instants, by a broken state or the wall clock) are received."""
        ens = self.ens
        held = [i for i, heap in ens.queue.held.items() if heap]
        if held:
            self.receive(np.array(sorted(held), np.intp))

"""The wall clock and the wire outlet: the engine's two seams as a live process fills them.

Run time is ``K`` times the wall seconds since the process started (``K``: the time scale,
1 on robots; larger only for simulated plants, so tests need not wait). Before each step
:class:`WallClock` sleeps until the engine's next scheduled instant is due, waking early
for datagrams: each one this process hosts an addressee of becomes a message event at the
run time it arrived (never before the engine's present), so the step ends there and the
engine receives it as it receives a simulated copy. :class:`WireOutlet` puts every send
of the hosted agents on the wire. Inside an instant, an agent's process waiting for the
world process's answer to its poses takes arrivals the same way
(:meth:`WallClock.take_until`).
"""

from __future__ import annotations

import logging
import random
import time
from collections import Counter
from collections.abc import Callable, Collection, Mapping
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.events import LOCAL
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.schedule import earliest
from hybridteam.live.transport import Transport
from hybridteam.live.wire import POSE, READING, Codec, WireError

if TYPE_CHECKING:
    from hybridteam.live.world import WorldLink

log = logging.getLogger(__name__)

#: The longest single wait (wall seconds): a stop request is seen within it.
MAX_WAIT = 0.05

#: The reason a copy dropped by ``--drop-copy`` has in the trace's message table.
SCRIPTED_LOSS = "loss (scripted)"


class WallClock:
    """Run time on the wall clock, arrivals from a transport (module docstring)."""

    def __init__(
        self,
        codec: Codec,
        transport: Transport,
        here: Collection[int],
        time_scale: float = 1.0,
        stop: Callable[[], str | None] = lambda: None,
        *,
        drop: float = 0.0,
        delay: float = 0.0,
        seed: int = 0,
        drop_copies: Mapping[str, Collection[int]] | None = None,
    ) -> None:
        """``stop``: asked while waiting; a reason (a signal's name) ends the run.
        ``drop``, ``delay`` and ``drop_copies`` are test aids, not a network model: each
        datagram of the team that arrives is dropped with probability ``drop`` (draws
        from ``seed``, in arrival order) or held ``delay`` run seconds more, and the
        ``n``-th copy of a message type for an agent here (``n`` in ``drop_copies[type]``,
        counting from 1) is dropped: a scripted loss, as a counterexample has one."""
        self.codec, self.transport = codec, transport
        self.here = sorted(here)
        self.scale = time_scale
        self.stop = stop
        self.start()
        self.received = 0
        self.delivered = 0
        self.dropped: Counter[str] = Counter()
        self.drop, self.delay = drop, delay
        self.rng = random.Random(seed)
        self.drop_copies = {k: frozenset(v) for k, v in (drop_copies or {}).items()}
        self.copies: Counter[str] = Counter()  # copies of each type for agents here
        self.injected = {"dropped": 0, "delayed": 0, "scripted": 0}
        #: wall seconds each instant the loop slept for was taken late (the jitter of a
        #: control period), and from each arrival that can change a mode (a message that
        #: is no stream's copy, an event the world raises) to the end of the step that
        #: handled it
        self.late: list[float] = []
        self.reaction: list[float] = []
        #: arrivals queued and not yet handled: (run time, time.monotonic() on arrival)
        self._waiting: list[tuple[float, float]] = []
        #: the world kinds' traffic (:mod:`~hybridteam.live.world`), for a team with world
        #: components
        self.world: WorldLink | None = None
        #: datagrams read before the run started (:meth:`backlog`), taken first
        self._backlog: list[tuple[bytes, float]] = []
        #: whether a reading answering this instant's poses queued events at it, and
        #: whether a message that is no stream's copy arrived for an agent here, while
        #: waiting (:meth:`take_until`); the types only streams send (periodic copies)
        self._raised_now = False
        self._message = False
        self.streamed: frozenset[str] = frozenset()

    def start(self, at: float | None = None) -> None:
        """Run time 0 is now (called as the run starts), or wall time ``at``
        (``time.time()``: launch's one start of all its processes, which a process that
        read it late is already past, and catches up with)."""
        mono, wall = time.monotonic(), time.time()
        self.wall0 = wall if at is None else at  # (on the wall clock: send times)
        self.mono0 = mono - (wall - self.wall0)
        self.cpu0 = time.process_time()

    def now(self) -> float:
        """The run time now."""
        return (time.monotonic() - self.mono0) * self.scale

    def advance(self, ens: Ensemble) -> None:
        if self._waiting:  # the arrivals the steps since the last call have handled
            handled = time.monotonic()
            t = float(ens.t[0])
            self.reaction += [handled - m for tau, m in self._waiting if tau <= t]
            self._waiting = [(tau, m) for tau, m in self._waiting if tau > t]
        due = min(float(earliest(ens.instants, ens.instants_at.shape[0])[0][0]), ens.t_end)
        slept = False
        while True:
            if self._take(ens):
                return
            reason = self.stop()
            if reason is not None:
                log.info("stopping at t=%.3f: %s", float(ens.t[0]), reason)
                ens.finish(
                    ens.everyone,
                    "stopped",
                    lambda i, why=reason: f"stopped by {why} at t={ens.when(i)}",  # type: ignore[misc]  # default-bound lambda
                )
                return
            now = self.now()
            if now >= due:
                if slept:
                    self.late.append((now - due) / self.scale)
                return
            self.transport.wait(min((due - now) / self.scale, MAX_WAIT))
            slept = True

    def take_until(self, ens: Ensemble, done: Callable[[], bool], seconds: float) -> bool:
        """Take arrivals as between instants until ``done()`` holds or ``seconds`` wall
        seconds pass: an agent's process waiting, inside an instant, for the world
        process's answer to its poses (:meth:`hybridteam.live.world.WorldLink.
        await_answers`). A reading that answers them raises its events at this instant, as
        the components' events are raised in a simulation; everything else arrives when
        it arrives. A message for an agent here that is no stream's copy (:attr:`streamed`)
        ends the wait too: its reply is not held for the world process (the instant's laws
        read the latest reading instead). Returns whether such a reading queued events."""
        self._raised_now = self._message = False
        end = time.monotonic() + seconds
        while True:
            self._take(ens)
            left = end - time.monotonic()
            if done() or self._message or ens.done[0] or left <= 0:
                return self._raised_now
            self.transport.wait(left)

    def _take(self, ens: Ensemble) -> bool:
        """Queue every datagram waiting for the hosted agents; whether any was queued."""
        queued = False
        arrivals, self._backlog = self._backlog + self.transport.receive(), []
        # (the world process answers every pose taken at once at one instant, the last's
        # arrival: the instant cannot run before they are all taken, and one instant is
        # one run of the components; a world process behind does not fall further behind)
        last = max((arrived for _, arrived in arrivals), default=0.0)
        for data, arrived in arrivals:
            self.received += 1
            try:
                dg = self.codec.decode(data)
            except WireError as exc:
                self.dropped[exc.reason] += 1
                log.debug("dropped a datagram (%s)", exc)
                continue
            if self.drop and self.rng.random() < self.drop:
                self.injected["dropped"] += 1
                continue
            if dg.type in (POSE, READING):
                queued = self._world(ens, dg, arrived, last) or queued
                continue
            receivers = [r for r in self.here if r != dg.sender and dg.to in (-1, r)]
            if receivers and dg.type in self.drop_copies:
                self.copies[dg.type] += 1
                if self.copies[dg.type] in self.drop_copies[dg.type]:
                    self.injected["scripted"] += 1
                    log.info("dropped copy %d of '%s' (--drop-copy)", self.copies[dg.type], dg.type)
                    # (in the trace as the simulator records a copy lost on its way, so
                    # the run shows the loss it was given, as a counterexample's run does)
                    for r in receivers:
                        ens.network.record(
                            0,
                            Message(
                                dg.sender,
                                r,
                                dg.seq,
                                (dg.sent - self.wall0) * self.scale,
                                dg.socket,
                                dg.type,
                                dict(dg.fields),
                                dg.msg_id,
                                dg.note,
                            ),
                            float("nan"),
                            "lost",
                            SCRIPTED_LOSS,
                        )
                    continue
            t = max((arrived - self.mono0) * self.scale, float(ens.t[0])) + self.delay
            if self.delay:
                self.injected["delayed"] += 1
            t_send = (dg.sent - self.wall0) * self.scale
            control = dg.type not in self.streamed
            if receivers and control:
                self._message = True
            for r in receivers:
                ens.network.arrive(
                    0,
                    Message(
                        dg.sender,
                        r,
                        dg.seq,
                        t_send,
                        dg.socket,
                        dg.type,
                        dict(dg.fields),
                        dg.msg_id,
                        dg.note,
                    ),
                    t,
                    dg.rank,
                )
                self.delivered += 1
                if control:  # (a stream's copy changes no mode: it is not a reaction)
                    self._waiting.append((t, arrived + self.delay / self.scale))
                queued = True
        return queued

    def _world(self, ens: Ensemble, dg, arrived: float, last: float) -> bool:
        """A pose or a reading (:mod:`~hybridteam.live.world`): a pose arriving at the world
        process is an instant there (at ``last``, the arrival of the last datagram taken
        with it); a reading's events are raised in their agent at its arrival, and its
        outcome ends the run. Whether the run must take an instant now."""
        if self.world is None:
            return False
        now = dg.type == READING and self.world.answers_now(dg)
        got = self.world.take(dg)
        if got is None:
            return False
        self.delivered += 1
        at = last if dg.type == POSE else arrived
        t = float(ens.t[0]) if now else max((at - self.mono0) * self.scale, float(ens.t[0]))
        t += self.delay
        events, outcome = got
        if outcome is not None:
            ens.finish(
                ens.everyone,
                outcome,
                lambda i: f"the world process concluded '{outcome}' at t={ens.when(i)}",
            )
            return True
        names = [POSE] if dg.type == POSE else events
        agent = dg.sender if dg.type == POSE else dg.to
        for name in names:
            ens.queue.push(np.array([0]), np.array([t]), LOCAL, agent, name)
            self._waiting.append((t, arrived + self.delay / self.scale))
        self._raised_now = self._raised_now or (now and bool(names))
        return bool(names)

    def backlog(self, datagrams: list[tuple[bytes, float]]) -> None:
        """Datagrams read from the transport before the run's first instant (while
        waiting for the world process's first reading), to be taken before any newer, as
        arrived at run time 0: that instant's (its laws read the first readings there)."""
        self._backlog = [*((data, self.mono0) for data, _ in datagrams), *self._backlog]

    def record(self) -> dict:
        """What the trace's ``meta.live`` says of the clock and the wire."""
        return {
            "clock": "wall",
            "time_scale": self.scale,
            "wall_start": self.wall0,
            "datagrams": {
                "received": self.received,
                "delivered": self.delivered,
                "dropped": dict(sorted(self.dropped.items())),
            },
            "injected": {
                "drop": self.drop,
                "delay": self.delay,
                "drop_copies": {k: sorted(v) for k, v in sorted(self.drop_copies.items())},
                **self.injected,
            },
            "wall_s": time.monotonic() - self.mono0,
            "cpu_s": time.process_time() - self.cpu0,
            "late_ms": percentiles(self.late),
            "reaction_ms": percentiles(self.reaction),
        }


def percentiles(seconds: list[float]) -> dict[str, float | int]:
    """Count, median, 99th percentile and largest of durations, in milliseconds."""
    if not seconds:
        return {"count": 0}
    ms = np.asarray(seconds) * 1e3
    return {
        "count": int(ms.size),
        "p50": float(np.percentile(ms, 50)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
    }


class WireOutlet:
    """The network's outlet: each send of a hosted agent, encoded, to the transport."""

    def __init__(self, codec: Codec, transport: Transport) -> None:
        self.codec, self.transport = codec, transport
        self.sent = 0

    def send(self, msg: Message, rank: float) -> None:
        self.transport.send(self.codec.encode(msg, rank, time.time()), msg.socket)
        self.sent += 1

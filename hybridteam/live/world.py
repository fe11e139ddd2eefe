"""The world process and the agents' reading of it: the engine's world seam, live.

A team's world components (a payload carried between robots, obstacles their range rings
see) couple agents that live in different processes, so they run in a process of their
own (``hybridteam live TEAM.yaml --world``; docs/live.md, *The world process*).

* :class:`WorldHost` is the world process's world: the team's own components
  (:class:`~hybridteam.engine.run.world.World`), run by the engine at every instant as in a
  simulation, on the poses and variables the agents' processes last sent (every agent is
  remote there). Each pose that arrives is an instant, and is answered with a reading for
  its agent: what it senses now, the events components raised for it, an outcome they
  concluded (that one goes to every agent).
* :class:`WorldReadings` is an agent process's world: it runs no component; it sends the
  hosted agents' poses at every instant and answers ``ctx.sense`` from the latest reading,
  except for a robot with a laser (``--plant ros2`` with a ``scan`` topic): its range
  rings are read from the laser, and its detect rules run on them here. At an instant
  where a hosted agent's law ticks it first waits, at most :data:`ANSWER_WAIT` of a
  control period, for the world process's reading that answers the poses just sent.

Why wait: in a simulation the components run on this instant's state before any law
samples, so a law reads the world as of its own instant. Live, without the wait, a law
ticking at the instant its pose is sent reads the world's answer to the previous pose, a
control period old (experiment 2's XR4000 docked up to two periods early). On loopback the
answer takes about a millisecond. Only the ticks wait, and a message that is no stream's
copy ends a wait (:meth:`~hybridteam.live.clock.WallClock.take_until`): waiting at a
message's arrival would delay every reply (each hop of a handshake). A law whose mode such
an instant enters reads the answer to the last instant's pose; events the world raises
for a pose of such an instant are raised where its reading arrives.

:class:`WorldLink` is what the wall clock (:mod:`~hybridteam.live.clock`) hands the
datagrams of the two kinds to, and what both sides send through. It also watches the other
side fall silent (``timeout`` wall seconds, :data:`SILENCE` unless told): an agent's process
whose pose goes that long unanswered stops its run (:meth:`WorldLink.world_silent`); the
world process holds a silent agent's last pose, as it holds every pose between two, logs the
silence and records it (:meth:`WorldLink.watch`), and goes on with the others.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.run.world import World
from hybridteam.live.transport import Transport
from hybridteam.live.wire import POSE, READING, WORLD_INDEX, Codec, Datagram
from hybridteam.world.obstacles import Obstacles
from hybridteam.world.sensors import RangeRing, detect

if TYPE_CHECKING:
    from hybridteam.engine.run.access import EnsembleAccess
    from hybridteam.model import Team

log = logging.getLogger(__name__)

#: Wall seconds the other side may be silent before it is taken for gone: longer than the
#: two-second pause of a process the team must ride out, short enough for an operator.
SILENCE = 5.0

#: The longest wait, as a fraction of the hosted agents' control period (their shortest
#: law period, in wall seconds), for the world process's answer to an instant's poses:
#: half a period leaves the other half for the instant itself before the next tick.
ANSWER_WAIT = 0.5


class WorldLink:
    """The world kinds' traffic of one process: what arrived, and the sending."""

    def __init__(
        self,
        codec: Codec,
        transport: Transport,
        here: Collection[int],
        host: bool,
        timeout: float = SILENCE,
    ) -> None:
        """``here``: the hosted agents' indices; ``host``: this is the world process;
        ``timeout``: wall seconds of silence after which the other side is gone."""
        self.codec, self.transport = codec, transport
        self.here, self.host = sorted(here), host
        self.timeout = timeout
        #: (world process) per agent, when its last pose arrived (``time.monotonic()``)
        #: and at which run time; the silences seen, and the open one of each agent
        self.heard: dict[int, float] = {}
        self.heard_t: dict[int, float] = {}
        self.silences: list[dict[str, Any]] = []
        self.silent: dict[int, dict[str, Any]] = {}
        #: (agents' process) when the first pose since the last reading was sent
        self.asked: float | None = None
        self.seq = 0
        #: (world process) each agent's last pose, and the agents to answer at the next
        #: instant with the number of the pose answered (every one at the start, -1:
        #: their first readings)
        self.poses: dict[int, dict[str, float]] = {}
        self.pending: dict[int, int] = dict.fromkeys(range(len(codec.agents)), -1) if host else {}
        #: (agents' process) per hosted agent, the number of its last pose not answered
        #: yet; the longest wait for an instant's answers (wall seconds, 0: none), whether
        #: this instant waits (a law ticks) and what waits (:meth:`await_answers`);
        #: whether it is waiting now; the instants whose answer did not come in time, and
        #: how long each answer that did took
        self.unanswered: dict[int, int] = {}
        self.wait = 0.0
        self.due: Callable[[], bool] = lambda: True
        self.pump: Callable[[Callable[[], bool], float], bool] | None = None
        self.answering = False
        self.late = 0
        self.answer_s: list[float] = []
        #: (agents' process) the last reading per hosted agent: sensed name -> values
        self.readings: dict[int, dict[str, np.ndarray]] = {}
        #: (agents' process) (agent, event) its process raises itself (a robot's detect
        #: rules on its laser): the world process's raising of them is not taken
        self.local: set[tuple[int, str]] = set()
        self.sent = 0

    def send(
        self, kind: str, sender: int, to: int, fields: dict[str, float], answers: int = -1
    ) -> None:
        """A pose (``sender`` an agent here) or a reading (to agent ``to``, answering its
        pose numbered ``answers``, -1: none)."""
        if kind == POSE:
            if self.asked is None:
                self.asked = time.monotonic()
            self.unanswered[sender] = self.seq
        self.transport.send(
            self.codec.encode_world(kind, sender, to, self.seq, fields, time.time(), answers),
            "data",
        )
        self.seq += 1
        self.sent += 1

    def take(self, dg: Datagram) -> tuple[list[str], str | None] | None:
        """A datagram of a world kind that arrived: kept if it is this process's (a pose
        in the world process, a reading for an agent here). Returns, for a reading, the
        events it raises and the outcome it concludes; None if it was not for here."""
        if dg.type == POSE:
            if not self.host:
                return None
            self.poses[dg.sender] = dg.fields
            self.pending[dg.sender] = dg.seq
            self.heard[dg.sender] = time.monotonic()
            return [], None
        if self.host or dg.to not in self.here:
            return None
        self.asked = None
        if dg.msg_id >= self.unanswered.get(dg.to, dg.msg_id + 1):
            del self.unanswered[dg.to]
        sensed: dict[str, list[tuple[int, float]]] = {}
        events, outcome = [], None
        for key, value in dg.fields.items():
            head, _, tail = key.partition(".")
            if head == "event":
                if (dg.to, tail) not in self.local:
                    events.append(tail)
            elif head == "outcome":
                outcome = tail
            else:
                sensed.setdefault(head, []).append((int(tail) if tail else -1, value))
        reading = self.readings.setdefault(dg.to, {})
        for name, items in sensed.items():
            if items[0][0] < 0:
                reading[name] = np.asarray(items[0][1], float)
            else:
                reading[name] = np.asarray([v for _, v in sorted(items)], float)
        return events, outcome

    def answers_now(self, dg: Datagram) -> bool:
        """(agents' process) Whether reading ``dg`` answers a pose of the instant being
        waited for (:meth:`await_answers`): its events are raised at that instant."""
        return self.answering and dg.msg_id >= self.unanswered.get(dg.to, dg.msg_id + 1)

    def overdue(self) -> bool:
        """(agents' process) Whether a pose sent has gone unanswered longer than a wait:
        the world process is behind (busy, paused), and waiting for it again would make
        this process late too."""
        return self.asked is not None and time.monotonic() - self.asked > self.wait

    def await_answers(self, behind: bool) -> bool:
        """(agents' process, at an instant, its poses just sent) Where :attr:`due` (a law
        ticks), take arrivals until the world process has answered every pose sent, for
        at most :attr:`wait` wall seconds (through :attr:`pump`, the clock's taking of
        arrivals). An instant whose answer does not come in time is counted
        (:attr:`late`; logged the first time) and its laws read the latest reading; so is
        one that does not wait because the world process is ``behind``
        (:meth:`overdue`). Returns whether answers raised events at this instant."""
        if not self.unanswered or self.pump is None or self.wait <= 0 or not self.due():
            return False
        if behind:
            self.note_late()
            return False
        start = time.monotonic()
        self.answering = True
        try:
            raised = self.pump(lambda: not self.unanswered, self.wait)
        finally:
            self.answering = False
        if self.unanswered:
            self.note_late()
        else:
            self.answer_s.append(time.monotonic() - start)
        return raised

    def note_late(self) -> None:
        """Count an instant whose laws read an older reading; log the first."""
        self.late += 1
        if self.late == 1:
            # (info, not a warning: on a loaded machine some answers are late in every run;
            # the count is the record)
            log.info(
                "the world process's answer to a pose did not come within %.1f ms: "
                "the laws read the latest reading (each such instant is counted in "
                "meta.live.world_late)",
                self.wait * 1e3,
            )

    def world_silent(self) -> str | None:
        """(agents' process) Why the run must stop, if a pose sent has gone unanswered
        for ``timeout`` wall seconds (the world process is gone, or cut off); else None."""
        if self.asked is None or time.monotonic() - self.asked <= self.timeout:
            return None
        why = f"the world process's silence (no reading within {self.timeout:g} s of a pose sent)"
        log.warning("%s", why)
        return why

    def watch(self, t: float) -> None:
        """(world process, at each instant, run time ``t``) Note each agent that has sent
        no pose for ``timeout`` wall seconds (since the world's start, before its first),
        and each silent one heard again: logged, and kept in :attr:`silences` (run times:
        its last pose, when the silence was noticed, when it was heard again or None).
        Nothing else changes: its last pose is held, as between any two."""
        now = time.monotonic()
        for a, name in enumerate(self.codec.agents):
            last = self.heard.setdefault(a, now)
            if a in self.poses:
                self.heard_t[a] = t
            gap = self.silent.get(a)
            if gap is not None and last > gap["mono"]:
                gap["to"] = t
                del gap["mono"], self.silent[a]
                log.info("agent '%s' heard again at t=%.3f", name, t)
            elif gap is None and now - last > self.timeout:
                since = self.heard_t.get(a)
                gap = {"agent": name, "from": since, "noticed": t, "to": None, "mono": now}
                self.silent[a] = gap
                self.silences.append(gap)
                log.warning(
                    "agent '%s' silent for %g s (%s): the world holds its last pose",
                    name,
                    self.timeout,
                    "no pose yet" if since is None else f"last pose at t={since:.3f}",
                )

    def silence_record(self) -> list[dict[str, Any]]:
        """The silences seen, for the trace's ``meta.live``."""
        return [{k: v for k, v in gap.items() if k != "mono"} for gap in self.silences]


class WorldHost(World):
    """The world process's world: the components on the poses received (module
    docstring)."""

    link: WorldLink  # (set by :func:`world_seam`)

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        link = self.link
        link.watch(float(access.t[idx[0]]))
        for a, fields in link.poses.items():
            names = access.state_names(a)
            state = [n for n in names if n in fields]
            if state:
                access.set_state(a, idx, np.array([[fields[n] for n in state]]), state)
            for n in access.variable_names(a):
                if n in fields:
                    access.set_variable(a, n, idx, np.array([fields[n]]))
        link.poses.clear()
        said = _Told(access)
        raised = super().update(said, idx)  # type: ignore[arg-type]  # a forwarding stand-in
        answer = set(link.pending) | set(said.events)
        if said.outcome is not None:
            answer = set(range(len(link.codec.agents)))
        for a in sorted(answer):
            fields = self.reading(a, idx)
            fields.update({f"event.{e}": 1.0 for e in said.events.get(a, [])})
            if said.outcome is not None:
                fields[f"outcome.{said.outcome}"] = 1.0
            link.send(READING, WORLD_INDEX, a, fields, link.pending.get(a, -1))
        link.pending.clear()
        return raised

    def reading(self, agent: int, idx: np.ndarray) -> dict[str, float]:
        """What ``agent`` senses now, flattened: ``name`` for a number, ``name.k`` for the
        k-th of a vector; names a component gives no finite value for are left out."""
        out: dict[str, float] = {}
        for c in self.components:
            for name in c.senses():
                if name in out or f"{name}.0" in out:
                    continue  # (the first component offering a name answers it)
                try:
                    values = np.asarray(c.sense(agent, idx, name), float)[0]
                except KeyError:  # (a range ring this robot does not have)
                    continue
                if not np.all(np.isfinite(values)):
                    continue
                if values.ndim == 0:
                    out[name] = float(values)
                else:
                    out.update({f"{name}.{k}": float(v) for k, v in enumerate(values.ravel())})
        return out


class _Told:
    """The world access as a component sees it in the world process, noting the events
    it raises (by agent index) and the outcome it concludes, to be sent on."""

    def __init__(self, access: EnsembleAccess) -> None:
        self._access = access
        self.events: dict[int, list[str]] = {}
        self.outcome: str | None = None

    def raise_event(self, idx: np.ndarray, agent: Any, event: str) -> None:
        self.events.setdefault(self._access.agent(agent), []).append(event)
        self._access.raise_event(idx, agent, event)

    def finish(self, idx: np.ndarray, outcome: str, message: Any) -> None:
        self.outcome = outcome
        self._access.finish(idx, outcome, message)

    def sensing(self, agent: Any, idx: np.ndarray) -> np.ndarray:
        """Every instant: the world process runs on the poses the agents send from their
        own processes (at their ticks) and answers what they ask for, so each of its
        instants is one of a robot's sensing instants; its own clocks tick nothing."""
        return np.ones(len(idx), bool)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._access, name)


class WorldReadings(World):
    """An agent process's world: the world process's readings (module docstring), and
    the lasers of the hosted robots that have one, read as their range rings."""

    link: WorldLink  # (set by :func:`world_seam`)
    #: by hosted agent's index, a robot whose laser its range rings are read from
    #: (:meth:`read_lasers`)
    lasers: Mapping[int, Any] = {}
    #: (rule, its ring, whether its beams read near at the last instant) for each detect
    #: rule of a robot with a laser
    laser_rules: Sequence[list[Any]] = ()

    @property
    def any(self) -> bool:
        return True  # (every instant sends the hosted agents' poses)

    @property
    def raises(self) -> bool:
        return True

    def start(self, access: EnsembleAccess) -> None:
        """Nothing to start: the components run in the world process."""

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        """Send the hosted agents' poses and, where a law ticks, wait for the world
        process's answer (:meth:`WorldLink.await_answers`); the instances where events
        were raised now (by the answer, or by a laser's detect rules)."""
        link = self.link
        behind = link.overdue()
        for a in link.here:
            fields = dict(zip(access.state_names(a), access.state(a, idx)[0].tolist(), strict=True))
            fields.update(
                {n: float(access.variable(a, n, idx)[0]) for n in access.variable_names(a)}
            )
            if fields:
                link.send(POSE, a, WORLD_INDEX, fields)
        answered = link.await_answers(behind)
        if self.laser_rules:
            self.detect_on_lasers(access, idx)
        raised = access.take_raised()
        return np.union1d(raised, idx) if answered else raised

    def read_lasers(self, lasers: Mapping[int, Any]) -> None:
        """Read the range rings of the robots ``lasers`` names (by agent index: an object
        whose ``ranges(ring)`` gives what ``ring`` reads of its laser,
        :meth:`hybridteam.live.ros2_plant.RobotPlant.ranges`) from their lasers, and run
        their detect rules on those readings here (:meth:`detect_on_lasers`); the world
        process's raising of those rules' events for them is not taken
        (:attr:`WorldLink.local`)."""
        self.lasers = dict(lasers)
        self.laser_rules = [
            [rule, self.ring(rule.agent, rule.sensor), False]
            for c in self.components
            if isinstance(c, Obstacles)
            for rule in c.rules
            if rule.agent in self.lasers
        ]
        self.link.local = {(rule.agent, rule.event) for rule, _, _ in self.laser_rules}

    def detect_on_lasers(self, access: EnsembleAccess, idx: np.ndarray) -> None:
        """The detect rules of the robots with a laser, on what the laser reads as the
        rule's ring, as the obstacles component runs them on its ray casting: the rule's
        event raised when the nearest of its beams drops below its threshold (on the
        rising edge; nothing counts as seen before the first instant), read at the
        robot's sensing instants only (:meth:`~hybridteam.world.access.WorldAccess.sensing`:
        its law ticks), as in a simulation: a message arriving between two ticks reads no
        laser, and what the rule saw at the last tick stands (docs/world.md)."""
        for entry in self.laser_rules:
            rule, ring, seen = entry
            if not access.sensing(rule.agent, idx)[0]:
                continue
            ranges = self.lasers[rule.agent].ranges(ring)
            near = bool(detect(ranges[None, :], rule.below, rule.beams)[0])
            if near and not seen:
                access.raise_event(idx, rule.agent, rule.event)
            entry[2] = near

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        laser = self.lasers.get(agent)
        if laser is not None:
            ring = self.ring(agent, name)
            ranges = None if ring is None else laser.ranges(ring)
            if ranges is not None and ring is not None:
                return np.broadcast_to(ranges, (len(idx), ring.count)).copy()
        reading = self.link.readings.get(agent, {}).get(name)
        if reading is None:
            raise KeyError(f"the world process gave agent {agent} no reading of '{name}'")
        return np.broadcast_to(reading, (len(idx), *reading.shape)).copy()

    def ring(self, agent: int, name: str) -> RangeRing | None:
        """Agent ``agent``'s range ring ``name`` as the team's obstacles declare it (a
        detect rule's, or its robot model's), or None."""
        for c in self.components:
            if isinstance(c, Obstacles):
                return c.ring(agent, name)
        return None

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        return {}  # (the world's series are the world process's records)

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {}

    def summary(self, i: int) -> dict[str, Any]:
        return {}


def world_seam(
    cls: type[WorldHost | WorldReadings], link: WorldLink
) -> Callable[[Team, int, Mapping[str, np.ndarray]], World]:
    """The engine's world seam filled with ``cls`` talking through ``link``."""

    def build(team: Team, n: int, params: Mapping[str, np.ndarray]) -> World:
        world = cls(team, n, params)
        world.link = link
        return world

    return build

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
  hosted agents' poses at every instant and answers ``ctx.sense`` from the latest reading.

:class:`WorldLink` is what the wall clock (:mod:`.clock`) hands the datagrams of the two
kinds to, and what both sides send through.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Collection, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.run.world import World
from hybridteam.live.transport import Transport
from hybridteam.live.wire import POSE, READING, WORLD_INDEX, Codec, Datagram

if TYPE_CHECKING:
    from hybridteam.engine.run.access import EnsembleAccess
    from hybridteam.model import Team

log = logging.getLogger("hybridteam.live")


class WorldLink:
    """The world kinds' traffic of one process: what arrived, and the sending."""

    def __init__(self, codec: Codec, transport: Transport, here: Collection[int],
                 host: bool) -> None:
        """``here``: the hosted agents' indices; ``host``: this is the world process."""
        self.codec, self.transport = codec, transport
        self.here, self.host = sorted(here), host
        self.seq = 0
        #: (world process) each agent's last pose, and the agents to answer at the next
        #: instant (every one at the start: their first readings)
        self.poses: dict[int, dict[str, float]] = {}
        self.pending: set[int] = set(range(len(codec.agents))) if host else set()
        #: (agents' process) the last reading per hosted agent: sensed name -> values
        self.readings: dict[int, dict[str, np.ndarray]] = {}
        self.sent = 0

    def send(self, kind: str, sender: int, to: int, fields: dict[str, float]) -> None:
        self.transport.send(self.codec.encode_world(kind, sender, to, self.seq, fields,
                                                    time.time()), "data")
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
            self.pending.add(dg.sender)
            return [], None
        if self.host or dg.to not in self.here:
            return None
        sensed: dict[str, list[tuple[int, float]]] = {}
        events, outcome = [], None
        for key, value in dg.fields.items():
            head, _, tail = key.partition(".")
            if head == "event":
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


class WorldHost(World):
    """The world process's world: the components on the poses received (module
    docstring)."""

    link: WorldLink  # (set by :func:`world_seam`)

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        link = self.link
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
        raised = super().update(said, idx)
        answer = link.pending | set(said.events)
        if said.outcome is not None:
            answer = set(range(len(link.codec.agents)))
        for a in sorted(answer):
            fields = self.reading(a, idx)
            fields.update({f"event.{e}": 1.0 for e in said.events.get(a, [])})
            if said.outcome is not None:
                fields[f"outcome.{said.outcome}"] = 1.0
            link.send(READING, WORLD_INDEX, a, fields)
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

    def __getattr__(self, name: str) -> Any:
        return getattr(self._access, name)


class WorldReadings(World):
    """An agent process's world: the world process's readings (module docstring)."""

    link: WorldLink  # (set by :func:`world_seam`)

    @property
    def any(self) -> bool:
        return True  # (every instant sends the hosted agents' poses)

    @property
    def raises(self) -> bool:
        return True

    def start(self, access: EnsembleAccess) -> None:
        """Nothing to start: the components run in the world process."""

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        for a in self.link.here:
            fields = dict(zip(access.state_names(a),
                              access.state(a, idx)[0].tolist(), strict=True))
            fields.update({n: float(access.variable(a, n, idx)[0])
                           for n in access.variable_names(a)})
            if fields:
                self.link.send(POSE, a, WORLD_INDEX, fields)
        return access.take_raised()

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        reading = self.link.readings.get(agent, {}).get(name)
        if reading is None:
            raise KeyError(f"the world process gave agent {agent} no reading of '{name}'")
        return np.broadcast_to(reading, (len(idx), *reading.shape)).copy()

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        return {}  # (the world's series are the world process's records)

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {}

    def summary(self, i: int) -> dict[str, Any]:
        return {}


def world_seam(cls: type[World], link: WorldLink
               ) -> Callable[[Team, int, Mapping[str, np.ndarray]], World]:
    """The engine's world seam filled with ``cls`` talking through ``link``."""

    def build(team: Team, n: int, params: Mapping[str, np.ndarray]) -> World:
        world = cls(team, n, params)
        world.link = link
        return world

    return build

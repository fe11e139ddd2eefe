"""One live process's run: the hosted agents of a team, on the wall clock, over a
transport (docs/live.md).

The engine's ordinary :class:`~hybridteam.engine.run.simulator.Simulator` runs one instance
of the team as this process hosts it (:mod:`~hybridteam.live.hosting`), with the wall clock
as its clock and the wire as its network's outlet (:mod:`~hybridteam.live.clock`). Its trace
is the ordinary format, kept to what this process knows: the hosted agents' modes,
transitions and samples (a remote agent's samples are NaN: unknown here), every copy that
reached a hosted agent, and ``meta.live``: the agents here, the transport, the clock and the
datagrams counted. For a team with world components the engine's world seam is filled by
:mod:`~hybridteam.live.world`: in the world process (``world=True``, no agent here) the
components run on the poses received; in an agent's process its agents read the world
process.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Collection, Mapping, Sequence

import numpy as np

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.plant import ExternalPlant
from hybridteam.engine.run.record import variables_key
from hybridteam.engine.run.simulator import Simulator
from hybridteam.live.clock import WallClock, WireOutlet, percentiles
from hybridteam.live.hosting import HostingError, hosted_team
from hybridteam.live.transport import Transport
from hybridteam.live.wire import (
    POSE,
    READING,
    VERSION,
    WORLD_INDEX,
    Codec,
    WireError,
    declarations,
    wire_mismatch,
)
from hybridteam.live.world import (
    ANSWER_WAIT,
    SILENCE,
    WorldHost,
    WorldLink,
    WorldReadings,
    world_seam,
)
from hybridteam.model import Team
from hybridteam.trace import Trace, command_series

log = logging.getLogger(__name__)


class LiveRun:
    """One live process's run, built (the team compiled, the engine set up) apart from
    being run, so that a launcher can start every process's clock together."""

    def __init__(
        self,
        team: Team,
        agents: Sequence[str],
        transport: Transport,
        *,
        transport_name: str = "udp",
        time_scale: float = 1.0,
        duration: float | None = None,
        stop: Callable[[], str | None] = lambda: None,
        drop: float = 0.0,
        delay: float = 0.0,
        seed: int = 0,
        drop_copies: Mapping[str, Collection[int]] | None = None,
        plants: Mapping[str, ExternalPlant] | None = None,
        plant_name: str = "sim",
        world: bool = False,
        wire_team: Team | None = None,
        world_timeout: float = SILENCE,
    ) -> None:
        """The agents named ``agents`` of ``team``, over ``transport`` (the caller's to
        close); ``duration`` in run seconds (default the team's); ``stop`` is asked while
        waiting and ends the run when it gives a reason; ``drop``, ``delay``, ``seed``,
        ``drop_copies``: injected loss and delay at the receiving socket
        (:class:`.clock.WallClock`). HostingError for agents or a team a live process
        cannot run, or a ``drop_copies`` type the team does not declare. ``plants``: by
        hosted agent's name, an external plant (a robot, :mod:`hybridteam.engine.run.plant`;
        the caller's to close) in place of the integrated one, ``plant_name`` what the
        trace calls them; HostingError for one of an agent not here, or one the engine
        cannot drive. ``world``: this is the team's world process (``agents`` empty): it
        runs the world components on the poses the agents' processes send
        (:mod:`~hybridteam.live.world`). ``wire_team``: a test aid, the team whose wire
        identity this process speaks while it runs ``team`` (a drifted copy of it: the
        same name, agents and messages, :func:`~hybridteam.live.wire.wire_mismatch`;
        HostingError otherwise). ``world_timeout``: wall seconds of silence after which an
        agent's process stops its run (no reading for a pose sent), and the world process
        logs and records an agent's (no pose)."""
        full = compile_team(team)
        self.wire = None if wire_team is None else compile_team(wire_team)
        if self.wire is not None and (why := wire_mismatch(full, self.wire)) is not None:
            raise HostingError(f"--wire-team: {why}")
        if world and agents:
            raise HostingError("--world: the world process hosts no agent")
        if world and not team.world:
            raise HostingError("--world: this team declares no world components")
        # (the whole team's declarations: every process's)
        self.codec = Codec(full, wire=self.wire)
        cteam = hosted_team(full, agents)
        check_drop_copies(full, drop_copies or {})
        hosted = sorted(ca.index for ca in full.agents if ca.name in agents)
        self.here = [full.agents[a].name for a in hosted]
        self.team, self.transport_name, self.time_scale = team, transport_name, time_scale
        self.clock = WallClock(
            self.codec,
            transport,
            hosted,
            time_scale,
            stop,
            drop=drop,
            delay=delay,
            seed=seed,
            drop_copies=drop_copies,
        )
        external = {}
        index = {ca.name: ca.index for ca in full.agents}
        for name, plant in (plants or {}).items():
            if name not in self.here:
                raise HostingError(f"a plant for '{name}', which this process does not host")
            external[index[name]] = plant
        self.plant_name = plant_name
        #: the robots' plants by agent name: their commands go into the trace
        self.robots = dict(plants or {})
        seam: dict = {}
        self.link: WorldLink | None = None
        if team.world:
            self.link = WorldLink(self.codec, transport, hosted, host=world, timeout=world_timeout)
            self.clock.world = self.link
            if not world:  # (a silent world process stops the run as a signal does)
                link = self.link
                self.clock.stop = lambda: stop() or link.world_silent()
            seam["world"] = world_seam(WorldHost if world else WorldReadings, self.link)
            # (the world process records the world's series at its output samples: they
            # are instants there, the components run on the latest poses)
            seam["sample_instants"] = world
        self.world_process = world
        self.transport = transport
        try:
            # (no wall-time limit: a live run's pace is the wall clock's by design, and the
            # simulator's limit would end a deployment of more than a day as too slow)
            self.sim = Simulator(
                cteam,
                1,
                duration=duration,
                clock=self.clock,
                max_wall=math.inf,
                plants=external or None,
                **seam,
            )
        except ValueError as exc:  # (an external plant the engine cannot drive)
            raise HostingError(str(exc)) from None
        # (what a reading may carry: the names the team's components let robots sense)
        self.codec.senses = frozenset(
            name for c in self.sim.ensemble.world.components for name in c.senses()
        )
        if isinstance(self.sim.ensemble.world, WorldReadings):  # robots' lasers: rings
            self.sim.ensemble.world.read_lasers(
                {a: plant for a, plant in external.items() if getattr(plant, "laser", False)}
            )
        self.full = full
        if self.link is not None and not world:  # (laws read this instant's world)
            self.answer_at_ticks(self.link, hosted)
        self.outlet = WireOutlet(self.codec, transport)
        self.sim.ensemble.network.outlet = self.outlet

    def run(self, start: float | None = None) -> Trace:
        """Run until the end rule holds for the agents here, the duration passes, or
        ``stop`` gives a reason; returns the process's trace. ``start``: the wall time
        (``time.time()``) of run time 0, launch's for all its processes (default now)."""
        log.info(
            "%s: running %s live (time scale %g, until t=%g)",
            self.team.name,
            "the world" if self.world_process else ", ".join(self.here),
            self.time_scale,
            self.sim.ensemble.t_end,
        )
        # run time 0 is launch's 'go' for all its processes, the world's too, so each
        # process's instants are at the same wall times as the others'
        self.clock.start(start)
        if (
            self.link is not None
            and not self.world_process
            and self.here
            and self.await_world() > ASK_AGAIN
        ):
            # (the world process was not up yet, started by hand after this one: the run
            # starts at its first reading, not at a time zero long past)
            self.clock.start()
        trace = self.sim.run()
        world_host = self.link is not None and self.world_process
        record = {
            "agents": self.here,
            "ending": [self.full.agents[a].name for a in self.full.ending],
            "transport": self.transport_name,
            "plant": self.plant_name,
            "wire": VERSION,
            "digest": self.codec.digest,
            **self.clock.record(),
            "sent": self.outlet.sent,
            "world": self.world_process,
            **({"world_sent": self.link.sent} if self.link is not None else {}),
            **(self.answers_record() if self.link is not None and not world_host else {}),
            **(
                {"world_silent": self.link.silence_record()}
                if world_host and self.link is not None
                else {}
            ),
        }
        dropped = record["datagrams"]["dropped"]
        if dropped:
            log.warning(
                "dropped %d datagram(s) not of this team: %s",
                sum(dropped.values()),
                ", ".join(f"{k} {v}" for k, v in dropped.items()),
            )
        return process_trace(
            trace,
            record,
            {name: getattr(plant, "commands", []) for name, plant in self.robots.items()},
        )

    def answer_at_ticks(self, link: WorldLink, hosted: Sequence[int]) -> None:
        """Have ``link`` wait for the world process's answer at the instants where a
        hosted agent's sampled law ticks, at most :data:`~hybridteam.live.world.
        ANSWER_WAIT` of their control period (:mod:`~hybridteam.live.world`)."""
        ens = self.sim.ensemble
        states = [
            ens.states[a]
            for a in hosted
            if any(d.kind == "sampled" for d in self.full.agents[a].drivers)
        ]
        link.wait = ANSWER_WAIT * control_period(self.full, hosted) / self.time_scale
        # (a stream's periodic copies do not end a wait; a type also sent by transitions
        # does, as every other message)
        sent = {
            act.name
            for ca in self.full.agents
            for tr in ca.transitions
            for act in tr.actions
            if act.kind == "send"
        }
        self.clock.streamed = (
            frozenset(cs.message for ca in self.full.agents for cs in ca.streams) - sent
        )
        link.due = lambda: any(ens.t[0] >= st.next_tick[0] for st in states)
        link.pump = lambda done, seconds: self.clock.take_until(ens, done, seconds)

    def answers_record(self) -> dict:
        """What ``meta.live`` says of an agent process's waits for the world process's
        answers: the longest wait (wall ms), the instants whose answer did not come in
        time (their laws read the latest reading), how long the answers that came took."""
        link = self.link
        assert link is not None
        return {
            "world_wait_ms": link.wait * 1e3,
            "world_late": link.late,
            "world_answer_ms": percentiles(link.answer_s),
        }

    def await_world(self) -> float:
        """Wait (at most FIRST_READING wall seconds) for the world process's first
        reading of every hosted agent, which its laws read from their first tick, asking
        again every ASK_AGAIN seconds; what else arrives meanwhile is handed to the clock
        to be taken first. Returns the wall seconds waited; HostingError if none comes
        (no world process runs)."""
        # (a codec of its own: the run's must see these datagrams first when it takes them)
        peek = Codec(self.full, self.codec.senses, self.wire)
        kept: list[tuple[bytes, float]] = []
        start = time.monotonic()
        end = start + FIRST_READING
        ask = start + ASK_AGAIN
        assert self.link is not None  # (only a run with a world process waits for it)
        waiting = set(self.link.here)
        while waiting:
            now = time.monotonic()
            if now >= ask:
                # the world process's first reading lost (a datagram, best-effort), or sent
                # before this process could hear it: it answers every pose, and one with no
                # field asks without saying where the agent is (its state is set only once
                # its run starts)
                for a in sorted(waiting):
                    self.link.send(POSE, a, WORLD_INDEX, {})
                ask = now + ASK_AGAIN
            if now > end:
                raise HostingError(
                    f"no reading from the world process within "
                    f"{FIRST_READING:g} s: a team with world components "
                    "needs one ('hybridteam live TEAM.yaml --world')"
                )
            if self.clock.stop() is not None:
                break
            self.transport.wait(0.05)
            for data, arrived in self.transport.receive():
                kept.append((data, arrived))
                try:
                    dg = peek.decode(data)
                except WireError:
                    continue
                if dg.type == READING and dg.to in waiting:
                    # (read now: the laws' first tick comes before the clock takes the
                    # backlog, which raises the reading's events, if any, at run time 0)
                    self.link.take(dg)
                    waiting.discard(dg.to)
        self.link.unanswered.clear()  # (a late answer to an ask is not the first instant's)
        self.clock.backlog(kept)
        return time.monotonic() - start


#: Wall seconds an agent's process waits for the world process's first reading.
FIRST_READING = 30.0

#: Wall seconds between an agent process's asks for its first reading while it waits.
ASK_AGAIN = 0.1


def control_period(cteam: CTeam, hosted: Collection[int]) -> float:
    """The hosted agents' control period (run seconds): their shortest sampled law period;
    the team's where they sample none (an operator), :data:`DEFAULT_PERIOD` where no agent
    does."""
    for agents in ([cteam.agents[a] for a in hosted], cteam.agents):
        periods = [
            d.period for ca in agents for d in ca.drivers if d.kind == "sampled" and d.period > 0
        ]
        if periods:
            return min(periods)
    return DEFAULT_PERIOD


#: The control period of a team that samples no law (run seconds): 20 Hz, the rate of the
#: paper's robots' laws.
DEFAULT_PERIOD = 0.05


def check_drop_copies(cteam: CTeam, drop_copies: Collection[str]) -> None:
    """HostingError for a scripted drop of a message type the team does not declare."""
    types = declarations(cteam)
    for name in drop_copies:
        if name not in types:
            raise HostingError(
                f"--drop-copy '{name}': the team has no message type "
                f"'{name}' (its types: {', '.join(types)})"
            )


def run_live(team: Team, agents: Sequence[str], transport: Transport, **options) -> Trace:
    """Build and run a :class:`LiveRun` (its options) at once; returns its trace."""
    return LiveRun(team, agents, transport, **options).run()


def process_trace(
    trace: Trace,
    record: dict,
    commands: Mapping[str, Sequence[tuple[float, np.ndarray]]] | None = None,
) -> Trace:
    """The trace kept to what the process hosting ``record['agents']`` knows; with
    ``commands`` (by agent, a robot's commands as ``(run time, inputs)``), each robot's
    series :func:`~hybridteam.trace.command_series`: at every sample time the command in
    force (the last given at or before it; NaN before the first), as a robot log's
    imported ``Twist`` topic is."""
    here = set(record["agents"])
    transitions = trace.transitions.filter(np.isin(trace.transitions["agent"], list(here)))
    intervals = trace.intervals.filter(np.isin(trace.intervals["agent"], list(here)))
    samples = dict(trace.samples)
    for name in trace.agents:
        if name not in here:
            for key in (name, variables_key(name)):
                if key in samples:
                    samples[key] = np.full_like(samples[key], np.nan)
    meta = {**trace.meta, "live": record}
    inputs = {a["name"]: a["inputs"] for a in trace.meta["agents"]}
    for name, given in (commands or {}).items():
        if not given:
            continue
        times = np.array([t for t, _ in given])
        values = np.array([u for _, u in given])
        k = np.searchsorted(times, trace.sample_times, side="right") - 1
        held = np.where((k >= 0)[:, None], values[np.maximum(k, 0)], np.nan)
        samples[command_series(name)] = held[:, None, :]
        meta["series"] = {**meta.get("series", {}), command_series(name): inputs[name]}
    return Trace(
        meta, trace.outcomes, transitions, intervals, trace.messages, trace.sample_times, samples
    )

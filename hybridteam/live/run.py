"""One live process's run: the hosted agents of a team, on the wall clock, over a
transport (docs/live.md).

The engine's ordinary :class:`~hybridteam.engine.simulator.Simulator` runs one instance of
the team as this process hosts it (:mod:`.hosting`), with the wall clock as its clock and
the wire as its network's outlet (:mod:`.clock`). Its trace is the ordinary format, kept
to what this process knows: the hosted agents' modes, transitions and samples (a remote
agent's samples are NaN: unknown here), every copy that reached a hosted agent, and
``meta.live``: the agents here, the transport, the clock and the datagrams counted.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np

from hybridteam.engine.compiler import compile_team
from hybridteam.engine.record import variables_key
from hybridteam.engine.simulator import Simulator
from hybridteam.live.clock import WallClock, WireOutlet
from hybridteam.live.hosting import hosted_team
from hybridteam.live.transport import Transport
from hybridteam.live.wire import VERSION, Codec
from hybridteam.model import Team
from hybridteam.trace import Trace

log = logging.getLogger("hybridteam.live")


def run_live(team: Team, agents: Sequence[str], transport: Transport, *,
             transport_name: str = "udp", time_scale: float = 1.0,
             duration: float | None = None,
             stop: Callable[[], str | None] = lambda: None) -> Trace:
    """Run the agents named ``agents`` of ``team`` live until the end rule holds for
    them, ``duration`` (run seconds; default the team's) passes, or ``stop`` gives a
    reason; returns the process's trace. The transport is the caller's to close."""
    full = compile_team(team)
    codec = Codec(full)  # (the whole team's declarations: every process has the same)
    cteam = hosted_team(full, agents)
    here = sorted(ca.index for ca in full.agents if ca.name in agents)
    clock = WallClock(codec, transport, here, time_scale, stop)
    sim = Simulator(cteam, 1, duration=duration, clock=clock)
    outlet = WireOutlet(codec, transport)
    sim.ensemble.network.outlet = outlet
    log.info("%s: running %s live (time scale %g, until t=%g)", team.name,
             ", ".join(agents), time_scale, sim.ensemble.t_end)
    clock.start()
    trace = sim.run()
    record = {"agents": [full.agents[a].name for a in here], "transport": transport_name,
              "wire": VERSION, "digest": codec.digest, **clock.record(),
              "sent": outlet.sent}
    dropped = record["datagrams"]["dropped"]
    if dropped:
        log.warning("dropped %d datagram(s) not of this team: %s", sum(dropped.values()),
                    ", ".join(f"{k} {v}" for k, v in dropped.items()))
    return process_trace(trace, record)


def process_trace(trace: Trace, record: dict) -> Trace:
    """The trace kept to what the process hosting ``record['agents']`` knows."""
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
    return Trace(meta, trace.outcomes, transitions, intervals, trace.messages,
                 trace.sample_times, samples)

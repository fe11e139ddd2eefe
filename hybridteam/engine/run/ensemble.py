"""The state of ``n`` instances of one team: what every engine module reads and writes.

The simulator's loop (:mod:`.simulator`), the discrete phase, crossing location, drivers,
outcome checks, streams and the reliable layer all act on one :class:`Ensemble`: clocks,
the done mask and outcomes, per-agent states (:class:`~.state.AgentState`), the event
queue, the network, the recorder and the world. Keeping the state in one typed object,
apart from the loop that advances it, is what lets each module be read (and tested) on its
own: a module's signature says it acts on the ensemble, not on a simulator's internals.

World components never see this object; they get a :class:`~.access.EnsembleAccess`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from hybridteam.arrays import some
from hybridteam.engine.compile.compiled import CTeam
from hybridteam.engine.compile.protocols import stream_fields
from hybridteam.engine.run.actions import entry_actions
from hybridteam.engine.run.costs import Costs
from hybridteam.engine.run.events import EventQueue
from hybridteam.engine.run.network import Message, Network
from hybridteam.engine.run.outputs import OutputSampling, output_times
from hybridteam.engine.run.overrides import apply_overrides, split_overrides
from hybridteam.engine.run.randomness import seed_value
from hybridteam.engine.run.record import Recorder
from hybridteam.engine.run.reliable import Reliable
from hybridteam.engine.run.state import AgentState
from hybridteam.engine.run.streams import Inbox, Streams
from hybridteam.engine.run.world import World
from hybridteam.engine.run.zeno import ZenoWindow


class Ensemble:
    """Every array of one simulation, leading axis the instance (see the module docstring).

    Clocks: ``t`` (now), ``t0`` and ``h`` (start and length of the step being taken),
    ``h_rk`` (each instance's next Runge–Kutta step size, NaN until first needed).
    Discrete bookkeeping: ``done`` and ``outcomes``, ``changed`` (something happened at
    this instant: an event was consumed or a transition fired), ``reconfigured`` (a
    transition fired, or a world component set the state: what the drivers, watched
    truths, timers and streams depend on), ``micro`` (superdense index), ``last_fired``
    (for Zeno messages), ``timer[a]`` (agent ``a``'s next ``after:`` deadline), ``zeno``
    (each agent's latest transition times, :class:`~.zeno.ZenoWindow`), ``instants``
    (every source of scheduled instants, one row each). Outputs: ``sampling`` (the sample
    grid and each instance's next sample, :class:`~.outputs.OutputSampling`), ``rec``.
    """

    def __init__(
        self,
        cteam: CTeam,
        n: int,
        seed: int | Sequence[int],
        t_end: float,
        overrides: Mapping[str, float | Sequence[float]],
        samples: bool = True,
        sample_instants: bool = False,
        world: Callable[..., World] = World,
    ) -> None:
        """``sample_instants``: the output samples are scheduled instants too (a step ends
        at each), for an agent whose state is read, not integrated (:mod:`.plant`): a
        sample inside a step would be read off an arc the engine does not have.
        ``world``: the world seam, :class:`World` (the components run here) or a subclass
        a live process fills it with (:mod:`hybridteam.live.world`)."""
        self.cteam = cteam
        self.n = n
        self.seed = seed_value(seed, n)  # one int, or a list: one seed per instance
        self.settings = cteam.team.simulation
        self.t_end = t_end
        self.t = np.zeros(n)
        self.t0 = np.zeros(n)
        self.h = np.zeros(n)
        self.done = np.zeros(n, bool)
        #: every instance's index, read-only: the live instances while none has ended
        self.everyone = np.arange(n)
        self.everyone.flags.writeable = False
        self.changed = np.zeros(n, bool)
        self.reconfigured = np.zeros(n, bool)
        self.micro = np.zeros(n, np.int64)
        self.last_fired = np.full(n, -1, np.int64)
        self.outcomes: list[dict | None] = [None] * n
        self.states = [AgentState(a, self.everyone) for a in cteam.agents]
        for a, st in zip(cteam.agents, self.states, strict=True):
            if a.mode_actions:
                st.entered = functools.partial(entry_actions, self, a, st)
        #: whether a run can end before its duration by the end rule or a deadlock: not
        #: without final modes (the end rule then holds nowhere, when some agent ends runs)
        #: nor without triggered transitions (a deadlock is someone waiting for an event)
        self.may_end_early = (not cteam.end_any and not cteam.ending) or any(
            some(ca.final_leaves) or some(ca.has_triggered) for ca in cteam.agents
        )
        #: whether some agent's eventless guard can change truth without a transition
        self.urgent_volatile = any(st.urgent_volatile for st in self.states)
        self.h_rk = np.full(n, np.nan)
        self.max_step = self.settings.max_step or np.inf
        checks = self.settings.crossing_checks
        #: where in a step atoms are checked for flips, as fractions of it (both ends too)
        self.thetas = np.array([0.0, *((k + 1) / (checks + 1) for k in range(checks)), 1.0])
        z = self.settings.zeno
        self.zeno = ZenoWindow(n, len(cteam.agents), z.max_transitions, z.window)
        # (no samples: none is ever due, and the trace has none)
        self.sampling = OutputSampling(
            output_times(t_end, self.settings.output_period()) if samples else np.zeros(0), n
        )
        self.rec = Recorder(cteam, n, self.sampling.times)
        self.costs = Costs()  # what the crossing search did, read after the run
        self.queue = EventQueue(n, cteam.scenario)
        overrides, medium = split_overrides(cteam.agents, overrides)
        apply_overrides(
            [st.ca for st in self.states],
            [st.p for st in self.states],
            n,
            overrides,
            cteam.team.network,
        )
        params = self.team_params()
        self.network = Network(cteam.team, n, self.seed, params, self.queue, self.rec, medium)
        self.reliable = Reliable(self)
        self.streams = Streams(self, [ca.streams for ca in cteam.agents])
        self.world = world(cteam.team, n, params)
        for st in self.states:
            st.world = self.world
        self.rec.add_series(self.world.sample_series())
        # every agent has an inbox when the team declares streams (in a live process the
        # streaming agents may all be elsewhere, and their copies still arrive here)
        fields = stream_fields(cteam.team)
        if fields:
            for st in self.states:
                st.inbox = Inbox(n, len(cteam.agents), fields)
        self._gather_instants(sample_instants)

    def _gather_instants(self, sample_instants: bool) -> None:
        """Put every source of scheduled instants in one array, ``instants`` (one row per
        source, every row a view its owner keeps writing in place): the event queue's next
        event, the end of the run, each agent's next ``after:`` deadline (rows ``at``:
        instants where transitions may fire), the streams' next copy and each agent's next
        law tick (rows ``tick``), and the next output sample where ``sample_instants``
        (a ``tick`` row: nothing fires there). The simulator asks for the earliest of them
        at every step, and which kind was reached; with them in one array that is one
        reduction each, not two array operations per source (at a single run's size, each
        costs its dispatch, about 1 µs, for one number)."""
        k = len(self.states)
        rows = np.empty((3 + 2 * k + sample_instants, self.n))
        rows[0], rows[1], rows[2 : 2 + k] = self.queue.next, self.t_end, np.inf
        rows[2 + k] = self.streams.next
        for a, st in enumerate(self.states):
            rows[3 + k + a] = st.next_tick
        self.instants = rows
        self.instants_at, self.instants_tick = rows[: 2 + k], rows[2 + k :]
        self.queue.next, self.streams.next = rows[0], rows[2 + k]
        self.timer = list(rows[2 : 2 + k])
        for a, st in enumerate(self.states):
            st.next_tick = rows[3 + k + a]
        if sample_instants:
            rows[-1] = self.sampling.next
            self.sampling.next = rows[-1]

    def team_params(self) -> dict[str, np.ndarray]:
        """Team parameters per instance (after overrides), as every agent sees them."""
        st = self.states[0]
        return {
            name: st.p[:, st.ca.param_index[name]].copy() for name in self.cteam.team.parameters
        }

    def screen(self, i: int, msg: Message, t: float) -> str | None:
        """The protocol layer's look at each copy that got through the medium: acks and
        duplicates are withheld from the modes; stream copies update the estimates."""
        why = self.reliable.screen(i, msg, t)
        inbox = self.states[msg.receiver].inbox
        if why is None and inbox is not None and msg.type in inbox.fields:
            inbox.deliver(i, msg)
        return why

    def live(self, idx: np.ndarray) -> np.ndarray:
        """The instances of ``idx`` not ended: ``idx`` itself where none has ended anywhere
        (a single run's every instant), without filtering it."""
        return idx if not some(self.done) else idx[~self.done[idx]]

    # ------------------------------------------------------------------ outcomes
    def finish(self, idx: np.ndarray, kind: str, message: Callable[[int], str]) -> None:
        """End instances ``idx`` (those not ended already) with outcome ``kind``."""
        for i in idx.tolist():
            if not self.done[i]:
                self.done[i] = True
                self.outcomes[i] = {
                    "instance": i,
                    "outcome": kind,
                    "t": float(self.t[i]),
                    "message": message(i),
                }

    def when(self, i: int) -> str:
        """Instance ``i``'s current time, printed exactly (shortest round-trip digits)."""
        return repr(float(self.t[i]))

    def last_step_text(self, i: int) -> str:
        code = int(self.last_fired[i])
        if code < 0:
            return "no transition"
        ca = self.cteam.agents[code // 1_000_000]
        tr = ca.transitions[code % 1_000_000]
        text = f"agent '{ca.name}' {ca.modes[tr.source].path} -> {ca.modes[tr.target].path}"
        return text + (f" on guard '{tr.guard_text}'" if tr.guard_text else "")

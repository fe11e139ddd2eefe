"""The simulator: ``n`` instances of one team advanced in lockstep.

Each instance keeps its own clock. One engine iteration moves every live instance from its
time to the nearest of: its next scheduled instant (a sampled law's tick, an ``after:``
deadline, a pending event, an output sample, the end of the run) or, when some agent flows
under a continuous law, the step its own error control allows. Kinematic plants under held
inputs move along their exact arcs; flows take a Dormand–Prince step. Guard and invariant
crossings found inside the step are located (:mod:`.crossing`) and the instance stops there.
Instances that arrived at an instant then run the discrete phase (:mod:`.discrete`).

Nothing an instance does depends on another instance: step sizes, event times, sequence
numbers and round-off are all per instance, so an ensemble equals that many single runs.
The state lives in an :class:`~.ensemble.Ensemble`; this module is only the loop.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from hybridteam.arrays import NO_INDEX, every, gather, some, union, where_true
from hybridteam.engine.compile.compiled import CTeam, Watch
from hybridteam.engine.run.access import EnsembleAccess
from hybridteam.engine.run.budget import Pace, check_budget
from hybridteam.engine.run.clock import Clock
from hybridteam.engine.run.costs import Costs
from hybridteam.engine.run.crossing import find_crossings, watch_truth
from hybridteam.engine.run.discrete import discrete_phase
from hybridteam.engine.run.drivers import sample_laws
from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.numerics import stop_broken_states
from hybridteam.engine.run.outcomes import check_instances
from hybridteam.engine.run.plant import ExternalPlant, check_external
from hybridteam.engine.run.quiet import QuietCopies
from hybridteam.engine.run.record import trace_meta, variables_key
from hybridteam.engine.run.schedule import earliest
from hybridteam.engine.run.step import AgentStep, state_at, take_step
from hybridteam.engine.run.stepsize import control_step_size, initial_step_sizes
from hybridteam.engine.run.world import World
from hybridteam.trace import Trace

Progress = Callable[[float], None]


class Simulator:
    """Runs an :class:`Ensemble` of ``n`` instances of ``cteam`` to the end of the run."""

    def __init__(
        self,
        cteam: CTeam,
        n: int = 1,
        *,
        seed: int | Sequence[int] = 0,
        duration: float | None = None,
        overrides: Mapping[str, float | Sequence[float]] | None = None,
        progress: Progress | None = None,
        max_memory: float | None = None,
        max_periods: float | None = None,
        max_wall: float | None = None,
        snapshots: bool = False,
        observe: Mapping[int, Sequence[Watch]] | None = None,
        samples: bool = True,
        written: bool = False,
        clock: Clock | None = None,
        plants: Mapping[int, ExternalPlant] | None = None,
        world: Callable[..., World] = World,
        sample_instants: bool = False,
    ) -> None:
        """``snapshots``: also keep every agent's state and the world's series at every
        instant the run stops at (events, crossings, law ticks), exact where samples are
        interpolated (:attr:`Recorder.snapshots`); requirement checks read them.
        ``observe``: extra watched comparisons per agent index (a requirement's), whose
        crossings the run stops at so that a snapshot holds the state there.
        ``samples`` false: no output samples (the trace has none). Samples are only
        recorded, never read by the run, so outcomes, transitions and the world's
        statistics are the same; a study's rows need none, and interpolating and
        recording them cost a sixth of the ladder's sample run. ``written``: the caller
        writes the trace's files (``hybridteam run``), whose rows count in the memory
        estimate.
        ``clock``: a live run's clock (:mod:`.clock`), asked before every step; None (a
        simulation) advances at once.
        ``plants``: external plants by agent index (:mod:`.plant`; a single run only):
        those agents' plants are commanded and read, not integrated, their guards
        sampled at every instant; None (a simulation): every plant is integrated.
        ``world``: the world seam (:class:`.world.World`, the components run here; a live
        process's agents read the world process instead, :mod:`hybridteam.live.world`).
        ``sample_instants``: the output samples are instants (the world's series read
        there, as a live world process records them; external plants imply it)."""
        if n < 1:
            raise ValueError(f"n must be at least 1, got {n}")
        t_end = float(duration if duration is not None else cteam.team.simulation.duration)
        if not 0 <= t_end < math.inf:
            raise ValueError(f"duration must be a finite number >= 0, got {t_end}")
        check_budget(
            cteam, n, t_end, cteam.team.simulation.output_period(), max_memory, max_periods, written
        )
        if plants:
            if n != 1:
                raise ValueError(f"external plants drive a single run, not n={n}")
            check_external(cteam, plants)
        if observe:
            cteam = dataclasses.replace(
                cteam,
                agents=[
                    dataclasses.replace(ca, watches=[*ca.watches, *observe.get(ca.index, ())])
                    for ca in cteam.agents
                ],
            )
        self.ensemble = Ensemble(
            cteam,
            n,
            seed,
            t_end,
            overrides or {},
            samples,
            sample_instants=bool(plants) or sample_instants,
            world=world,
        )
        if snapshots:
            self.ensemble.rec.snapshots = []
        self.max_wall = max_wall
        self.clock = clock
        #: external plants by agent index (None: every plant is integrated)
        self.plants = dict(plants) if plants else None
        #: whether any agent can ever be integrated (a flow plant, or an integrated law):
        #: else no step is limited by error control, and it ends at the next instant due
        self.may_flow = any(
            ca.plant.kind == "flow" or any(d.needs_rk for d in ca.drivers) for ca in cteam.agents
        )
        #: whether any agent watches a guard or invariant atom: else no step is searched
        #: for crossings (a law-only team like the ladder's)
        self.may_cross = any(st.ca.watches for st in self.ensemble.states)
        self.access = EnsembleAccess(self.ensemble)
        self.progress = progress
        #: the world's series the last instant's snapshot took: ``(idx, values)``. The
        #: samples recorded right after it, at the same time and before any world update,
        #: read the same values (a clearance series costs as much as the rest of a run).
        self._world_snapshot: tuple[np.ndarray, dict[str, np.ndarray]] | None = None
        #: no instance (a flag per instance, read-only): what a step where nothing flows
        #: has for its flowing rows
        self._no_rows = np.zeros(self.ensemble.n, bool)
        self._no_rows.flags.writeable = False
        #: stream copies held rather than made instants (:mod:`.quiet`), from the run's
        #: start: None in a live run or a replay, or where no copy can be quiet
        self.quiet: QuietCopies | None = None

    @property
    def costs(self) -> Costs:
        """What the crossing search did so far (:class:`.costs.Costs`): true steps and
        flips located, the counters a test reads instead of wrapping the search."""
        return self.ensemble.costs

    # ------------------------------------------------------------------ the run
    def run(self) -> Trace:
        ens = self.ensemble
        pace = Pace(ens.t_end, self.max_wall)
        with np.errstate(all="ignore"):
            net = ens.network  # (a live run's outlet and a replay's script are set by now)
            simulated = getattr(self.clock, "simulated_time", False)  # (a log's replay)
            medium = (self.clock is net.outlet is None) or simulated
            if medium and self.plants is net.script is None:
                quiet = QuietCopies(ens)
                self.quiet = quiet if quiet.any else None
            self._initialize()
            last_report = -1.0
            steps = 0
            clock = self.clock
            while not every(ens.done):
                if clock is not None:
                    clock.advance(ens)
                    if every(ens.done):  # the clock ended the run (a signal, the wall)
                        break
                self._step()
                steps += 1
                if self.progress is not None or steps % 64 == 0:
                    frac = float(np.min(np.where(ens.done, ens.t_end, ens.t))) / (ens.t_end or 1.0)
                    if steps % 64 == 0:
                        pace.check(frac)
                    if self.progress is not None and frac - last_report >= 0.01:
                        self.progress(frac)
                        last_report = frac
            return self._close()

    def _initialize(self) -> None:
        ens = self.ensemble
        everyone = np.arange(ens.n)
        for st in ens.states:
            st.x[:], st.v[:] = st.ca.initial_values(st.p)
        if self.plants is not None:  # (the robot is where it is, whatever the file says)
            for a, plant in self.plants.items():
                ens.states[a].x[0] = plant.state(0.0)
        ens.world.start(self.access)
        for st in ens.states:
            ca = st.ca
            st.activate(0, everyone, ens.t)
            st.enter_default(0, everyone, ens.t)
            for leaf in ca.leaves.tolist():
                sel = everyone[st.active[:, leaf]]
                if sel.size:
                    ens.rec.initial(ca.index, leaf, sel, ens.t[sel])
        ens.changed[:] = True
        self._instant(everyone, entering=True)
        ens.sampling.record(ens, everyone, self._world_snapshot)
        self._world_snapshot = None

    def _instant(
        self,
        idx: np.ndarray,
        entering: bool = False,
        crossed: np.ndarray | None = None,
        discrete: np.ndarray | None = None,
    ) -> None:
        """Discrete phase at the current time of instances ``idx``, then bookkeeping.

        ``discrete`` (default: all of ``idx``) are the instances that may take transitions:
        one that only reached a sampling tick cannot — a guard changes truth only when one
        of its comparisons flips, and flips are located as crossings. (Equality tests on
        continuous state, which no search can locate, are therefore evaluated at events
        only.) Invariants, deadlock and final modes are checked only where something
        happened (a transition, an event, a located crossing).
        """
        ens = self.ensemble
        if self.quiet is not None:  # held copies that arrived since the last instant
            now = self.quiet.receive(idx)
            if now.size and discrete is not None:
                discrete = union(discrete, now)
        # only law ticks or stream copies reached, and no component that could raise an
        # event or move a state: nothing fires, no mode, variable or state changes, so no
        # instance is marked changed or reconfigured (their flags are not read)
        ticks_only = (
            not entering and discrete is not None and discrete.size == 0 and not ens.world.any
        )
        if not entering and not ticks_only:
            instances = slice(None) if idx.size == ens.n else idx  # a slice writes faster
            ens.changed[instances] = False
            ens.reconfigured[instances] = False
        if discrete is None:
            discrete = idx
        if ens.world.any:  # components see the state first; events they raise run now
            raised = ens.world.update(self.access, idx)
            if raised.size:
                discrete = union(discrete, raised)
            discrete = ens.live(discrete)
        discrete_phase(ens, discrete)
        if ens.rec.snapshots is not None:
            ens.rec.snapshot(idx, ens.t[idx], {st.ca.name: st.x[idx] for st in ens.states})
            ens.rec.snapshot(
                idx,
                ens.t[idx],
                {variables_key(st.ca.name): st.v[idx] for st in ens.states if st.v.shape[1]},
            )
            world = ens.world.sample(idx)
            ens.rec.snapshot(idx, ens.t[idx], world)
            self._world_snapshot = (idx, world)
        live = ens.live(idx)
        # (with every instance live, whole-array masks instead of gathers: same indices)
        whole = live.size == ens.n
        # no transition fired and no event was consumed where nothing was due to fire
        # (``discrete`` is empty): nothing changed there
        quiet = not entering and discrete.size == 0
        changed = (
            live
            if entering
            else NO_INDEX
            if quiet
            else where_true(ens.changed)
            if whole
            else live[ens.changed[live]]
        )
        # an event consumed without a transition changes no mode, variable or state: what
        # depends on those is refreshed only where the configuration changed (a component
        # may have moved a state)
        config = (
            live
            if entering
            else NO_INDEX
            if ticks_only
            else where_true(ens.reconfigured)
            if whole
            else live[ens.reconfigured[live]]
        )
        for a, st in enumerate(ens.states):
            if live.size and st.after_slots.size:
                # the earliest deadline ahead changes only with the configuration or once
                # it is reached: elsewhere the stored one is still the earliest ahead (and
                # where nothing was due to fire, no deadline was reached)
                if quiet:
                    due = config
                else:
                    due = (
                        where_true(ens.t >= ens.timer[a])
                        if whole
                        else live[ens.t[live] >= ens.timer[a][live]]
                    )
                    due = union(due, config)
                if due.size:
                    ens.timer[a][due] = st.next_timer(due, ens.t[due])
            if config.size:
                st.update_drivers(config)
                if st.ca.plant.kind == "flow":
                    st.rk[config] = True
            fresh = changed if st.watch_estimates else config
            if st.ca.watches and fresh.size:
                st.truth[:, fresh] = watch_truth(ens, a, fresh, gather(st.x, fresh), ens.t[fresh])
            # changed, not config: a law whose mode was entered at this instant samples
            # again when a copy arrives later in the instant (it may read the copy)
            sample_laws(ens, a, live, changed)
        # commands out: the held inputs (not once the run has ended, by broken inputs too)
        if self.plants is not None and not ens.done[0]:
            t = float(ens.t[0])
            for a, plant in self.plants.items():
                plant.command(ens.states[a].u[0].copy(), t)
        ens.streams.update(live, config)
        if self.quiet is not None and config.size:
            self.quiet.refresh(config)
        if crossed is not None and crossed.size:
            changed = union(changed, crossed[~ens.done[crossed]])
        check_instances(ens, changed, None if entering else config)

    # ------------------------------------------------------------------ one iteration
    def _step(self) -> None:
        """Advance every live instance to its next instant (or as far as its error control
        allows), stop it at the first located crossing, then run the instants reached."""
        ens = self.ensemble
        idx = ens.live(ens.everyone)  # (everyone itself while none has ended)
        # with every instance live (the usual case) gathers are views, not copies
        full = idx.size == ens.n
        sel: slice | np.ndarray = slice(None) if full else idx
        t1, any_rk, limited, reach = self._step_end(full)
        ens.t0 = ens.t  # (ens.t is replaced at the step's end, never written in place)
        ens.h = t1 - ens.t
        h = ens.h[sel]
        err = np.zeros(idx.size) if self.may_flow else None
        moved = [take_step(ens, a, idx, sel, h, err) for a in range(len(ens.states))]
        x_end = [xe for xe, _ in moved]
        steps = [s for _, s in moved]
        if self.may_flow and some(any_rk[sel]):
            assert err is not None
            control_step_size(ens, idx, sel, t1, any_rk, limited, err, x_end, steps)
        stop_broken_states(ens, idx, sel, t1, x_end, steps)
        crossing, end_truths = self._locate(idx, sel, t1, x_end, steps)
        if self.plants is not None:
            crossing = self._read_plants(idx, t1, x_end, crossing, end_truths)
        tn = t1[sel]
        # an output sample is due inside the step or at its end (after the instant, which
        # moves no clock and no sample): else neither looks for one
        sampling = some((ens.sampling.next if full else ens.sampling.next[idx]) <= tn)
        if sampling:
            ens.sampling.interpolate(ens, idx, tn, steps)
        for a, st in enumerate(ens.states):
            if full:
                st.x = x_end[a]
            else:
                st.x[idx] = x_end[a]
        ens.t = t1
        self._arrive(idx, sel, tn, crossing, end_truths, full, reach, sampling)

    def _step_end(
        self, full: bool
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """Where each instance's step ends: its next scheduled instant, or sooner where an
        agent flows and the error control asks for a shorter step. Returns ``(t1, any_rk,
        limited, reach)``: whether some agent of the instance flows, whether its step size
        (rather than a scheduled instant) set ``t1``, and the earliest instants of each
        kind, ``at`` and ``tick`` (:func:`.schedule.earliest`; the step reached a kind
        where it ends at or after its earliest). ``full``: every instance is live."""
        ens = self.ensemble
        t = ens.t
        t_next, first_at, first_tick = earliest(ens.instants, ens.instants_at.shape[0])
        if not self.may_flow:
            t1, any_rk, limited = t_next, self._no_rows, self._no_rows
        else:
            any_rk = np.zeros(ens.n, bool)
            for st in ens.states:
                any_rk |= st.rk
            any_rk &= ~ens.done
            if some(any_rk):
                initial_step_sizes(ens, where_true(any_rk & np.isnan(ens.h_rk)))
                t_rk = t + np.minimum(ens.h_rk, ens.max_step)
                t1 = np.where(any_rk, np.minimum(t_next, t_rk), t_next)
                limited = any_rk & (t_rk < t_next)
            else:
                t1, limited = t_next, any_rk
        t1 = np.maximum(t1, t) if full else np.where(ens.done, t, np.maximum(t1, t))
        return t1, any_rk, limited, (first_at, first_tick)

    def _locate(
        self,
        idx: np.ndarray,
        sel: slice | np.ndarray,
        t1: np.ndarray,
        x_end: list[np.ndarray],
        steps: list[AgentStep],
    ) -> tuple[np.ndarray | None, list[np.ndarray | None]]:
        """Stop instances at their first located guard or invariant crossing inside the
        step: ``t1`` and ``x_end`` move back to it. Returns which rows crossed (None: none
        was searched for) and each agent's atom truths at the step's end (valid where
        nothing crossed)."""
        ens = self.ensemble
        accepted = ens.h[sel] > 0 if self.may_cross else None  # (else: no atom to search)
        if accepted is None or not some(accepted):
            return None, [None] * len(ens.states)
        tau, end_truths, searched = find_crossings(ens, idx, x_end, steps, self.plants or ())
        if tau is None:  # no atom flipped inside the step: nothing was searched
            return None, end_truths
        crossing = np.isfinite(tau) & accepted
        if some(crossing):
            rows = where_true(crossing)
            for a in range(len(ens.states)):
                seg = searched.get(a)  # its search has the states at its trial points
                x_end[a][rows] = (
                    seg.true_state(rows, tau[rows])
                    if seg is not None
                    else state_at(ens, a, idx[rows], tau[rows], steps[a], rows=rows)
                )
            t1[idx[rows]] = ens.t[idx[rows]] + tau[rows]
        return crossing, end_truths

    def _read_plants(
        self,
        idx: np.ndarray,
        t1: np.ndarray,
        x_end: list[np.ndarray],
        crossing: np.ndarray | None,
        end_truths: list[np.ndarray | None],
    ) -> np.ndarray | None:
        """Poses in: each external plant's state at the step's end replaces the
        integrated one in ``x_end``, and its watched atoms are sampled there (:mod:`.plant`;
        the search skipped them): a flip of a watched atom is a crossing at the step's
        end. Returns the rows that crossed (``crossing``, widened)."""
        assert self.plants is not None
        ens = self.ensemble
        t = float(t1[0])
        for a, plant in self.plants.items():
            x_end[a] = np.array(plant.state(t), dtype=float).reshape(1, -1)
            st = ens.states[a]
            if not st.ca.watches:
                continue
            truth = watch_truth(ens, a, idx, x_end[a], t1[idx])
            end_truths[a] = truth
            flipped = np.logical_or.reduce((truth != st.truth[:, idx]) & st.watched[:, idx], axis=0)
            if some(flipped):
                crossing = flipped if crossing is None else crossing | flipped
        return crossing

    def _arrive(
        self,
        idx: np.ndarray,
        sel: slice | np.ndarray,
        tn: np.ndarray,
        crossing: np.ndarray | None,
        end_truths: list[np.ndarray | None],
        full: bool,
        reach: tuple[np.ndarray, np.ndarray],
        sampling: bool,
    ) -> None:
        """After the step: refresh watched truths, run the instants the step reached
        (events, deadlines, crossings, law ticks), record samples, end finished runs.
        ``reach``: the earliest ``at`` and ``tick`` instants of every instance;
        ``sampling``: whether an output sample may be due at the step's end."""
        ens = self.ensemble
        ending = tn >= ens.t_end
        # reached an instant of some source: at or after the earliest of them (a NaN
        # source, which no time reaches, was skipped); the end of the run is an ``at`` one
        first_at, first_tick = reach
        at = tn >= first_at[sel]
        if crossing is not None:
            at |= crossing
        tick = tn >= first_tick[sel]
        moved = idx[crossing] if crossing is not None else NO_INDEX
        plain = None
        for a, st in enumerate(ens.states):
            truths = end_truths[a]
            if truths is not None:
                if plain is None:
                    plain = ens.h[sel] > 0
                    if crossing is not None:
                        plain &= ~crossing
                if full and every(plain):
                    st.truth = truths
                else:
                    st.truth[:, idx[plain]] = truths[:, plain]
            if st.ca.watches and moved.size:
                st.truth[:, moved] = watch_truth(ens, a, moved, gather(st.x, moved), ens.t[moved])
        events = idx[at | tick]
        if events.size:
            self._instant(events, crossed=moved, discrete=idx[at])
        if sampling:
            ens.sampling.record(ens, idx, self._world_snapshot)
        # (a snapshot is read by the samples right after its instant, never later)
        self._world_snapshot = None
        if not some(ending):  # (the discrete phase moves no clock: ens.t[sel] is tn)
            return
        ended = idx[ending & ~ens.done[sel]]
        if ended.size:
            ens.finish(ended, "ok", lambda i: f"reached the end of the run at t={ens.when(i)}")

    def _close(self) -> Trace:
        ens = self.ensemble
        everyone = np.arange(ens.n)
        if self.quiet is not None:
            self.quiet.close()
        for st in ens.states:
            st.exit(0, everyone, ens.t, ens.rec)
        ens.network.close(ens.queue.pending_messages())
        transitions, intervals, messages = ens.rec.tables()
        meta = trace_meta(ens.cteam, ens.n, ens.seed, ens.t_end, ens.world)
        outcomes = [
            o
            if o is not None
            else {"instance": i, "outcome": "ok", "t": float(ens.t[i]), "message": ""}
            for i, o in enumerate(ens.outcomes)
        ]
        if ens.world.any:
            for i, o in enumerate(outcomes):
                o["stats"] = ens.world.summary(i)
        return Trace(
            meta, outcomes, transitions, intervals, messages, ens.sampling.times, ens.rec.samples
        )

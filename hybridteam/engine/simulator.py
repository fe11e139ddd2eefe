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
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from hybridteam.dynamics import rk
from hybridteam.engine.compiled import CTeam, Ctx
from hybridteam.engine.crossing import find_crossings, watch_truth
from hybridteam.engine.discrete import discrete_phase
from hybridteam.engine.drivers import derivative, sample_laws
from hybridteam.engine.events import EventQueue
from hybridteam.engine.outcomes import check_instances
from hybridteam.engine.overrides import apply_overrides
from hybridteam.engine.protocols import stream_fields
from hybridteam.engine.randomness import seed_value
from hybridteam.engine.record import Recorder
from hybridteam.engine.reliable import Reliable
from hybridteam.engine.state import AgentState
from hybridteam.engine.streams import Inbox, Streams
from hybridteam.engine.world import World
from hybridteam.network import Message, Network
from hybridteam.trace import Trace

Progress = Callable[[float], None]


class Simulator:
    def __init__(self, cteam: CTeam, n: int = 1, *, seed: int | Sequence[int] = 0,
                 duration: float | None = None,
                 overrides: Mapping[str, float | Sequence[float]] | None = None,
                 progress: Progress | None = None) -> None:
        if n < 1:
            raise ValueError(f"n must be at least 1, got {n}")
        self.cteam = cteam
        self.n = n
        self.seed = seed_value(seed, n)  # one int, or a list: one seed per instance
        self.settings = cteam.team.simulation
        self.t_end = float(duration if duration is not None else self.settings.duration)
        if not self.t_end >= 0:
            raise ValueError(f"duration must be >= 0, got {self.t_end}")
        self.progress = progress
        self.t = np.zeros(n)
        self.t0 = np.zeros(n)
        self.h = np.zeros(n)
        self.done = np.zeros(n, bool)
        self.changed = np.zeros(n, bool)
        self.micro = np.zeros(n, np.int64)
        self.last_fired = np.full(n, -1, np.int64)
        self.outcomes: list[dict | None] = [None] * n
        self.states = [AgentState(a, n) for a in cteam.agents]
        self.timer = [np.full(n, np.inf) for _ in cteam.agents]
        self.h_rk = np.full(n, np.nan)
        self.max_step = self.settings.max_step or np.inf
        zk = self.settings.zeno.max_transitions
        self.zeno_ring = [np.full((n, zk), -np.inf) for _ in cteam.agents]
        self.zeno_ptr = [np.zeros(n, np.intp) for _ in cteam.agents]
        dt = self.settings.output_period()
        k = int(np.floor(self.t_end / dt + 1e-9)) + 1
        times = np.arange(k) * dt
        if times[-1] < self.t_end - 1e-12 * max(1.0, self.t_end):
            times = np.append(times, self.t_end)
        self.sample_times = times
        self._sample_after = np.append(times, np.inf)
        self.out_k = np.zeros(n, np.intp)
        self.next_out = np.full(n, times[0])
        self.rec = Recorder(cteam, n, times)
        self.queue = EventQueue(n, cteam.scenario)
        self._apply_overrides(overrides or {})
        self.network = Network(cteam.team, n, self.seed, self._team_params(), self.queue,
                               self.rec)
        self.reliable = Reliable(self)
        self.streams = Streams(self, [ca.streams for ca in cteam.agents])
        self.world = World(cteam.team, n, self._team_params())
        for st in self.states:
            st.world = self.world
        self.rec.add_series(self.world.sample_series())
        if self.streams.any:
            fields = stream_fields(cteam.team)
            for st in self.states:
                st.inbox = Inbox(n, len(cteam.agents), fields)

    def screen(self, i: int, msg: Message, t: float) -> str | None:
        """The protocol layer's look at each copy that got through the medium: acks and
        duplicates are withheld from the modes; stream copies update the estimates."""
        why = self.reliable.screen(i, msg, t)
        inbox = self.states[msg.receiver].inbox
        if why is None and inbox is not None and msg.type in inbox.fields:
            inbox.deliver(i, msg)
        return why

    # ------------------------------------------------------------------ set-up
    def _apply_overrides(self, overrides: Mapping[str, float | Sequence[float]]) -> None:
        apply_overrides([st.ca for st in self.states], [st.p for st in self.states], self.n,
                        overrides)

    def _team_params(self) -> dict[str, np.ndarray]:
        """Team parameters per instance (after overrides), as every agent sees them."""
        st = self.states[0]
        return {name: st.p[:, st.ca.param_index[name]].copy()
                for name in self.cteam.team.parameters}

    # ------------------------------------------------------------------ drivers
    def state_at(self, a: int, idx: np.ndarray, tau: np.ndarray, step: dict, *,
                 dense: bool = False, rows: np.ndarray | None = None) -> np.ndarray:
        """Agent ``a``'s state ``tau`` after the step start, for instances ``idx``.

        ``rows`` are the positions of ``idx`` in the step's arrays (all when None).
        """
        if rows is None:
            rows = np.arange(idx.size)
        x0, u, is_rk = step["x0"][rows], step["u"][rows], step["rk"][rows]
        plant = self.states[a].ca.plant
        if not is_rk.any():
            return plant.propagate(x0, u, tau)
        out = np.empty_like(x0)
        ex = ~is_rk
        if ex.any():
            out[ex] = plant.propagate(x0[ex], u[ex], tau[ex])
        r = np.flatnonzero(is_rk)
        if dense:
            pos = step["rk_pos"][rows[r]]
            s: rk.Step = step["rk_step"]
            out[r] = s.dense(tau[r] / np.where(s.h[pos] > 0, s.h[pos], 1.0), pos)
        else:
            sub = idx[r]
            s = rk.step(derivative(self, a, sub), self.t0[sub], x0[r], tau[r], self.settings.rtol,
                        self.settings.atol)
            out[r] = s.x1
        return out

    # ------------------------------------------------------------------ outcomes
    def finish(self, idx: np.ndarray, kind: str, message: Callable[[int], str]) -> None:
        for i in idx.tolist():
            if not self.done[i]:
                self.done[i] = True
                self.outcomes[i] = {"instance": i, "outcome": kind, "t": float(self.t[i]),
                                    "message": message(i)}

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

    # ------------------------------------------------------------------ the run
    def run(self) -> Trace:
        with np.errstate(all="ignore"):
            self._initialize()
            last_report = -1.0
            while not self.done.all():
                self._step()
                if self.progress is not None:
                    frac = float(np.min(np.where(self.done, self.t_end, self.t))) / \
                        (self.t_end or 1.0)
                    if frac - last_report >= 0.01:
                        self.progress(frac)
                        last_report = frac
            return self._close()

    def _initialize(self) -> None:
        everyone = np.arange(self.n)
        for st in self.states:
            ca = st.ca
            ctx = Ctx(st.x, st.v, st.p, self.t)
            for j, e in enumerate(ca.init_state):
                st.x[:, j] = np.broadcast_to(e(ctx), (self.n,))
            for j, e in enumerate(ca.init_vars):
                st.v[:, j] = np.broadcast_to(e(ctx), (self.n,))
        self.world.start(self)
        for st in self.states:
            ca = st.ca
            st.activate(0, everyone, self.t)
            st.enter_default(0, everyone, self.t)
            for leaf in ca.leaves.tolist():
                sel = everyone[st.active[:, leaf]]
                if sel.size:
                    self.rec.initial(ca.index, leaf, sel, self.t[sel])
        self.changed[:] = True
        self._instant(everyone, entering=True)
        self._record_samples(everyone)

    def _instant(self, idx: np.ndarray, entering: bool = False,
                 crossed: np.ndarray | None = None,
                 discrete: np.ndarray | None = None) -> None:
        """Discrete phase at the current time of instances ``idx``, then bookkeeping.

        ``discrete`` (default: all of ``idx``) are the instances that may take transitions:
        one that only reached a sampling tick cannot — a guard changes truth only when one
        of its comparisons flips, and flips are located as crossings. (Equality tests on
        continuous state, which no search can locate, are therefore evaluated at events
        only.) Invariants, deadlock and final modes are checked only where something
        happened (a transition, an event, a located crossing).
        """
        if not entering:
            self.changed[idx] = False
        if discrete is None:
            discrete = idx
        if self.world.any:  # components see the state first; events they raise run now
            raised = self.world.update(self, idx)
            if raised.size:
                discrete = np.union1d(discrete, raised)
            discrete = discrete[~self.done[discrete]]
        discrete_phase(self, discrete)
        live = idx[~self.done[idx]]
        changed = live[self.changed[live]] if not entering else live
        for a, st in enumerate(self.states):
            if live.size:
                self.timer[a][live] = st.next_timer(live, self.t[live])
            if changed.size:
                st.update_drivers(changed)
                if st.ca.plant.kind == "flow":
                    st.rk[changed] = True
                if st.ca.watches:
                    st.truth[:, changed] = watch_truth(self, a, changed, st.x[changed],
                                                       self.t[changed])
            sample_laws(self, a, live, changed)
        self.streams.update(live)
        if crossed is not None and crossed.size:
            changed = np.union1d(changed, crossed[~self.done[crossed]])
        check_instances(self, changed)

    def _step(self) -> None:
        live = ~self.done
        idx = np.flatnonzero(live)
        # with every instance live (the usual case) gathers are views, not copies
        full = idx.size == self.n
        sel: slice | np.ndarray = slice(None) if full else idx
        t = self.t
        t_next = np.minimum(self.queue.next, self.t_end)
        np.minimum(t_next, self.streams.next, out=t_next)
        any_rk = np.zeros(self.n, bool)
        for a, st in enumerate(self.states):
            np.minimum(t_next, st.next_tick, out=t_next)
            np.minimum(t_next, self.timer[a], out=t_next)
            any_rk |= st.rk
        any_rk &= live
        if any_rk.any():
            self._initial_rk_steps(np.flatnonzero(any_rk & np.isnan(self.h_rk)))
            t_rk = t + np.minimum(self.h_rk, self.max_step)
            t1 = np.where(any_rk, np.minimum(t_next, t_rk), t_next)
            limited = any_rk & (t_rk < t_next)
        else:
            t1, limited = t_next, any_rk
        t1 = np.where(live, np.maximum(t1, t), t)
        self.t0 = t.copy()
        self.h = t1 - t
        h = self.h[sel]
        x_end, steps = [], []
        err = np.zeros(idx.size)
        for a, st in enumerate(self.states):
            x0, u, is_rk = st.x[sel], st.u[sel], st.rk[sel]
            step: dict = {"x0": x0, "u": u, "rk": is_rk}
            if not is_rk.any():
                xe = st.ca.plant.propagate(x0, u, h)
            else:
                xe = np.empty_like(x0)
                ex = ~is_rk
                if ex.any():
                    xe[ex] = st.ca.plant.propagate(x0[ex], u[ex], h[ex])
                r = np.flatnonzero(is_rk)
                sub = idx[r]
                s = rk.step(derivative(self, a, sub), t[sub], x0[r], h[r], self.settings.rtol,
                            self.settings.atol)
                xe[r] = s.x1
                err[r] = np.maximum(err[r], s.err)
                pos = np.full(idx.size, -1, np.intp)
                pos[r] = np.arange(r.size)
                step.update(rk_step=s, rk_pos=pos)
            x_end.append(xe)
            steps.append(step)
        rows_rk = any_rk[sel]
        if rows_rk.any():
            new_h = rk.next_step_size(h, err)
            reject = rows_rk & (err > 1)
            grow = rows_rk & ~reject & limited[sel]
            upd = reject | grow
            self.h_rk[idx[upd]] = new_h[upd]
            if reject.any():
                t1[idx[reject]] = t[idx[reject]]
                self.h[idx[reject]] = 0.0
                for a in range(len(self.states)):
                    x_end[a][reject] = steps[a]["x0"][reject]
        accepted = self.h[sel] > 0
        cache: dict = {}
        if accepted.any():
            tau, end_truths, cache = find_crossings(self, idx, x_end, steps)
        else:
            tau, end_truths = np.full(idx.size, np.inf), [None] * len(self.states)
        crossing = np.isfinite(tau) & accepted
        if crossing.any():
            rows = np.flatnonzero(crossing)
            for a in range(len(self.states)):
                known = cache.get(a, {})
                hits = [known.get((r, tt)) for r, tt in zip(rows.tolist(), tau[rows].tolist(),
                                                            strict=True)]
                miss = np.array([x is None for x in hits], bool)
                for k in np.flatnonzero(~miss).tolist():
                    x_end[a][rows[k]] = hits[k]
                if miss.any():
                    r = rows[miss]
                    x_end[a][r] = self.state_at(a, idx[r], tau[r], steps[a], rows=r)
            t1[idx[rows]] = t[idx[rows]] + tau[rows]
        tn = t1[sel]
        self._interpolate_samples(idx, tn, steps)
        for a, st in enumerate(self.states):
            if full:
                st.x = x_end[a]
            else:
                st.x[idx] = x_end[a]
        self.t = t1
        at = crossing | (tn >= self.t_end) | (tn >= self.queue.next[sel])
        tick = tn >= self.streams.next[sel]
        for a, st in enumerate(self.states):
            at |= tn >= self.timer[a][sel]
            tick |= tn >= st.next_tick[sel]
        plain = accepted & ~crossing
        moved = idx[crossing]
        for a, st in enumerate(self.states):
            if end_truths[a] is not None:
                if plain.all() and full:
                    st.truth = end_truths[a]
                else:
                    st.truth[:, idx[plain]] = end_truths[a][:, plain]
            if st.ca.watches and moved.size:
                st.truth[:, moved] = watch_truth(self, a, moved, st.x[moved], self.t[moved])
        events = idx[at | tick]
        if events.size:
            self._instant(events, crossed=moved, discrete=idx[at])
        self._record_samples(idx)
        ended = idx[(self.t[sel] >= self.t_end) & ~self.done[sel]]
        if ended.size:
            self.finish(ended, "ok", lambda i: f"reached the end of the run at t={self.when(i)}")

    def _initial_rk_steps(self, idx: np.ndarray) -> None:
        if idx.size == 0:
            return
        h = np.full(idx.size, np.inf)
        for a, st in enumerate(self.states):
            rows = np.flatnonzero(st.rk[idx])
            if rows.size == 0:
                continue
            sub = idx[rows]
            h0 = rk.initial_step_size(derivative(self, a, sub), self.t[sub], st.x[sub],
                                      self.settings.rtol, self.settings.atol,
                                      min(self.max_step, self.t_end or 1.0))
            h[rows] = np.minimum(h[rows], h0)
        self.h_rk[idx] = h

    def _interpolate_samples(self, idx: np.ndarray, t1: np.ndarray, steps: list[dict]) -> None:
        """Record output samples that fall strictly inside this step, without stopping there.

        Outputs do not constrain the integrator: flows are read off the step's dense
        output, kinematic plants off their exact arcs, all samples of a step in one call.
        Samples exactly at the step's end are taken after that instant's discrete steps,
        by :meth:`_record_samples`.
        """
        first = self.out_k[idx]
        last = np.searchsorted(self.sample_times, t1, side="left")  # samples < t1
        count = np.maximum(last - first, 0)
        if not count.any():
            return
        rows = np.repeat(np.arange(idx.size), count)
        k = np.repeat(first, count) + (np.arange(rows.size) - np.repeat(np.cumsum(count) - count,
                                                                         count))
        due = idx[rows]
        tau = self.sample_times[k] - self.t0[due]
        for a, st in enumerate(self.states):
            x = self.state_at(a, due, tau, steps[a], rows=rows, dense=True)
            self.rec.sample(k, due, st.ca.name, x)
        moved = idx[count > 0]
        self.out_k[moved] = last[count > 0]
        self.next_out[moved] = self._sample_after[self.out_k[moved]]

    def _record_samples(self, idx: np.ndarray) -> None:
        due = idx[self.t[idx] >= self.next_out[idx]]
        if due.size == 0:
            return
        k = self.out_k[due]
        for st in self.states:
            self.rec.sample(k, due, st.ca.name, st.x[due])
        for name, values in self.world.sample(due).items():
            self.rec.sample(k, due, name, values)
        self.out_k[due] += 1
        self.next_out[due] = self._sample_after[self.out_k[due]]

    def _world_meta(self, meta: dict) -> None:
        """What the world components tell the views: walls, payloads, robot footprints."""
        extra = self.world.meta()
        footprints = extra.pop("footprints", {})
        for a in meta["agents"]:
            preset = self.cteam.team.agent(a["name"]).preset
            if a["name"] in footprints:
                a["footprint"] = footprints[a["name"]]
            elif preset is not None:  # no component drew it: the robot model's disk
                a["footprint"] = {"radius": preset.footprint.radius}
        series = self.world.sample_series()
        meta["series"] = {k: list(v) for k, v in series.items()}
        meta.update(extra)

    def _close(self) -> Trace:
        everyone = np.arange(self.n)
        for st in self.states:
            st.exit(0, everyone, self.t, self.rec)
        self.network.close(self.queue.pending_messages())
        transitions, intervals, messages = self.rec.tables()
        team = self.cteam.team
        meta = {
            "team": team.name,
            "n": self.n,
            "seed": self.seed,
            "duration": self.t_end,
            "agents": [{
                "name": ca.name,
                "plant": ca.plant.kind,
                "state": list(ca.plant.state_names),
                "inputs": list(ca.plant.input_names),
                "modes": [{"path": m.path, "depth": m.depth, "kind": m.kind, "final": m.final,
                           **({"role": m.role} if m.role else {})}
                          for m in ca.modes if m.index],
            } for ca in self.cteam.agents],
        }
        self._world_meta(meta)
        outcomes = [o if o is not None else {"instance": i, "outcome": "ok",
                                             "t": float(self.t[i]), "message": ""}
                    for i, o in enumerate(self.outcomes)]
        if self.world.any:
            for i, o in enumerate(outcomes):
                o["stats"] = self.world.summary(i)
        return Trace(meta, outcomes, transitions, intervals, messages, self.sample_times,
                     self.rec.samples)

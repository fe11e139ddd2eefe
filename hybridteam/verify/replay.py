"""Counterexamples as runs: the engine replays a skeleton path in time.

A path of the skeleton says in which order things happen, not when. The replay gives each
step a moment and runs the ordinary simulator, plant, streams, world and all, with a
scripted network (:attr:`~hybridteam.engine.network.Network.script`):

- the copies the path delivers arrive at their step's moment, the copies it loses are
  lost, every other copy of a control message stays in flight until the run ends;
- the scenario events the path raises are raised at their step's moment (the team's own
  times are replaced; events the path does not reach are left out);
- what the replay cannot schedule happens on its own: an ack timeout expires its timeout
  after the message was last sent, an ``after:`` timeout or a guard over time or state
  fires when the run makes it true, a world component raises its event when it does.

Moments come from a simple temporal network (:mod:`.schedule`): steps in the path's order,
as early as possible, each ack timeout and ``after:`` timeout the path takes exactly when
the engine would expire it, and none it does not take expiring while armed. A guard over
time or state, or a world event, is measured: the run up to the step before shows when it
fires, and that moment is fixed. The run must then agree with the path — the same mode
configuration after every step, the same control messages sent at every step, nothing
else in between; where it does not at a step the replay controls, that step is tried
later (:data:`DELAYS` after the one before: a guard may need time to pass). Once it agrees,
the run is checked for the violation itself: the requirement's verdict on the trace, or
for ``deadlock`` that nothing happens any more. A path the simulator cannot follow, or
whose run does not violate the property, is *spurious*: the skeleton over-approximates
timing, and the replay says at which step and why.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Graph, active_of
from hybridteam.verify.machine import Copy, Machine, State
from hybridteam.verify.paths import step_text
from hybridteam.verify.schedule import GAPS, Bound, solve

#: the least times tried between a step the replay controls and the step before, when the
#: run does not follow the path with the earliest moment (seconds)
DELAYS = (0.01, 0.1, 0.5, 2.0, 10.0)
_TOL = 1e-9
_CONTROLLED = ("deliver", "scenario")


@dataclass
class Step:
    """One step of a path, with what a replay needs to schedule and to check it."""

    kind: str  # initial, deliver, lose, dup, timer, scenario, world, time
    text: str
    active: frozenset  # (agent name, mode path) of every active mode after the step
    sends: Counter  # (sender, receiver, type) of the control copies the step sends
    outbox: dict = field(default_factory=dict)  # (sender, id) -> ack timeout, after it
    armed: tuple = ()  # (agent, transition, delay) of the after: timeouts it arms
    key: tuple | None = None  # deliver/lose/dup: (sender, receiver, type, n) of the copy
    agent: int = -1  # time/world: whose transition; scenario: who gets the event
    event: str = ""  # scenario: the event
    transition: int = -1  # time: which transition
    entry: tuple | None = None  # timer: (sender, id) of the message
    sent_at: int = -1  # timer: the step that last sent the message
    timeout: float = 0.0  # timer: the message's ack timeout


@dataclass
class Replay:
    """The outcome: ``reproduced``, or why not (``reason``), the moments of the steps, and
    the run (None when the path could not be followed)."""

    reproduced: bool
    reason: str
    steps: list[Step]
    times: list[float] = field(default_factory=list)
    run: object = None
    stop: int = -1  # the step the run could not follow (-1: none, or the whole path)

    @property
    def verdict(self) -> str:
        return "reproduced" if self.reproduced else "spurious (abstraction)"

    def lines(self) -> list[str]:
        """The path's steps with the moments the replay gave them."""
        return [f"t={t:9.6f} s  {s.text}" for s, t in zip(self.steps[1:], self.times[1:],
                                                           strict=False)]


def follow(sk: Skeleton, g: Graph, path: list[int], m: Machine) -> list[Step]:
    """The steps of ``path`` with the identity of every copy (which send of its link and
    type it is), found by re-running the path with the engine's own message ids on ``m``
    (a raw machine of capacity 1)."""
    names = [ca.name for ca in sk.original.agents]
    raw = m.initial()
    count: Counter = Counter()
    ident: list[tuple] = []

    def keys(copies) -> Counter:
        sends: Counter = Counter()
        for c in copies:
            link = (names[c.sender], names[c.receiver], c.type)
            ident.append((*link, count[link]))
            count[link] += 1
            sends[link] += 1
        return sends

    steps = [Step("initial", "initial", _active(sk, raw), keys(raw.inflight),
                  _outbox(raw), _armed(m, m.armed0))]
    sent_at = {(e.sender, e.msg_id): 0 for e in raw.outbox}
    for a, b in pairwise(path):
        choice = g.edge_how[(a, b)]
        rc, nxt = _match(m, raw, g.states[a], choice, g.states[b])
        step = Step(rc[0], step_text(sk, g.states[a], choice), _active(sk, nxt), Counter(),
                    _outbox(nxt))
        if rc[0] in ("deliver", "lose", "dup"):
            step.key = ident[rc[1]]
            if rc[0] == "dup":
                ident.append(step.key)
            else:
                del ident[rc[1]]
        elif rc[0] == "timer":
            e = raw.outbox[rc[1]]
            step.entry = (e.sender, e.msg_id)
            step.sent_at, step.timeout = sent_at[step.entry], e.timeout
        elif rc[0] == "scenario":
            _, step.agent, step.event = sk.original.scenario[raw.cursor]
        elif rc[0] in ("time", "world"):
            step.agent = rc[1]
            step.transition = rc[2] if rc[0] == "time" else -1
        if rc[0] not in ("lose", "dup"):
            step.sends = keys(nxt.inflight[len(ident):])
            step.armed = _armed(m)
        for e in nxt.outbox:  # a new acknowledged message: its timer starts here
            if (e.sender, e.msg_id) not in sent_at:
                sent_at[(e.sender, e.msg_id)] = len(steps)
        if step.entry is not None and step.sends:  # resent: the timer starts again
            sent_at[step.entry] = len(steps)
        steps.append(step)
        raw = nxt
    return steps


def _active(sk: Skeleton, s: State) -> frozenset:
    out = set()
    for a, ca in enumerate(sk.original.agents):
        act = active_of(s, a, len(ca.modes))
        out |= {(ca.name, ca.modes[k].path) for k in np.flatnonzero(act).tolist()
                if ca.modes[k].path}  # the root is not a mode of the trace
    return frozenset(out)


def _outbox(s: State) -> dict:
    return {(e.sender, e.msg_id): e.timeout for e in s.outbox}


def _armed(m: Machine, rows: list[np.ndarray] | None = None) -> tuple:
    """(agent, transition, delay) of each after: timeout the last step armed: the
    machine's clock stands at 0, so an armed deadline is the delay itself."""
    out = []
    for a, st in enumerate(m.ens.states):
        row = st.deadline[0] if rows is None else rows[a]
        for j in st.ca.after:
            d = float(row[st.ca.transitions[j].after_slot])
            if math.isfinite(d) and d >= 0:
                out.append((a, j, d))
    return tuple(out)


def _same(x: Copy, y: Copy) -> bool:
    """The same copy up to message ids (raw ids against canonical ones)."""
    def strip(c: Copy) -> tuple:
        return (*c[:4], tuple(f for f in c.fields if f[0] != "id"))
    return strip(x) == strip(y)


def _match(m: Machine, raw: State, parent: State, choice: tuple, child: State
           ) -> tuple[tuple, State]:
    """The choice on the raw state whose successor is ``child`` in canonical form, and
    that successor; identical copies are tried oldest first."""
    kind = choice[0]
    if kind in ("deliver", "lose", "dup"):
        c = parent.inflight[choice[1]]
        options = [(kind, j) for j, r in enumerate(raw.inflight) if _same(r, c)]
    elif kind == "timer":
        e = parent.outbox[choice[1]]
        options = [("timer", j) for j, r in enumerate(raw.outbox)
                   if r._replace(msg_id=0) == e._replace(msg_id=0)]
    else:
        options = [choice]
    for option in options:
        tapes: list[tuple] = [()]
        while tapes:
            tape = tapes.pop(0)
            r = m.run([(raw, option, tape)])[0]
            if m.canonical(r.state) == child:
                return option, r.state
            tapes += [tape + (False,) * (k - len(tape)) + (True,)
                      for k in range(len(tape), r.reads)]
    raise AssertionError(f"the path's step {choice} cannot be followed")  # a bug: say so


def bounds(sk: Skeleton, steps: list[Step], gap: float) -> list[Bound]:
    """The timing the engine imposes on the path (see :mod:`.schedule`), with ``gap``
    between consecutive steps."""
    names = [ca.name for ca in sk.original.agents]
    n = len(steps) - 1
    out = []
    for k in range(1, n + 1):
        s = steps[k]
        if s.kind in ("lose", "dup"):  # decided when the copy was sent: no moment of its own
            out.append(Bound(k - 1, k, 0.0, 0.0, f"step {k} takes no time"))
        else:
            out.append(Bound(k - 1, k, gap, math.inf, f"step {k} comes after step {k - 1}"))
        if s.kind == "timer":
            out.append(Bound(s.sent_at, k, s.timeout, s.timeout,
                             f"the ack timeout at step {k} expires {s.timeout:g} s after "
                             f"step {s.sent_at} sent the message"))
    for k in range(n + 1):  # timers the path does not take must not expire while armed
        for entry, timeout in steps[k].outbox.items():
            if k and entry in steps[k - 1].outbox and not (
                    steps[k].entry == entry and steps[k].sends):
                continue  # armed earlier
            e = next((j for j in range(k + 1, n + 1) if entry not in steps[j].outbox
                      or steps[j].entry == entry), None)
            if e is not None and steps[e].entry == entry:
                continue  # it expires at step e: the bound above
            what = f"{names[entry[0]]}'s message #{entry[1]} (sent at step {k})"
            out.append(Bound(k, n if e is None else e, -math.inf, timeout - gap,
                             f"{what} is not settled by the path's end" if e is None
                             else f"{what} is settled at step {e}, before its ack "
                             f"timeout ({timeout:g} s)"))
    ca_of = sk.original.agents
    for k in range(n + 1):
        for a, j, d in steps[k].armed:
            tr = ca_of[a].transitions[j]
            source = (names[a], ca_of[a].modes[tr.source].path)
            for e in range(k + 1, n + 1):
                s = steps[e]
                if s.kind == "time" and (s.agent, s.transition) == (a, j):
                    exact = tr.guard is None
                    out.append(Bound(k, e, d, d if exact else math.inf,
                                     f"{names[a]}'s 'after {d:g} s' ({tr.text}) fires at "
                                     f"step {e}, entered at step {k}"))
                    break
                if source not in s.active or any((b, i) == (a, j) for b, i, _ in s.armed):
                    out.append(Bound(k, e, -math.inf, d - gap,
                                     f"{names[a]} leaves {source[1]} (step {e}) before its "
                                     f"'after {d:g} s' (entered at step {k})"))
                    break
            else:
                out.append(Bound(k, n, -math.inf, d - gap,
                                 f"{names[a]}'s 'after {d:g} s' ({tr.text}) does not fire "
                                 f"by the path's end"))
    return out


class Script:
    """A replay's network: each control copy's arrival times, by (sender, receiver, type,
    n) — the n-th copy of that type on that link; +inf: still in flight at the end."""

    def __init__(self, names: list[str], streams: set[str], plan: dict[tuple, list[float]]
                 ) -> None:
        self.names, self.streams, self.plan = names, streams, plan
        self.count: Counter = Counter()

    def arrivals(self, sender: int, receiver: int, type_: str) -> list[float]:
        link = (self.names[sender], self.names[receiver], type_)
        key = (*link, self.count[link])
        self.count[link] += 1
        return self.plan.get(key, [math.inf])


class Replayer:
    """Runs the simulator on a schedule of the path's steps and compares the run."""

    def __init__(self, team, cteam, sk: Skeleton, steps: list[Step]) -> None:
        self.team, self.cteam, self.sk, self.steps = team, cteam, sk, steps
        self.names = [ca.name for ca in self.cteam.agents]
        self.streams = {s.message for ca in self.cteam.agents for s in ca.streams}

    def run(self, times: list[float], duration: float):
        """The run with steps 1..len(times)-1 at ``times`` (a :class:`~hybridteam.api.Run`
        with its requirement verdicts)."""
        from hybridteam.api import Run, check_requirements
        from hybridteam.engine.simulator import Simulator
        from hybridteam.requirements.check import compile_requirements

        plan: dict[tuple, list[float]] = {}
        copies: Counter = Counter()
        for s in self.steps:
            for link, k in s.sends.items():
                for j in range(k):
                    copies[(*link, _nth(self.steps, s, link, j))] = 1
        for s in self.steps[1:]:
            if s.kind == "dup":
                copies[s.key] += 1
        delivered: dict[tuple, list[float]] = {}
        lost: Counter = Counter()
        for s, t in zip(self.steps[1:], times[1:], strict=False):
            if s.kind == "deliver":
                delivered.setdefault(s.key, []).append(t)
            elif s.kind == "lose":
                lost[s.key] += 1
        for key, n in copies.items():
            got = delivered.get(key, [])
            plan[key] = got + [math.inf] * (n - len(got) - lost[key])
        scenario = [(t, s.agent, s.event) for s, t in zip(self.steps[1:], times[1:],
                                                          strict=False)
                    if s.kind == "scenario"]
        cteam = dataclasses.replace(self.cteam, scenario=scenario)
        reqs = compile_requirements(cteam)
        sim = Simulator(cteam, 1, seed=self.team.simulation.seed, duration=duration,
                        snapshots=bool(reqs), observe=reqs.observers(cteam))
        sim.ensemble.network.script = Script(self.names, self.streams, plan)
        run = Run.of(sim.run())
        if reqs:
            check_requirements(run, reqs, sim)
        return run

    def diverges(self, run, times: list[float]) -> tuple[int, str] | None:
        """The first step of 0..len(times)-1 that ``run`` does not follow, and how."""
        k = len(times) - 1
        moments = sorted(set(times))
        found: list[tuple[int, str]] = []
        for j in range(k + 1):
            if j < k and times[j + 1] == times[j]:
                continue  # a loss or duplication: the next step shows the state
            got = _active_at(run, times[j])
            if got != self.steps[j].active:
                extra = sorted(f"{a} in {m}" for a, m in got - self.steps[j].active)
                missing = sorted(f"{a} in {m}" for a, m in self.steps[j].active - got)
                found.append((j, f"after step {j} (t={times[j]:.6g} s) the run has "
                              f"{', '.join(extra) or 'nothing else'} where the path has "
                              f"{', '.join(missing) or 'nothing else'}"))
                break
        end = times[-1] + _TOL
        for row in run.transitions:
            if row.cause != "init" and row.t <= end and \
                    not any(abs(row.t - t) <= _TOL for t in moments):
                found.append((_step_at(times, row.t), f"at t={row.t:.6g} s {row.agent}: "
                              f"{row.source} -> {row.target} ({row.cause}), which the path "
                              "does not have there"))
                break
        found += self._sends(run, times, moments)
        return min(found) if found else None

    def _sends(self, run, times: list[float], moments: list[float]) -> list[tuple[int, str]]:
        """The first moment at which the run sends other control copies than the path."""
        expected: dict[float, Counter] = {t: Counter() for t in moments}
        for s, t in zip(self.steps, times, strict=False):
            expected[t] += s.sends
        got: dict[float, Counter] = {t: Counter() for t in moments}
        end = times[-1] + _TOL
        for row in run.messages:
            if row.type in self.streams or row.t_send > end:
                continue
            at = next((t for t in moments if abs(row.t_send - t) <= _TOL), None)
            if at is None:
                return [(_step_at(times, row.t_send), f"at t={row.t_send:.6g} s "
                         f"{row.sender} sends {row.type} to {row.receiver}, which the path "
                         "does not have")]
            got[at][(row.sender, row.receiver, row.type)] += 1
        for t in moments:
            if got[t] != expected[t]:
                more = ", ".join(f"{s}->{r}: {ty}" for (s, r, ty) in got[t] - expected[t])
                less = ", ".join(f"{s}->{r}: {ty}" for (s, r, ty) in expected[t] - got[t])
                return [(_step_at(times, t), f"at t={t:.6g} s the run sends "
                         f"{more or 'nothing more'} where the path sends "
                         f"{less or 'nothing more'}")]
        return []

    def measure(self, times: list[float], step: Step, horizon: float) -> float | None:
        """When a guard over time or state, or a world event, fires after the steps before
        it (which are at ``times``): the first transition of its agent in that run, looked
        for in ever longer runs up to ``horizon``."""
        name = self.names[step.agent]
        for window in (1.0, 10.0, math.inf):
            end = min(times[-1] + window, horizon)
            run = self.run(times, end)
            after = [row.t for row in run.transitions if row.agent == name and
                     row.cause != "init" and row.t > times[-1] + _TOL]
            if after:
                return min(after)
            if end >= horizon:
                return None
        return None


def _step_at(times: list[float], t: float) -> int:
    """The first step at or after moment ``t``."""
    return next((j for j, tj in enumerate(times) if tj >= t - _TOL), len(times) - 1)


def _nth(steps: list[Step], step: Step, link: tuple, j: int) -> int:
    """The sequence number of the ``j``-th copy on ``link`` that ``step`` sends."""
    before = 0
    for s in steps:
        if s is step:
            return before + j
        before += s.sends.get(link, 0)
    raise ValueError("step not in steps")


def _active_at(run, t: float) -> frozenset:
    """The (agent, mode) pairs active just after ``t``. At the run's end (the team's end
    rule may stop it at ``t``, closing every interval there) each agent's last entered
    mode per depth: the interval closed last among those entered last."""
    rows = run.modes
    last = float(run.diagnostics[0]["t"])
    if t < last - _TOL:
        mask = (rows["start"] <= t + _TOL) & (rows["end"] > t + _TOL)
        return frozenset(zip(rows["agent"][mask].tolist(), rows["mode"][mask].tolist(),
                             strict=True))
    best: dict[tuple, tuple] = {}
    for k, r in enumerate(rows):
        if r.start <= t + _TOL and r.end >= last - _TOL:
            key = (r.agent, r.depth)
            if key not in best or (r.start, k) >= best[key][:2]:
                best[key] = (r.start, k, r.mode)
    return frozenset((a, m) for (a, _), (_, _, m) in best.items())


def _measured(sk: Skeleton, s: Step) -> bool:
    """Whether a step happens when the run makes it happen (not when the replay says)."""
    if s.kind == "world":
        return True
    if s.kind != "time":
        return False
    tr = sk.original.agents[s.agent].transitions[s.transition]
    return tr.after is None or tr.guard is not None


class Context:
    """What every replay of one report shares: the team, compiled, and a raw machine."""

    def __init__(self, team, sk: Skeleton, g: Graph, fifo: bool) -> None:
        from hybridteam.engine.compiler import compile_team

        self.team, self.sk, self.g = team, sk, g
        self.cteam = compile_team(team)
        self.machine = Machine(sk, 1, fifo=fifo, raw=True)
        self.timed: dict[tuple, object] = {}  # path -> its schedule, or why it has none


def replay(ctx: Context, path: list[int], kind: str, name: str, loops: bool = False
           ) -> Replay:
    """Schedule ``path`` in time and check that the run violates property ``name``."""
    key = tuple(path)
    if key not in ctx.timed:  # two properties often share a counterexample
        ctx.timed[key] = _timed(ctx, path)
    found = ctx.timed[key]
    if isinstance(found, Replay):
        return found
    r, times, gap = found
    return _final(r, r.steps, times, kind, name, float(ctx.team.simulation.duration),
                  loops, gap)


def _timed(ctx: Context, path: list[int]) -> Replay | tuple[Replayer, list[float], float]:
    """The moments at which the run follows ``path``, or why it cannot."""
    team, sk = ctx.team, ctx.sk
    steps = follow(sk, ctx.g, path, ctx.machine)
    r = Replayer(team, ctx.cteam, sk, steps)
    horizon = float(team.simulation.duration)
    n = len(steps) - 1
    gap = next((g for g in GAPS if not isinstance(solve(n, bounds(sk, steps, g)), str)), 0.0)
    if not gap:  # the shortest prefix that cannot be timed: no path through it can either
        m = next(m for m in range(1, n + 1)
                 if isinstance(solve(m, bounds(sk, steps[: m + 1], GAPS[-1])), str))
        why = solve(m, bounds(sk, steps[: m + 1], GAPS[-1]))
        return Replay(False, f"the path cannot be timed: {why}", steps, stop=m)
    base = bounds(sk, steps, gap)
    fixed: dict[int, float] = {}  # measured moments
    floor: dict[int, int] = {}  # step -> index into DELAYS of its least gap
    measure = [k for k, s in enumerate(steps) if _measured(sk, s)]
    first, first_k = "", -1  # where the run first left the path, and how
    while True:
        extra = [Bound(0, k, t, t, f"step {k} fires at t={t:.6g} s in the run")
                 for k, t in fixed.items()]
        extra += [Bound(k - 1, k, DELAYS[d], math.inf, f"step {k} waits {DELAYS[d]:g} s")
                  for k, d in floor.items()]
        times = solve(n, base + extra)
        if isinstance(times, str):
            why = first + " (and it cannot wait longer: " + times + ")" if first else \
                f"the path cannot be timed: {times}"
            return Replay(False, why, steps, stop=first_k)
        times = [float(t) for t in times]
        todo = [k for k in measure if k not in fixed]
        if todo:
            k = todo[0]
            t = r.measure(times[:k], steps[k], max(horizon, times[k - 1] + 10.0))
            if t is None:
                return Replay(False, f"step {k} ({steps[k].text}) does not happen in the "
                              f"run after t={times[k - 1]:.6g} s", steps, times[:k], stop=k)
            fixed[k] = t
            continue
        bad = r.diverges(r.run(times, times[-1] + gap / 2), times)
        if bad is None:
            return r, times, gap
        k, why = bad
        if not first:
            first, first_k = f"the run cannot follow step {k} ({steps[k].text}): {why}", k
        ks = [j for j in range(k, 0, -1) if steps[j].kind in _CONTROLLED]
        j = ks[0] if ks else -1
        if j < 0 or floor.get(j, -1) + 1 >= len(DELAYS):
            return Replay(False, first, steps, times, stop=first_k)
        floor[j] = floor.get(j, -1) + 1
        for later in [m for m in fixed if m > j]:
            del fixed[later]  # measured with the earlier schedule


def _final(r: Replayer, steps: list[Step], times: list[float], kind: str, name: str,
           horizon: float, loops: bool, gap: float) -> Replay:
    """The whole path scheduled: run on (to the end of the team's run after a dead end,
    five steps' time after a cycle or an invariant's violation) and check the property."""
    end = times[-1]
    long = kind == "deadlock" or (kind == "response" and not loops)
    duration = max(horizon, end + 1.0) if long else end + 5 * gap
    run = r.run(times, duration)
    if kind == "deadlock":
        later = [row for row in run.transitions if row.t > end + _TOL]
        if later:
            row = later[0]
            return Replay(False, f"the run goes on: at t={row.t:.4g} s {row.agent}: "
                          f"{row.source} -> {row.target} ({row.cause})", steps, times, run)
        out = run.diagnostics[0]
        why = "" if out["outcome"] == "ok" and out["t"] >= run.meta["duration"] else \
            f": {out['message']}"
        return Replay(True, f"nothing happens from t={end:.6g} s to the end of the run "
                      f"(t={out['t']:.6g} s{why})", steps, times, run)
    verdict = run.diagnostics[0].get("requirements", {}).get(name, {})
    if verdict.get("satisfied", True):
        return Replay(False, f"the run follows the path, but its trace satisfies {name} "
                      f"(robustness {verdict.get('robustness')})", steps, times, run)
    if kind == "response":
        return Replay(True, f"the run's trace violates {name}: the answer has not come by "
                      f"the end of the run (t={run.diagnostics[0]['t']:.6g} s)", steps, times,
                      run)
    return Replay(True, f"the run's trace violates {name} at "
                  f"t={float(verdict.get('violated_at', end)):.6g} s", steps, times, run)

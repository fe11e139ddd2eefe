"""Counterexamples as runs: the engine replays a skeleton path in time.

A path of the skeleton says in which order things happen, not when. The replay gives each
step a moment and runs the ordinary simulator, plant, streams, world and all, with a
scripted network (:attr:`~hybridteam.engine.run.network.Network.script`):

- the copies the path delivers arrive at their step's moment, the copies it loses are
  lost, every other copy of a control message stays in flight until the run ends;
- the scenario events the path raises are raised at their step's moment (the team's own
  times are replaced; events the path does not reach are left out);
- what the replay cannot schedule happens on its own: an ack timeout expires its timeout
  after the message was last sent, an ``after:`` timeout or a guard over time or state
  fires when the run makes it true, a world component raises its event when it does.

Moments come from a simple temporal network (:mod:`~hybridteam.verify.schedule`): steps in the
path's order, as early as possible, each ack timeout and ``after:`` timeout the path takes exactly
when the engine would expire it, and none it does not take expiring while armed. A guard over time
or state, or a world event, is measured: the run up to the step before shows when it fires, and that
moment is fixed. The run must then agree with the path — the same mode configuration after every
step, the same control messages sent at every step, nothing else in between; where it does not at a
step the replay controls, that step is tried later (:data:`DELAYS` after the one before: a guard may
need time to pass). Once it agrees, the run is checked for the violation itself: the requirement's
verdict on the trace, or for ``deadlock`` that nothing happens any more. A path the simulator cannot
follow, or whose run does not violate the property, is *spurious*: the skeleton over-approximates
timing, and the replay says at which step and why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Graph
from hybridteam.verify.machine import Machine
from hybridteam.verify.runs import TOL, Replayer
from hybridteam.verify.schedule import GAPS, Bound, solve
from hybridteam.verify.steps import PathStep, bounds, follow

#: the least times tried between a step the replay controls and the step before, when the
#: run does not follow the path with the earliest moment (seconds)
DELAYS = (0.01, 0.1, 0.5, 2.0, 10.0)
_CONTROLLED = ("deliver", "scenario")


@dataclass
class Replay:
    """The outcome: ``reproduced``, or why not (``reason``), the moments of the steps, and
    the run (None when the path could not be followed)."""

    reproduced: bool
    reason: str
    steps: list[PathStep]
    times: list[float] = field(default_factory=list)
    run: object = None
    stop: int = -1  # the step the run could not follow (-1: none, or the whole path)

    @property
    def verdict(self) -> str:
        return "reproduced" if self.reproduced else "spurious (abstraction)"

    def lines(self) -> list[str]:
        """The path's steps with the moments the replay gave them."""
        return [
            f"t={t:9.6f} s  {s.text}" for s, t in zip(self.steps[1:], self.times[1:], strict=False)
        ]


def _measured(sk: Skeleton, s: PathStep) -> bool:
    """Whether a step happens when the run makes it happen (not when the replay says)."""
    if s.kind == "world":
        return True
    if s.kind != "time":
        return False
    tr = sk.original.agents[s.agent].transitions[s.transition]
    return tr.after is None or tr.guard is not None


class Context:
    """What every replay of one report shares: the team and its requirements, compiled,
    and a raw machine."""

    def __init__(
        self,
        team,
        sk: Skeleton,
        g: Graph,
        fifo: bool,
        concrete: Callable[[list[int]], tuple[Graph, list[int]]] | None = None,
    ) -> None:
        """``concrete``: the team's own states along a path of ``g`` (a graph and the path
        in it), where ``g`` holds representatives of states (:mod:`.symmetry`)."""
        from hybridteam.engine.compile.compiler import compile_team
        from hybridteam.requirements.check import compile_requirements

        self.team, self.sk, self.g = team, sk, g
        self.concrete = concrete or (lambda path: (g, path))
        self.cteam = compile_team(team)
        self.requirements = compile_requirements(self.cteam)
        self.machine = Machine(sk, 1, fifo=fifo, raw=True)
        # path -> its schedule (the replayer, its times and gap), or why it has none
        self.timed: dict[tuple, Replay | tuple[Replayer, list[float], float]] = {}


def replay(ctx: Context, path: list[int], kind: str, name: str, loops: bool = False) -> Replay:
    """Schedule ``path`` in time and check that the run violates property ``name``."""
    key = tuple(path)
    if key not in ctx.timed:  # two properties often share a counterexample
        ctx.timed[key] = _timed(ctx, path)
    found = ctx.timed[key]
    if isinstance(found, Replay):
        return found
    r, times, gap = found
    return _final(r, r.steps, times, kind, name, float(ctx.team.simulation.duration), loops, gap)


def _timed(ctx: Context, path: list[int]) -> Replay | tuple[Replayer, list[float], float]:
    """The moments at which the run follows ``path``, or why it cannot."""
    team, sk = ctx.team, ctx.sk
    steps = follow(sk, *ctx.concrete(path), ctx.machine)
    r = Replayer(team, ctx.cteam, ctx.requirements, steps)
    horizon = float(team.simulation.duration)
    n = len(steps) - 1
    gap = next((g for g in GAPS if not isinstance(solve(n, bounds(sk, steps, g)), str)), 0.0)
    if not gap:  # the shortest prefix that cannot be timed: no path through it can either
        m = next(
            m
            for m in range(1, n + 1)
            if isinstance(solve(m, bounds(sk, steps[: m + 1], GAPS[-1])), str)
        )
        why = solve(m, bounds(sk, steps[: m + 1], GAPS[-1]))
        return Replay(False, f"the path cannot be timed: {why}", steps, stop=m)
    base = bounds(sk, steps, gap)
    fixed: dict[int, float] = {}  # measured moments
    floor: dict[int, int] = {}  # step -> index into DELAYS of its least gap
    measure = [k for k, s in enumerate(steps) if _measured(sk, s)]
    first, first_k = "", -1  # where the run first left the path, and how
    while True:
        extra = [
            Bound(0, k, t, t, f"step {k} fires at t={t:.6g} s in the run") for k, t in fixed.items()
        ]
        extra += [
            Bound(k - 1, k, DELAYS[d], math.inf, f"step {k} waits {DELAYS[d]:g} s")
            for k, d in floor.items()
        ]
        times = solve(n, base + extra)
        if isinstance(times, str):
            why = (
                first + " (and it cannot wait longer: " + times + ")"
                if first
                else f"the path cannot be timed: {times}"
            )
            return Replay(False, why, steps, stop=first_k)
        times = [float(t) for t in times]
        todo = [k for k in measure if k not in fixed]
        if todo:
            k = todo[0]
            t = r.measure(times[:k], steps[k], max(horizon, times[k - 1] + 10.0))
            if t is None:
                return Replay(
                    False,
                    f"step {k} ({steps[k].text}) does not happen in the "
                    f"run after t={times[k - 1]:.6g} s",
                    steps,
                    times[:k],
                    stop=k,
                )
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


def _final(
    r: Replayer,
    steps: list[PathStep],
    times: list[float],
    kind: str,
    name: str,
    horizon: float,
    loops: bool,
    gap: float,
) -> Replay:
    """The whole path scheduled: run on (to the end of the team's run after a dead end,
    five steps' time after a cycle or an invariant's violation) and check the property."""
    end = times[-1]
    long = kind == "deadlock" or (kind == "response" and not loops)
    duration = max(horizon, end + 1.0) if long else end + 5 * gap
    run = r.run(times, duration)
    if kind == "deadlock":
        later = [row for row in run.transitions if row.t > end + TOL]
        if later:
            row = later[0]
            return Replay(
                False,
                f"the run goes on: at t={row.t:.4g} s {row.agent}: "
                f"{row.source} -> {row.target} ({row.cause})",
                steps,
                times,
                run,
            )
        out = run.diagnostics[0]
        why = (
            ""
            if out["outcome"] == "ok" and out["t"] >= run.meta["duration"]
            else f": {out['message']}"
        )
        return Replay(
            True,
            f"nothing happens from t={end:.6g} s to the end of the run (t={out['t']:.6g} s{why})",
            steps,
            times,
            run,
        )
    verdict = run.diagnostics[0].get("requirements", {}).get(name, {})
    if verdict.get("satisfied", True):
        return Replay(
            False,
            f"the run follows the path, but its trace satisfies {name} "
            f"(robustness {verdict.get('robustness')})",
            steps,
            times,
            run,
        )
    if kind == "response":
        return Replay(
            True,
            f"the run's trace violates {name}: the answer has not come by "
            f"the end of the run (t={run.diagnostics[0]['t']:.6g} s)",
            steps,
            times,
            run,
        )
    return Replay(
        True,
        f"the run's trace violates {name} at t={float(verdict.get('violated_at', end)):.6g} s",
        steps,
        times,
        run,
    )

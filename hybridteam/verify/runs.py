"""Runs of the simulator on a scheduled path, and how they compare with it.

:class:`Script` is the replay's network (:attr:`~hybridteam.engine.run.network.Network.script`):
each control copy's arrival times by its identity. :class:`Replayer` runs the team with a
schedule (the path's scenario events at their moments, the script) and tells where a run
leaves the path: another mode configuration after a step, another control message sent,
or anything happening between steps.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter

from hybridteam.verify.steps import PathStep

TOL = 1e-9  # seconds: moments this close are one (the engine adds the same floats)


class Script:
    """A replay's network: each control copy's arrival times, by (sender, receiver, type,
    n) — the n-th copy of that type on that link; +inf: still in flight at the end."""

    def __init__(self, names: list[str], streams: set[str], plan: dict[tuple, list[float]]) -> None:
        self.names, self.streams, self.plan = names, streams, plan
        self.count: Counter = Counter()

    def arrivals(self, sender: int, receiver: int, type_: str) -> list[float]:
        link = (self.names[sender], self.names[receiver], type_)
        key = (*link, self.count[link])
        self.count[link] += 1
        return self.plan.get(key, [math.inf])


class Replayer:
    """Runs the simulator on a schedule of the path's steps and compares the run."""

    def __init__(self, team, cteam, reqs, steps: list[PathStep]) -> None:
        """``reqs``: the team's compiled requirements (a replay's scenario leaves them as
        they are)."""
        self.team, self.cteam, self.reqs, self.steps = team, cteam, reqs, steps
        self.names = [ca.name for ca in self.cteam.agents]
        self.streams = {s.message for ca in self.cteam.agents for s in ca.streams}
        #: how many times each copy the path sends exists (twice once duplicated)
        self.copies: Counter = Counter(c for s in steps for c in s.copies)
        self.copies.update(s.key for s in steps[1:] if s.kind == "dup")

    def run(self, times: list[float], duration: float):
        """The run with steps 1..len(times)-1 at ``times`` (a :class:`~hybridteam.api.Run`
        with its requirement verdicts)."""
        from hybridteam.api import Run, check_requirements
        from hybridteam.engine.run.simulator import Simulator

        delivered: dict[tuple, list[float]] = {}
        lost: Counter = Counter()
        for s, t in zip(self.steps[1:], times[1:], strict=False):
            if s.kind == "deliver":
                assert s.key is not None  # (a delivery names its copy)
                delivered.setdefault(s.key, []).append(t)
            elif s.kind == "lose":
                lost[s.key] += 1
        plan: dict[tuple, list[float]] = {}
        for key, n in self.copies.items():
            got = delivered.get(key, [])
            plan[key] = got + [math.inf] * (n - len(got) - lost[key])
        scenario = [
            (t, s.agent, s.event)
            for s, t in zip(self.steps[1:], times[1:], strict=False)
            if s.kind == "scenario"
        ]
        cteam = dataclasses.replace(self.cteam, scenario=scenario)
        reqs = self.reqs
        sim = Simulator(
            cteam,
            1,
            seed=self.team.simulation.seed,
            duration=duration,
            snapshots=bool(reqs),
            observe=reqs.observers(cteam),
        )
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
                found.append(
                    (
                        j,
                        f"after step {j} (t={times[j]:.6g} s) the run has "
                        f"{', '.join(extra) or 'nothing else'} where the path has "
                        f"{', '.join(missing) or 'nothing else'}",
                    )
                )
                break
        end = times[-1] + TOL
        for row in run.transitions:
            if (
                row.cause != "init"
                and row.t <= end
                and not any(abs(row.t - t) <= TOL for t in moments)
            ):
                found.append(
                    (
                        _step_at(times, row.t),
                        f"at t={row.t:.6g} s {row.agent}: "
                        f"{row.source} -> {row.target} ({row.cause}), which the path "
                        "does not have there",
                    )
                )
                break
        found += self._sends(run, times, moments)
        return min(found) if found else None

    def _sends(self, run, times: list[float], moments: list[float]) -> list[tuple[int, str]]:
        """The first moment at which the run sends other control copies than the path."""
        expected: dict[float, Counter] = {t: Counter() for t in moments}
        for s, t in zip(self.steps, times, strict=False):
            expected[t] += s.sends
        got: dict[float, Counter] = {t: Counter() for t in moments}
        end = times[-1] + TOL
        copies = set()  # a duplicated copy has a row per arrival: one send
        for row in run.messages:
            if row.type in self.streams or row.t_send > end:
                continue
            if (row.sender, row.receiver, row.seq) in copies:
                continue
            copies.add((row.sender, row.receiver, row.seq))
            at = next((t for t in moments if abs(row.t_send - t) <= TOL), None)
            if at is None:
                return [
                    (
                        _step_at(times, row.t_send),
                        f"at t={row.t_send:.6g} s "
                        f"{row.sender} sends {row.type} to {row.receiver}, which the path "
                        "does not have",
                    )
                ]
            got[at][(row.sender, row.receiver, row.type)] += 1
        for t in moments:
            if got[t] != expected[t]:
                more = ", ".join(f"{s}->{r}: {ty}" for (s, r, ty) in got[t] - expected[t])
                less = ", ".join(f"{s}->{r}: {ty}" for (s, r, ty) in expected[t] - got[t])
                return [
                    (
                        _step_at(times, t),
                        f"at t={t:.6g} s the run sends "
                        f"{more or 'nothing more'} where the path sends "
                        f"{less or 'nothing more'}",
                    )
                ]
        return []

    def measure(self, times: list[float], step: PathStep, horizon: float) -> float | None:
        """When a guard over time or state, or a world event, fires after the steps before
        it (which are at ``times``): the first transition of its agent in that run, looked
        for in ever longer runs up to ``horizon``."""
        name = self.names[step.agent]
        for window in (1.0, 10.0, math.inf):
            end = min(times[-1] + window, horizon)
            run = self.run(times, end)
            after = [
                row.t
                for row in run.transitions
                if row.agent == name and row.cause != "init" and row.t > times[-1] + TOL
            ]
            if after:
                return min(after)
            if end >= horizon:
                return None
        return None


def _step_at(times: list[float], t: float) -> int:
    """The first step at or after moment ``t``."""
    return next((j for j, tj in enumerate(times) if tj >= t - TOL), len(times) - 1)


def _active_at(run, t: float) -> frozenset:
    """The (agent, mode) pairs active just after ``t``. At the run's end (the team's end
    rule may stop it at ``t``, closing every interval there) each agent's last entered
    mode per depth: the interval closed last among those entered last."""
    rows = run.modes
    last = float(run.diagnostics[0]["t"])
    if t < last - TOL:
        mask = (rows["start"] <= t + TOL) & (rows["end"] > t + TOL)
        return frozenset(
            zip(rows["agent"][mask].tolist(), rows["mode"][mask].tolist(), strict=True)
        )
    best: dict[tuple, tuple] = {}
    for k, r in enumerate(rows):
        if r.start <= t + TOL and r.end >= last - TOL:
            key = (r.agent, r.depth)
            if key not in best or (r.start, k) >= best[key][:2]:
                best[key] = (r.start, k, r.mode)
    return frozenset((a, m) for (a, _), (_, _, m) in best.items())

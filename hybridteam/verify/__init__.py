"""``hybridteam verify``: exhaustive checking of a team's discrete protocol logic.

Simulation samples behaviours; this explores all of them in the team's discrete skeleton
(:mod:`.abstraction`): every order of message arrivals, every loss up to a bound, every
timeout and every outcome of a guard over time or state. The engine itself computes each
step (:mod:`.machine`), so the skeleton has the simulator's semantics, not a second
reading of the model. :func:`verify` returns a :class:`Report`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from hybridteam.engine.run.budget import memory_limit
from hybridteam.verify.abstraction import Skeleton, skeleton
from hybridteam.verify.ample import ample
from hybridteam.verify.explore import Graph, Options, Progress, explore
from hybridteam.verify.machine import Machine
from hybridteam.verify.paths import agent_leaves, describe
from hybridteam.verify.properties import Verdict, check, properties
from hybridteam.verify.replay import Context, Replay
from hybridteam.verify.replay import replay as replay_path
from hybridteam.verify.symmetry import Symmetry, lift, symmetry

__all__ = ["NotInPartialSearch", "Options", "Report", "UnknownProperty", "verify"]


class UnknownProperty(ValueError):
    """``only`` names a property the team does not have (checked before exploring)."""

    def __init__(self, name: str, known: list[str]) -> None:
        super().__init__(name)
        self.name, self.known = name, known


class NotInPartialSearch(ValueError):
    """``only`` names a response, which a partial search cannot check (checked before
    exploring)."""

    def __init__(self, name: str, storage: str) -> None:
        super().__init__(
            f"'{name}' is a response (phi leads to psi): it needs the whole state graph, "
            f"which --storage {storage} (a partial search) does not keep; a partial search "
            "checks invariants and deadlock (use --storage exact for responses)"
        )


@dataclass
class Report:
    skeleton: Skeleton
    graph: Graph
    verdicts: list[Verdict]
    options: Options
    notes: list[str] = field(default_factory=list)
    team: object = None
    #: property name -> (the violating state shown, its replay, candidates tried)
    replays: dict[str, tuple[int, Replay, int]] = field(default_factory=dict)
    #: the symmetry the exploration was reduced by (None: ``--symmetry off``)
    symmetry: Symmetry | None = None
    _context: Context | None = None
    _lifter: Machine | None = None

    def concrete(self, path: list[int]) -> tuple[Graph, list[int]]:
        """The team's own states along ``path`` (of :attr:`graph`), as a graph and a path
        in it: ``path`` itself unless the graph holds symmetry representatives, whose path
        is mapped back step by step (:func:`~.symmetry.lift`)."""
        if self.symmetry is None or not self.symmetry.active:
            return self.graph, path
        if self._lifter is None:
            self._lifter = Machine(self.skeleton, 1, fifo=self.options.order == "fifo")
        return lift(self.symmetry, self._lifter, self.graph, path)

    @property
    def violated(self) -> list[Verdict]:
        """Properties violated in the skeleton."""
        return [v for v in self.verdicts if v.holds is False]

    @property
    def reproduced(self) -> list[Verdict]:
        """Violations whose counterexample a run of the simulator shows."""
        return [
            v
            for v in self.violated
            if v.prop.name in self.replays and self.replays[v.prop.name][1].reproduced
        ]

    def path(self, v: Verdict, state: int | None = None) -> list[int]:
        """The counterexample's states: a shortest path to the violation (``state``, by
        default the replayed one), and for a response the continuation through states
        where the answer never comes."""
        if state is None:
            state = self.replays[v.prop.name][0] if v.prop.name in self.replays else v.state
        path = self.graph.path(state)
        if v.lasso and state == v.state:
            path = path + v.lasso[1:]
        return path

    def replay(
        self,
        v: Verdict,
        seconds: float = 120.0,
        tries: int = 1000,
        progress: Callable[[int, float], None] | None = None,
    ) -> Replay:
        """Replay a counterexample of ``v`` in the simulator (:mod:`.replay`): the
        shortest first, then the shortest paths to the other violating states, in
        breadth-first order, skipping those that start like a path the simulator could
        not follow, until one is reproduced (or ``tries`` paths or ``seconds`` are
        spent). The replayed one becomes the counterexample shown. ``progress`` gets
        (paths tried, seconds) after each path not reproduced."""
        start = time.perf_counter()
        if self._context is None:
            self._context = Context(
                self.team, self.skeleton, self.graph, self.options.order == "fifo", self.concrete
            )
        failed: set[int] = set()  # last states of prefixes that failed (a breadth-first
        # tree's path to a state is unique, so its last state names a prefix)
        first: Replay | None = None
        tried = 0
        for k in [v.state, *(v.others if v.prop.kind != "response" else [])]:
            path = self.path(v, k)
            if not failed.isdisjoint(path):
                continue
            if tried >= tries or time.perf_counter() - start > seconds:
                break
            tried += 1
            r = replay_path(self._context, path, v.prop.kind, v.prop.name, v.loops)
            first = first or r
            if r.reproduced:
                self.replays[v.prop.name] = (k, r, tried)
                return r
            if r.stop >= 0:
                failed.add(path[r.stop])
            if progress is not None:
                progress(tried, time.perf_counter() - start)
        assert first is not None
        self.replays[v.prop.name] = (v.state, first, tried)
        return first

    def counterexample(self, v: Verdict) -> list[str]:
        """The counterexample in words, each step at the moment its replay gave it."""
        times = self.replays[v.prop.name][1].times if v.prop.name in self.replays else None
        if v.prop.kind != "response":
            return describe(self.skeleton, *self.concrete(self.path(v)), times=times)
        mark = (
            len(self.graph.path(v.state)) - 1,  # (a response property has its phi)
            f"     --- {v.prop.name}: '{v.prop.phi.source}' holds here; "  # type: ignore[union-attr]
            "from here on the answer never comes ---",
        )
        lines = describe(self.skeleton, *self.concrete(self.path(v)), mark, times)
        lines.append(
            "     (then round this cycle again and again)"
            if v.loops
            else "     (then nothing can happen any more)"
        )
        return lines

    def configurations(self, v: Verdict) -> list[str]:
        """The distinct mode configurations among a violation's states (first the
        counterexample's), each in words."""
        out: list[str] = []
        for k in [v.state, *v.others]:
            text = "; ".join(
                f"{ca.name} in {', '.join(m)}"
                for ca, m in zip(
                    self.skeleton.original.agents,
                    agent_leaves(self.skeleton, self.graph.states.agents_of(k)),
                    strict=True,
                )
            )
            if text not in out:
                out.append(text)
        return out

    def summary(self) -> dict:
        g = self.graph
        return {
            "states": len(g.states),
            "transitions": g.transitions,
            "exhaustive": g.exhaustive,
            "search": "partial" if g.coverage is not None else "exact",
            **({"coverage": g.coverage.summary()} if g.coverage is not None else {}),
            "bound": g.bound,
            "seconds": round(g.seconds, 3),
            "explorer": g.explorer,
            "options": {
                "losses": self.options.losses,
                "duplicates": self.options.duplicates,
                "order": self.options.order,
                "max_states": self.options.max_states,
                "max_values": self.options.max_values,
                "max_memory": memory_limit(self.options.max_memory),
                "ack_timing": self.options.ack_timing,
                "timeouts": self.options.timeouts,
                "storage": self.options.storage,
                "jobs": self.options.jobs,
                "kernel": self.options.kernel,
                **(
                    {
                        "bitstate_mb": self.options.bitstate_mb,
                        "hash_functions": self.options.hash_functions,
                    }
                    if self.options.storage == "bitstate"
                    else {}
                ),
                "symmetry": self.options.symmetry,
                "por": self.options.por,
            },
            "symmetry": None
            if self.symmetry is None
            else self.symmetry.describe([ca.name for ca in self.skeleton.original.agents]),
            "abstracted": self.skeleton.notes,
            "properties": {
                v.prop.name: {
                    "kind": v.prop.kind,
                    "formula": v.prop.text,
                    "verdict": word(v, g),
                    "message": v.message,
                    **(
                        {
                            "counterexample": self.counterexample(v),
                            "configurations": self.configurations(v),
                        }
                        if v.holds is False
                        else {}
                    ),
                    **({"replay": self._replay_summary(v)} if v.prop.name in self.replays else {}),
                }
                for v in self.verdicts
            },
        }

    def _replay_summary(self, v: Verdict) -> dict:
        _, r, tried = self.replays[v.prop.name]
        return {"verdict": r.verdict, "reason": r.reason, "paths_tried": tried, "times": r.times}


def word(v: Verdict, g: Graph) -> str:
    """A verdict in words: a property that held in a search that was not exhaustive says
    how it was not (a bound stopped it, or the search was partial)."""
    if v.holds is None:
        return "not checked"
    if v.holds is False:
        return "violated"  # in the skeleton; the replay says whether a run shows it
    if g.exhaustive:
        return "holds"
    if g.coverage is None:
        return "holds (bounded)"
    return "holds (partial search)" if g.bound is None else "holds (partial search, bounded)"


def verify(
    team,
    options: Options | None = None,
    only: list[str] | None = None,
    progress: Progress | None = None,
    replay: bool = True,
    note: Callable[[str], None] | None = None,
) -> Report:
    """Explore ``team``'s skeleton and check its properties (``only``: these names); with
    ``replay``, replay each violation's counterexample in the simulator
    (:meth:`Report.replay`); ``note`` gets what the explorer says before it starts."""
    import numpy as np

    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.world import World

    opts = options or Options()
    cteam = compile_team(team)
    raises: tuple[str, ...] = ()
    if team.world:
        params = {k: np.array([float(v)]) for k, v in team.parameters.items()}
        raises = tuple(e for c in World(team, 1, params).components for e in c.raises)
    sk = skeleton(cteam, raises)
    props = properties(sk)
    if only:
        known = [p.name for p in props]
        unknown = [name for name in only if name not in known]
        if unknown:
            raise UnknownProperty(unknown[0], known)
        props = [p for p in props if p.name in only]
        if opts.storage != "exact":
            for p in props:
                if p.kind == "response":
                    raise NotInPartialSearch(p.name, opts.storage)
    sym = symmetry(sk, props, opts.order == "fifo") if opts.symmetry == "on" else None
    por = ample(sk, props, opts) if opts.por == "ample" else None
    g = explore(
        sk,
        opts,
        progress,
        sym.representative if sym is not None and sym.active else None,
        None if por is None else por.choose,
        note,
    )
    report = Report(sk, g, check(props, sk, g), opts, team=team, symmetry=sym)
    if replay:
        for v in report.violated:
            report.replay(v)
    return report

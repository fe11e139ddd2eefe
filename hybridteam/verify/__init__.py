"""``hybridteam verify``: exhaustive checking of a team's discrete protocol logic.

Simulation samples behaviours; this explores all of them in the team's discrete skeleton
(:mod:`.abstraction`): every order of message arrivals, every loss up to a bound, every
timeout and every outcome of a guard over time or state. The engine itself computes each
step (:mod:`.machine`), so the skeleton has the simulator's semantics, not a second
reading of the model. :func:`verify` returns a :class:`Report`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hybridteam.verify.abstraction import Skeleton, skeleton
from hybridteam.verify.explore import Graph, Options, Progress, explore
from hybridteam.verify.paths import describe, leaves
from hybridteam.verify.properties import Verdict, check, properties

__all__ = ["Options", "Report", "UnknownProperty", "verify"]


class UnknownProperty(ValueError):
    """``only`` names a property the team does not have (checked before exploring)."""

    def __init__(self, name: str, known: list[str]) -> None:
        super().__init__(name)
        self.name, self.known = name, known


@dataclass
class Report:
    skeleton: Skeleton
    graph: Graph
    verdicts: list[Verdict]
    options: Options
    notes: list[str] = field(default_factory=list)

    @property
    def violated(self) -> list[Verdict]:
        return [v for v in self.verdicts if v.holds is False]

    def path(self, v: Verdict) -> list[int]:
        """The counterexample's states: a shortest path to the violation, and for a
        response the continuation through states where the answer never comes."""
        path = self.graph.path(v.state)
        if v.lasso:
            path = path + v.lasso[1:]
        return path

    def counterexample(self, v: Verdict) -> list[str]:
        if v.prop.kind != "response":
            return describe(self.skeleton, self.graph, self.path(v))
        mark = (len(self.graph.path(v.state)) - 1,
                f"     --- {v.prop.name}: '{v.prop.phi.source}' holds here; "  # type: ignore
                "from here on the answer never comes ---")
        lines = describe(self.skeleton, self.graph, self.path(v), mark)
        lines.append("     (then round this cycle again and again)" if v.loops else
                     "     (then nothing can happen any more)")
        return lines

    def configurations(self, v: Verdict) -> list[str]:
        """The distinct mode configurations among a violation's states (first the
        counterexample's), each in words."""
        out: list[str] = []
        for k in [v.state, *v.others]:
            text = "; ".join(f"{ca.name} in {', '.join(m)}" for ca, m in zip(
                self.skeleton.original.agents, leaves(self.skeleton, self.graph.states[k]),
                strict=True))
            if text not in out:
                out.append(text)
        return out

    def summary(self) -> dict:
        g = self.graph
        return {
            "states": len(g.states), "transitions": g.transitions,
            "exhaustive": g.exhaustive, "seconds": round(g.seconds, 3),
            "options": {"losses": self.options.losses,
                        "duplicates": self.options.duplicates,
                        "order": self.options.order, "max_states": self.options.max_states,
                        "ack_timing": self.options.ack_timing,
                        "timeouts": self.options.timeouts},
            "abstracted": self.skeleton.notes,
            "properties": {v.prop.name: {
                "kind": v.prop.kind, "formula": v.prop.text,
                "verdict": _word(v, g.exhaustive), "message": v.message,
                **({"counterexample": self.counterexample(v),
                    "configurations": self.configurations(v)} if v.holds is False else {})}
                for v in self.verdicts},
        }


def _word(v: Verdict, exhaustive: bool) -> str:
    if v.holds is None:
        return "not checked"
    if v.holds is False:
        return "violated"
    return "holds" if exhaustive else "holds so far (bounded)"


def verify(team, options: Options | None = None, only: list[str] | None = None,
           progress: Progress | None = None) -> Report:
    """Explore ``team``'s skeleton and check its properties (``only``: these names)."""
    import numpy as np

    from hybridteam.engine.compiler import compile_team
    from hybridteam.engine.world import World

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
    g = explore(sk, opts, progress)
    return Report(sk, g, check(props, sk, g), opts)

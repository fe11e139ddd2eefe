"""The signals a team's requirements may read, and how each is fetched from a run.

Built once per team from its compiled form (agents, states, parameters, modes, roles,
message types) and the world's sampled series. Every name a formula uses is resolved
here at load time, so a requirement that compiles cannot fail on a name after a run;
each getter reads the run's :class:`~hybridteam.requirements.signals.Signals`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from hybridteam.engine.compile.compiler import message_fields
from hybridteam.engine.compile.scope import resolve_mode
from hybridteam.errors import did_you_mean

Getter = Callable[[Any], Any]
Problem = tuple[str, str | None]


@dataclass
class AgentNames:
    state: list[str]
    params: list[str]
    variables: list[str]
    modes: list[str]  # paths, index = mode index (0 is the root, "")
    roles: dict[str, list[int]] = field(default_factory=dict)  # role -> mode indices


@dataclass
class Catalog:
    agents: dict[str, AgentNames]
    team_params: list[str]
    series: dict[str, list[str]]
    messages: set[str]
    used_events: set[str] = field(default_factory=set)  # message types formulas read

    @classmethod
    def of(cls, cteam: Any, series: Mapping[str, Any]) -> Catalog:
        agents = {}
        for ca in cteam.agents:
            roles: dict[str, list[int]] = {}
            for m in ca.modes:
                if m.role:
                    roles.setdefault(m.role, []).append(m.index)
            agents[ca.name] = AgentNames(
                list(ca.plant.state_names),
                list(ca.param_index),
                list(ca.var_index),
                [m.path for m in ca.modes],
                roles,
            )
        messages = set(message_fields(cteam.team))
        for agent in cteam.team.agents:
            messages.update(s.message for s in agent.streams)
        return cls(
            agents, list(cteam.team.parameters), {k: list(v) for k, v in series.items()}, messages
        )

    # -- bare names -----------------------------------------------------------------------
    def single(self) -> str | None:
        return next(iter(self.agents)) if len(self.agents) == 1 else None

    def bare_symbols(self) -> dict[str, Getter]:
        syms: dict[str, Getter] = {"t": lambda s: s.t}
        for p in self.team_params:
            syms[p] = lambda s, p=p: s.team_param(p)  # type: ignore[misc]  # default-bound lambda
        one = self.single()
        if one is not None:
            names = self.agents[one]
            for p in names.params:
                syms[p] = lambda s, p=p, a=one: s.param(a, p)  # type: ignore[misc]  # default-bound lambda
            for j, x in enumerate(names.state):
                syms[x] = lambda s, j=j, a=one: s.state(a, j)  # type: ignore[misc]  # default-bound lambda
            for j, v in enumerate(names.variables):
                syms[v] = lambda s, j=j, a=one: s.variable(a, j)  # type: ignore[misc]  # default-bound lambda
        return syms

    def is_variable(self, text: str) -> bool:
        """Whether ``agent.name`` (or a bare name in a one-agent team) is a discrete
        variable: a signal that jumps at instants rather than moving continuously."""
        head, _, tail = text.rpartition(".")
        if not head:
            head = self.single() or ""
        return head in self.agents and tail in self.agents[head].variables

    def bare_hint(self, name: str) -> str | None:
        owners = [
            a
            for a, n in self.agents.items()
            if name in n.state or name in n.params or name in n.variables
        ]
        if owners:
            return f"name the agent: {owners[0]}.{name}"
        return did_you_mean(name, [*self.agents, *self.team_params, "t"])

    # -- agent.name, series.column ----------------------------------------------------------
    def dotted(self, text: str) -> tuple[Getter | None, Problem]:
        head, _, tail = text.partition(".")
        if head in self.agents:
            names = self.agents[head]
            if tail in names.state:
                j = names.state.index(tail)
                return (lambda s: s.state(head, j)), ("", None)
            if tail in names.params:
                return (lambda s: s.param(head, tail)), ("", None)
            if tail in names.variables:
                j = names.variables.index(tail)
                return (lambda s: s.variable(head, j)), ("", None)
            return None, (
                f"agent '{head}' has no state, parameter or variable '{tail}'",
                did_you_mean(tail, [*names.state, *names.params, *names.variables])
                or f"its states: {', '.join(names.state) or 'none'}",
            )
        if head in self.series:
            cols = self.series[head]
            if tail in cols:
                j = cols.index(tail)
                return (lambda s: s.series(head, j)), ("", None)
            return None, (
                f"series '{head}' has no column '{tail}'",
                f"its columns: {', '.join(cols)}",
            )
        return None, (
            f"unknown signal '{text}'",
            did_you_mean(head, [*self.agents, *self.series])
            or "write agent.state, agent.parameter or payload.column",
        )

    # -- in_mode(...), count_in_role(...), received(...) -------------------------------------
    def function(
        self, name: str, args: list[tuple[str, int, int]]
    ) -> tuple[Getter | None, tuple[int, int, str, str | None]]:
        if len(args) == 2 or (name in ("in_mode", "in_role") and len(args) == 1):
            if len(args) == 1:
                one = self.single()
                if one is None:
                    _, s, e = args[0]
                    return None, (
                        s,
                        e,
                        f"{name}() needs the agent in a team of {len(self.agents)}",
                        f"e.g. {name}({next(iter(self.agents))}, {args[0][0]})",
                    )
                agent, rest = one, args[0]
            else:
                (agent, s, e), rest = args[0], args[1]
                if agent not in self.agents:
                    return None, (
                        s,
                        e,
                        f"unknown agent '{agent}'",
                        did_you_mean(agent, self.agents),
                    )
            return self._agent_function(name, agent, rest)
        return self._team_function(name, args[0])

    def _agent_function(self, name: str, agent: str, arg: tuple[str, int, int]):
        what, s, e = arg
        names = self.agents[agent]
        if name == "in_mode":
            idx, matches = resolve_mode(what, names.modes)
            if idx is None:
                return None, (s, e, self._mode_problem(agent, what, matches), None)
            return (lambda sig: sig.in_modes(agent, [idx])), (0, 0, "", None)
        if name == "in_role":
            if what not in names.roles:
                return None, (
                    s,
                    e,
                    f"agent '{agent}' has no role '{what}'",
                    f"its roles: {', '.join(names.roles) or 'none'}",
                )
            modes = names.roles[what]
            return (lambda sig: sig.in_modes(agent, modes)), (0, 0, "", None)
        return self._event(name, agent, arg)

    def _team_function(self, name: str, arg: tuple[str, int, int]):
        what, s, e = arg
        if name in ("received", "sent"):
            return self._event(name, None, arg)
        found: dict[str, list[int]] = {}
        for agent, names in self.agents.items():
            if name == "count_in_mode":
                idx, _ = resolve_mode(what, names.modes)
                if idx is not None:
                    found[agent] = [idx]
            elif what in names.roles:
                found[agent] = names.roles[what]
        if not found:
            kind = "mode" if name == "count_in_mode" else "role"
            return None, (s, e, f"no agent has a {kind} '{what}'", None)
        return (lambda sig: sum(sig.in_modes(a, m).astype(float) for a, m in found.items())), (
            0,
            0,
            "",
            None,
        )

    def _event(self, name: str, agent: str | None, arg: tuple[str, int, int]):
        what, s, e = arg
        if what not in self.messages:
            return None, (
                s,
                e,
                f"unknown message type '{what}'",
                did_you_mean(what, self.messages)
                or f"the team's messages: {', '.join(sorted(self.messages))}",
            )
        self.used_events.add(what)
        return (lambda sig: sig.event(name, agent, what)), (0, 0, "", None)

    def _mode_problem(self, agent: str, what: str, matches: list[str]) -> str:
        if matches:
            return f"mode '{what}' of '{agent}' is ambiguous: {', '.join(matches)}"
        hint = did_you_mean(what, [p for p in self.agents[agent].modes if p])
        return f"agent '{agent}' has no mode '{what}'" + (f"; {hint}" if hint else "")

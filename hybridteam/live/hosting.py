"""What one live process runs of a team: its own agents, and the others held inert.

A process compiles the whole team (agent indices, message senders and addressees, the
trace's modes are the team's) and runs the agents it hosts with the engine's semantics.
Every other agent is *remote*: its behaviour happens in its own process and reaches this
one only as datagrams. Here it keeps its place but does nothing: no transition can fire
(none is a candidate, no mode has an outgoing one, so no ``after:`` deadline is set), no
guard or invariant is watched, no stream sends, no law drives its plant (the zero input),
and no scenario event is delivered to it. The end rule is the team's over the hosted
agents.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection

import numpy as np

from hybridteam.engine.compile.compiled import CAgent, CTeam


class HostingError(ValueError):
    """A team or a choice of agents that a live process cannot run (one line)."""


def hosted_team(cteam: CTeam, here: Collection[str]) -> CTeam:
    """``cteam`` as a process hosting the agents named ``here`` runs it."""
    names = [ca.name for ca in cteam.agents]
    for name in here:
        if name not in names:
            raise HostingError(
                f"--agent '{name}' is not an agent of the team (its agents: {', '.join(names)})"
            )
    hosted = {names.index(name) for name in here}
    ending = [a for a in cteam.ending if a in hosted]
    team = cteam.team
    if ending != cteam.ending:  # the rule's agents here: what the outcome's message names
        team = dataclasses.replace(
            team, end=dataclasses.replace(team.end, agents=tuple(names[a] for a in ending))
        )
    return dataclasses.replace(
        cteam,
        team=team,
        agents=[ca if ca.index in hosted else inert(ca) for ca in cteam.agents],
        scenario=[s for s in cteam.scenario if s[1] in hosted],
        ending=ending,
        # none of the end rule's agents here: the rule never holds in this process (an
        # empty "all of them" would hold at once)
        end_any=cteam.end_any if ending else True,
    )


def inert(ca: CAgent) -> CAgent:
    """A remote agent as a process that does not host it holds it (module docstring)."""
    count = len(ca.modes)
    return dataclasses.replace(
        ca,
        modes=[
            dataclasses.replace(m, invariant=None, invariant_text="", outgoing=[]) for m in ca.modes
        ],
        eventless=[],
        triggered={},
        after=[],
        watches=[],
        driver_modes=[],
        streams=[],
        has_eventless=np.zeros(count, bool),
        has_triggered=np.zeros(count, bool),
    )

"""The engine's side of :class:`~hybridteam.world.access.WorldAccess`: a component's window
on the ensemble.

Column rules live here once: a pose is found by state *name* (x, y, theta) for every plant,
parameters and variables by name through the compiled agent's indexes. Events a component
raises go into the event queue at the instance's current time and are remembered, so the
engine knows whose discrete phase must run without the component having to say.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hybridteam.arrays import NO_INDEX, every
from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.events import LOCAL
from hybridteam.errors import did_you_mean
from hybridteam.world.access import Agent, Message, WorldAccess
from hybridteam.world.component import WorldComponent

#: :meth:`EnsembleAccess.sensing`'s answers for one instance (read-only: shared)
_YES, _NO = np.ones(1, bool), np.zeros(1, bool)
_YES.flags.writeable = _NO.flags.writeable = False


class EnsembleAccess(WorldAccess):
    """:class:`WorldAccess` over one :class:`Ensemble`."""

    def __init__(self, ens: Ensemble) -> None:
        self._ens = ens
        self.n = ens.n
        self.agents = tuple(ca.name for ca in ens.cteam.agents)
        self._index = {name: i for i, name in enumerate(self.agents)}
        self._pose_cols: list[tuple[int, int, int | None] | None] = []
        for ca in ens.cteam.agents:
            names = ca.plant.state_names
            self._pose_cols.append(
                (
                    names.index("x"),
                    names.index("y"),
                    names.index("theta") if "theta" in names else None,
                )
                if "x" in names and "y" in names
                else None
            )
        self._raised: list[np.ndarray] = []

    # ------------------------------------------------------------------ time and runs
    @property
    def t(self) -> np.ndarray:
        view = self._ens.t.view()
        view.flags.writeable = False
        return view

    def live(self, idx: np.ndarray) -> np.ndarray:
        """The instances of ``idx`` not ended. Where none has ended anywhere (a single run's
        every instant), ``idx`` itself, read-only: a component cannot write the engine's
        index through it."""
        live = self._ens.live(idx)
        if live is not idx or live is self._ens.everyone:  # (everyone is read-only)
            return live
        view = idx.view()
        view.flags.writeable = False
        return view

    def finish(self, idx: np.ndarray, outcome: str, message: Message) -> None:
        text = message if callable(message) else (lambda i, m=message: m)
        self._ens.finish(np.asarray(idx, np.intp), outcome, text)

    def raise_event(self, idx: np.ndarray, agent: Agent, event: str) -> None:
        idx = np.asarray(idx, np.intp)
        if idx.size:
            self._ens.queue.push(idx, self._ens.t[idx], LOCAL, self.agent(agent), event)
            self._raised.append(idx)

    def take_raised(self) -> np.ndarray:
        """Instances where events were raised or variables written since the last call:
        their discrete phase runs now (for the engine)."""
        if not self._raised:
            return NO_INDEX
        out = np.unique(np.concatenate(self._raised))
        self._raised.clear()
        return out

    def sensing(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        """Law ticks due now (``t >= next_tick``, the comparison the laws' sampling makes
        just after the world), and every instant where no tick is scheduled: before the
        first sampling and under a law with no period (``next_tick`` infinite).

        Asked by every component at every instant, mostly where only a copy arrived: a
        single instance's answer is compared on Python floats (the same comparison) and
        is one of two shared read-only rows."""
        a = agent if type(agent) is int and 0 <= agent < len(self.agents) else self.agent(agent)
        next_tick = self._ens.states[a].next_tick
        if idx.size == 1:
            i = idx.item(0)
            tick = next_tick.item(i)
            return _YES if self._ens.t.item(i) >= tick or tick == math.inf else _NO
        tick = next_tick[idx]
        return (self._ens.t[idx] >= tick) | (tick == np.inf)

    # ------------------------------------------------------------------ agents
    def agent(self, name: Agent) -> int:
        if isinstance(name, int | np.integer) and not isinstance(name, bool):
            if 0 <= name < len(self.agents):
                return int(name)
            raise ValueError(f"no agent {name} (the team has {len(self.agents)})")
        if name in self._index:
            return self._index[name]
        hint = did_you_mean(str(name), self.agents)
        raise ValueError(
            f"unknown agent '{name}' (agents: {', '.join(self.agents)})"
            + (f"; {hint}" if hint else "")
        )

    def state_names(self, agent: Agent) -> tuple[str, ...]:
        return tuple(self._ens.cteam.agents[self.agent(agent)].plant.state_names)

    def state(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        return self._ens.states[self.agent(agent)].x[idx].copy()

    def set_state(
        self, agent: Agent, idx: np.ndarray, values: np.ndarray, names: Sequence[str] | None = None
    ) -> None:
        a = self.agent(agent)
        st = self._ens.states[a]
        cols = (
            list(range(st.x.shape[1]))
            if names is None
            else [self._column(a, st.ca.state_index, n, "state") for n in names]
        )
        st.x[np.ix_(np.asarray(idx, np.intp), np.asarray(cols, np.intp))] = values
        self._ens.reconfigured[idx] = True  # watched truths are read afresh there

    def has_pose(self, agent: Agent) -> bool:
        return self._pose_cols[self.agent(agent)] is not None

    def pose(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        a = self.agent(agent)
        cols = self._pose_cols[a]
        if cols is None:
            raise ValueError(
                f"agent '{self.agents[a]}' has no position: its plant state is "
                f"{', '.join(self.state_names(a)) or 'empty'} (no x and y)"
            )
        x, y, th = cols
        s = self._ens.states[a].x
        if cols == (0, 1, 2):  # a unicycle's or a holonomic base's state: one gather
            return s.take(idx, 0)[:, :3]  # s[idx, :3] (see arrays.gather)
        if th is not None:
            return s.take(idx, 0).take([x, y, th], 1)
        out = np.zeros((len(idx), 3))
        out[:, 0], out[:, 1] = s[:, x][idx], s[:, y][idx]
        return out

    def variable_names(self, agent: Agent) -> tuple[str, ...]:
        return tuple(self._ens.cteam.agents[self.agent(agent)].var_index)

    def variable(self, agent: Agent, name: str, idx: np.ndarray) -> np.ndarray:
        a = self.agent(agent)
        st = self._ens.states[a]
        return st.v[:, self._column(a, st.ca.var_index, name, "variable")][idx]

    def set_variable(
        self, agent: Agent, name: str, idx: np.ndarray, values: np.ndarray | float
    ) -> None:
        """What :func:`~hybridteam.engine.run.discrete.fire` does for an assignment: the rows'
        values as floats, and the instances marked changed and reconfigured (their watched
        truths are read afresh); they are remembered with the raised events, so their
        discrete phase runs at this instant."""
        a = self.agent(agent)
        st = self._ens.states[a]
        col = self._column(a, st.ca.var_index, name, "variable")
        idx = np.asarray(idx, np.intp)
        value = np.broadcast_to(np.asarray(values, float), idx.shape)
        live = ~self._ens.done[idx]
        if not every(live):
            idx, value = idx[live], value[live]
        if not every(np.isfinite(value)):
            k = int(np.flatnonzero(~np.isfinite(value))[0])
            raise ValueError(
                f"set_variable: '{self.agents[a]}.{name}' would be {value[k]} "
                f"in instance {int(idx[k])}; a variable is a finite number"
            )
        if idx.size:
            st.v[:, col][idx] = value
            self._ens.changed[idx] = True
            self._ens.reconfigured[idx] = True
            self._raised.append(idx)

    def parameter_names(self, agent: Agent) -> tuple[str, ...]:
        return tuple(self._ens.cteam.agents[self.agent(agent)].param_index)

    def parameter(self, agent: Agent, name: str, idx: np.ndarray | None = None) -> np.ndarray:
        a = self.agent(agent)
        st = self._ens.states[a]
        col = self._column(a, st.ca.param_index, name, "parameter")
        return st.p[:, col].copy() if idx is None else st.p[:, col][idx]

    def _column(self, a: int, index: dict[str, int], name: str, what: str) -> int:
        if name in index:
            return index[name]
        hint = did_you_mean(name, index)
        raise ValueError(
            f"agent '{self.agents[a]}' has no {what} '{name}' (its {what}s: "
            f"{', '.join(index) or 'none'})" + (f"; {hint}" if hint else "")
        )

    # ------------------------------------------------------------------ the world
    def components(self, kind: type | str | None = None) -> list[WorldComponent]:
        found = self._ens.world.components
        if kind is None:
            return list(found)
        if isinstance(kind, str):
            return [c for c in found if c.name == kind]
        return [c for c in found if isinstance(c, kind)]

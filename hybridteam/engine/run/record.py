"""Collects what the engine does, in vectorized chunks, and assembles the :class:`Trace`.

The engine records whole groups of instances at a time (``instances`` is an index array);
rows are only materialized once, at the end, and sorted stably by instance so an instance's
rows come out in the order it produced them, whatever its neighbours did.
"""

from __future__ import annotations

from itertools import chain
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.trace import (
    INTERVAL_COLUMNS,
    MESSAGE_COLUMNS,
    TRANSITION_COLUMNS,
    Table,
)
from hybridteam.world.scene import Footprint

if TYPE_CHECKING:
    from hybridteam.engine.run.world import World


class Recorder:
    def __init__(self, cteam: CTeam, n: int, sample_times: np.ndarray) -> None:
        self.cteam = cteam
        self.n = n
        self._transitions: list[tuple] = []
        self._intervals: list[tuple] = []
        #: one tuple per message copy, in the order of :data:`MESSAGE_COLUMNS`
        self._messages: list[tuple] = []
        self._names = [a.name for a in cteam.agents]
        self.sample_times = sample_times
        self.samples = {
            a.name: np.full((len(sample_times), n, len(a.plant.state_names)), np.nan)
            for a in cteam.agents
        }
        #: None, or (instances, t, {series: values}) at every instant (``snapshots=True``)
        self.snapshots: list[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]] | None = None

    def add_series(self, series: dict[str, tuple[str, ...]]) -> None:
        """Sample series besides the agents' states (a payload's pose, from the world)."""
        for name, columns in series.items():
            self.samples[name] = np.full((len(self.sample_times), self.n, len(columns)), np.nan)

    # the engine calls these with index arrays ------------------------------------------
    def transition(
        self,
        agent: int,
        index: int,
        instances: np.ndarray,
        t: np.ndarray,
        step: np.ndarray,
        cause: str,
    ) -> None:
        self._transitions.append((agent, index, instances.copy(), t.copy(), step.copy(), cause))

    def initial(self, agent: int, mode: int, instances: np.ndarray, t: np.ndarray) -> None:
        self._transitions.append(
            (
                agent,
                -1 - mode,
                instances.copy(),
                t.copy(),
                np.zeros(len(instances), np.int64),
                "init",
            )
        )

    def interval(
        self, agent: int, mode: int, instances: np.ndarray, start: np.ndarray, end: np.ndarray
    ) -> None:
        self._intervals.append((agent, mode, instances.copy(), start.copy(), end.copy()))

    def message(
        self,
        instances: np.ndarray,
        seq: np.ndarray,
        sender: int,
        receiver: int,
        socket: str,
        kind: str,
        t_send: np.ndarray,
        t_recv: np.ndarray,
        status: str,
        reason: str = "",
        msg_id: np.ndarray | None = None,
    ) -> None:
        """One row per copy. ``msg_id`` identifies an acknowledged message across its
        retransmissions (-1 for plain datagrams)."""
        k = len(instances)
        ids = [-1] * k if msg_id is None else msg_id.tolist()
        names = self._names
        self._messages.extend(
            zip(
                instances.tolist(),
                seq.tolist(),
                [names[sender]] * k,
                [names[receiver]] * k,
                [socket] * k,
                [kind] * k,
                t_send.tolist(),
                t_recv.tolist(),
                [status] * k,
                [reason] * k,
                ids,
                strict=True,
            )
        )

    def message_row(
        self,
        i: int,
        seq: int,
        sender: int,
        receiver: int,
        socket: str,
        kind: str,
        t_send: float,
        t_recv: float,
        status: str,
        reason: str,
        msg_id: int,
    ) -> None:
        """:meth:`message` for one copy, from plain numbers: every arrival is recorded
        alone, and arrays for one copy cost more than the rest of its receipt."""
        names = self._names
        self._messages.append(
            (
                i,
                seq,
                names[sender],
                names[receiver],
                socket,
                kind,
                t_send,
                t_recv,
                status,
                reason,
                msg_id,
            )
        )

    def snapshot(self, instances: np.ndarray, t: np.ndarray, values: dict[str, np.ndarray]) -> None:
        assert self.snapshots is not None
        if instances.size and values:
            self.snapshots.append(
                (
                    instances.copy(),
                    t.copy(),
                    {k: np.array(v, dtype=float) for k, v in values.items()},
                )
            )

    def merged_snapshots(self) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per series: (instances, times, values), in the order they were taken."""
        out: dict[str, list] = {}
        for inst, t, values in self.snapshots or []:
            for name, v in values.items():
                out.setdefault(name, []).append((inst, t, v.reshape(len(inst), -1)))
        return {
            name: (
                np.concatenate([p[0] for p in parts]),
                np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]),
            )
            for name, parts in out.items()
        }

    def sample(self, k: np.ndarray, instances: np.ndarray, agent: str, x: np.ndarray) -> None:
        if k.size == 1:  # a single run's sample: no masks
            self.sample_one(int(k[0]), int(instances[0]), agent, x[0])
            return
        ok = k < len(self.sample_times)
        self.samples[agent][k[ok], instances[ok]] = x[ok]

    def sample_one(self, k: int, instance: int, agent: str, row: np.ndarray) -> None:
        """Sample ``k`` of one instance (none past the last sample time)."""
        if k < len(self.sample_times):
            self.samples[agent][k, instance] = row

    # assembly ---------------------------------------------------------------------------
    def _transition_table(self) -> Table:
        cols: dict[str, list[Any]] = {c: [] for c in TRANSITION_COLUMNS}
        agents = self.cteam.agents
        for agent, index, inst, t, step, cause in self._transitions:
            ca = agents[agent]
            if index < 0:
                source, target, guard = "", ca.modes[-1 - index].path, ""
            else:
                tr = ca.transitions[index]
                source, target, guard = (
                    ca.modes[tr.source].path,
                    ca.modes[tr.target].path,
                    tr.guard_text,
                )
            k = len(inst)
            cols["instance"].append(inst)
            cols["agent"].append([ca.name] * k)
            cols["t"].append(t)
            cols["step"].append(step)
            cols["source"].append([source] * k)
            cols["target"].append([target] * k)
            cols["cause"].append([cause] * k)
            cols["guard"].append([guard] * k)
        return _sorted(TRANSITION_COLUMNS, cols)

    def _interval_table(self) -> Table:
        cols: dict[str, list[Any]] = {c: [] for c in INTERVAL_COLUMNS}
        agents = self.cteam.agents
        for agent, mode, inst, start, end in self._intervals:
            m = agents[agent].modes[mode]
            k = len(inst)
            cols["instance"].append(inst)
            cols["agent"].append([agents[agent].name] * k)
            cols["mode"].append([m.path] * k)
            cols["depth"].append(np.full(k, m.depth))
            cols["start"].append(start)
            cols["end"].append(end)
        return _sorted(INTERVAL_COLUMNS, cols)

    def _message_table(self) -> Table:
        # the rows are kept as tuples, in the order recorded: one transposition makes the
        # columns (a chunk of arrays per copy cost a seventh of a streaming run to flatten)
        if not self._messages:
            return Table(MESSAGE_COLUMNS)
        columns = zip(MESSAGE_COLUMNS, zip(*self._messages, strict=True), strict=True)
        return _sorted(MESSAGE_COLUMNS, {c: [values] for c, values in columns})

    def tables(self) -> tuple[Table, Table, Table]:
        return self._transition_table(), self._interval_table(), self._message_table()


def variables_key(agent: str) -> str:
    """The snapshot series of an agent's discrete variables ('#' is in no model name)."""
    return f"{agent}#variables"


def _plain(chunk: Any) -> list:
    """A chunk of a numeric column as a list of Python numbers."""
    return chunk.tolist() if isinstance(chunk, np.ndarray) else chunk


def _sorted(names: tuple[str, ...], cols: dict[str, list[Any]]) -> Table:
    if not cols["instance"]:
        return Table(names)
    flat = {}
    for name, chunks in cols.items():
        if name in (
            "instance",
            "t",
            "step",
            "depth",
            "start",
            "end",
            "seq",
            "t_send",
            "t_recv",
            "msg_id",
        ):
            # one list of Python numbers, then one array: a message's row is recorded
            # alone (:meth:`Recorder.message_row`), and an array per one-number chunk cost
            # a seventh of a streaming run; the numbers, and their promotion, are the same
            flat[name] = np.array(list(chain.from_iterable(map(_plain, chunks))))
        else:
            flat[name] = np.array(list(chain.from_iterable(chunks)), dtype=object)
    order = np.argsort(flat["instance"], kind="stable")
    return Table(names, {n: c[order] for n, c in flat.items()})


def trace_meta(
    cteam: CTeam, n: int, seed: int | list[int], t_end: float, world: World
) -> dict[str, Any]:
    """The trace's ``meta``: the team's agents and modes, and what the world components
    tell the views (walls, payloads, robot footprints, extra sample series)."""
    meta: dict[str, Any] = {
        "team": cteam.team.name,
        "n": n,
        "seed": seed,
        "duration": t_end,
        "agents": [
            {
                "name": ca.name,
                "plant": ca.plant.kind,
                "state": list(ca.plant.state_names),
                "inputs": list(ca.plant.input_names),
                "modes": [
                    {
                        "path": m.path,
                        "depth": m.depth,
                        "kind": m.kind,
                        "final": m.final,
                        **({"role": m.role} if m.role else {}),
                    }
                    for m in ca.modes
                    if m.index
                ],
            }
            for ca in cteam.agents
        ],
    }
    extra = world.meta()
    footprints = extra.pop("footprints", {})
    declared = {a.name: a for a in cteam.team.agents}
    for a in meta["agents"]:
        preset = declared[a["name"]].preset
        if a["name"] in footprints:
            a["footprint"] = footprints[a["name"]]
        elif preset is not None:  # no component drew it: the robot model's disk
            a["footprint"] = Footprint(preset.footprint.radius).to_meta()
    meta["series"] = {k: list(v) for k, v in world.sample_series().items()}
    meta.update(extra)
    return meta

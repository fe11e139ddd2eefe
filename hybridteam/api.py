"""The Python API: ``load`` a team, ``simulate`` it, read the :class:`Run`.

>>> import hybridteam as ht
>>> team = ht.load("examples/automata/bouncing_ball.yaml")
>>> run = ht.simulate(team, duration=2.0)
>>> run.outcome, len(run.transitions)
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.costs import Costs
from hybridteam.engine.run.simulator import Simulator
from hybridteam.model import Team
from hybridteam.requirements.check import RequirementSet, compile_requirements
from hybridteam.trace import Table, Trace


class Run(Trace):
    """The result of :func:`simulate`: a :class:`~hybridteam.trace.Trace` with conveniences.

    For an ensemble (``n > 1``) every table has an ``instance`` column;
    :meth:`instance` gives the run of one instance as if it had been simulated alone.
    """

    #: What the crossing search cost in the simulation that made this run (true steps,
    #: flips located; :class:`~hybridteam.engine.run.costs.Costs`), as scipy's ``nfev``
    #: tells a ``solve_ivp`` result's. None for a run read back or taken apart (its
    #: instances): only :func:`simulate` counts. Not part of the trace or its files.
    costs: Costs | None = None

    @property  # type: ignore[override]  # Trace's is the list of outcome records
    def outcomes(self) -> list[str]:
        return [o["outcome"] for o in self._outcomes]

    @outcomes.setter
    def outcomes(self, value: list[dict[str, Any]]) -> None:
        self._outcomes = value

    @property
    def diagnostics(self) -> list[dict[str, Any]]:
        """Per instance: outcome, time and a message naming agent, mode, guard."""
        return self._outcomes

    @property
    def outcome(self) -> str:
        if self.n != 1:
            raise ValueError(
                f"this run has n={self.n} instances: use run.outcomes or run.instance(i).outcome"
            )
        return self._outcomes[0]["outcome"]

    @property
    def message(self) -> str:
        return self.diagnostics[0]["message"] if self.n == 1 else ""

    @property
    def modes(self) -> Table:
        """The interval table, one row per stay in a mode (``modes.csv``): the same table
        as ``intervals``, under the name of its file."""
        return self.intervals

    def to_pandas(self) -> dict[str, Any]:
        """Every table as a pandas DataFrame: ``modes``, ``transitions``, ``messages``,
        ``samples`` (tidy: instance, t, series, variable, value) and ``outcomes``."""
        from hybridteam.frames import run_frames

        return run_frames(self)

    def samples_frame(self, wide: bool = False) -> Any:
        """The samples as a DataFrame: tidy, or ``wide`` (a column per series.variable)."""
        from hybridteam.frames import samples_frame

        return samples_frame(self, wide)

    def to_bag(self, path: str | os.PathLike, format: str | None = None, instance: int = 0) -> Any:
        """Write instance ``instance`` as a rosbag2 (``run.mcap``, ``run.db3`` or a bag
        folder; see docs/logs.md). Needs ``pip install 'hybridteam[logs]'``."""
        from hybridteam.logs.export import write_bag

        return write_bag(self, path, format, instance)

    @classmethod
    def from_bag(
        cls, path: str | os.PathLike, team: Team, mapping: str | os.PathLike | None = None
    ) -> Run:
        """The run a rosbag2 recorded of ``team`` (topics as ``mapping`` names them, by
        default those :meth:`to_bag` writes)."""
        from hybridteam.logs.bag import read_bag

        return read_bag(path, team, mapping)

    def __repr__(self) -> str:
        counts = f"{len(self.transitions)} transitions, {len(self.messages)} messages"
        if self.n == 1:
            o = self._outcomes[0]
            return f"<Run of {self.meta['team']!r}: {o['outcome']} at t={o['t']:g}, {counts}>"
        shown = ", ".join(f"{k}: {v}" for k, v in self.tally().items())
        return f"<Run of {self.meta['team']!r}: {self.n} instances ({shown}), {counts}>"

    def _repr_html_(self) -> str:
        """In Jupyter: the outcome of each instance (the first 20) and the timeline of the
        first, drawn inline."""
        from hybridteam.notebook import run_html

        return run_html(self)

    def tally(self) -> dict[str, int]:
        """How many instances ended with each outcome, in order of first appearance."""
        return dict(Counter(self.outcomes))

    @classmethod
    def of(cls, trace: Trace) -> Run:
        """The run a simulator's trace records."""
        return cls(
            trace.meta,
            trace.outcomes,
            trace.transitions,
            trace.intervals,
            trace.messages,
            trace.sample_times,
            trace.samples,
        )

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["outcomes"] = self._outcomes
        return d

    def instance(self, i: int) -> Run:
        """Instance ``i`` of an ensemble as a single run (instance numbers reset to 0)."""
        if not 0 <= i < self.n:
            raise IndexError(f"instance {i} out of range 0..{self.n - 1}")

        def pick(table: Table) -> Table:
            sub = table.filter(table["instance"] == i)
            sub.columns["instance"] = np.zeros(len(sub), np.int64)
            return sub

        meta = dict(self.meta, n=1)
        if isinstance(meta.get("seed"), list):  # per-instance seeds: this instance's own
            meta["seed"] = meta["seed"][i]
        outcome = dict(self._outcomes[i], instance=0)
        return Run(
            meta,
            [outcome],
            pick(self.transitions),
            pick(self.intervals),
            pick(self.messages),
            self.sample_times.copy(),
            {a: s[:, i : i + 1].copy() for a, s in self.samples.items()},
        )

    def summary(self) -> dict[str, Any]:
        """Counts per instance, for ``summary.json`` and the terminal."""
        counts = np.bincount(
            np.asarray(self.transitions["instance"], dtype=np.int64), minlength=self.n
        )
        msgs = np.bincount(np.asarray(self.messages["instance"], dtype=np.int64), minlength=self.n)
        seeds = self.meta["seed"]
        per = []
        for i, o in enumerate(self._outcomes):
            per.append(
                {
                    "instance": i,
                    "outcome": o["outcome"],
                    "t_end": o["t"],
                    "message": o["message"],
                    "transitions": int(counts[i]),
                    "messages": int(msgs[i]),
                    **o.get("stats", {}),
                }
            )
            if "requirements" in o:
                per[-1]["requirements"] = o["requirements"]
            if isinstance(seeds, list):  # per-instance seeds: say which one each ran with
                per[-1]["seed"] = seeds[i]
        tally = self.tally()
        return {
            "team": self.meta["team"],
            "n": self.n,
            "seed": self.meta["seed"],
            "duration": self.meta["duration"],
            "outcomes": tally,
            "instances": per,
        }


def load(path: str | os.PathLike) -> Team:
    """Load and validate a team file (raises ``InputErrors`` with file:line messages)."""
    from hybridteam.io.loader import load_team

    return load_team(path)


def simulate(
    team: Team,
    seed: int | Sequence[int] | None = None,
    n: int = 1,
    duration: float | None = None,
    overrides: Mapping[str, float | Sequence[float]] | None = None,
    progress: Callable[[float], None] | None = None,
    *,
    max_memory: float | None = None,
    max_periods: float | None = None,
    max_wall: float | None = None,
    written: bool = False,
) -> Run:
    """Simulate ``n`` instances of ``team`` in lockstep and return the :class:`Run`.

    ``overrides`` maps ``"agent.param"`` (or a team parameter ``"param"``, or a network
    setting ``"network.jitter"``, see :mod:`hybridteam.engine.run.overrides`) to one value or
    to ``n`` values, one per instance — that is how an ensemble varies. ``seed`` defaults to
    the team's ``simulation.seed``; it may also be ``n`` seeds, one per instance, and
    instance ``i`` then draws exactly what a single run with ``seed[i]`` draws (how a
    parameter study packs runs with their own seeds into one ensemble). The trace's
    ``meta["seed"]`` is then that list. A run that would need more than ``max_memory``
    bytes (default 4 GB) or ``max_periods`` control periods per instance (default 1e8)
    raises :class:`~hybridteam.engine.run.budget.ResourceError` before allocating anything;
    one whose pace projects more than ``max_wall`` seconds (default 24 h) raises it once it
    has run a few seconds. ``written``: the caller will write the run's files
    (``trace.json``, ``samples.csv``), whose rows then count in the memory estimate.
    """
    cteam = compile_team(team)
    seed = team.simulation.seed if seed is None else seed
    requirements = compile_requirements(cteam)
    sim = Simulator(
        cteam,
        n,
        seed=seed,
        duration=duration,
        overrides=overrides,
        progress=progress,
        max_memory=max_memory,
        max_periods=max_periods,
        max_wall=max_wall,
        snapshots=bool(requirements),
        observe=requirements.observers(cteam),
        written=written,
    )
    run = Run.of(sim.run())
    run.costs = sim.costs
    if requirements:
        check_requirements(run, requirements, sim)
    return run


def check_requirements(run: Run, requirements: RequirementSet, sim: Simulator) -> None:
    """Add each instance's requirement verdicts to its outcome (``summary.json`` and the
    trace carry them), reading parameters as the simulator set them per instance."""
    snapshots = sim.ensemble.rec.merged_snapshots()
    for outcome, verdicts in zip(
        run.diagnostics, requirements.check(run, parameters(sim), snapshots), strict=True
    ):
        outcome["requirements"] = verdicts


def parameters(sim: Simulator) -> dict[str, tuple[list[str], np.ndarray]]:
    """Per agent, its parameter names and their values per instance (one row each), as
    the simulator set them (after overrides): what requirement checks read."""
    params = {}
    for st in sim.ensemble.states:
        names = sorted(st.ca.param_index, key=st.ca.param_index.__getitem__)
        params[st.ca.name] = (names, st.p)
    return params


def check(run: Trace, team: Team) -> Table:
    """``team``'s requirements evaluated on a recorded ``run`` (a log read with
    :meth:`Run.from_bag`, or a trace): a row per instance and requirement with
    ``satisfied``, ``robustness``, ``violated_at`` and ``failed`` (see
    :mod:`hybridteam.logs.check`)."""
    from hybridteam.logs.check import check_run, verdict_table

    return verdict_table(check_run(run, team))


def conformance(run: Trace, team: Team, tolerance: float = 0.1) -> Table:
    """How a recorded ``run`` conforms to ``team``: what the log says arrived replayed into
    the model and compared, a row per agent (transitions logged, in the model, matched, the
    largest time shift, the largest pose deviation off the plant driven by the logged
    commands and off the model's replay, and where it first diverges; see
    :mod:`hybridteam.logs.conformance`). ``tolerance``: seconds a transition may be off."""
    from hybridteam.logs.conformance import conformance as replayed

    return replayed(run, team, tolerance=tolerance).table()


def summaries(
    team: Team,
    n: int = 1,
    overrides: Mapping[str, Any] | None = None,
    seed: int | Sequence[int] | None = None,
    *,
    accelerate: bool = True,
) -> list[dict[str, Any]]:
    """Per-instance results of ``n`` runs (outcome, end time and the world's statistics),
    without keeping a trace: what a parameter study needs. The runs record no output
    samples unless the team's requirements are checked (they read them).

    When ``accelerate`` is true, every world component with a batch fast path
    (:meth:`~hybridteam.library.WorldComponent.batch`) is offered the runs, in declaration
    order, and the first that accepts gives the rows; it must give the rows the engine
    gives (its library's tests pin this). Otherwise the engine runs them.
    """
    overrides = dict(overrides or {})
    seed = team.simulation.seed if seed is None else seed
    cteam = compile_team(team)
    if accelerate and team.world:  # a batch path keeps no trace: requirements go unchecked
        from hybridteam.engine.run.batch import batch_rows

        rows = batch_rows(cteam, n, overrides, seed)
        if rows is not None:
            return rows
    requirements = compile_requirements(cteam)
    # rows need no output samples (only requirement checks read them)
    sim = Simulator(
        cteam,
        n,
        seed=seed,
        overrides=overrides,
        snapshots=bool(requirements),
        observe=requirements.observers(cteam),
        samples=bool(requirements),
    )
    run = Run.of(sim.run())
    if requirements:
        check_requirements(run, requirements, sim)
    return [
        {k: v for k, v in row.items() if k not in _COUNTS} for row in run.summary()["instances"]
    ]


_COUNTS = frozenset({"message", "transitions", "messages"})

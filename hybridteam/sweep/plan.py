"""A study expanded into runs, and the runs cut into ensemble chunks.

Run order is fixed: settings (factor by factor, value by value, the axes crossed with the
first axis outermost), then population members, then repetitions. Run ``r`` gets the
``r``-th child of ``SeedSequence(study.seed).spawn(...)``; member ``i`` draws its
parameters from a generator seeded by ``(population.seed, i, draw name)``, so it is the same
member whatever the population size or the other draws. A run's overrides and seed are
therefore functions of its own index alone — which, with the engine's guarantee that an
ensemble instance equals its single run, makes results independent of chunk size and of
the executor.

A chunk is a slice of one factor's runs (at most ``chunk`` of them, across its values and
axis points) and runs as one ensemble. All settings of one factor set the same override
keys (the factor's and the axes'), only to other values, so every instance of a chunk sets
the same keys and no key ever needs a "team default" filled in for runs that do not vary
it. Chunks span settings because a batch simulator vectorizes across instances: the
ladder's stepper runs a 500-pair ensemble (five ladder lengths) in less than half the time
of five 100-pair ones, and a study's settings are often only a population (100) large.
"""

from __future__ import annotations

import itertools
import zlib
from dataclasses import dataclass

import numpy as np

from hybridteam.sweep.study import MAX_RUNS, FactorValue, Study, run_count

BASE = "base"  # the factor name of a study without factors


@dataclass(frozen=True)
class Setting:
    """One row of the result table: a factor at one value, at one point of the axes."""

    index: int
    factor: str
    value: FactorValue | None  # None: the base setting of a study without factors
    axes: tuple[tuple[str, float], ...]
    assign: tuple[tuple[str, float], ...]  # override keys this setting fixes

    @property
    def label(self) -> str:
        """The value as the table shows it: ``0.4``, ``240``, ``(1.5, 0.5)``."""
        return value_label(self.value)


@dataclass(frozen=True)
class Chunk:
    """Runs ``start .. stop - 1``, all of factor number ``group``: one ensemble call."""

    id: str
    group: int
    start: int
    stop: int

    @property
    def size(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class Task:
    """What a worker needs to run a chunk: no study, no files — only arrays."""

    chunk: Chunk
    settings: list[int]
    overrides: dict[str, np.ndarray]
    seeds: list[int]
    members: list[int]
    repetitions: list[int]
    metrics: tuple[str, ...]
    accelerate: bool


def value_label(value: FactorValue | None) -> str:
    if value is None:
        return ""
    if isinstance(value, tuple):
        return "(" + ", ".join(value_label(v) for v in value) + ")"
    return repr(int(value)) if float(value).is_integer() and abs(value) < 1e15 else repr(value)


class Plan:
    """Settings, runs and chunks of a study; chunk size fixed at construction."""

    def __init__(self, study: Study, chunk: int | None = None) -> None:
        self.study = study
        self.chunk = int(chunk or study.chunk)
        if self.chunk < 1:
            raise ValueError(f"chunk must be at least 1, got {self.chunk}")
        if run_count(study) > MAX_RUNS:  # a study built in Python skipped the file check
            raise ValueError(
                f"the study asks for {run_count(study):,} runs, more than the "
                f"{MAX_RUNS:,} a study may plan"
            )
        self.per_setting = study.size * study.repetitions
        self.settings = _settings(study)
        self.runs = len(self.settings) * self.per_setting
        self.chunks: list[Chunk] = []
        first = 0  # a factor's settings are consecutive, so its runs are one range
        for group, (_, settings) in enumerate(itertools.groupby(self.settings, lambda s: s.factor)):
            stop = first + len(list(settings)) * self.per_setting
            self.chunks += [
                Chunk(f"{group:03d}-{p:05d}", group, a, min(a + self.chunk, stop))
                for p, a in enumerate(range(first, stop, self.chunk))
            ]
            first = stop
        self._draws: dict[str, np.ndarray] | None = None

    # ------------------------------------------------------------------ per run
    def member(self, run: np.ndarray | int) -> np.ndarray:
        return (np.asarray(run) % self.per_setting) // self.study.repetitions

    def repetition(self, run: np.ndarray | int) -> np.ndarray:
        return np.asarray(run) % self.study.repetitions

    def setting_of(self, run: np.ndarray | int) -> np.ndarray:
        return np.asarray(run) // self.per_setting

    def seeds(self, start: int, stop: int) -> list[int]:
        """Runs' seeds: child ``r`` of ``SeedSequence(seed).spawn``, as a 63-bit int.

        ``SeedSequence(seed, spawn_key=(r,))`` *is* that child, so a chunk derives its own
        seeds without spawning everyone else's.
        """
        return [
            int(
                np.random.SeedSequence(self.study.seed, spawn_key=(r,)).generate_state(
                    1, np.uint64
                )[0]
                >> np.uint64(1)
            )
            for r in range(start, stop)
        ]

    def draws(self) -> dict[str, np.ndarray]:
        """Population values (fixed, then drawn): override key -> (size,), member by member."""
        if self._draws is None:
            self._draws = population(self.study)
        return self._draws

    def task(self, chunk: Chunk) -> Task:
        """The settings, overrides (one value per instance) and seeds of a chunk's runs.

        Population values first, then the settings' own: where a factor varies a drawn
        parameter its value must win, and the engine applies overrides in order.
        """
        runs = np.arange(chunk.start, chunk.stop)
        members = self.member(runs)
        settings = self.setting_of(runs)
        overrides = {key: values[members] for key, values in self.draws().items()}
        mine = [dict(s.assign) for s in self.settings[settings[0] : settings[-1] + 1]]
        for key in mine[0]:  # one factor's settings: the same keys in each
            overrides.pop(key, None)
            overrides[key] = np.array([m[key] for m in mine])[settings - settings[0]]
        return Task(
            chunk,
            settings.tolist(),
            overrides,
            self.seeds(chunk.start, chunk.stop),
            members.tolist(),
            self.repetition(runs).tolist(),
            self.study.metrics,
            self.study.accelerate,
        )


def spread_chunk(study: Study, workers: int) -> int:
    """The study's chunk size, or a smaller one where it would leave asked-for workers idle.

    A chunk is what an executor hands to a worker, so a study of 8 runs cut at 500 is one
    chunk and runs in one process however many workers were asked for. Where the study's
    size makes fewer chunks than ``workers``, this is an even share, ceil(runs / workers),
    or the largest size below it that makes at least ``workers`` chunks (a chunk never
    mixes two factors' runs, so each factor is cut on its own; one run per chunk for fewer
    runs than workers): no worker idle, chunks as large as that allows for the batch
    simulator.
    """
    size = study.chunk
    if workers <= 1:
        return size
    groups = [c.size for c in Plan(study, max(1, run_count(study))).chunks]

    def count(k: int) -> int:
        return sum(-(-g // k) for g in groups)

    if count(size) >= workers:
        return size
    size = min(size, -(-sum(groups) // workers))  # ceil(runs / workers): even shares
    while size > 1 and count(size) < workers:  # at most once: floor(runs / workers) does
        size -= 1
    return size


def _settings(study: Study) -> list[Setting]:
    axis_points = list(
        itertools.product(*[[(a.name, a.keys, v) for v in a.values] for a in study.axes])
    )
    factor_values: list[tuple[str, tuple[str, ...], FactorValue | None]] = [
        (f.name, f.keys, v) for f in study.factors for v in f.values
    ] or [(BASE, (), None)]
    out: list[Setting] = []
    for name, keys, value in factor_values:
        for point in axis_points:
            assign: list[tuple[str, float]] = []
            if value is not None:
                per_key = value if isinstance(value, tuple) else (value,) * len(keys)
                assign += [(k, float(v)) for k, v in zip(keys, per_key, strict=True)]
            for _, axis_keys, v in point:
                assign += [(k, float(v)) for k in axis_keys]
            out.append(
                Setting(
                    len(out), name, value, tuple((a, float(v)) for a, _, v in point), tuple(assign)
                )
            )
    return out


def population(study: Study) -> dict[str, np.ndarray]:
    """Every member's parameters: ``population.set`` values, then the draws. Member ``i``'s
    draw ``name`` comes from its own generator, seeded ``(population.seed, i, crc32(name))``:
    independent of size and of other draws."""
    out: dict[str, np.ndarray] = {
        key: np.full(study.size, float(value)) for key, value in study.fixed
    }
    for d in study.draws:
        tag = zlib.crc32(d.name.encode("utf-8"))
        values = np.empty(study.size)
        for i in range(study.size):
            rng = np.random.default_rng(
                np.random.SeedSequence(study.population_seed, spawn_key=(i, tag))
            )
            if d.kind == "uniform":
                values[i] = rng.uniform(d.low, d.high)
            else:
                values[i] = rng.integers(int(d.low), int(d.high), endpoint=True)
        for key in d.keys:
            out[key] = values
    return out

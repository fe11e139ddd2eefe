"""Study files -> a validated :class:`Study`, every mistake located in the file.

Three gates, like a team file's: YAML syntax, the schema (:mod:`~hybridteam.sweep.schema`), then
what needs the team — the team file must load, every override key must name a parameter (checked by
building the simulator with it, since the engine is what knows), factor values must have one number
per key, and each metric must be a per-instance summary key. Everything is checked before a single
run starts: a typo must not surface an hour into a study.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, replace
from pathlib import Path

from pydantic import ValidationError

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.overrides import key_problem
from hybridteam.io.errors import located_errors
from hybridteam.io.filekind import Document, FileKind, InputErrors, Loaded, read_document
from hybridteam.io.loader import load_team
from hybridteam.io.yamlpos import Path as DocPath
from hybridteam.io.yamlpos import Positions, SourceError
from hybridteam.model import Team
from hybridteam.sweep.schema import AxisSchema, AxisSpec, FactorSchema, FactorSpec, StudyFile

#: A factor value: one number for all the factor's keys, or one per key.
FactorValue = float | tuple[float, ...]


@dataclass(frozen=True)
class Draw:
    """A population parameter: drawn per member, then set on every key in ``keys``."""

    name: str
    keys: tuple[str, ...]
    kind: str  # "uniform" or "integers" (inclusive hi)
    low: float
    high: float


@dataclass(frozen=True)
class Factor:
    """Varied alone over ``values``; the other parameters keep the population's draws."""

    name: str
    keys: tuple[str, ...]
    values: tuple[FactorValue, ...]


@dataclass(frozen=True)
class Axis:
    """Crossed with every factor value; ``name`` is its column in the table."""

    name: str
    keys: tuple[str, ...]
    values: tuple[float, ...]


@dataclass(frozen=True)
class Study:
    """A validated study, its team loaded; ``digest`` identifies it for resuming."""

    path: Path
    name: str
    team_path: Path
    team: Team
    size: int
    population_seed: int
    fixed: tuple[tuple[str, float], ...]  # population.set: key -> one value for every member
    draws: tuple[Draw, ...]
    factors: tuple[Factor, ...]
    axes: tuple[Axis, ...]
    repetitions: int
    seed: int
    success: tuple[str, ...]
    outcomes: tuple[str, ...]
    metrics: tuple[str, ...]
    chunk: int
    accelerate: bool
    digest: str


def load_study(source: str | os.PathLike) -> Study:
    """Load and fully check a study file; raises :class:`InputErrors` (file:line messages)."""
    return _load(read_document(source))


def _load(document: Document) -> Study:
    """A parsed study file, validated and checked against its team."""
    data, positions, filename = document.data, document.positions, document.filename
    source = Path(filename)
    if not isinstance(data, dict) or data.get("kind") != "study":
        mark = positions.value(("kind",)) or positions.nearest(())[1]
        what = (
            f"got kind {data['kind']!r}"
            if isinstance(data, dict) and "kind" in data
            else "no 'kind:' key"
        )
        raise InputErrors(
            [
                SourceError(
                    filename,
                    mark.line,
                    mark.column,
                    ("kind",),
                    f"expected a study file with 'kind: study' ({what})",
                )
            ]
        )
    try:
        doc = StudyFile.model_validate(data)
    except ValidationError as exc:
        raise InputErrors(located_errors(exc, StudyFile, data, positions, filename)) from None
    team_path = (Path(source).resolve().parent / doc.team).resolve()
    if not team_path.is_file():
        raise InputErrors(
            [positions.error(("team",), f"no team file '{doc.team}' (looked for {team_path})")]
        )
    team = load_team(team_path)  # its own errors name the team file
    if doc.duration is not None:  # the study's duration is the team's, for every executor
        team = with_duration(team, doc.duration)
    errors: list[SourceError] = []
    draws = tuple(
        Draw(
            name,
            tuple(d.keys or [name]),
            "uniform" if d.uniform else "integers",
            *(d.uniform or d.integers),
        )  # type: ignore[misc]  # (the schema gives one)
        for name, d in doc.population.draws.items()
    )
    factors = tuple(_factor(name, spec, positions, errors) for name, spec in doc.factors.items())
    axes = tuple(
        Axis(name, _keys(name, spec), tuple(_axis_values(spec))) for name, spec in doc.axes.items()
    )
    study = Study(
        path=Path(source),
        name=doc.name or Path(source).stem,
        team_path=team_path,
        team=team,
        size=doc.population.size,
        population_seed=doc.population.seed,
        fixed=tuple(doc.population.set.items()),
        draws=draws,
        factors=factors,
        axes=axes,
        repetitions=doc.repetitions,
        seed=doc.seed,
        success=tuple(doc.success),
        outcomes=tuple(doc.outcomes),
        metrics=tuple(doc.metrics),
        chunk=doc.chunk,
        accelerate=doc.accelerate,
        digest=_digest(Path(source), team_path),
    )
    cteam = compile_team(study.team)
    if not errors:
        errors += _check_size(study, positions)
    if not errors:
        errors += _check_keys(study, cteam, positions)
    if not errors:
        errors += _check_overlaps(study, cteam, positions)
    if not errors:
        errors += _check_metrics(study, positions)
    if errors:
        raise InputErrors(sorted(errors, key=lambda e: (e.line or 0, e.column or 0)))
    return study


def restrict(study: Study, **keep: list[float | tuple[float, ...]]) -> Study:
    """``study`` with only some values of its factors or axes, e.g. a quick look (or a
    test) at one ladder length: ``restrict(study, alpha=[0.4, 0.8], ladder_length=[480])``.

    Each name is a factor or an axis of the study and keeps the listed values, which must
    be among its own (an empty list drops a factor); the rest stays whole. The population
    is the study's, member for member, but runs are numbered — and seeded — within the
    slice, so a stochastic team's runs differ from the full study's (a deterministic
    one's, like the ladder's, do not). The digest changes, so the slice's output folder
    cannot be mistaken for the study's.
    """

    def kept(name: str, values: tuple) -> tuple:
        wanted = [
            tuple(float(x) for x in v) if isinstance(v, list | tuple) else float(v)
            for v in keep[name]
        ]
        have = [tuple(map(float, v)) if isinstance(v, tuple) else float(v) for v in values]
        missing = [v for v in wanted if v not in have]
        if missing:
            raise ValueError(
                f"{name}: {missing[0]!r} is not one of the study's values {list(values)}"
            )
        return tuple(v for v, h in zip(values, have, strict=True) if h in wanted)

    names = {f.name for f in study.factors} | {a.name for a in study.axes}
    unknown = sorted(set(keep) - names)
    if unknown:
        raise ValueError(
            f"'{unknown[0]}' is no factor or axis of the study (it has {', '.join(sorted(names))})"
        )
    if any(not keep.get(a.name, True) for a in study.axes):
        raise ValueError("an axis needs at least one value")
    factors = tuple(
        replace(f, values=kept(f.name, f.values)) if f.name in keep else f for f in study.factors
    )
    factors = tuple(f for f in factors if f.values)
    axes = tuple(
        replace(a, values=kept(a.name, a.values)) if a.name in keep else a for a in study.axes
    )
    digest = hashlib.sha256((study.digest + repr(sorted(keep.items()))).encode()).hexdigest()
    return replace(study, factors=factors, axes=axes, digest=digest)


def with_duration(team: Team, duration: float) -> Team:
    """``team`` simulated for ``duration``, sampled as before (like ``run --duration``)."""
    sim = team.simulation
    return replace(
        team, simulation=replace(sim, duration=duration, sample_period=sim.output_period())
    )


def _keys(name: str, spec: object) -> tuple[str, ...]:
    if isinstance(spec, FactorSchema | AxisSchema):
        if spec.keys is not None:
            return tuple(spec.keys)
        if spec.key is not None:
            return (spec.key,)
    return (name,)


def _axis_values(spec: AxisSpec) -> list[float]:
    return spec.values if isinstance(spec, AxisSchema) else spec


def _factor(name: str, spec: FactorSpec, positions: Positions, errors: list[SourceError]) -> Factor:
    keys = _keys(name, spec)
    raw = spec.values if isinstance(spec, FactorSchema) else spec
    where: DocPath = (
        ("factors", name, "values") if isinstance(spec, FactorSchema) else ("factors", name)
    )
    values: list[FactorValue] = []
    for k, v in enumerate(raw):
        if isinstance(v, list):
            if len(v) != len(keys):
                errors.append(
                    positions.error(
                        (*where, k),
                        f"a list value gives one number "
                        f"per key: expected {len(keys)} "
                        f"({', '.join(keys)}), got {len(v)}",
                    )
                )
            values.append(v[0] if len(v) == 1 else tuple(v))
        else:
            values.append(v)
    return Factor(name, keys, tuple(values))


def _check_overlaps(study: Study, cteam: CTeam, positions: Positions) -> list[SourceError]:
    """No parameter set twice in one run: by two draws (or a draw and ``population.set``),
    two axes, an axis and a factor, or two keys of one item — ``wait`` and ``asker.wait``
    count as the same parameter. (A factor may set a drawn or fixed parameter: that is what
    varying it means.)"""

    def targets(key: str) -> list[str]:
        agent, _, name = key.rpartition(".")
        return [
            f"{ca.name}.{name}"
            for ca in cteam.agents
            if (not agent or ca.name == agent) and name in ca.param_index
        ]

    errors: list[SourceError] = []

    def claim(owners: dict[str, str], label: str, keys: tuple[str, ...], where: DocPath) -> None:
        for key in keys:
            for t in targets(key):
                if t in owners:
                    errors.append(
                        positions.error(
                            where, f"'{key}' sets {t}, which {owners[t]} sets too", at_key=True
                        )
                    )
                    return
            owners.update({t: label for t in targets(key)})

    drawn: dict[str, str] = {}
    for key, _ in study.fixed:
        claim(drawn, f"population.set '{key}'", (key,), ("population", "set", key))
    for d in study.draws:
        claim(drawn, f"draw '{d.name}'", d.keys, ("population", "draws", d.name))
    by_axes: dict[str, str] = {}
    for axis in study.axes:
        claim(by_axes, f"axis '{axis.name}'", axis.keys, ("axes", axis.name))
    for factor in study.factors:
        claim(dict(by_axes), f"factor '{factor.name}'", factor.keys, ("factors", factor.name))
    return errors


#: The most runs a study may plan (its table, plan and chunk list are held in memory).
MAX_RUNS = 10_000_000


def run_count(study: Study) -> int:
    """How many runs the study asks for: settings x members x repetitions."""
    settings = max(sum(len(f.values) for f in study.factors), 1)
    for axis in study.axes:
        settings *= len(axis.values)
    return settings * study.size * study.repetitions


def _check_size(study: Study, positions: Positions) -> list[SourceError]:
    """At most :data:`MAX_RUNS` runs; the error sits at the largest factor of the count."""
    runs = run_count(study)
    if runs <= MAX_RUNS:
        return []
    settings = runs // (study.size * study.repetitions)
    parts = {("repetitions",): study.repetitions, ("population", "size"): study.size}
    where = (
        max(parts, key=lambda k: parts[k])
        if max(parts.values()) > settings
        else (("factors",) if study.factors else ("axes",))
    )
    return [
        positions.error(
            where,
            f"this study asks for {runs:,} runs ({settings:,} "
            f"settings x {study.size:,} members x {study.repetitions:,} "
            f"repetitions), more than the {MAX_RUNS:,} a study may plan; "
            "split it into several studies",
        )
    ]


def _check_keys(study: Study, cteam: CTeam, positions: Positions) -> list[SourceError]:
    """Each override key must name a parameter of the team (the engine's own rule)."""
    uses: list[tuple[str, DocPath, bool]] = []  # key, where it is written, at a mapping key
    named: list[tuple[str, str, str | None, tuple[str, ...]]] = [
        ("population", "set", key, (key,)) for key, _ in study.fixed
    ]
    named += [("population", "draws", d.name, d.keys) for d in study.draws]
    named += [
        (group, item.name, None, item.keys)
        for group, items in (("factors", study.factors), ("axes", study.axes))
        for item in items
    ]
    for group, name, sub, keys in named:
        base: DocPath = (group, name, sub) if sub else (group, name)
        for j, key in enumerate(keys):
            if positions.value((*base, "keys")) is not None:
                uses.append((key, (*base, "keys", j), False))
            elif positions.value((*base, "key")) is not None:
                uses.append((key, (*base, "key"), False))
            else:  # shorthand: the name is the key
                uses.append((key, base, True))
    errors: list[SourceError] = []
    for key, where, at_key in uses:
        problem = key_problem(cteam.agents, key, cteam.team.network)
        if problem is not None:
            head, _, hint = problem.partition("; ")  # "...; did you mean 'x'?"
            errors.append(
                positions.error(
                    where,
                    f"{head} of team '{study.team.name}'" + (f"; {hint}" if hint else ""),
                    at_key=at_key,
                )
            )
    return errors


def _check_metrics(study: Study, positions: Positions) -> list[SourceError]:
    """Each metric must be a per-instance summary key (as :func:`hybridteam.api.summaries`
    gives them; tried on a zero-length run of the engine)."""
    if not study.metrics:
        return []
    from hybridteam.api import summaries

    row = summaries(with_duration(study.team, 0.0), n=1, accelerate=False)[0]
    known = [k for k, v in row.items() if k != "instance" and not isinstance(v, str)]
    from hybridteam.errors import did_you_mean

    return [
        positions.error(
            ("metrics", j),
            f"'{m}' is not a per-instance summary key of team "
            f"'{study.team.name}' (known: {', '.join(known)})"
            + (f"; {hint}" if (hint := did_you_mean(m, known)) else ""),
        )
        for j, m in enumerate(study.metrics)
        if m not in known
    ]


def _digest(study_path: Path, team_path: Path) -> str:
    """What a resumed study must match: the bytes of the study file and of its team file."""
    h = hashlib.sha256()
    for path in (study_path, team_path):
        data = path.read_bytes()
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()


#: Studies are a file kind (``hybridteam validate``, ``hybridteam schema study``).
FILE_KINDS = (FileKind("study", lambda: StudyFile, lambda doc: Loaded("study", _load(doc))),)

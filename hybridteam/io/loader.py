"""YAML files -> validated model declarations, with every error located in the file.

Loading runs three gates, each reporting *all* its problems with ``file:line:column``:
YAML syntax (:mod:`.yamlpos`), the schema (:mod:`.schema`, pydantic), and the model itself
(names, expressions, laws — by compiling it). The semantic checker (:mod:`.check`) adds
warnings for unreachable modes and dead ends. Nothing is run before all gates pass.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from hybridteam.engine.compiler import compile_team
from hybridteam.errors import DocPath, ModelError, ModelErrors
from hybridteam.io.errors import did_you_mean, located_errors
from hybridteam.io.schema import (
    FILE_KINDS,
    AgentSchema,
    ModeSchema,
    RaiseSchema,
    SendSchema,
    TeamFile,
    detect_kind,
)
from hybridteam.io.yamlpos import Positions, SourceError, load_yaml
from hybridteam.model import (
    Agent,
    Assign,
    LawBinding,
    LinkSettings,
    Mode,
    NetworkSpec,
    PlantSpec,
    Raise,
    ScenarioEvent,
    Send,
    Simulation,
    Team,
    Transition,
    Zeno,
)


class InputErrors(Exception):
    """All problems found in one input file; ``str()`` gives one located line per error."""

    def __init__(self, errors: list[SourceError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))


@dataclass
class Loaded:
    """A validated document: its kind, the schema object, the model and any warnings."""

    kind: str
    document: BaseModel
    model: Any
    warnings: list[SourceError] = field(default_factory=list)


def locate(err: ModelError, positions: Positions, filename: str) -> SourceError:
    """A :class:`ModelError` (document path + offset) as a ``file:line:col`` error."""
    mark = positions.key(err.path) if err.at_key else None
    if err.offset is not None:
        mark = positions.in_scalar(err.path, err.offset)
    if mark is None:
        mark = positions.value(err.path)
    if mark is None:
        _, mark = positions.nearest(err.path)
    message = err.message + (f"; {err.hint}" if err.hint else "")
    return SourceError(filename, mark.line if mark else None, mark.column if mark else None,
                       err.path, message)


def read_document(source: str | os.PathLike) -> tuple[str, dict, Positions, str]:
    """Parse a YAML file and tell its kind; raise :class:`InputErrors` on any problem."""
    filename = str(source)
    try:
        data, positions = load_yaml(Path(source), filename=filename)
    except SourceError as exc:
        raise InputErrors([exc]) from None
    kind = detect_kind(data)
    if kind not in FILE_KINDS:
        hint = did_you_mean(kind, FILE_KINDS) if isinstance(kind, str) else None
        what = f"unknown file kind '{kind}'" if kind else \
            "cannot tell what kind of file this is (expected e.g. 'team:' and 'agents:')"
        mark = positions.value(("kind",)) if kind else None
        raise InputErrors([SourceError(filename, mark.line if mark else 1,
                                       mark.column if mark else 1, ("kind",) if kind else (),
                                       what + (f"; {hint}" if hint else ""))])
    return kind, data, positions, filename


def load(source: str | os.PathLike) -> Loaded:
    """Load and fully validate any hybridteam file (kind detected from its keys)."""
    kind, data, positions, filename = read_document(source)
    schema = FILE_KINDS[kind]
    try:
        document = schema.model_validate(data)
    except ValidationError as exc:
        raise InputErrors(located_errors(exc, schema, data, positions, filename)) from None
    if kind == "team":
        team = build_team(document, filename)  # type: ignore[arg-type]
        try:
            compile_team(team)
        except ModelErrors as exc:
            raise InputErrors([locate(e, positions, filename) for e in exc.errors]) from None
        from hybridteam.io.check import check_team

        warnings = [locate(w, positions, filename) for w in check_team(team)]
        return Loaded(kind, document, team, warnings)
    raise AssertionError(kind)  # pragma: no cover


def load_team(source: str | os.PathLike) -> Team:
    """Load a team file; raises :class:`InputErrors` with located messages."""
    loaded = load(source)
    if loaded.kind != "team":
        raise InputErrors([SourceError(str(source), 1, 1, (), f"expected a team file, "
                                       f"got a {loaded.kind} file")])
    return loaded.model


# ------------------------------------------------------------------ schema -> model


def build_team(doc: TeamFile, filename: str) -> Team:
    agents = tuple(_agent(name, spec, ("agents", name)) for name, spec in doc.agents.items())
    s = doc.simulation
    sim = Simulation(
        duration=s.duration, seed=s.seed, sample_period=s.sample_period, rtol=s.rtol,
        atol=s.atol, max_step=s.max_step, event_tol=s.event_tol,
        crossing_checks=s.crossing_checks,
        zeno=Zeno(s.zeno.max_steps_per_instant, s.zeno.max_transitions, s.zeno.window),
        where=("simulation",),
    )
    scenario = tuple(ScenarioEvent(e.at, e.agent, e.raise_, ("scenario", k))
                     for k, e in enumerate(doc.scenario))
    net = doc.network

    def link(spec, where) -> LinkSettings:
        return LinkSettings(spec.latency, spec.jitter, spec.loss, where)

    network = NetworkSpec(
        default=link(net, ("network",)),
        links={tuple(s.strip() for s in key.split("->", 1)): link(spec, ("network", "links", key))
               for key, spec in net.links.items()},
        rate_limits={agent: dict(limits) for agent, limits in net.rate_limits.items()},
        where=("network",),
    )
    return Team(doc.team, agents, dict(doc.parameters), sim, scenario,
                source=Path(filename).name, network=network)


def _agent(name: str, spec: AgentSchema, where: DocPath) -> Agent:
    plant = PlantSpec(spec.plant.kind, dict(spec.plant.state),
                      {k: tuple(v) for k, v in spec.plant.limits.items()},  # type: ignore[misc]
                      (*where, "plant"))
    children = tuple(_mode(n, m, (*where, "modes", n)) for n, m in spec.modes.items())
    root = Mode(name, children, initial=spec.initial, history=spec.history,
                where=where)
    return Agent(name, plant, root, dict(spec.parameters), dict(spec.variables), where)


def _mode(name: str, spec: ModeSchema, where: DocPath) -> Mode:
    children = tuple(_mode(n, m, (*where, "modes", n)) for n, m in (spec.modes or {}).items())
    law = None
    if spec.law is not None:
        if isinstance(spec.law, str):
            law = LawBinding(spec.law, where=(*where, "law"))
        else:
            law = LawBinding(spec.law.use, spec.law.period, dict(spec.law.with_),
                             where=(*where, "law"))
    transitions = tuple(_transition(t, (*where, "transitions", k))
                        for k, t in enumerate(spec.transitions))
    return Mode(
        name, children, initial=spec.initial, parallel=spec.parallel, history=spec.history,
        law=law, inputs=None if spec.inputs is None else dict(spec.inputs),
        input_period=spec.period, flow=None if spec.flow is None else dict(spec.flow),
        invariant=spec.invariant, final=spec.final, transitions=transitions, where=where,
    )


def _transition(spec, where: DocPath) -> Transition:
    actions = []
    for k, act in enumerate(spec.do):
        awhere = (*where, "do", k)
        if isinstance(act, str):
            actions.append(Assign(act, awhere))
        elif isinstance(act, SendSchema):
            actions.append(Send(act.send, act.to, act.socket, dict(act.fields), awhere))
        elif isinstance(act, RaiseSchema):
            actions.append(Raise(act.raise_, awhere))
    return Transition(spec.to, spec.on, spec.after, spec.guard, tuple(actions), spec.priority,
                      where)

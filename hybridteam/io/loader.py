"""YAML files -> validated model declarations, with every error located in the file.

Loading runs three gates, each reporting *all* its problems with ``file:line:column``: YAML syntax
(:mod:`~hybridteam.io.yamlpos`), the schema (:mod:`~hybridteam.io.schema`, pydantic), and the model
itself (names, expressions, laws — by compiling it). The semantic checker
(:mod:`~hybridteam.io.check`) adds warnings for unreachable modes and dead ends. Nothing is run
before all gates pass. Team and protocol files are file kinds (:data:`FILE_KINDS`);
:mod:`hybridteam.kinds` dispatches any file to its kind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from pydantic import BaseModel, ValidationError

from hybridteam.engine.compile.compiler import compile_team
from hybridteam.errors import DocPath, ModelError, ModelErrors
from hybridteam.io.errors import did_you_mean, located_errors
from hybridteam.io.filekind import (
    Document,
    FileKind,
    InputErrors,
    Loaded,
    detect,
    kind_error,
    read_document,
)
from hybridteam.io.protocols import Composer, InFile, ProtocolErrors, message_spec
from hybridteam.io.schema import (
    AgentSchema,
    ModeSchema,
    ProtocolFile,
    RaiseSchema,
    SendSchema,
    TeamFile,
)
from hybridteam.io.yamlpos import Positions, SourceError
from hybridteam.model import (
    Action,
    Agent,
    Assign,
    EndRule,
    LawBinding,
    LinkSettings,
    MessageSpec,
    Mode,
    NetworkSpec,
    PlantSpec,
    Raise,
    Requirement,
    ScenarioEvent,
    Send,
    Simulation,
    Team,
    Transition,
    WorldSpec,
    Zeno,
)
from hybridteam.model.deploy import UDP, PlantDeploy, UdpDeploy, agent_deploy
from hybridteam.requirements.check import compile_requirements

if TYPE_CHECKING:
    from hybridteam.robots.presets import RobotPreset


def _link_pair(key: str) -> tuple[str, str]:
    """A ``network.links`` key, ``'sender->receiver'`` (the schema checked its form), as
    its two names."""
    sender, _, receiver = key.partition("->")
    return sender.strip(), receiver.strip()


def locate(
    err: ModelError,
    positions: Positions,
    filename: str,
    elsewhere: Mapping[InFile, Positions] | None = None,
) -> SourceError:
    """A :class:`ModelError` (document path + offset) as a ``file:line:col`` error.

    A path starting with an :class:`InFile` tag lies in that file (a protocol's), found in
    ``elsewhere``.
    """
    if err.path and isinstance(err.path[0], InFile) and elsewhere and err.path[0] in elsewhere:
        filename, positions = str(err.path[0]), elsewhere[err.path[0]]
        err = ModelError(
            err.path[1:], err.message, offset=err.offset, hint=err.hint, at_key=err.at_key
        )
    mark = positions.key(err.path) if err.at_key else None
    if err.offset is not None:
        mark = positions.in_scalar(err.path, err.offset)
    if mark is None:
        mark = positions.value(err.path)
    if mark is None:
        _, mark = positions.nearest(err.path)
    message = err.message + (f"; {err.hint}" if err.hint else "")
    return SourceError(
        filename, mark.line if mark else None, mark.column if mark else None, err.path, message
    )


def locate_in_file(err: ModelError, team_file: str | os.PathLike) -> SourceError:
    """A run-time :class:`ModelError` (a delay, rate or link setting out of range for some
    instance) located in the team file it came from, or in the protocol file its path
    names: the file is read again for its positions."""
    elsewhere: dict[InFile, Positions] = {}
    if err.path and isinstance(err.path[0], InFile):
        with contextlib.suppress(InputErrors):  # then it is located by its path alone
            elsewhere[err.path[0]] = read_document(str(err.path[0])).positions
    try:
        doc = read_document(team_file)
    except InputErrors:
        return SourceError(str(team_file), None, None, err.path, err.message)
    return locate(err, doc.positions, doc.filename, elsewhere)


def _load_team(doc: Document) -> Loaded:
    """A team document: schema, protocols composed, compiled (every name and expression
    checked), then the semantic checker's warnings."""
    document = _validated(doc, TeamFile)
    try:
        team, comp = compose_team(document, doc.filename)
    except ProtocolErrors as exc:
        raise InputErrors(exc.errors) from None
    others = {InFile(p.filename): p.positions for p in comp.cache.values()}
    others.update(comp.requirement_files)
    try:
        if comp.errors:
            raise ModelErrors(comp.errors)
        cteam = compile_team(team)
        compile_requirements(cteam)
    except ModelErrors as exc:
        raise InputErrors(
            [locate(e, doc.positions, doc.filename, others) for e in exc.errors]
        ) from None
    from hybridteam.io.check import check_team

    warnings = [locate(w, doc.positions, doc.filename, others) for w in check_team(team, cteam)]
    return Loaded("team", team, warnings)


def _load_protocol(doc: Document) -> Loaded:
    return Loaded("protocol", _validated(doc, ProtocolFile))


#: the schema a document is validated against, and so the model it gives
_Schema = TypeVar("_Schema", bound=BaseModel)


def _validated(doc: Document, schema: type[_Schema]) -> _Schema:
    try:
        return schema.model_validate(doc.data)
    except ValidationError as exc:
        raise InputErrors(
            located_errors(exc, schema, doc.data, doc.positions, doc.filename)
        ) from None


#: The file kinds this package reads (collected by :mod:`hybridteam.kinds`).
FILE_KINDS = (
    FileKind("team", lambda: TeamFile, _load_team, marks=("agents", "team")),
    FileKind("protocol", lambda: ProtocolFile, _load_protocol, marks=("protocol",)),
    FileKind(
        "requirements",
        lambda: _requirements_schema(),
        lambda doc: Loaded("requirements", _validated(doc, _requirements_schema())),
        marks=("requirements",),
    ),
)


def _requirements_schema() -> type[BaseModel]:
    from hybridteam.io.reqschema import RequirementsFile

    return RequirementsFile


def load_team_file(source: str | os.PathLike) -> Loaded:
    """Load a team file with its warnings; raises :class:`InputErrors` with located
    messages (also for a file of another kind)."""
    doc = read_document(source)
    kind = detect(doc.data, FILE_KINDS)
    if kind != "team":
        raise kind_error(doc, kind, ["team", "protocol", "study"], expected="team")
    return _load_team(doc)


def load_team(source: str | os.PathLike) -> Team:
    """Load a team file; raises :class:`InputErrors` with located messages."""
    return load_team_file(source).model


# ------------------------------------------------------------------ schema -> model


def build_team(doc: TeamFile, filename: str) -> Team:
    """The team a validated document declares (protocol errors raised, not collected)."""
    team, comp = compose_team(doc, filename)
    if comp.errors:
        raise ModelErrors(comp.errors)
    return team


def compose_team(doc: TeamFile, filename: str) -> tuple[Team, Composer]:
    """The team, and the composer that brought in its protocols (with their errors)."""
    comp = Composer(Path(filename).resolve().parent, _mode)
    agents = tuple(
        _agent(name, spec, ("agents", name), comp, set(doc.parameters))
        for name, spec in doc.agents.items()
    )
    s = doc.simulation
    sim = Simulation(
        duration=s.duration,
        seed=s.seed,
        sample_period=s.sample_period,
        rtol=s.rtol,
        atol=s.atol,
        max_step=s.max_step,
        min_step=s.min_step,
        event_tol=s.event_tol,
        crossing_checks=s.crossing_checks,
        zeno=Zeno(s.zeno.max_steps_per_instant, s.zeno.max_transitions, s.zeno.window),
        where=("simulation",),
    )
    scenario = tuple(
        ScenarioEvent(e.at, e.agent, e.raise_, ("scenario", k)) for k, e in enumerate(doc.scenario)
    )
    net = doc.network

    def link(spec, where) -> LinkSettings:
        return LinkSettings(spec.latency, spec.jitter, spec.loss, where)

    network = NetworkSpec(
        default=link(net, ("network",)),
        links={
            _link_pair(key): link(spec, ("network", "links", key))
            for key, spec in net.links.items()
        },
        rate_limits={agent: dict(limits) for agent, limits in net.rate_limits.items()},
        where=("network",),
    )
    world = tuple(WorldSpec(w.use, dict(w.with_), ("world", k)) for k, w in enumerate(doc.world))
    robots, udp = _deploy(doc, comp)
    team = Team(
        doc.team,
        agents,
        dict(doc.parameters),
        sim,
        scenario,
        source=Path(filename).name,
        network=network,
        messages=_messages(doc, comp),
        world=world,
        folder=str(Path(filename).resolve().parent),
        end=EndRule(
            tuple(doc.end.agents) if doc.end and doc.end.agents else None,
            doc.end.when if doc.end else "all",
            ("end",),
        ),
        requirements=_requirements(doc, filename, comp),
        priority_rule=doc.semantics.priority,
        deploy=robots,
        udp=udp,
    )
    return team, comp


def _deploy(doc: TeamFile, comp: Composer) -> tuple[dict[str, PlantDeploy], UdpDeploy]:
    """The ``deploy:`` section: the agents' robots, and the team's UDP addressing (its
    ``udp`` key and the agents' ``listen``); a setting that is not one, or an entry for
    an agent the team does not have, is a located error."""
    robots, listen, udp = {}, {}, UdpDeploy()
    for name, config in doc.deploy.items():
        where = ("deploy", name)
        try:
            if name == UDP:
                udp = UdpDeploy.from_mapping(config, where)
                continue
            if name not in doc.agents:
                comp.errors.append(
                    ModelError(
                        where,
                        f"'{name}' is not an agent of the team (nor '{UDP}', the team's "
                        "UDP addressing)",
                        hint=did_you_mean(name, [*doc.agents, UDP]),
                        at_key=True,
                    )
                )
                continue
            robot, address = agent_deploy(config, where)
        except ModelError as exc:
            comp.errors.append(exc)
            continue
        if robot is not None:
            robots[name] = robot
        if address is not None:
            listen[name] = address
    return robots, dataclasses.replace(udp, listen=listen)


def _requirements(doc: TeamFile, filename: str, comp: Composer) -> tuple[Requirement, ...]:
    """The team's requirements: those of its ``requirements_from`` files, then its own."""
    out: list[Requirement] = []
    for k, ref in enumerate(doc.requirements_from):
        where = ("requirements_from", k)
        loaded = load_requirement_file(Path(filename).resolve().parent / ref, where)
        if isinstance(loaded, ModelError):
            comp.errors.append(loaded)
            continue
        other, positions = loaded
        tag = InFile(str(Path(filename).resolve().parent / ref))
        comp.requirement_files[tag] = positions
        out += _entries(other.requirements, (tag, "requirements"))
    seen = {r.name: r for r in out}
    for r in _entries(doc.requirements, ("requirements",)):
        if r.name in seen:
            comp.errors.append(
                ModelError(
                    r.where[:2],
                    f"requirement '{r.name}' is also in {seen[r.name].where[0]}",
                    at_key=True,
                )
            )
        out.append(r)
    return tuple(out)


def _entries(entries: dict, where: DocPath) -> list[Requirement]:
    out = []
    for name, entry in entries.items():
        if isinstance(entry, str):
            out.append(Requirement(name, entry, None, (*where, name)))
        else:
            out.append(
                Requirement(name, entry.formula, entry.description, (*where, name, "formula"))
            )
    return out


def load_requirement_file(path: Path, where: DocPath):
    """``(RequirementsFile, positions)``, or a :class:`ModelError` at ``where`` (the
    include) for a file that cannot be read; errors inside it raise located."""
    from hybridteam.io.reqschema import RequirementsFile

    if not path.is_file():
        return ModelError(where, f"no requirement file '{path}'")
    doc = read_document(path)
    data = doc.data
    if not (data.get("kind") == "requirements" or ("kind" not in data and "requirements" in data)):
        # any other YAML mapping (a private file reached through a link, say) would be
        # reported key by key, its lines printed back: refuse it whole, quoting nothing
        return ModelError(
            where,
            f"'{path}' is not a requirements document (expected "
            "'kind: requirements' and a 'requirements:' mapping of named "
            "formulas)",
        )
    return _validated(doc, RequirementsFile), doc.positions


def _messages(doc: TeamFile, comp: Composer) -> dict[str, MessageSpec]:
    """The protocols' message types, then the team's own (a name may be declared once)."""
    out = comp.messages()
    for name, m in doc.messages.items():
        where: DocPath = ("messages", name)
        if name in out:
            comp.errors.append(
                ModelError(
                    where,
                    f"message '{name}' is already declared by protocol '{out[name].protocol}'",
                    at_key=True,
                )
            )
            continue
        out[name] = message_spec(name, m, "", where)
    return out


def _agent(
    name: str, spec: AgentSchema, where: DocPath, comp: Composer, team_params: set[str]
) -> Agent:
    extra: dict = {
        "parameters": dict(spec.parameters),
        "variables": dict(spec.variables),
        "streams": [],
        "initial": spec.initial,
    }
    preset = None
    if spec.operator is not None:
        plant = PlantSpec("none", {}, {}, where)
        children = comp.operator(spec.operator, where, extra) or ()
    else:
        assert spec.plant is not None and spec.modes is not None  # the schema checked
        plant, preset = _plant(spec, where, comp.errors)
        children = tuple(
            _compose(n, m, (*where, "modes", n), comp, extra) for n, m in spec.modes.items()
        )
    root = Mode(
        name, children, initial=spec.initial or extra["initial"], history=spec.history, where=where
    )
    # protocol defaults yield to the team's parameters of the same name
    params = {
        k: v for k, v in extra["parameters"].items() if k in spec.parameters or k not in team_params
    }
    return Agent(
        name,
        plant,
        root,
        params,
        extra["variables"],
        where,
        tuple(extra["streams"]),
        preset,
        operator=spec.operator is not None,
    )


_OVERRIDDEN = ("sensors", "manipulator", "footprint")


def _plant(
    spec: AgentSchema, where: DocPath, errors: list[ModelError]
) -> tuple[PlantSpec, RobotPreset | None]:
    """The agent's plant, and its robot model with the team's overrides (``model:``).

    The model's kind and limits become the plant's, the agent's ``plant.limits`` merged onto
    them input by input; a ``plant.kind`` that says otherwise is an error rather than a
    silent choice. Problems are recorded in ``errors`` located in the team file (the
    override paths are the agent's own keys), with a stand-in plant so loading can go on.
    """
    from hybridteam.robots.presets import resolve

    p, pwhere = spec.plant, (*where, "plant")
    assert p is not None
    limits = {k: tuple(v) for k, v in p.limits.items()}
    # (the schema checked each limit is a [low, high] pair)
    stand_in = PlantSpec(p.kind or "none", dict(p.state), limits, pwhere)  # type: ignore[arg-type]
    if spec.model is None:
        return stand_in, None
    # the sections the agent wrote, even as null (which removes the model's manipulator)
    overrides: dict[str, Any] = {
        k: getattr(spec, k) for k in _OVERRIDDEN if k in spec.model_fields_set
    }
    if p.limits:
        overrides["plant"] = {"limits": {k: list(v) for k, v in p.limits.items()}}
    try:
        base = resolve(spec.model)
        kind = base.plant.kind
        if p.kind is not None and p.kind != kind:
            raise ModelError(
                ("plant", "kind"),
                f"robot model '{spec.model}' is a {kind}, not a {p.kind}",
                hint="remove 'kind': it comes from the model",
            )
        for n, (lo, hi) in p.limits.items():  # located at the input, as without a model
            if n not in base.inputs:
                raise ModelError(
                    ("plant", "limits", n),
                    f"a {kind} plant has no input '{n}'",
                    hint=did_you_mean(n, base.inputs),
                    at_key=True,
                )
            if lo > hi:
                raise ModelError(("plant", "limits", n), f"lower limit {lo} exceeds upper {hi}")
        preset = resolve(spec.model, overrides)
    except (ModelError, ModelErrors) as exc:
        found = exc.errors if isinstance(exc, ModelErrors) else [exc]
        errors += [
            ModelError((*where, *(e.path or ("model",))), e.message, hint=e.hint, at_key=e.at_key)
            for e in found
        ]
        return stand_in, None
    return PlantSpec(preset.plant.kind, dict(p.state), dict(preset.plant.limits), pwhere), preset


def _compose(name: str, spec: ModeSchema, where: DocPath, comp: Composer, extra: dict) -> Mode:
    """A mode of an agent's tree; one declared with ``protocol:`` gets the role region."""
    if spec.protocol is not None:
        return comp.region(name, spec, where, extra) or _mode(
            name, spec.model_copy(update={"protocol": None, "roles": None}), where
        )
    if not spec.modes:
        return _mode(name, spec, where)
    mode = _mode(name, spec.model_copy(update={"modes": None}), where)
    return dataclasses.replace(
        mode,
        children=tuple(
            _compose(n, m, (*where, "modes", n), comp, extra) for n, m in spec.modes.items()
        ),
    )


def _mode(name: str, spec: ModeSchema, where: DocPath) -> Mode:
    children = tuple(_mode(n, m, (*where, "modes", n)) for n, m in (spec.modes or {}).items())
    law = None
    if spec.law is not None:
        if isinstance(spec.law, str):
            law = LawBinding(spec.law, where=(*where, "law"))
        else:
            law = LawBinding(
                spec.law.use, spec.law.period, dict(spec.law.with_), where=(*where, "law")
            )
    transitions = tuple(
        _transition(t, (*where, "transitions", k)) for k, t in enumerate(spec.transitions)
    )
    history, history_default = (
        (spec.history, None)
        if isinstance(spec.history, str)
        else (spec.history.kind, spec.history.default)
    )
    return Mode(
        name,
        children,
        initial=spec.initial,
        parallel=spec.parallel,
        history=history,
        history_default=history_default,
        law=law,
        inputs=None if spec.inputs is None else dict(spec.inputs),
        input_period=spec.period,
        flow=None if spec.flow is None else dict(spec.flow),
        invariant=spec.invariant,
        final=spec.final,
        outcome=spec.outcome,
        transitions=transitions,
        where=where,
        on_entry=_actions(spec.entry, (*where, "entry")),
        on_exit=_actions(spec.exit, (*where, "exit")),
    )


def _actions(specs: list, where: DocPath) -> tuple[Action, ...]:
    """A list of actions (a transition's ``do:``, a mode's ``entry:`` or ``exit:``)."""
    actions: list[Action] = []
    for k, act in enumerate(specs):
        awhere = (*where, k)
        if isinstance(act, str):
            actions.append(Assign(act, awhere))
        elif isinstance(act, SendSchema):
            actions.append(Send(act.send, act.to, act.socket, dict(act.fields), awhere))
        elif isinstance(act, RaiseSchema):
            actions.append(Raise(act.raise_, awhere))
    return tuple(actions)


def _transition(spec, where: DocPath) -> Transition:
    targets = [spec.to] if isinstance(spec.to, str) else spec.to or [None]
    return Transition(
        targets[0],
        spec.on,
        spec.after,
        spec.guard,
        _actions(spec.do, (*where, "do")),
        spec.priority,
        where,
        more_targets=tuple(targets[1:]),
        local=spec.local,
    )

"""Protocol files, and composing a protocol's role region onto an agent's mode.

A team agent writes ``Transport: {protocol: role_assignment, initial: Follow, roles: {lead:
..., follow: ...}}``. The protocol's region modes (Lead, Follow, Requesting, ...) become
``Transport``'s children; a region mode with ``role: lead`` gets the agent's ``lead`` body
(its law, submodes and transitions) plus the protocol's own transitions, so a follower that
is waiting for a grant keeps following. The protocol's parameters and variables become the
agent's (its own and team parameters take precedence), its streams are sent by the agent,
and its message types (with their ack policies) are declared team-wide.

Protocols are found by name among the shipped ones (``hybridteam/protocols/<name>.yaml``) or
as a path relative to the team file. Errors inside a protocol are reported in the protocol's
file: document paths of protocol parts start with an :class:`InFile` tag.
"""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

from pydantic import ValidationError

from hybridteam.errors import DocPath, ModelError, did_you_mean
from hybridteam.io.errors import located_errors
from hybridteam.io.schema import MessageDeclSchema, ProtocolFile
from hybridteam.io.yamlpos import Positions, SourceError, load_yaml
from hybridteam.model import AckPolicy, MessageSpec, Mode, StreamSpec


class InFile(str):
    """First element of a document path that lies in another file (a protocol)."""

    __slots__ = ()


@dataclasses.dataclass
class Protocol:
    doc: ProtocolFile
    filename: str
    positions: Positions

    @property
    def tag(self) -> InFile:
        return InFile(self.filename)


class ProtocolErrors(Exception):
    def __init__(self, errors: list[SourceError]) -> None:
        self.errors = errors
        super().__init__("\n".join(map(str, errors)))


def shipped() -> list[str]:
    """Names of the protocols that come with hybridteam."""
    root = resources.files("hybridteam.protocols")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".yaml"))


def find(reference: str, base: Path) -> Path | None:
    """The file a protocol reference names: a shipped name or a path from the team file."""
    if reference.endswith((".yaml", ".yml")) or "/" in reference:
        path = (base / reference).resolve()
        return path if path.is_file() else None
    candidate = resources.files("hybridteam.protocols") / f"{reference}.yaml"
    return Path(str(candidate)) if candidate.is_file() else None


def load_protocol(path: Path) -> Protocol:
    """Read and validate one protocol file; :class:`ProtocolErrors` with located errors."""
    filename = str(path)
    try:
        data, positions = load_yaml(path, filename=filename)
    except SourceError as exc:
        raise ProtocolErrors([exc]) from None
    try:
        doc = ProtocolFile.model_validate(data)
    except ValidationError as exc:
        raise ProtocolErrors(located_errors(exc, ProtocolFile, data, positions, filename)) from None
    return Protocol(doc, filename, positions)


class Composer:
    """Loads protocols once per team and composes them onto agents."""

    def __init__(self, base: Path, mode_builder) -> None:
        self.base = base
        self.cache: dict[str, Protocol] = {}
        #: the positions of requirement files the team includes (their errors are located)
        self.requirement_files: dict[InFile, Positions] = {}
        self.build_mode = mode_builder
        self.used: dict[str, Protocol] = {}
        self.errors: list[ModelError] = []

    def get(self, reference: str, where: DocPath) -> Protocol | None:
        if reference not in self.cache:
            path = find(reference, self.base)
            if path is None:
                self.errors.append(
                    ModelError(
                        where,
                        f"unknown protocol '{reference}'",
                        hint=did_you_mean(reference, shipped()),
                    )
                )
                return None
            self.cache[reference] = load_protocol(path)
        proto = self.cache[reference]
        self.used[proto.doc.protocol] = proto
        return proto

    def section(self, reference: str, where: DocPath, key: str, what: str):
        """The protocol a reference names and its ``key`` section (``region`` or
        ``operator``); None, with the error recorded, when either is missing."""
        proto = self.get(reference, where)
        if proto is None:
            return None, None
        part = getattr(proto.doc, key)
        if part is None:
            self.errors.append(
                ModelError(where, f"protocol '{proto.doc.protocol}' declares no {what}")
            )
            return None, None
        return proto, part

    # ------------------------------------------------------------------ composition
    def region(self, name: str, spec, where: DocPath, agent_extra: dict) -> Mode | None:
        """The mode ``name`` (declared with ``protocol:``) with the protocol's region."""
        proto, region = self.section(spec.protocol, (*where, "protocol"), "region", "role region")
        if proto is None:
            return None
        roles = spec.roles or {}
        for role in roles:
            if role not in region.roles:
                self.errors.append(
                    ModelError(
                        (*where, "roles", role),
                        f"protocol '{proto.doc.protocol}' has no role '{role}'",
                        hint=did_you_mean(role, region.roles),
                        at_key=True,
                    )
                )
        tag = proto.tag
        children = []
        for rname, rspec in region.modes.items():
            rwhere: DocPath = (tag, "region", "modes", rname)
            own = self.build_mode(rname, rspec, rwhere)
            body = roles.get(rspec.role) if rspec.role else None
            if body is None:
                children.append(dataclasses.replace(own, role=rspec.role))
                continue
            bwhere: DocPath = (*where, "roles", rspec.role)
            mine = self.build_mode(rname, body, bwhere)
            children.append(
                dataclasses.replace(
                    mine,
                    transitions=own.transitions + mine.transitions,
                    where=rwhere,
                    invariant=mine.invariant or own.invariant,
                    final=own.final,
                    outcome=own.outcome,
                    role=rspec.role,
                    body=bwhere,
                )
            )
        self._add_agent_parts(proto, agent_extra, where)
        host = self.build_mode(
            name, spec.model_copy(update={"protocol": None, "roles": None}), where
        )
        return dataclasses.replace(
            host, children=tuple(children), initial=spec.initial or region.initial
        )

    def operator(
        self, reference: str, where: DocPath, agent_extra: dict
    ) -> tuple[Mode, ...] | None:
        proto, op = self.section(reference, (*where, "operator"), "operator", "operator")
        if proto is None:
            return None
        tag = proto.tag
        agent_extra["initial"] = op.initial
        _defaults(agent_extra, op.parameters, op.variables)
        self._add_agent_parts(proto, agent_extra, where, streams=False)
        return tuple(
            self.build_mode(n, m, (tag, "operator", "modes", n)) for n, m in op.modes.items()
        )

    def _add_agent_parts(
        self, proto: Protocol, extra: dict, where: DocPath, streams: bool = True
    ) -> None:
        doc, tag = proto.doc, proto.tag
        _defaults(extra, doc.parameters, doc.variables)
        if streams:
            for j, s in enumerate(doc.streams):
                extra["streams"].append(
                    StreamSpec(
                        s.message,
                        s.rate,
                        dict(s.fields),
                        tuple(s.while_ or ()),
                        s.socket,
                        (tag, "streams", j),
                    )
                )

    def messages(self) -> dict[str, MessageSpec]:
        """Message types of every protocol used (first declaration wins; clashes reported)."""
        out: dict[str, MessageSpec] = {}
        for proto in self.used.values():
            tag = proto.tag
            for name, m in proto.doc.messages.items():
                where: DocPath = (tag, "messages", name)
                spec = message_spec(name, m, proto.doc.protocol, where)
                if name in out and out[name].protocol != spec.protocol:
                    self.errors.append(
                        ModelError(
                            where,
                            f"message '{name}' is also declared by protocol '{out[name].protocol}'",
                            at_key=True,
                        )
                    )
                out.setdefault(name, spec)
        return out


def message_spec(name: str, m: MessageDeclSchema, protocol: str, where: DocPath) -> MessageSpec:
    """The model of a declared message type, a protocol's or (``protocol`` "") a team's."""
    ack = (
        None
        if m.ack is None
        else AckPolicy(m.ack.timeout, m.ack.retries, (*where, "ack"), m.ack.dedupe)
    )
    return MessageSpec(name, m.socket, tuple(m.fields), ack, m.priority, protocol, where)


def _defaults(extra: dict, parameters: dict, variables: dict) -> None:
    """A protocol's parameters and variables, where the agent does not declare its own."""
    for k, v in parameters.items():
        extra["parameters"].setdefault(k, v)
    for k, v in variables.items():
        extra["variables"].setdefault(k, v)

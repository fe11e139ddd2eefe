"""The format of ``trace.json``, checked before a view reads one.

The views (``timeline``, ``plot``, ``animate``, ``sequence``) take a trace file as input, and
a file can be anything: hand-edited, cut short, produced by another version, or made to
break the reader (a list where an object belongs, ``inf`` times, ragged samples). This
pydantic model says what a trace is — the keys, their types, every table column as long as
the others, instances within ``0..n-1``, samples shaped ``(len(t), n, columns)`` — so a bad
file is refused with the path of its first bad field instead of failing somewhere inside
matplotlib.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hybridteam.io.yamlcompose import LONE_SURROGATE
from hybridteam.trace import INTERVAL_COLUMNS, MESSAGE_COLUMNS, TRANSITION_COLUMNS

Finite = Annotated[float, Field(allow_inf_nan=False)]
Time = Annotated[float, Field(allow_inf_nan=True)]  # a lost message's t_recv is null/NaN
Count = Annotated[int, Field(ge=0)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="allow", allow_inf_nan=False)


class ModeMeta(_Model):
    path: str
    depth: Count
    kind: Literal["leaf", "or", "and"]
    final: bool
    role: str | None = None


class AgentMeta(_Model):
    name: str
    plant: str
    state: list[str]
    inputs: list[str]
    modes: list[ModeMeta]
    footprint: dict[str, Any] | None = None


class CollisionMark(_Model):
    """Where and when a robot, pair or payload first collided (drawn by the views)."""

    instance: Count
    who: str
    t: Finite
    x: Finite
    y: Finite


class WorldMeta(_Model):
    collisions: list[CollisionMark] = Field(default_factory=list)


class Meta(_Model):
    team: str
    n: Annotated[int, Field(ge=1)]
    seed: int | list[int]
    duration: Annotated[float, Field(ge=0, allow_inf_nan=False)]
    agents: list[AgentMeta] = Field(min_length=1)
    series: dict[str, list[str]] = Field(default_factory=dict)
    world: WorldMeta | None = None
    payloads: list[str] | None = None


class Outcome(_Model):
    instance: Count
    outcome: str
    t: Finite
    message: str
    stats: dict[str, Any] | None = None


class Samples(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    t: list[Finite]
    agents: dict[str, list[list[list[Finite | None]]]]


def _table(columns: tuple[str, ...], ints: tuple[str, ...], floats: tuple[str, ...]):
    fields: dict[str, Any] = {}
    for c in columns:
        kind = list[int] if c in ints else list[Time | None] if c in floats else list[str]
        fields[c] = (kind, ...)
    return fields


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="after")
    def _same_length(self) -> _Table:
        lengths = {name: len(v) for name, v in self.__dict__.items()}
        if len(set(lengths.values())) > 1:
            first = next(iter(lengths))
            other = next(k for k, v in lengths.items() if v != lengths[first])
            raise ValueError(
                f"column '{other}' has {lengths[other]} rows, column '{first}' {lengths[first]}"
            )
        return self


def _make(
    name: str, columns: tuple[str, ...], ints: tuple[str, ...], floats: tuple[str, ...]
) -> type[_Table]:
    from pydantic import create_model

    return create_model(name, __base__=_Table, **_table(columns, ints, floats))


Transitions = _make("Transitions", TRANSITION_COLUMNS, ("instance", "step"), ("t",))
Intervals = _make("Intervals", INTERVAL_COLUMNS, ("instance", "depth"), ("start", "end"))
Messages = _make("Messages", MESSAGE_COLUMNS, ("instance", "seq", "msg_id"), ("t_send", "t_recv"))


class TraceFile(BaseModel):
    """A whole ``trace.json`` (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    format: Literal["hybridteam.trace"]
    version: Literal[1]
    meta: Meta
    outcomes: list[Outcome]
    transitions: Transitions  # type: ignore[valid-type]  # (a model _make builds)
    intervals: Intervals  # type: ignore[valid-type]  # (a model _make builds)
    messages: Messages  # type: ignore[valid-type]  # (a model _make builds)
    samples: Samples

    @model_validator(mode="after")
    def _consistent(self) -> TraceFile:
        n = self.meta.n
        if len(self.outcomes) != n:
            raise ValueError(f"outcomes: {len(self.outcomes)} entries for n = {n} instances")
        for name in ("transitions", "intervals", "messages"):
            bad = [i for i in getattr(self, name).instance if not 0 <= i < n]
            if bad:
                raise ValueError(f"{name}.instance: {bad[0]} is not an instance of 0..{n - 1}")
        columns = {a.name: len(a.state) for a in self.meta.agents}
        columns.update({k: len(v) for k, v in self.meta.series.items()})
        missing = sorted(set(columns) - set(self.samples.agents))
        if missing:
            raise ValueError(f"samples.agents: no samples of '{missing[0]}'")
        k = len(self.samples.t)
        for name, rows in self.samples.agents.items():
            d = columns.get(name)
            if d is None:
                raise ValueError(f"samples.agents.{name}: not an agent or series of the run")
            if len(rows) != k or any(len(r) != n or any(len(c) != d for c in r) for r in rows):
                raise ValueError(
                    f"samples.agents.{name}: expected {k} x {n} x {d} values "
                    "(times x instances x columns)"
                )
        return self


def _lone_surrogate(data: Any, where: str = "") -> str | None:
    """Where a string (or key) of ``data`` holds a lone surrogate (JSON's ``"\\ud800"``
    escape gives one; no SVG, PNG label or terminal can hold it), as
    ``"meta.agents[0].name: U+D800 ..."``; or None. Lists of numbers are not walked: a
    column is numbers or strings (the schema checks which) and samples are numbers."""
    if isinstance(data, str):
        lone = LONE_SURROGATE.search(data)
        return (
            None
            if lone is None
            else (
                f"{where.lstrip('.') or 'the file'}: U+{ord(lone.group()):04X} (a lone surrogate "
                "escape) is not text"
            )
        )
    if isinstance(data, dict):
        for key, value in data.items():
            found = _lone_surrogate(key, where) or _lone_surrogate(value, f"{where}.{key}")
            if found:
                return found
    elif isinstance(data, list) and data and not isinstance(data[0], int | float):
        for i, value in enumerate(data):
            if found := _lone_surrogate(value, f"{where}[{i}]"):
                return found
    return None


def first_problem(model: type[BaseModel], data: Any, what: str) -> tuple[tuple, str] | None:
    """The first problem of ``data`` read as ``model``: its path in the file (JSON keys and
    indices) and ``"samples.t[3]: ..."``; None when it fits. ``what`` names the file's kind
    in the message for data that is not even a JSON object."""
    try:
        model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        path = _in_data(err["loc"], data)
        where = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path)
        where = where.lstrip(".") or "the file"
        message = err["msg"].removeprefix("Value error, ")
        if err["type"] == "model_type":
            message = f"expected a JSON object of {what}"
        return path, (f"{where}: {message}" if err["loc"] else message)
    return None


def _in_data(loc: tuple, data: Any) -> tuple:
    """The segments of a pydantic ``loc`` that are keys and indices of ``data`` (or a key
    missing from an object): without the names of union members pydantic inserts
    (``seed.int``), which the file does not have."""
    path = []
    for seg in loc:
        in_dict = isinstance(data, dict) and isinstance(seg, str) and seg in data
        in_list = isinstance(data, list) and type(seg) is int and 0 <= seg < len(data)
        if in_dict or in_list:
            data = data[seg]
            path.append(seg)
        elif isinstance(data, dict):  # a required key the object lacks: the path ends here
            path.append(seg)
            break
    return tuple(path)


def check_trace(data: Any) -> str | None:
    """The first problem of a parsed ``trace.json`` (``"samples.t[3]: ..."``), or None."""
    if found := _lone_surrogate(data):
        return found
    problem = first_problem(TraceFile, data, "a hybridteam trace")
    return None if problem is None else problem[1]

"""What every kind of hybridteam file has in common: how it is read, told apart, loaded.

A file kind (team, protocol, study) is a :class:`FileKind`: its name, the keys that mark a
document as one of its kind when it has no ``kind:`` key, its pydantic schema (for
``hybridteam schema``) and a loader that turns a parsed :class:`Document` into a
:class:`Loaded` model. The kinds are collected above ``io`` and ``sweep`` by
:mod:`hybridteam.kinds`, which reads a file once, tells its kind and dispatches; ``io``
never needs to know about studies, nor ``sweep`` about the dispatch.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from hybridteam.io.yamlpos import Positions, SourceError, load_yaml


class InputErrors(Exception):
    """All problems found in one input file; ``str()`` gives one located line per error."""

    def __init__(self, errors: list[SourceError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))


@dataclass(frozen=True)
class Document:
    """A parsed YAML file: its data and where each value came from."""

    filename: str
    data: Any
    positions: Positions


@dataclass
class Loaded:
    """A validated file: its kind, its model (a Team, a protocol document, a Study) and
    any warnings."""

    kind: str
    model: Any
    warnings: list[SourceError] = field(default_factory=list)


@dataclass(frozen=True)
class FileKind:
    """One kind of file (see the module docstring)."""

    name: str
    schema: Callable[[], type[BaseModel]]
    load: Callable[[Document], Loaded]
    marks: tuple[str, ...] = ()  # top-level keys that tell this kind without ``kind:``


def read_document(source: str | os.PathLike) -> Document:
    """Parse a YAML file (an ``.scxml`` chart: a team of one agent, see
    :mod:`hybridteam.io.scxml`); raise :class:`InputErrors` on any problem reading it."""
    filename = str(source)
    if filename.lower().endswith(".scxml"):
        from hybridteam.io.scxml import read_chart

        return read_chart(source)
    try:
        data, positions = load_yaml(Path(source), filename=filename)
    except SourceError as exc:
        raise InputErrors([exc]) from None
    return Document(filename, data, positions)


def detect(data: Any, kinds: Sequence[FileKind]) -> str | None:
    """The kind a document declares (``kind:``), else the first kind whose marks it has."""
    if not isinstance(data, dict):
        return None
    kind = data.get("kind")
    if isinstance(kind, str):
        return kind
    for k in kinds:
        if any(mark in data for mark in k.marks):
            return k.name
    return None


def kind_error(
    doc: Document, kind: str | None, known: Sequence[str], expected: str = ""
) -> InputErrors:
    """A located error for a document of no known kind, or of another kind than
    ``expected`` (``"expected a team file, got a study file"``)."""
    from hybridteam.errors import did_you_mean

    if expected and kind in known:
        what = f"expected a {expected} file, got a {kind} file"
    elif kind:
        hint = did_you_mean(kind, known)
        what = f"unknown file kind '{kind}' (kinds: {', '.join(known)})" + (
            f"; {hint}" if hint else ""
        )
    else:
        what = "cannot tell what kind of file this is (expected e.g. 'team:' and 'agents:')"
    mark = doc.positions.value(("kind",)) if kind else None
    return InputErrors(
        [
            SourceError(
                doc.filename,
                mark.line if mark else 1,
                mark.column if mark else 1,
                ("kind",) if kind else (),
                what,
            )
        ]
    )

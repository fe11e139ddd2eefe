"""Safe YAML loading that remembers where every key and value came from.

Users write robot teams and hybrid automata by hand, so a mistake must be reported as
``file:line:column`` plus the path inside the document. PyYAML's own constructors throw the
node marks away and apply YAML 1.1 scalar rules (``on``/``no`` become booleans, ``1e-6`` stays a
string), which would silently corrupt transition tables keyed by ``on:``. We therefore let PyYAML
compose the node graph only, and build plain Python values ourselves with YAML 1.2-like rules,
recording a :class:`Mark` for every value and key on the way.
"""

from __future__ import annotations

import bisect
import os
import re
from dataclasses import dataclass
from typing import Any

from hybridteam.errors import printable

Path = tuple[str | int, ...]

#: Values a document may expand to through aliases before we call it an alias bomb.
MAX_NODES = 100_000
#: Nesting depth limit: far beyond any real model, well below Python's recursion limit.
MAX_DEPTH = 200

_PLAIN = "tag:hybridteam,2024:plain"  # marker tag: untagged plain scalar, typed by our own rules
_STD = "tag:yaml.org,2002:"
_BREAKS = "\n\x85\u2028\u2029"
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
_NULL = re.compile(r"~|null|Null|NULL|")
_BOOL = {"true": True, "True": True, "TRUE": True, "false": False, "False": False, "FALSE": False}
_INT = re.compile(r"[-+]?[0-9]+")
_FLOAT = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?")
_SPECIAL = re.compile(r"[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)")
_LINE = re.compile(r"^.*$", re.MULTILINE)
_PROPERTIES = re.compile(r"(?:[&!]\S*(?:\s+|#[^\n]*)*)*")  # anchors, tags, comments between


@dataclass(frozen=True)
class Mark:
    """A 1-based position in a source file (PyYAML's marks are 0-based)."""

    line: int
    column: int


def format_path(path: Path) -> str:
    """Render a document path the way users would write it: ``agents.ball.modes[2].guard``."""
    out: list[str] = []
    for part in path:
        if isinstance(part, int):
            out.append(f"[{part}]")
        elif _NAME.fullmatch(part):
            out.append(f".{part}" if out else part)
        else:
            out.append("[" + repr(part) + "]")
    return "".join(out)


class SourceError(Exception):
    """One located problem in an input file; ``str()`` is the message users see.

    The location parts are optional because some problems (an unreadable file, an empty file)
    have no meaningful position; ``str()`` simply leaves out what is unknown.
    """

    def __init__(
        self,
        file: str,
        line: int | None = None,
        column: int | None = None,
        path: Path = (),
        message: str = "",
    ) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.path = tuple(path)
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        """``file:line:column: path: message``, printable: a name quoted from the file
        (or the file's own name) shows its control characters as escapes, never runs them
        on the terminal."""
        numbers = [n for n in (self.line, self.column) if n is not None] if self.line else []
        where = ":".join([self.file, *map(str, numbers)])
        return printable(
            ": ".join([where, *([format_path(self.path)] if self.path else []), self.message])
        )

    def __reduce__(self) -> tuple[Any, ...]:
        # Exceptions pickle via their args; ours has keyword-ish state (multiprocessing needs it).
        return (type(self), (self.file, self.line, self.column, self.path, self.message))


@dataclass(frozen=True)
class _Entry:
    value: Mark
    key: Mark | None
    scalar: tuple[int, int, str | None, str] | None  # content start index, end index, style, raw


class _Lines:
    """Index <-> line/column conversion for the (newline-normalised) document text."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.starts = [0] + [m.end() for m in re.finditer("[" + _BREAKS + "]", text)]

    def mark(self, index: int) -> Mark:
        row = bisect.bisect_right(self.starts, index) - 1
        return Mark(row + 1, index - self.starts[row] + 1)


class Positions:
    """Where each value (and each mapping key) of a loaded document starts.

    Paths are tuples of keys and list indices from the document root, matching the shape of
    the loaded data, so validation errors (which speak in data paths) can be located.
    """

    def __init__(self, filename: str, lines: _Lines, entries: dict[Path, _Entry]) -> None:
        self.filename = filename
        self._lines = lines
        self._entries = entries

    @classmethod
    def of_marks(cls, filename: str, text: str, marks: dict[Path, Mark]) -> Positions:
        """Positions of a document built from another format (an SCXML chart): each path
        at its mark (its key too), no scalar offsets (an error points at the element)."""
        return cls(
            filename, _Lines(text), {path: _Entry(mark, mark, None) for path, mark in marks.items()}
        )

    def value(self, path: Path) -> Mark | None:
        entry = self._entries.get(tuple(path))
        return entry.value if entry else None

    def key(self, path: Path) -> Mark | None:
        entry = self._entries.get(tuple(path))
        return entry.key if entry else None

    def nearest(self, path: Path) -> tuple[Path, Mark]:
        """The longest prefix of ``path`` that exists in the document, with its mark."""
        path = tuple(path)
        for end in range(len(path), -1, -1):
            entry = self._entries.get(path[:end])
            if entry is not None:
                return path[:end], entry.value
        return (), Mark(1, 1)

    def in_scalar(self, path: Path, offset: int) -> Mark | None:
        """Position of character ``offset`` of the scalar string at ``path``.

        Lets callers point at a bad token inside a value (e.g. ``vv`` in a guard expression)
        instead of at the start of the value. ``offset == len(value)`` means "just after it".
        """
        entry = self._entries.get(tuple(path))
        if entry is None or entry.scalar is None:
            return None
        start, end, style, raw = entry.scalar
        if not 0 <= offset <= len(raw):
            return None
        indices = _scalar_indices(self._lines.text, start, end, style, raw)
        if offset < len(raw):
            index = indices[offset]
        else:
            index = next((i + 1 for i in reversed(indices) if i is not None), None)
        if index is None:
            return entry.value  # best effort: alignment failed, point at the value itself
        return self._lines.mark(index)

    def error(self, path: Path, message: str, *, at_key: bool = False) -> SourceError:
        """A :class:`SourceError` at ``path`` (its key if ``at_key``), for semantic checks."""
        mark = self.key(path) if at_key else None
        if mark is None:
            mark = self.nearest(path)[1]
        return SourceError(self.filename, mark.line, mark.column, tuple(path), message)


def _scalar_indices(
    text: str, start: int, end: int, style: str | None, raw: str
) -> list[int | None]:
    """Text index of each character of ``raw``, the loaded value of a scalar.

    We list the characters the source contributes (block indentation removed, an escape
    standing for the one character it produces) and align ``raw`` against them greedily;
    a folded line break may stand for a space.
    """
    seq: list[tuple[int, str | None]] = []  # None: an escape, stands for any one character
    if style in ("|", ">"):
        body = text.find("\n", start, end) + 1 or end
        rows = [(m.start(), m.group()) for m in _LINE.finditer(text, body, end)]
        widths = [len(row) - len(row.lstrip(" ")) for _, row in rows if row.strip()]
        explicit = re.match(r"[|>][-+]?[1-9]", text[start:body])  # e.g. "|2": indent is given
        indent = (min(widths) if explicit else widths[0]) if widths else 0
        for at, row in rows:
            seq.extend((at + k, ch) for k, ch in enumerate(row[indent:], indent))
            seq.append((at + len(row), "\n"))
    elif style == '"':
        i = start + 1
        while i < end - 1:
            if text[i] != "\\":
                seq.append((i, text[i]))
                i += 1
            elif text[i + 1] in _BREAKS:  # escaped line break: contributes nothing
                i += 2
                while i < end and text[i] in " \t":
                    i += 1
            else:
                seq.append((i, None))
                i += 2 + {"x": 2, "u": 4, "U": 8}.get(text[i + 1], 0)
    elif style == "'":
        i = start + 1
        while i < end - 1:
            seq.append((i, text[i]))
            i += 2 if text[i : i + 2] == "''" else 1
    else:
        seq = [(i, text[i]) for i in range(start, end)]
    out: list[int | None] = []
    j = 0
    for ch in raw:
        found = None
        while j < len(seq):
            index, src = seq[j]
            j += 1
            if src in (ch, None) or (ch in " \n" and src in _BREAKS):
                found = index
                break
        out.append(found)
    return out


def load_yaml(
    source: str | bytes | os.PathLike[str], *, filename: str | None = None
) -> tuple[Any, Positions]:
    """Load one YAML document whose top level must be a mapping.

    ``source`` is the document text (``str`` or ``bytes``) or a path (``os.PathLike``; plain
    strings are always treated as text, never guessed to be paths). Returns the plain data and
    its :class:`Positions`. Any problem raises :class:`SourceError` and nothing else.
    """
    from hybridteam.io.yamlcompose import compose_yaml

    return compose_yaml(source, filename=filename)

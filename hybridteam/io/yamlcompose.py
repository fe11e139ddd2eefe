"""Compose YAML with PyYAML's parser, then build plain values with our own scalar rules.

PyYAML composes the node graph (with marks); :class:`_Builder` turns it into dicts, lists
and scalars under YAML 1.2-like rules (``on``/``no`` stay strings, ``1e-6`` is a float),
records a :class:`~.yamlpos.Mark` for every key and value, and rejects what a model file
must not contain: custom tags, non-name keys, duplicate keys, alias bombs, deep nesting.
"""

from __future__ import annotations

import codecs
import os
import re
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import BaseResolver
from yaml.scanner import Scanner

try:
    # (types-PyYAML declares it in yaml._yaml, which yaml.cyaml imports it from)
    from yaml.cyaml import CParser  # type: ignore[attr-defined]
except ImportError:  # PyYAML built without libyaml
    CParser = None  # type: ignore[assignment,misc]

from hybridteam.io.files import read_regular
from hybridteam.io.yamlpos import (
    _BOOL,
    _FLOAT,
    _INT,
    _NULL,
    _PLAIN,
    _PROPERTIES,
    _SPECIAL,
    _STD,
    MAX_DEPTH,
    MAX_NODES,
    Mark,
    Path,
    Positions,
    SourceError,
    _Entry,
    _Lines,
)


class _Hooks:
    """What our composers add to PyYAML's: no implicit typing, alias tracking, a depth cap."""

    alias_uses: list[tuple[str | None, Any, Node]]  # (anchor, its yaml or libyaml mark, node)
    depth: int

    def resolve(self, kind: type, value: Any, implicit: tuple[bool, bool]) -> str:
        # Untagged plain scalars get a marker tag; _Builder types them with YAML 1.2 rules.
        if kind is ScalarNode and implicit[0]:
            return _PLAIN
        return super().resolve(kind, value, implicit)  # type: ignore[misc]  # (a mixin: the resolver's)

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        event = self.peek_event()  # type: ignore[attr-defined]  # (a mixin: the parser's)
        if isinstance(event, yaml.AliasEvent):
            node = super().compose_node(parent, index)  # type: ignore[misc]  # (the composer's)
            self.alias_uses.append((event.anchor, event.start_mark, node))
            return node
        self.depth += 1
        if self.depth > MAX_DEPTH:
            message = f"the document is nested too deeply (more than {MAX_DEPTH} levels)"
            raise yaml.composer.ComposerError(None, None, message, event.start_mark)
        try:
            return super().compose_node(parent, index)  # type: ignore[misc]  # (the composer's)
        finally:
            self.depth -= 1


class _Composer(_Hooks, Reader, Scanner, Parser, Composer, BaseResolver):
    """PyYAML's pure-Python reader/scanner/parser/composer with our hooks."""

    def __init__(self, text: str) -> None:
        Reader.__init__(self, text)
        Scanner.__init__(self)
        Parser.__init__(self)
        Composer.__init__(self)
        BaseResolver.__init__(self)
        self.alias_uses = []
        self.depth = 0


if CParser is not None:

    class _FastComposer(_Hooks, Composer, CParser, BaseResolver):
        """The same composer on libyaml's parser: an order of magnitude faster on large
        files. Only for documents that parse: on any error the document is parsed again
        by :class:`_Composer`, whose messages are the ones tested."""

        def __init__(self, text: str) -> None:
            CParser.__init__(self, text)
            Composer.__init__(self)
            BaseResolver.__init__(self)
            self.alias_uses = []
            self.depth = 0


def _short_tag(tag: str) -> str:
    return "!!" + tag[len(_STD) :] if tag.startswith(_STD) else tag


def _describe(value: Any) -> str:
    """Plain-words name of a value's kind, for messages about the wrong kind of thing."""
    kinds = {bool: "a boolean", int: "a number", float: "a number", str: "a string", list: "a list"}
    return "null" if value is None else kinds.get(type(value), "a mapping")


class _Builder:
    """Turns the composed node graph into plain Python values, recording positions."""

    def __init__(self, filename: str, lines: _Lines) -> None:
        self.filename = filename
        self.lines = lines
        self.entries: dict[Path, _Entry] = {}

    def fail(self, mark: yaml.Mark, path: Path, message: str) -> SourceError:
        return SourceError(self.filename, mark.line + 1, mark.column + 1, path, message)

    def build(self, node: Node, path: Path, key: Mark | None = None) -> Any:
        mark = Mark(node.start_mark.line + 1, node.start_mark.column + 1)
        if isinstance(node, ScalarNode):
            value = self.scalar(node, path)
            start = self.content_start(node.start_mark.index, node.end_mark.index)
            info = (start, node.end_mark.index, node.style, node.value)
            self.entries[path] = _Entry(mark, key, info)
            return value
        self.entries[path] = _Entry(mark, key, None)
        expected = _STD + ("seq" if isinstance(node, SequenceNode) else "map")
        if node.tag != expected:
            raise self.fail(node.start_mark, path, self.tag_message(node.tag))
        if isinstance(node, SequenceNode):
            return [self.build(item, (*path, i)) for i, item in enumerate(node.value)]
        result: dict[str, Any] = {}
        first: dict[str, Mark] = {}
        for key_node, value_node in node.value:
            name = self.key(key_node, path)
            key_mark = Mark(key_node.start_mark.line + 1, key_node.start_mark.column + 1)
            if name in first:
                message = f"duplicate key {name!r} (first at line {first[name].line})"
                raise self.fail(key_node.start_mark, (*path, name), message)
            first[name] = key_mark
            result[name] = self.build(value_node, (*path, name), key_mark)
        return result

    def key(self, node: Node, path: Path) -> str:
        if not isinstance(node, ScalarNode):
            what = "a list" if isinstance(node, SequenceNode) else "a mapping"
            raise self.fail(node.start_mark, path, f"mapping keys must be names, got {what}")
        if node.tag == _PLAIN and node.value == "<<":
            message = "merge keys ('<<') are not supported; write the keys out in full"
            raise self.fail(node.start_mark, path, message)
        value = self.scalar(node, path)
        if not isinstance(value, str):
            shown = node.value or "an empty key"
            message = f"mapping keys must be names, got {shown}"
            if node.value:
                message += f"; write '{node.value}' in quotes to use it as a name"
            raise self.fail(node.start_mark, path, message)
        return value

    def scalar(self, node: ScalarNode, path: Path) -> Any:
        """Type a scalar: our plain-scalar rules, or an explicit standard tag like ``!!str``."""
        raw, tag = node.value, node.tag
        lone = LONE_SURROGATE.search(raw)
        if lone:  # "\ud800" in double quotes: no UTF-8 file, SVG or trace can hold it
            raise self.fail(
                node.start_mark,
                path,
                f"U+{ord(lone.group()):04X} (a lone "
                "surrogate escape) cannot be written as UTF-8; names and text "
                "must be valid Unicode",
            )
        if tag in (_PLAIN, _STD + "str"):
            return self.plain(raw, node, path) if tag == _PLAIN else raw
        kinds = {"null": type(None), "bool": bool, "int": int, "float": float}
        kind = kinds.get(tag.removeprefix(_STD)) if tag.startswith(_STD) else None
        if kind is None:
            raise self.fail(node.start_mark, path, self.tag_message(tag))
        value = self.plain(raw, node, path)
        value = float(value) if kind is float and type(value) is int else value
        if type(value) is not kind:
            raise self.fail(node.start_mark, path, f"{raw!r} is not a valid {_short_tag(tag)}")
        return value

    def plain(self, raw: str, node: ScalarNode, path: Path) -> Any:
        """YAML 1.2 core-schema typing (minus the oddities) of an untagged plain scalar."""
        if _NULL.fullmatch(raw):
            return None
        if raw in _BOOL:
            return _BOOL[raw]
        if _INT.fullmatch(raw):
            try:
                return int(raw)
            except ValueError:  # longer than Python's int-from-string digit limit
                raise self.fail(node.start_mark, path, "integer is too large") from None
        if _FLOAT.fullmatch(raw) or _SPECIAL.fullmatch(raw):
            return float(raw.lower().replace(".inf", "inf").replace(".nan", "nan"))
        return raw

    def tag_message(self, tag: str) -> str:
        return (
            f"tag {_short_tag(tag)} is not supported (only plain mappings, lists, strings, "
            "numbers, booleans and null are allowed)"
        )

    def content_start(self, index: int, end: int) -> int:
        """Skip an anchor/tag written before a scalar, so offsets count from its content."""
        match = _PROPERTIES.match(self.lines.text, index, end)
        return match.end() if match else index


def _check_aliases(root: Node, composer: _Hooks, filename: str) -> None:
    """Reject recursive aliases and alias bombs before expanding anything."""
    if not composer.alias_uses:
        return
    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(node: Node) -> int:
        ident = id(node)
        if ident in sizes:
            return sizes[ident]
        if ident in active:
            anchor, mark, _ = next(use for use in composer.alias_uses if use[2] is node)
            message = f"alias '*{anchor}' refers to a value that contains it (recursive alias)"
            raise SourceError(filename, mark.line + 1, mark.column + 1, (), message)
        active.add(ident)
        total = 1
        if isinstance(node, SequenceNode):
            total += sum(size(child) for child in node.value)
        elif isinstance(node, MappingNode):
            total += sum(size(k) + size(v) for k, v in node.value)
        active.discard(ident)
        sizes[ident] = min(total, MAX_NODES + 1)
        return sizes[ident]

    if size(root) > MAX_NODES:
        anchor, mark, _ = max(composer.alias_uses, key=lambda use: sizes[id(use[2])])
        message = (
            f"aliases expand the document to more than {MAX_NODES} values "
            f"(the biggest is '*{anchor}' here)"
        )
        raise SourceError(filename, mark.line + 1, mark.column + 1, (), message)


def _decode(data: bytes, filename: str) -> str:
    """Strict UTF-8 decoding, so binary or Latin-1 files are reported, not half-parsed."""
    skip = 3 if data.startswith(codecs.BOM_UTF8) else 0
    try:
        return data[skip:].decode("utf-8")
    except UnicodeDecodeError as exc:
        pos = exc.start + skip
        line_start = data.rfind(b"\n", 0, pos) + 1
        column = len(data[max(line_start, skip) : pos].decode("utf-8", "replace")) + 1
        message = f"not a text file (invalid UTF-8 at byte {pos})"
        if data[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE):
            message += "; it looks like UTF-16, please save it as UTF-8"
        raise SourceError(filename, data.count(b"\n", 0, pos) + 1, column, (), message) from None


def _syntax_message(exc: yaml.MarkedYAMLError) -> str:
    """PyYAML's problem text, with the context it gives when that context is elsewhere."""
    problem, context = exc.problem or "invalid YAML", exc.context
    if context and context.startswith("found duplicate anchor") and exc.context_mark:
        name = context.split("'")[1] if "'" in context else "?"
        return f"duplicate anchor '&{name}' (first at line {exc.context_mark.line + 1})"
    if context == "expected a single document in the stream":
        return "expected a single document in the file, but found another ('---')"
    if "'\\t'" in problem:
        return problem + " (tabs are not allowed for indentation; use spaces)"
    mark, pmark = exc.context_mark, exc.problem_mark
    elsewhere = pmark is None or (mark and (mark.line, mark.column) != (pmark.line, pmark.column))
    if context and mark and elsewhere:
        return f"{problem} ({context} at line {mark.line + 1}, column {mark.column + 1})"
    return problem


def _compose(text: str, filename: str, lines: _Lines) -> tuple[Node | None, _Hooks]:
    """Run PyYAML up to the node graph; every failure becomes a located SourceError."""
    if CParser is not None:
        try:
            fast = _FastComposer(text)
            return fast.get_single_node(), fast
        except Exception:  # the slow parser below reports it, in its words
            pass
    try:
        composer = _Composer(text)
        return composer.get_single_node(), composer
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, column = (mark.line + 1, mark.column + 1) if mark else (None, None)
        raise SourceError(filename, line, column, (), _syntax_message(exc)) from None
    except yaml.reader.ReaderError as exc:  # NUL was caught earlier; other control characters
        at = lines.mark(exc.position)
        message = f"special character U+{exc.character:04X} is not allowed in YAML"
        raise SourceError(filename, at.line, at.column, (), message) from None
    except RecursionError:  # only if the caller is already deep; MAX_DEPTH normally stops it
        raise SourceError(filename, message="the document is nested too deeply") from None
    except yaml.YAMLError as exc:  # unmarked PyYAML errors: still ours to report
        raise SourceError(filename, None, None, (), f"invalid YAML: {exc}") from None


#: a UTF-16 surrogate on its own: YAML's "\ud800" escape gives one, and it is no character
LONE_SURROGATE = re.compile("[\ud800-\udfff]")

#: Model files larger than this are refused (``HYBRIDTEAM_MAX_FILE_MB`` raises it): a team
#: of a hundred robots is some 50 kB, and reading YAML costs seconds per megabyte.
MAX_FILE_MB = 1.0


def _read(path: os.PathLike[str], name: str) -> bytes:
    """A model file's bytes; only regular files of a sensible size (a FIFO would block
    forever, a device or a huge file would not end either)."""
    return read_regular(
        path, name, limit_mb=MAX_FILE_MB, env="HYBRIDTEAM_MAX_FILE_MB", what="model files"
    )


def read_text(path: os.PathLike[str], name: str) -> str:
    """A model file's text, read as a YAML file is (a regular file within the size limit,
    UTF-8); :class:`SourceError` otherwise. Other formats (SCXML charts) read it so."""
    return _decode(_read(path, name), name)


def compose_yaml(
    source: str | bytes | os.PathLike[str], *, filename: str | None = None
) -> tuple[Any, Positions]:
    """The implementation of :func:`hybridteam.io.yamlpos.load_yaml` (see there)."""
    if isinstance(source, os.PathLike):
        name = filename if filename is not None else os.fspath(source)
        text = _decode(_read(source, name), name)
    elif isinstance(source, bytes | bytearray):
        name = filename if filename is not None else "<string>"
        text = _decode(bytes(source), name)
    else:
        name = filename if filename is not None else "<string>"
        text = source
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = _Lines(text)
    if "\x00" in text:
        mark = lines.mark(text.index("\x00"))
        raise SourceError(name, mark.line, mark.column, (), "not a text file (contains a NUL byte)")
    root, composer = _compose(text, name, lines)
    if root is None or (root.tag == _PLAIN and root.value == ""):
        raise SourceError(name, 1, 1, (), "file is empty (no document in it)")
    _check_aliases(root, composer, name)
    builder = _Builder(name, lines)
    data = builder.build(root, ())
    if not isinstance(data, dict):
        message = f"expected a mapping of keys at the top level, got {_describe(data)}"
        raise SourceError(name, root.start_mark.line + 1, root.start_mark.column + 1, (), message)
    builder.entries[()] = _Entry(Mark(1, 1), None, None)  # the document itself starts at 1:1
    return data, Positions(name, lines, builder.entries)

"""Turn pydantic validation errors into located, plain-words messages.

pydantic speaks in *validation* paths: it inserts union-member and tag segments that do not
exist in the user's file, says "Extra inputs are not permitted" without naming the allowed keys,
and reports every member of a failed union. Users need the opposite: the line they wrote, the
path they would type, the key they probably meant. We walk the loaded data and the model type
side by side to translate each error, keep only the union member the user evidently meant, and
merge "expected X" / "expected Y" for the same value into one message.
"""

from __future__ import annotations

import re
import types
from collections.abc import Mapping, Sequence
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from hybridteam.errors import closest, did_you_mean
from hybridteam.io.yamlpos import Path, Positions, SourceError, format_path

_EXPECTED = {
    "float_parsing": "a number",
    "float_type": "a number",
    "int_parsing": "an integer",
    "int_type": "an integer",
    "int_from_float": "an integer",
    "bool_parsing": "true or false",
    "bool_type": "true or false",
    "string_type": "a string",
    "dict_type": "a mapping",
    "mapping_type": "a mapping",
    "model_type": "a mapping",
    "model_attributes_type": "a mapping",
    "dataclass_type": "a mapping",
    "list_type": "a list",
    "tuple_type": "a list",
    "set_type": "a list",
    "frozen_set_type": "a list",
    "iterable_type": "a list",
    "none_required": "nothing (null)",
    "finite_number": "a finite number",
}
_COMPARE = {
    "greater_than": ("gt", ">"),
    "greater_than_equal": ("ge", ">="),
    "less_than": ("lt", "<"),
    "less_than_equal": ("le", "<="),
    "multiple_of": ("multiple_of", "a multiple of"),
}
_QUOTED = re.compile(r"'((?:[^'\\]|\\.)*)'")


def _show(value: Any) -> str:
    """The offending input as the user would recognise it, kept short."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# --- walking the model type alongside the data --------------------------------------------


@dataclass(frozen=True)
class _Disc:
    """Carries a field's discriminator into the walk, like ``Field(discriminator=...)`` does."""

    discriminator: Any


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _peel(tp: Any) -> tuple[Any, str | None]:
    """Strip Annotated, Optional and type aliases; a real union comes back as a list."""
    disc = None
    for _ in range(100):
        origin = get_origin(tp)
        if origin is Annotated:
            for meta in tp.__metadata__:
                found = getattr(meta, "discriminator", None)
                found = getattr(found, "discriminator", found)  # pydantic.Discriminator
                disc = found if isinstance(found, str) else disc
            tp = get_args(tp)[0]
        elif origin in (Union, types.UnionType):
            members = [arg for arg in get_args(tp) if arg is not type(None)]
            if len(members) != 1:
                return members, disc
            tp = members[0]
        elif not isinstance(tp, type) and hasattr(tp, "__value__"):  # `type X = ...`
            tp = tp.__value__
        else:
            break
    return tp, disc


def _fields(model: type[BaseModel]) -> dict[str, Any]:
    """Keys accepted in the data for ``model`` -> FieldInfo."""
    config = model.model_config
    by_name = config.get("validate_by_name") or config.get("populate_by_name")
    out: dict[str, Any] = {}
    for name, info in model.model_fields.items():
        out[info.alias or name] = info
        if isinstance(info.validation_alias, str):
            out[info.validation_alias] = info
        if by_name:
            out.setdefault(name, info)
    return out


def _literals(tp: Any) -> list[Any] | None:
    tp, _ = _peel(tp)
    return list(get_args(tp)) if get_origin(tp) is Literal else None


def _child(tp: Any, seg: str | int) -> Any:
    """The type of ``tp[seg]``; Any when it cannot be known."""
    if _is_model(tp):
        info = _fields(tp).get(seg) if isinstance(seg, str) else None
        if info is None:
            return Any
        if info.discriminator is not None:
            return Annotated[info.annotation, _Disc(info.discriminator)]
        return info.annotation
    origin, args = get_origin(tp), get_args(tp)
    if not isinstance(origin, type):
        return Any
    if issubclass(origin, Mapping):
        return args[1] if len(args) == 2 else Any
    if issubclass(origin, tuple) and args:
        if len(args) == 2 and args[1] is Ellipsis:
            return args[0]
        return args[seg] if isinstance(seg, int) and seg < len(args) else Any
    if issubclass(origin, Sequence | AbstractSet):
        return args[0] if args else Any
    return Any


def _tag_field(model: Any, disc: str | None) -> tuple[str, list[Any]] | None:
    """(data key, allowed tag values) of a union member's discriminator field."""
    if disc is None or not _is_model(model):
        return None
    for name, info in model.model_fields.items():
        if disc in (name, info.alias):
            return info.alias or name, _literals(info.annotation) or []
    return None


def _by_label(members: list[Any], seg: Any, disc: str | None) -> Any:
    """The union member pydantic named by ``seg`` (class name, tag value or type label)."""
    if not isinstance(seg, str):
        return None
    for member in members:
        tp, _ = _peel(member)
        tag = _tag_field(tp, disc)
        if tag and seg in [str(value) for value in tag[1]]:
            return member
        name = getattr(get_origin(tp) or tp, "__name__", None) or getattr(tp, "_name", None)
        if isinstance(name, str) and (seg == name or seg.lower().startswith(name.lower() + "[")):
            return member
    return None


def _score(member: Any, value: Any) -> tuple[int, ...]:
    """How well ``value`` fits a union member; models compare tag literals, then keys."""
    tp, _ = _peel(member)
    if _is_model(tp):
        if not isinstance(value, dict):
            return (-1,)
        fields = _fields(tp)
        tags = 0
        for key, info in fields.items():
            options = _literals(info.annotation)
            if key in value and options is not None:
                tags += 1 if value[key] in options else -1
        missing = sum(1 for key, info in fields.items() if info.is_required() and key not in value)
        known = len(value.keys() & fields.keys())
        typos = sum(1 for key in value.keys() - fields.keys() if closest(str(key), fields))
        return (2, tags, known, typos, known - len(value), -missing)
    origin = get_origin(tp) or tp
    if isinstance(value, dict | list):
        kinds = Mapping if isinstance(value, dict) else Sequence | AbstractSet
        fits = isinstance(origin, type) and issubclass(origin, kinds) and origin is not str
        return (1,) if fits else (-1,)
    if origin is Literal:
        return (2,) if value in get_args(tp) else (0,)
    return (1,) if isinstance(tp, type) and isinstance(value, tp) else (0,)


def _best(members: list[Any], value: Any, disc: str | None) -> tuple[Any, bool]:
    """The member the user evidently meant, and whether that choice is unambiguous."""
    if disc is not None and isinstance(value, dict):
        for member in members:
            tag = _tag_field(_peel(member)[0], disc)
            if tag and tag[0] in value and value[tag[0]] in tag[1]:
                return member, True
    scores = [_score(member, value) for member in members]
    top = max(scores)
    return members[scores.index(top)], scores.count(top) == 1


@dataclass
class _Walk:
    path: list[str | int] = field(default_factory=list)
    value: Any = None
    parent: Any = None  # type that governs the container of the last path element
    tp: Any = Any  # type at the end of the walk
    unions: list[tuple[tuple[Any, ...], str, list[Any], str | None, Any]] = field(
        default_factory=list
    )


def _walk(loc: tuple[Any, ...], model: Any, data: Any) -> _Walk:
    """Map a pydantic ``loc`` onto the document, skipping segments the data does not have."""
    walk = _Walk(value=data)
    tp: Any = model
    for i, seg in enumerate(loc):
        tp, disc = _peel(tp)
        if isinstance(tp, list):
            chosen = _by_label(tp, seg, disc)
            if chosen is not None:
                walk.unions.append((loc[:i], seg, tp, disc, walk.value))
                tp = chosen
                continue
            tp, disc = _peel(_best(tp, walk.value, disc)[0])
        value = walk.value
        in_dict = isinstance(value, dict) and isinstance(seg, str) and seg in value
        in_list = isinstance(value, list) and type(seg) is int and 0 <= seg < len(value)
        if not (in_dict or in_list):
            continue  # pydantic's own segment: a union tag, '[key]', 'function-after[...]'
        walk.parent = tp
        walk.path.append(seg)
        walk.value = value[seg]
        tp = _child(tp, seg)
    tp, disc = _peel(tp)
    walk.tp = _peel(_best(tp, walk.value, disc)[0])[0] if isinstance(tp, list) else tp
    return walk


# --- messages ------------------------------------------------------------------------------


@dataclass
class _Item:
    path: Path
    anchor: str  # "key", "value"
    text: str = ""
    expected: str | None = None  # "expected <expected>, got <got>" messages can be merged
    got: str = ""
    hint: str | None = None
    key: str | None = None  # the missing key, or the key suggested for an unknown one

    def message(self) -> str:
        text = f"expected {self.expected}, got {self.got}" if self.expected else self.text
        return f"{text}; {self.hint}" if self.hint else text


def _describe(err: Any, walk: _Walk) -> _Item:
    kind, loc, ctx = err["type"], err["loc"], err.get("ctx") or {}
    given, path = err.get("input"), tuple(walk.path)
    item = _Item(path, "value", got=_show(given))
    last = loc[-1] if loc else None
    if kind == "missing":
        item.text = f"missing required key {last!r}" if isinstance(last, str) else "missing item"
        item.key = last if isinstance(last, str) else None
    elif kind == "extra_forbidden":
        item.anchor, name = "key", path[-1] if path else last
        item.text = f"unknown key {name!r}"
        if _is_model(walk.parent):
            item.key = closest(str(name), _fields(walk.parent))
            item.hint = f"did you mean {item.key!r}?" if item.key else None
    elif kind in ("union_tag_invalid", "union_tag_not_found"):
        disc = str(ctx.get("discriminator", "kind")).strip("'\"")
        if kind == "union_tag_not_found":
            item.text = f"missing required key {disc!r}"
            typo = closest(disc, walk.value) if isinstance(walk.value, dict) else None
            item.hint = f"is {typo!r} a misspelling of it?" if typo else None
        else:
            tags = _QUOTED.findall(str(ctx.get("expected_tags", "")))
            expected = ", ".join(repr(tag) for tag in tags)
            item.text = f"unknown {disc} {ctx.get('tag')!r}; expected one of {expected}"
            item.hint = did_you_mean(str(ctx.get("tag")), tags)
            if isinstance(walk.value, dict) and disc in walk.value:
                item.path = (*path, disc)
    elif kind in ("literal_error", "enum"):
        options = _literals(walk.tp) if kind == "literal_error" else None
        names = _QUOTED.findall(str(ctx.get("expected", ""))) if options is None else options
        shown = [repr(option) for option in names] or [str(ctx.get("expected", "?"))]
        item.expected = shown[0] if len(shown) == 1 else "one of " + ", ".join(shown)
        names = [str(option) for option in names]
        item.hint = did_you_mean(given, names) if isinstance(given, str) else None
    elif kind in _EXPECTED:
        item.expected = _EXPECTED[kind]
    elif kind in _COMPARE:
        key, op = _COMPARE[kind]
        bound = ctx.get(key)
        if isinstance(bound, float) and bound.is_integer():
            bound = int(bound)  # Field(gt=0) on a float field reports 0.0
        item.text = f"must be {op} {bound}, got {item.got}"
    elif kind in ("too_short", "too_long", "string_too_short", "string_too_long"):
        size = ctx.get("min_length", ctx.get("max_length"))
        bound = "at least" if kind.endswith("short") else "at most"
        unit = "character" if kind.startswith("string") else "item"
        actual = item.got if unit == "character" else ctx.get("actual_length", "?")
        item.text = f"must have {bound} {size} {unit}{'' if size == 1 else 's'}, got {actual}"
    elif kind == "string_pattern_mismatch":
        item.text = f"must match the pattern {ctx.get('pattern')!r}, got {item.got}"
    elif kind in ("value_error", "assertion_error"):
        item.text = re.sub(r"^(Value error|Assertion failed), ", "", err["msg"])
    elif err["msg"].startswith("Input should be "):
        item.expected = err["msg"][len("Input should be ") :]
    else:
        item.text = err["msg"]
    if "[key]" in loc:
        item.anchor = "key"
    return item


def _drop_unintended_members(walks: list[_Walk]) -> set[int]:
    """Indices of errors from union members other than the one the data evidently targets."""
    seen: dict[tuple[Any, ...], dict[str, list[int]]] = {}
    context: dict[tuple[Any, ...], tuple[list[Any], str | None, Any]] = {}
    for index, walk in enumerate(walks):
        for prefix, label, members, disc, value in walk.unions:
            seen.setdefault(prefix, {}).setdefault(label, []).append(index)
            context[prefix] = (members, disc, value)
    dropped: set[int] = set()
    for prefix, labels in seen.items():
        members, disc, value = context[prefix]
        best, clear = _best(members, value, disc)
        keep = [label for label in labels if _by_label(members, label, disc) is best]
        if len(labels) > 1 and clear and keep:
            for label, indices in labels.items():
                if label not in keep:
                    dropped.update(indices)
    return dropped


def located_errors(
    exc: ValidationError,
    model: type[BaseModel],
    data: Any,
    positions: Positions,
    filename: str,
) -> list[SourceError]:
    """One located :class:`SourceError` per distinct problem, in file order."""
    errors = exc.errors(include_url=False)
    walks = [_walk(tuple(err["loc"]), model, data) for err in errors]
    dropped = _drop_unintended_members(walks)
    pairs = enumerate(zip(errors, walks, strict=True))
    items = [_describe(err, walk) for i, (err, walk) in pairs if i not in dropped]
    # "unknown key 'radus'; did you mean 'radius'?" already explains the missing 'radius'
    typos = {(item.path[:-1], item.key) for item in items if item.anchor == "key" and item.key}
    items = [item for item in items if item.anchor == "key" or (item.path, item.key) not in typos]
    merged: dict[tuple[Any, ...], _Item] = {}
    for item in items:
        if item.expected is None:
            merged[(item.path, item.anchor, item.message())] = item
            continue
        slot = (item.path, item.anchor, "expected", item.got)
        if slot not in merged:
            merged[slot] = item
        elif item.expected not in merged[slot].expected.split(" or "):  # type: ignore[union-attr]  # (None went above)
            merged[slot].expected = f"{merged[slot].expected} or {item.expected}"
            merged[slot].hint = merged[slot].hint or item.hint
    results: dict[tuple[Any, ...], SourceError] = {}
    for item in merged.values():
        mark = positions.key(item.path) if item.anchor == "key" else None
        mark = mark or positions.value(item.path) or positions.nearest(item.path)[1]
        error = SourceError(filename, mark.line, mark.column, item.path, item.message())
        results.setdefault((mark.line, mark.column, format_path(item.path), error.message), error)
    return [results[key] for key in sorted(results)]

"""The expression language: its types, functions and constants, and compiled results.

Model files are data and may come from anyone, so user text never reaches eval/exec/compile: it is
only given to ``ast.parse``, the tree is checked against a small whitelist, and what passes is
turned once into a tree of closures over numpy ufuncs (:mod:`~hybridteam.expr.compiler`). Values are
arrays over the ensemble axis (or scalars that broadcast), so nothing loops over instances.

Two static types exist, *number* and *condition*; mixing them is a compile-time error, which
catches ``x and y`` or ``(x > 0) + 1`` before a simulation runs. Ordering comparisons are
exposed as :class:`Atom` objects because the engine locates events by their margins' zeros.
"""

from __future__ import annotations

import ast
import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import reduce
from types import MappingProxyType
from typing import Any, NamedTuple

import numpy as np

Getter = Callable[[Any], "np.ndarray | float"]
MAX_LENGTH = 2000  # characters; longer text is generated or hostile, not written by hand
MAX_DEPTH = 60  # nesting limit; keeps every recursive step far below Python's recursion limit
_DEEP = f"expression is nested too deeply (limit {MAX_DEPTH})"


class ExpressionError(ValueError):
    """A rejected expression; ``offset``/``length`` locate the culprit in the source string."""

    def __init__(
        self, message: str, offset: int = 0, length: int = 1, hint: str | None = None
    ) -> None:
        self.message, self.offset, self.length, self.hint = message, offset, max(1, length), hint
        super().__init__(message, offset, self.length, hint)  # args make the error picklable

    def __str__(self) -> str:
        text = f"{self.message} (column {self.offset + 1})"
        return f"{text}; {self.hint}" if self.hint else text


class _Function(NamedTuple):
    impl: Callable[..., Any]
    min_args: int
    max_args: int | None  # None: any number of arguments
    usage: str


def _wrap(angle: Any) -> Any:
    """Wrap to [-pi, pi); the correction catches remainders that round up to exactly 2*pi."""
    r = np.remainder(np.add(angle, np.pi), 2 * np.pi) - np.pi
    return r - (r >= np.pi) * (2 * np.pi)


_UNARY: dict[str, Callable[..., Any]]  # (numpy's functions and _wrap: no common type)
_UNARY = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "sqrt": np.sqrt,
    "abs": np.abs,
    "exp": np.exp,
    "log": np.log,
    "floor": np.floor,
    "ceil": np.ceil,
    "sign": np.sign,
    "wrap": _wrap,
}
FUNCTIONS: Mapping[str, _Function] = MappingProxyType(
    {
        **{name: _Function(f, 1, 1, f"{name}(x)") for name, f in _UNARY.items()},
        "atan2": _Function(np.arctan2, 2, 2, "atan2(y, x)"),
        "hypot": _Function(np.hypot, 2, 2, "hypot(a, b)"),
        "min": _Function(lambda *a: reduce(np.minimum, a), 2, None, "min(a, b, ...)"),
        "max": _Function(lambda *a: reduce(np.maximum, a), 2, None, "max(a, b, ...)"),
        "clip": _Function(
            lambda x, lo, hi: np.minimum(np.maximum(x, lo), hi), 3, 3, "clip(x, lo, hi)"
        ),
    }
)
CONSTANTS: Mapping[str, float] = MappingProxyType({"pi": math.pi, "inf": math.inf})
_BOOL_NAMES = {"true": True, "false": False}
#: names only requirement formulas know (temporal operators and mode signals)
REQUIREMENT_ONLY = frozenset(
    {
        "always",
        "eventually",
        "until",
        "implies",
        "in_mode",
        "in_role",
        "count_in_mode",
        "count_in_role",
        "received",
        "sent",
    }
)
_FUNCTION_HINTS = {"pow": "use ** for powers", "ln": "did you mean 'log'?", "mod": "use a % b"}
_BINOPS: dict[type, tuple[str, Any]] = {
    ast.Add: ("+", np.add),
    ast.Sub: ("-", np.subtract),
    ast.Mult: ("*", np.multiply),
    ast.Div: ("/", np.true_divide),
    ast.Mod: ("%", np.remainder),
    ast.Pow: ("**", np.float_power),
}  # float_power: int operands can neither wrap nor raise
_AUGOPS = dict(_BINOPS.values())
_BAD_BINOPS: dict[type, tuple[str, str | None]] = {
    ast.BitXor: ("^", "use ** for powers"),
    ast.BitAnd: ("&", "use 'and'/'or'"),
    ast.BitOr: ("|", "use 'and'/'or'"),
    ast.LShift: ("<<", None),
    ast.RShift: (">>", None),
    ast.FloorDiv: ("//", "use floor(a / b)"),
    ast.MatMult: ("@", None),
}
_CMPOPS: dict[type, tuple[str, Any]] = {
    ast.Lt: ("<", np.less),
    ast.LtE: ("<=", np.less_equal),
    ast.Gt: (">", np.greater),
    ast.GtE: (">=", np.greater_equal),
    ast.Eq: ("==", np.equal),
    ast.NotEq: ("!=", np.not_equal),
}
_REJECTED: dict[type, str] = {
    ast.Attribute: "attribute access is not allowed",
    ast.Subscript: "indexing with [...] is not allowed",
    ast.Lambda: "lambda is not allowed",
    ast.NamedExpr: "':=' is not allowed",
    ast.JoinedStr: "strings are not allowed",
    ast.IfExp: "'a if c else b' is not allowed",
    ast.Starred: "'*' unpacking is not allowed",
    **dict.fromkeys(
        (ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp),
        "comprehensions are not allowed",
    ),
    **dict.fromkeys(
        (ast.List, ast.Tuple, ast.Set, ast.Dict), "lists, tuples, sets and dicts are not allowed"
    ),
}
_IGNORED = (ast.expr_context, ast.operator, ast.boolop, ast.unaryop, ast.cmpop)
_ASSIGN_RE = re.compile(r"\s*([^\W\d]\w*)\s*(\*\*|//|<<|>>|[-+*/%@&|^])?=(?!=)")
_NOVALUE = object()
_Problem = tuple[int, int, int, str, str | None]  # (rank, start, end, message, hint)


@dataclass(frozen=True, eq=False)
class Atom:
    """An ordering comparison `a OP b` (OP in <, <=, >, >=); the engine watches its margin for
    zero crossings.  The margin is positive where the comparison holds strictly, so one sign
    convention serves every operator; ``truth`` compares directly so equality stays exact."""

    source: str
    op: str
    _margin: Callable[[Any], Any] = field(repr=False)
    _truth: Callable[[Any], Any] = field(repr=False)
    _both: Callable[[Any], Any] = field(repr=False)
    #: ``(truth, margin)`` of one instance on Python floats, where both operands are
    #: arithmetic of names and numbers (see :data:`ON_FLOATS`); None otherwise. A crossing
    #: search of a single run evaluates the atom dozens of times on one number, where each
    #: numpy call costs its dispatch; these are the same IEEE operations, so the same bits
    #: (a NaN's sign may differ, which no comparison or test for NaN sees).
    row: Callable[[Any], tuple[bool, float]] | None = field(default=None, repr=False)

    def margin(self, ctx: Any) -> np.ndarray | float:
        return self._margin(ctx)

    def truth(self, ctx: Any) -> np.ndarray | bool:
        return self._truth(ctx)

    def truth_and_margin(self, ctx: Any) -> tuple[Any, Any]:
        """Both at once, evaluating each operand once (what a crossing search needs)."""
        return self._both(ctx)


def _truth_and_margin(ufunc: Any, a: Any, b: Any, less: bool) -> tuple[Any, Any]:
    return ufunc(a, b), (np.subtract(b, a) if less else np.subtract(a, b))


def _divide(a: float, b: float) -> float:
    """``a / b`` as numpy divides: by zero it gives inf or NaN (quietly, as a run's
    arithmetic is) where Python raises."""
    if b:
        return a / b
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.true_divide(a, b))


#: The ufuncs whose Python-float counterparts give the same IEEE result (one rounding of
#: the exact operation), so an expression built of them alone can be evaluated on one
#: instance's floats with the bits of its array evaluation (:attr:`Atom.row`).
ON_FLOATS: Mapping[Any, Callable[..., Any]] = MappingProxyType(
    {
        np.add: operator.add,
        np.subtract: operator.sub,
        np.multiply: operator.mul,
        np.true_divide: _divide,
        np.negative: operator.neg,
        np.less: operator.lt,
        np.less_equal: operator.le,
        np.greater: operator.gt,
        np.greater_equal: operator.ge,
        np.equal: operator.eq,
        np.not_equal: operator.ne,
        np.logical_and: operator.and_,
        np.logical_or: operator.or_,
        np.logical_not: operator.not_,
    }
)


def row_truth_and_margin(
    op: Callable[[float, float], bool], a: float, b: float, less: bool
) -> tuple[bool, float]:
    """:func:`_truth_and_margin` on floats."""
    return op(a, b), (b - a if less else a - b)


class Expression:
    """A compiled expression; calling it evaluates the closure tree on an engine context."""

    __slots__ = ("_fn", "atoms", "conjuncts", "is_condition", "names", "row", "source")

    def __init__(
        self,
        source: str,
        fn: Callable[[Any], Any],
        names: frozenset[str],
        is_condition: bool,
        atoms: tuple[Atom, ...],
        conjuncts: tuple[Atom, ...] = (),
        row: Callable[[Any], Any] | None = None,
    ) -> None:
        """``conjuncts``: the atoms that are conjuncts of a condition (where one is false,
        so is the condition; a crossing search uses it to skip flips that cannot
        matter). ``row``: the expression on one instance's floats, where every part of it
        has a float form (as :attr:`Atom.row`), else None."""
        self.source, self._fn, self.names = source, fn, names
        self.is_condition, self.atoms, self.conjuncts = is_condition, atoms, conjuncts
        self.row = row

    def __call__(self, ctx: Any) -> np.ndarray | float | bool:
        return self._fn(ctx)

    def __repr__(self) -> str:
        return f"Expression({self.source!r})"


class Reader:
    """A symbol's getter of the engine's context, with its reader of one instance's floats
    (``row``: what :attr:`Atom.row` closures read). A symbol table may hold these or bare
    getters; names read through bare getters give no float form."""

    __slots__ = ("get", "row")

    def __init__(self, get: Getter, row: Callable[[Any], float]) -> None:
        self.get, self.row = get, row


class ModeTest:
    """The symbol table's entry ``in_mode``, where a guard may ask whether a mode of its
    own agent is active (SCXML's ``In()``): ``resolve(name)`` takes the mode's name as
    written (``Up`` or ``Arm.Up``) and gives the getter of a condition, or raises
    :class:`ExpressionError` (at offset 0 of the name) when no such mode is known. The
    language knows only that the argument is a dotted name; which modes exist is the
    engine's business."""

    __slots__ = ("resolve",)

    def __init__(self, resolve: Callable[[str], Getter]) -> None:
        self.resolve = resolve


class _C:
    """A compiled node: its closure, its static type and, if constant-folded, its value;
    ``row``, where the node is built of names, numbers and the operations of
    :data:`ON_FLOATS` alone, its closure on one instance's floats (see :attr:`Atom.row`)."""

    __slots__ = ("cond", "fn", "row", "value")

    def __init__(
        self,
        fn: Callable[[Any], Any],
        cond: bool,
        value: Any = _NOVALUE,
        row: Callable[[Any], float] | None = None,
    ) -> None:
        self.fn, self.cond, self.value, self.row = fn, cond, value, row

    @property
    def const(self) -> bool:
        return self.value is not _NOVALUE


def _const(value: Any, cond: bool) -> _C:
    if cond:
        row = (lambda r, c=bool(value): c) if isinstance(value, bool | np.bool_) else None
    elif isinstance(value, int | float | np.floating):
        row = lambda r, c=float(value): c  # noqa: E731
    else:
        row = None
    return _C(lambda ctx: value, cond, value, row)


def _row_apply(impl: Callable[..., Any], args: list[_C]) -> Callable[[Any], float] | None:
    """The float closure of ``impl`` applied to ``args``, where it has one."""
    op = ON_FLOATS.get(impl)
    rows = [a.row for a in args if a.row is not None]
    if op is None or len(rows) < len(args):
        return None
    if len(rows) == 1:
        (f,) = rows
        return lambda r: op(f(r))
    if len(rows) == 2:
        f, g = rows
        return lambda r: op(f(r), g(r))
    return None


def _apply(impl: Callable[..., Any], args: list[_C], cond: bool) -> _C:
    """Apply `impl` to compiled arguments: folded when all are constant, else one closure."""
    if all(a.const for a in args):
        with np.errstate(all="ignore"):
            return _const(impl(*(a.value for a in args)), cond)
    fns, row = [a.fn for a in args], _row_apply(impl, args)
    if len(args) == 1:
        (f,) = fns
        return _C(lambda ctx: impl(f(ctx)), cond, row=row)
    if len(args) == 2:  # the hot case: inline constants instead of calling their closures
        (f, g), (a, b) = fns, args
        if b.const:
            return _C(lambda ctx, c=b.value: impl(f(ctx), c), cond, row=row)  # type: ignore[misc]  # default-bound lambda
        if a.const:
            return _C(lambda ctx, c=a.value: impl(c, g(ctx)), cond, row=row)  # type: ignore[misc]  # default-bound lambda
        return _C(lambda ctx: impl(f(ctx), g(ctx)), cond, row=row)
    return _C(lambda ctx: impl(*[f(ctx) for f in fns]), cond)


def _fold_left(first: _C, steps: list[tuple[Any, _C]], cond: bool) -> _C:
    """Evaluate ``((first u1 a1) u2 a2) ...`` in one loop, so that long chains such as
    a+b+c+... need no deep recursion; a constant prefix is folded at compile time."""
    while steps and first.const and steps[0][1].const:
        first = _apply(steps[0][0], [first, steps.pop(0)[1]], cond)
    if len(steps) <= 1:
        return _apply(steps[0][0], [first, steps[0][1]], cond) if steps else first
    f0, rest = first.fn, tuple((u, a.fn) for u, a in steps)

    def fn(ctx: Any) -> Any:
        value = f0(ctx)
        for u, g in rest:
            value = u(value, g(ctx))
        return value

    return _C(fn, cond, row=_row_fold(first, steps))


def _row_fold(first: _C, steps: list[tuple[Any, _C]]) -> Callable[[Any], float] | None:
    """:func:`_fold_left`'s loop on one instance's floats, where every step has one."""
    ops = [ON_FLOATS.get(u) for u, _ in steps]
    if first.row is None or None in ops or any(a.row is None for _, a in steps):
        return None
    r0, rest = first.row, tuple((op, a.row) for op, (_, a) in zip(ops, steps, strict=True))

    def row(r: Any) -> float:
        value = r0(r)
        for op, g in rest:
            value = op(value, g(r))  # type: ignore[misc]  # (no None: checked above)
        return value

    return row

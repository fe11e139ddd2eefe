"""The float paths: their public switch, and their float forms made from one definition.

Where an array version costs a numpy dispatch (about 1 µs) per operation for one number, a
single run takes a path on Python floats that gives the same bits (``docs/design.md``,
"Performance"). Those paths must never change a trace, and the way to check that is to run
the same model both ways. This switch turns them off, so the check goes through one
documented setting instead of patching the engine's or a library's private names:

- the environment: ``HYBRIDTEAM_FLOAT_PATHS=off`` (or ``0``, ``false``, ``no``) before the
  process starts, for comparing two command-line runs; any other value, or none, leaves
  them on;
- in Python: ``with FLOAT_PATHS.off(): ...`` (a mode library reads it as
  ``hybridteam.library.FLOAT_PATHS``).

It covers the crossing search's float forms (its checkpoints' truths, the dense bracket
and the judgement of a flip, :attr:`hybridteam.expr.Atom.row`), the last few brackets of
:func:`~hybridteam.engine.run.crossing.illinois.illinois`, a few rows' unicycle arcs and
dense-output reads (:mod:`hybridteam.dynamics`), a carried payload's settling, the
clearances in a scene of posts (:mod:`hybridteam.world.measure_one`), a law's
dead reckoning of a stream copy (:mod:`hybridteam.laws`), the transport library's leader
estimate and the ladder library's law and corridor instant; and a single run's shortcuts
to a detect rule's verdicts (:mod:`hybridteam.world.sight`: off, every rule reads its cast
beams). A hot path reads one attribute
(:attr:`FloatPaths.on`), which costs about as much as a local comparison.

:func:`float_form` makes a float path from the array version's own source, where the
algorithm is written once over an operations namespace ``ops`` (numpy for arrays): the
second copy is generated, not written. Made so: the Illinois rounds of the crossing
search, a unicycle's arc, a payload's spring equilibrium, and the ladder library's law
after its nearest-point search and its corridor's corner test.
"""

from __future__ import annotations

import ast
import inspect
import math
import os
import textwrap
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from types import MappingProxyType
from typing import Any

import numpy as np

#: The environment variable that turns the float paths off for a whole process.
ENV = "HYBRIDTEAM_FLOAT_PATHS"


class FloatPaths:
    """Whether the float paths are taken (:attr:`on`); :meth:`off` turns them off for a
    block. One instance, :data:`FLOAT_PATHS`, is read by every path."""

    __slots__ = ("on",)

    def __init__(self, on: bool) -> None:
        self.on = on

    @contextmanager
    def off(self) -> Iterator[None]:
        """Arrays only inside the block (the setting before it is restored after, also on
        an error)."""
        before, self.on = self.on, False
        try:
            yield
        finally:
            self.on = before


#: What the environment variable may say to turn the float paths off.
OFF = frozenset({"off", "0", "false", "no"})
#: The process's switch, on unless the environment says off.
FLOAT_PATHS = FloatPaths(os.environ.get(ENV, "on").strip().lower() not in OFF)


# ------------------------------------------------------------ one definition, two forms
#: numpy's operations that :func:`float_form` writes out inline, as expressions with numpy's
#: result on one element (``{0}``, ``{1}``: the arguments, each evaluated once):
#: ``np.where`` evaluates only the branch taken; ``np.minimum``/``np.maximum`` give their
#: second argument on ties (``-0.0`` against ``0.0``) and NaN if either is NaN (Python's
#: ``min``/``max`` do not); a quotient by zero, where Python raises, is numpy's inf or NaN
#: (:func:`_by_zero`, off the common path).
INLINE: Mapping[str, str] = MappingProxyType(
    {
        "where": "({1} if {0} else {2})",
        "minimum": "({t0} if (({t0} := {0}) < ({t1} := {1}) or {t0} != {t0}) else {t1})",
        "maximum": "({t0} if (({t0} := {0}) > ({t1} := {1}) or {t0} != {t0}) else {t1})",
        "true_divide": "({0} / {t0} if ({t0} := {1}) != 0.0 else _float_by_zero({0}, {t0}))",
    }
)


def _by_zero(a: float, zero: float) -> float:
    """``a / zero`` as numpy divides a double by a (signed) zero: inf of the signs' product,
    NaN for ``0 / 0`` and NaN."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.true_divide(a, zero))


class _Fill(ast.NodeTransformer):
    """An :data:`INLINE` template with its placeholder names replaced by argument nodes."""

    def __init__(self, args: Mapping[str, ast.expr]) -> None:
        self.args = args

    def visit_Name(self, node: ast.Name) -> ast.AST:
        return self.args.get(node.id, node)


class _OnFloats(ast.NodeTransformer):
    """Rewrites a function written over ``ops`` into its float form (:func:`float_form`):
    each ``ops.NAME`` becomes the name ``_float_NAME`` (bound to ``ops[NAME]`` in the
    form's namespace), and a call of one of :data:`INLINE` its written-out expression."""

    def __init__(self, ops: str, known: Mapping[str, Callable[..., Any]]) -> None:
        self.ops, self.known, self.temps = ops, known, 0

    def visit_Attribute(self, node: ast.Attribute) -> ast.AST:
        if not (isinstance(node.value, ast.Name) and node.value.id == self.ops):
            return self.generic_visit(node)
        if node.attr not in self.known and node.attr not in INLINE:
            raise TypeError(f"float_form: no float form of {self.ops}.{node.attr}")
        return ast.copy_location(ast.Name(id=f"_float_{node.attr}", ctx=ast.Load()), node)

    def visit_Call(self, node: ast.Call) -> ast.AST:
        self.generic_visit(node)  # (the callee ops.NAME is now the name _float_NAME)
        callee = node.func.id if isinstance(node.func, ast.Name) else ""
        name = callee.removeprefix("_float_")
        if name == callee or name not in INLINE:
            return node
        temps = {}
        for k in range(2):  # walrus names of the form's own, one pair per site
            self.temps += 1
            temps[f"t{k}"] = f"_float_t{self.temps}"
        args = [f"_float_arg{k}" for k in range(len(node.args))]
        template = ast.parse(INLINE[name].format(*args, **temps), mode="eval").body
        filled = _Fill(dict(zip(args, node.args, strict=True))).visit(template)
        return ast.copy_location(filled, node)


def _arctan2(y: float, x: float) -> float:
    """``np.arctan2`` itself: its result is not correctly rounded, so ``math.atan2`` could
    differ from it."""
    return float(np.arctan2(y, x))


def _cos(x: float) -> float:
    """``np.cos`` itself (the array loop on one number; ``math.cos`` could differ)."""
    return float(np.cos(x))


def _sin(x: float) -> float:
    """``np.sin`` itself."""
    return float(np.sin(x))


#: The operations :func:`float_form` calls (the others are written out: :data:`INLINE`),
#: each with numpy's result on one double: ``+ - * /`` and ``sqrt`` are correctly rounded
#: in both; numpy's transcendental functions are called as they are.
ON_FLOATS: Mapping[str, Callable[..., Any]] = MappingProxyType(
    {"isfinite": math.isfinite, "sqrt": math.sqrt, "arctan2": _arctan2, "cos": _cos, "sin": _sin}
)

#: The operations namespace an algorithm written once takes (its parameter ``ops``):
#: numpy itself for arrays; its float form has none.
Ops = Any


def _drop_ops(args: ast.arguments) -> None:
    """Remove the parameter ``ops`` (and its default) from a signature."""
    names = [a.arg for a in args.args]
    if "ops" in names:
        at = names.index("ops")
        first_default = len(names) - len(args.defaults)
        if at >= first_default:
            del args.defaults[at - first_default]
        del args.args[at]
        return
    names = [a.arg for a in args.kwonlyargs]
    if "ops" not in names:
        raise TypeError("float_form: the function has no parameter 'ops'")
    at = names.index("ops")
    del args.kwonlyargs[at], args.kw_defaults[at]


def float_form(
    fn: Callable[..., Any], ops: Mapping[str, Callable[..., Any]] = ON_FLOATS
) -> Callable[..., Any]:
    """The float form of ``fn``, an algorithm written once over its parameter ``ops``, an
    operations namespace (``ops.where``, ``ops.minimum``, ...) that is numpy itself for
    arrays (as an argument, or as the parameter's default).

    Generated from ``fn``'s own source, so a change to the algorithm is made once: the
    parameter ``ops`` is dropped, each ``ops.where(c, a, b)`` becomes ``a if c else b`` (one
    element: only the branch taken is evaluated, without a call), ``ops.minimum``,
    ``ops.maximum`` and ``ops.quotient`` are written out as :data:`INLINE` says, and each
    other ``ops.NAME`` becomes a call of ``ops[NAME]``, a Python-float function with numpy's
    result (``math.isfinite`` for ``np.isfinite``). Operators (``+ - *``, comparisons, ``&``
    of truths) are the same IEEE operations on floats as on arrays, so both forms give the
    same bits (a division is written ``ops.quotient``: Python's ``/`` raises on zero); the form's
    line numbers are ``fn``'s, for tracebacks and profiles. Only the project's own source is
    compiled here, once, at import; nothing read from a model file. ``fn`` must be defined
    with ``def`` in a source file (TypeError otherwise).
    """
    try:
        source = textwrap.dedent(inspect.getsource(fn))
    except (OSError, TypeError) as exc:  # typed at a prompt, or shipped without sources
        raise TypeError(f"float_form: the source of {fn!r} cannot be read: {exc}") from None
    tree = ast.parse(source)
    ast.increment_lineno(tree, fn.__code__.co_firstlineno - 1)
    func = tree.body[0]
    if not isinstance(func, ast.FunctionDef):
        raise TypeError(f"float_form: {fn!r} is not a function defined with def")
    func.decorator_list = []
    _drop_ops(func.args)
    tree = ast.fix_missing_locations(_OnFloats("ops", ops).visit(tree))
    namespace = dict(fn.__globals__)
    namespace.update({f"_float_{name}": op for name, op in ops.items()})
    namespace["_float_by_zero"] = _by_zero
    exec(compile(tree, inspect.getsourcefile(fn) or "<float form>", "exec"), namespace)
    made = namespace[func.name]
    made.__name__ = made.__qualname__ = f"{fn.__name__}_on_floats"
    return made

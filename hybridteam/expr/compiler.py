"""Compile expression text to vectorized callables, or reject it with the culprit's position.

The parser is Python's own (``ast.parse``, parsing only); a whitelist walk rejects anything
but numbers, names, arithmetic, comparisons, ``and/or/not`` and calls of the fixed function
table, and reports the offending token's character offset for ``file:line:column`` errors.
"""

from __future__ import annotations

import ast
import math
import re
import unicodedata
import warnings
from collections.abc import Collection, Mapping
from typing import Any, TypeGuard

import numpy as np

from hybridteam.errors import did_you_mean
from hybridteam.expr.language import (
    _ASSIGN_RE,
    _AUGOPS,
    _BAD_BINOPS,
    _BINOPS,
    _BOOL_NAMES,
    _C,
    _CMPOPS,
    _DEEP,
    _FUNCTION_HINTS,
    _IGNORED,
    _REJECTED,
    CONSTANTS,
    FUNCTIONS,
    MAX_DEPTH,
    MAX_LENGTH,
    ON_FLOATS,
    REQUIREMENT_ONLY,
    Atom,
    Expression,
    ExpressionError,
    Getter,
    ModeTest,
    Reader,
    _apply,
    _const,
    _fold_left,
    _Problem,
    _truth_and_margin,
    row_truth_and_margin,
)


class _Compiler:
    """Parses a slice of `source` and compiles it; every offset refers to the full `source`."""

    def __init__(self, source: str, symbols: Mapping[str, Getter] | None) -> None:
        if not isinstance(source, str):
            raise ExpressionError(f"expected a string, got {type(source).__name__}")
        if len(source) > MAX_LENGTH:
            raise ExpressionError(
                f"expression is too long ({len(source)} characters, at most {MAX_LENGTH})",
                MAX_LENGTH,
                len(source) - MAX_LENGTH,
            )
        self.source, self.symbols = source, symbols
        self.names: set[str] = set()
        self.atoms: list[Atom] = []
        self.node_atoms: dict[int, list[Atom]] = {}  # a comparison node's atoms (by id)

    def error(
        self, message: str, start: int, end: int | None = None, hint: str | None = None
    ) -> ExpressionError:
        start = min(max(start, 0), len(self.source))
        return ExpressionError(message, start, (end or start + 1) - start, hint)

    # -- parsing -------------------------------------------------------------------------------
    def parse(self, start: int) -> ast.expr:
        # Line breaks (YAML block scalars) become spaces: same length, so character offsets are
        # unchanged and a multi-line expression needs no parentheses.  Comments are rejected
        # because on the joined line one would silently swallow the lines after it.
        text = self.source[start:].replace("\r", " ").replace("\n", " ")
        stripped = text.lstrip(" \t\f")  # eval mode rejects leading indentation
        self.base, text = start + len(text) - len(stripped), stripped
        if not text.strip():
            raise self.error("empty expression", start)
        if "\0" in text:
            raise self.error("NUL characters are not allowed", self.base + text.index("\0"))
        try:
            encoded = text.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise self.error("invalid character", self.base + exc.start) from None
        # ast columns are UTF-8 byte offsets: map them back to characters once.
        self.b2c = (
            None
            if text.isascii()
            else [i for i, ch in enumerate(text) for _ in ch.encode("utf-8")] + [len(text)]
        )
        self.line_starts = [0] + [i + 1 for i, b in enumerate(encoded) if b == 10]
        quote = min([i for i in (text.find("'"), text.find('"')) if i >= 0] or [len(text)])
        if 0 <= text.find("#") < quote:  # a '#' after a quote may sit in a (rejected) string
            at = self.base + text.index("#")
            end = self.source.find("\n", at) % (len(self.source) + 1)  # -1: to the end
            raise self.error(
                "comments are not allowed in expressions",
                at,
                end,
                "put comments in YAML, outside the string",
            )
        depth = 0
        for i, ch in enumerate(text[:quote]):  # paren-only nesting leaves no trace in the AST
            depth = depth + 1 if ch in "([{" else max(depth - 1, 0) if ch in ")]}" else depth
            if depth > MAX_DEPTH:
                raise self.error(_DEEP, self.base + i)
        try:
            tree = self._ast_parse(text, "eval").body
        except SyntaxError as exc:
            raise self._syntax_error(exc, text) from None
        except (RecursionError, MemoryError):
            raise self.error(_DEEP, self.base) from None
        except Exception as exc:  # defensive: nothing but ExpressionError may escape
            raise self.error(f"cannot parse expression ({type(exc).__name__})", self.base) from None
        self._check(tree)
        return tree

    @staticmethod
    def _ast_parse(text: str, mode: str) -> Any:
        with warnings.catch_warnings():  # e.g. invalid escapes inside strings we reject anyway
            warnings.simplefilter("ignore")
            return ast.parse(text, mode=mode)

    def _syntax_error(self, exc: SyntaxError, text: str) -> ExpressionError:
        try:  # statements and assignments parse in exec mode: report them more helpfully
            body = self._ast_parse(text, "exec").body
        except Exception:
            body = []
        if len(body) > 1:
            return self.error(
                "only one expression is allowed",
                self.pos(body[1])[0],
                hint="combine conditions with 'and'/'or'",
            )
        if body and isinstance(body[0], ast.Assign | ast.AugAssign):
            target = body[0].targets[0] if isinstance(body[0], ast.Assign) else body[0].target
            at = self.between(self.pos(target)[1], self.pos(body[0].value)[0])
            return self.error("assignment is not allowed here", *at, "use '==' to compare")
        if body and not isinstance(body[0], ast.Expr):
            start = self.pos(body[0])[0]
            end = start + len(re.match(r"\w*", self.source[start:]).group())  # type: ignore[union-attr]  # \w* matches anywhere
            return self.error(
                "statements are not allowed; write one expression such as 'x >= 5'", start, end
            )
        col = (exc.offset or 0) - 1  # 1-based characters within the (single) line
        if not 0 <= col < len(text):
            return self.error("unexpected end of expression", self.base + len(text.rstrip()))
        length = 1
        if exc.end_lineno == exc.lineno and (exc.end_offset or 0) > (exc.offset or 0):
            length = (exc.end_offset or 0) - (exc.offset or 0)
        hint = (
            "use '==' to compare" if text[col] == "=" and text[col + 1 : col + 2] != "=" else None
        )
        return self.error(exc.msg, self.base + col, self.base + col + length, hint)

    def pos(self, node: Any) -> tuple[int, int]:
        """(start, end) character offsets of `node` in the full source."""
        return (
            self._char(node.lineno, node.col_offset),
            self._char(node.end_lineno, node.end_col_offset),
        )

    def _char(self, lineno: int, col: int) -> int:
        byte = self.line_starts[min(lineno, len(self.line_starts)) - 1] + col
        return self.base + (byte if self.b2c is None else self.b2c[min(byte, len(self.b2c) - 1)])

    def between(self, left_end: int, right_start: int) -> tuple[int, int]:
        """Span of the operator token between two operands, skipping parentheses."""
        s, i, j = self.source, left_end, right_start
        while i < j and (s[i].isspace() or s[i] == ")"):
            i += 1
        while j > i and (s[j - 1].isspace() or s[j - 1] == "("):
            j -= 1
        return i, max(j, i + 1)

    def _token_after(self, node: ast.expr, inner: ast.expr, token: str) -> tuple[int, int]:
        """Span of `token` ('[', 'if', ':=') after the sub-node `inner`; for '.', the name."""
        s, at = self.source, self.source.find(token, self.pos(inner)[1])
        if at < 0:
            return self.pos(node)
        if token != ".":
            return at, at + len(token)
        at += 1
        while at < len(s) and s[at].isspace():
            at += 1
        return at, self.pos(node)[1]

    # -- whitelist -----------------------------------------------------------------------------
    def _check(self, root: ast.expr) -> None:
        """Iterative whitelist and depth check of the whole tree before anything is compiled.
        Reports the forbidden construct that comes first in the source; unknown functions and
        wrong arity (rank 1) come after forbidden constructs (rank 0)."""
        problems: list[_Problem] = []
        stack: list[tuple[ast.AST, int]] = [(root, 1)]
        while stack:
            node, depth = stack.pop()
            if hasattr(node, "lineno"):
                if depth > MAX_DEPTH:
                    start = self.pos(node)[0]
                    problems.append((0, start, start + 1, _DEEP, None))
                    continue
                problem = self._problem(node)
                if problem is not None:
                    problems.append(problem)
                elif _is_mode_test(node):  # its argument is a mode's name, not an expression
                    continue
            for child in ast.iter_child_nodes(node):
                if not isinstance(child, _IGNORED):  # a left-leaning chain a+b+c counts once
                    flat = isinstance(node, ast.BinOp) and child is node.left
                    stack.append((child, depth if flat else depth + 1))
        if problems:
            _, start, end, message, hint = min(problems, key=lambda p: (p[0], p[1]))
            raise self.error(message, start, end, hint)

    def _problem(self, node: Any) -> _Problem | None:
        """Whitelist one node: None if allowed, else (rank, start, end, message, hint)."""
        start, end = self.pos(node)
        if isinstance(node, ast.BoolOp):
            return None
        if isinstance(node, ast.Name):
            if node.id.startswith("__"):
                return 0, start, end, f"names starting with '__' are not allowed: {node.id}", None
            return None
        if isinstance(node, ast.Constant):
            if isinstance(node.value, str | bytes):
                return 0, start, end, "strings are not allowed", None
            if not isinstance(node.value, int | float):  # complex, None, Ellipsis
                return 0, start, end, f"'{self.source[start:end]}' is not allowed", None
            return None
        if isinstance(node, ast.BinOp):
            if type(node.op) in _BAD_BINOPS:
                sym, hint = _BAD_BINOPS[type(node.op)]
                at = self.between(self.pos(node.left)[1], self.pos(node.right)[0])
                return 0, *at, f"operator '{sym}' is not allowed", hint
            return None
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.Invert):
                return 0, start, start + 1, "operator '~' is not allowed", "use 'not'"
            return None
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            for i, op in enumerate(node.ops):
                if type(op) not in _CMPOPS:
                    at = self.between(self.pos(operands[i])[1], self.pos(operands[i + 1])[0])
                    word = self.source[at[0] : at[1]]
                    hint = "use '==' or '!='" if word.startswith("is") else None
                    return 0, *at, f"'{word}' is not allowed", hint
            return None
        if isinstance(node, ast.keyword):
            what = "keyword arguments are" if node.arg else "'**' unpacking is"
            return 0, start, end, f"{what} not allowed", "pass arguments by position"
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name):
                paren = self.source.find("(", self.pos(node.func)[1])
                return 1, paren, paren + 1, "only functions such as sin(x) can be called", None
            name, n = node.func.id, len(node.args)
            if name == "in_mode" and self._mode_tests():
                if n != 1 or node.keywords or dotted_name(node.args[0]) is None:
                    return (
                        1,
                        start,
                        end,
                        "in_mode() takes one mode name",
                        "e.g. in_mode(Climb) or in_mode(Arm.Up)",
                    )
                return None
            if name in REQUIREMENT_ONLY:
                return 1, *self.pos(node.func), _requirement_only(name), None
            if name not in FUNCTIONS:
                hint = _FUNCTION_HINTS.get(name) or did_you_mean(name, FUNCTIONS)
                return 1, *self.pos(node.func), f"unknown function '{name}'", hint
            spec = FUNCTIONS[name]
            if n < spec.min_args or (spec.max_args is not None and n > spec.max_args):
                return (
                    1,
                    start,
                    end,
                    f"wrong number of arguments ({n}) in call to {name}",
                    f"usage: {spec.usage}",
                )
            return None
        if (
            isinstance(node, ast.Subscript)
            and isinstance(node.value, ast.Name)
            and node.value.id in REQUIREMENT_ONLY
        ):
            return 0, *self.pos(node.value), _requirement_only(node.value.id), None
        if isinstance(node, ast.Attribute | ast.Subscript):
            start, end = self._token_after(
                node, node.value, "." if isinstance(node, ast.Attribute) else "["
            )
        elif isinstance(node, ast.NamedExpr):
            start, end = self._token_after(node, node.target, ":=")
        elif isinstance(node, ast.IfExp):
            start, end = self._token_after(node, node.body, "if")
        message = _REJECTED.get(type(node), f"'{type(node).__name__}' is not allowed")
        return 0, start, end, message, None

    # -- typed compilation (depth is bounded by _check) ----------------------------------------
    def compile(self, node: ast.expr) -> _C:
        if isinstance(node, ast.Name):
            return self.name(node.id, *self.pos(node))
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool):
                return _const(node.value, True)
            try:
                return _const(float(node.value), False)  # type: ignore[arg-type]  # (_check: numbers)
            except OverflowError:  # an integer literal beyond the float range
                return _const(math.inf, False)
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.Not):
                return _apply(np.logical_not, [self.typed(node.operand, True, "'not'")], True)
            operand = self.typed(node.operand, False, "unary minus/plus")
            return (
                operand if isinstance(node.op, ast.UAdd) else _apply(np.negative, [operand], False)
            )
        if isinstance(node, ast.BinOp):
            chain = []
            while isinstance(node, ast.BinOp):
                chain.append(node)
                node = node.left
            first = self.typed(node, False, f"'{_BINOPS[type(chain[-1].op)][0]}'")
            ops = [_BINOPS[type(b.op)] for b in reversed(chain)]
            return _fold_left(
                first,
                [
                    (u, self.typed(b.right, False, f"'{sym}'"))
                    for (sym, u), b in zip(ops, reversed(chain), strict=True)
                ],
                False,
            )
        if isinstance(node, ast.BoolOp):
            word, ufunc = (
                ("'and'", np.logical_and)
                if isinstance(node.op, ast.And)
                else ("'or'", np.logical_or)
            )
            values = [self.typed(v, True, word) for v in node.values]
            return _fold_left(values[0], [(ufunc, v) for v in values[1:]], True)
        if isinstance(node, ast.Compare):
            return self._compare(node)
        if _is_mode_test(node):
            return self._mode_test(node.args[0])
        if isinstance(node, ast.Call):
            name = node.func.id  # type: ignore[attr-defined]  # (_check: calls of names only)
            args = [self.typed(a, False, f"{name}()") for a in node.args]
            return _apply(FUNCTIONS[name].impl, args, False)
        raise self.error("unsupported expression", *self.pos(node))  # unreachable after _check

    def _mode_tests(self) -> bool:
        """Whether ``in_mode(...)`` may be called here: the symbol table offers it (a
        guard's), or there is none (:func:`free_names` validates any guard)."""
        return self.symbols is None or isinstance(self.symbols.get("in_mode"), ModeTest)

    def _mode_test(self, arg: ast.expr) -> _C:
        """``in_mode(Name)``: a condition read from the agent's configuration."""
        if self.symbols is None:
            return _C(lambda ctx: False, True)
        start, end = self.pos(arg)
        try:
            return _C(self.symbols["in_mode"].resolve(dotted_name(arg)), True)  # type: ignore[attr-defined]  # a ModeTest
        except ExpressionError as exc:
            raise self.error(exc.message, start, end, exc.hint) from None

    def name(self, name: str, start: int, end: int) -> _C:
        if self.symbols is not None and name in self.symbols:  # symbols win over constants
            self.names.add(name)
            sym = self.symbols[name]
            if isinstance(sym, Reader):
                return _C(sym.get, False, row=sym.row)
            return _C(sym, False)
        if name in CONSTANTS or name in _BOOL_NAMES:
            return _const(CONSTANTS.get(name, _BOOL_NAMES.get(name)), name in _BOOL_NAMES)
        if self.symbols is None:  # free_names(): any other name is a free number
            self.names.add(name)
            return _C(lambda ctx: 0.0, False)
        if name in FUNCTIONS:
            raise self.error(f"'{name}' is a function", start, end, f"call it: {name}(...)")
        hint = did_you_mean(name, [*self.symbols, *CONSTANTS])
        raise self.error(f"unknown name '{name}'", start, end, hint)

    def typed(self, node: ast.expr, cond: bool, user: str) -> _C:
        result = self.compile(node)
        if result.cond != cond:
            start, end = self.pos(node)
            if cond:
                text = self.source[start:end] if end - start <= 20 else "x"
                raise self.error(
                    f"{user} needs a condition, but this is a number",
                    start,
                    end,
                    f"compare it, e.g. '{text} > 0'",
                )
            raise self.error(f"{user} needs a number, but this is a condition", start, end)
        return result

    def _compare(self, node: ast.Compare) -> _C:
        operands = [node.left, *node.comparators]
        values = [self.typed(o, False, "a comparison") for o in operands]
        ops = [_CMPOPS[type(op)] for op in node.ops]
        first_atom = len(self.atoms)
        for i, (sym, ufunc) in enumerate(ops):
            if sym not in ("==", "!="):  # a chain 0 < x < 1 yields the atoms 0 < x and x < 1
                start = self.pos(node if i == 0 else operands[i])[0]
                end = self.pos(node if i == len(ops) - 1 else operands[i + 1])[1]
                f, g = values[i].fn, values[i + 1].fn
                hi, lo = (g, f) if sym in ("<", "<=") else (f, g)
                less = sym in ("<", "<=")
                fr, gr = values[i].row, values[i + 1].row
                self.atoms.append(
                    Atom(
                        self._balanced(start, end),
                        sym,
                        lambda ctx, hi=hi, lo=lo: np.subtract(hi(ctx), lo(ctx)),  # type: ignore[misc]  # default-bound lambda
                        lambda ctx, u=ufunc, f=f, g=g: u(f(ctx), g(ctx)),  # type: ignore[misc]  # default-bound lambda
                        lambda ctx, u=ufunc, f=f, g=g, less=less: _truth_and_margin(  # type: ignore[misc]  # default-bound lambda
                            u, f(ctx), g(ctx), less
                        ),
                        None
                        if fr is None or gr is None
                        else (
                            lambda r, op=ON_FLOATS[ufunc], f=fr, g=gr, less=less: (  # type: ignore[misc]  # default-bound lambda
                                row_truth_and_margin(op, f(r), g(r), less)
                            )
                        ),
                    )
                )
        self.node_atoms[id(node)] = self.atoms[first_atom:]
        if len(ops) == 1:
            return _apply(ops[0][1], values, True)
        if all(v.const for v in values):
            with np.errstate(all="ignore"):
                return _const(
                    all(
                        u(a.value, b.value)
                        for (_, u), a, b in zip(ops, values, values[1:], strict=False)
                    ),
                    True,
                )
        first, pairs = (
            values[0].fn,
            tuple((u, v.fn) for (_, u), v in zip(ops, values[1:], strict=True)),
        )

        def fn(ctx: Any) -> Any:  # each operand is evaluated once, as in Python's chains
            a, out = first(ctx), None
            for u, g in pairs:
                b = g(ctx)
                out = u(a, b) if out is None else np.logical_and(out, u(a, b))
                a = b
            return out

        return _C(fn, True)

    def _balanced(self, start: int, end: int) -> str:
        """Widen a chain slice such as '0 < (x' so that its parentheses match."""
        s = self.source
        opens, closes = s.count("(", start, end), s.count(")", start, end)
        while opens > closes and s[end:].lstrip().startswith(")"):
            end, closes = s.index(")", end) + 1, closes + 1
        while closes > opens and s[:start].rstrip().endswith("("):
            start, opens = s.rindex("(", 0, start), opens + 1
        return s[start:end].strip()

    def run(self, start: int, condition: bool) -> tuple[ast.expr, _C]:
        tree = self.parse(start)
        result = self.compile(tree)
        if result.cond != condition:
            raise self.error(
                "must be a condition, e.g. 'x >= 5', not a number"
                if condition
                else "must be a number, not a condition",
                *self.pos(tree),
            )
        return tree, result


def _is_mode_test(node: ast.AST) -> TypeGuard[ast.Call]:
    return (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "in_mode"
        and len(node.args) == 1
        and not node.keywords
        and dotted_name(node.args[0]) is not None
    )


def dotted_name(node: ast.expr) -> str | None:
    """``Arm.Up`` as text, if ``node`` is a name or a dotted chain of names (a mode's path
    in ``in_mode(...)`` here and in the requirements' formulas); else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([node.id, *reversed(parts)])


def _requirement_only(name: str) -> str:
    return (
        f"'{name}' belongs to requirement formulas (a team's requirements:), not to "
        "guards, invariants, inputs or flows"
    )


def _conjuncts(node: ast.expr, node_atoms: Mapping[int, list[Atom]]) -> list[Atom]:
    """The atoms of ``node`` that are conjuncts of it (through ``and`` only, a chain
    ``0 < x < 1`` being one too): where one is false, so is the whole condition."""
    if isinstance(node, ast.BoolOp) and isinstance(node.op, ast.And):
        return [a for v in node.values for a in _conjuncts(v, node_atoms)]
    if isinstance(node, ast.Compare):
        return list(node_atoms.get(id(node), ()))
    return []


def compile_expression(
    source: str, symbols: Mapping[str, Getter], *, condition: bool = False
) -> Expression:
    """Compile `source` once into a vectorized callable over the engine's context."""
    comp = _Compiler(source, symbols)
    tree, result = comp.run(0, condition)
    return Expression(
        source,
        result.fn,
        frozenset(comp.names),
        condition,
        tuple(comp.atoms),
        tuple(_conjuncts(tree, comp.node_atoms)) if condition else (),
        result.row,
    )


def free_names(source: str, *, condition: bool = False) -> frozenset[str]:
    """Validate `source` (whitelist and types) without resolving symbols; return its names."""
    comp = _Compiler(source, None)
    comp.run(0, condition)
    return frozenset(comp.names)


def compile_assignment(
    source: str, symbols: Mapping[str, Getter], targets: Collection[str]
) -> tuple[str, Expression]:
    """Compile ``target = expr`` or ``target op= expr`` (op in ``+ - * / % **``)."""
    comp = _Compiler(source, symbols)
    match = _ASSIGN_RE.match(source)
    if not match:
        if not source.strip():
            raise comp.error("empty assignment", 0)
        start = len(source) - len(source.lstrip())
        raise comp.error("expected an assignment such as 'v = -e*v'", start, len(source))
    (t0, t1), target, op = match.span(1), unicodedata.normalize("NFKC", match[1]), match[2]
    if target.startswith("__"):
        raise comp.error(f"names starting with '__' are not allowed: {target}", t0, t1)
    if not target.isidentifier():
        raise comp.error(f"invalid assignment target '{match[1]}'", t0, t1)
    if op and op not in _AUGOPS:
        raise comp.error(
            f"'{op}=' is not supported",
            match.start(2),
            match.end(2) + 1,
            "use =, +=, -=, *=, /=, %= or **=",
        )
    if target not in targets:
        raise comp.error(
            f"unknown assignment target '{target}'", t0, t1, did_you_mean(target, targets)
        )
    tree, rhs = comp.run(match.end(), False)
    text = source[match.end() :].strip()
    if op:  # n += 1 is n + (1): the target is read, so it must also be a symbol
        rhs = _apply(_AUGOPS[op], [comp.name(target, t0, t1), rhs], False)
        text = f"{target} {op} " + (
            text if isinstance(tree, ast.Name | ast.Constant) else f"({text})"
        )
    return target, Expression(text, rhs.fn, frozenset(comp.names), False, tuple(comp.atoms))

"""Requirement formulas: the expression language extended with Signal Temporal Logic.

A requirement is text in the same safe language as guards (parsed by ``ast.parse`` and a
whitelist, compiled to closures, never evaluated), with these additions:

- temporal operators ``always[a, b](phi)``, ``eventually[a, b](phi)``,
  ``until[a, b](phi, psi)`` (the window is optional: ``always(phi)`` means ``[0, inf]``)
  and ``implies(phi, psi)``;
- signals: ``agent.state`` (``labmate.x``), ``agent.parameter``, a world series' column
  (``box.theta``), bare names for a one-agent team (``x``) and team parameters, ``t``;
- discrete signals: ``in_mode(agent, Mode.Path)``, ``count_in_mode(Mode.Path)``,
  ``in_role(agent, role)``, ``count_in_role(role)``, ``received([agent,] message)`` and
  ``sent([agent,] message)`` (true at the instants a message is received or sent).

The result is a tree of :class:`~hybridteam.requirements.nodes.Node` objects whose
robustness is computed on a run's signals (:mod:`.signals`). The parser rules, the error
offsets and the number/condition typing are the expression compiler's own.
"""

from __future__ import annotations

import ast
import math
from typing import Any

from hybridteam.expr.compiler import _Compiler, dotted_name
from hybridteam.expr.language import _C, ExpressionError, _Problem
from hybridteam.requirements import nodes as N
from hybridteam.requirements.catalog import Catalog

TEMPORAL = {"always": 1, "eventually": 1, "until": 2}
SIGNAL_FUNCTIONS = {  # name: (usage, accepts an agent first, result is a condition)
    "in_mode": ("in_mode(agent, Mode.Path)", True, True),
    "in_role": ("in_role(agent, role)", True, True),
    "count_in_mode": ("count_in_mode(Mode.Path)", False, False),
    "count_in_role": ("count_in_role(role)", False, False),
    "received": ("received([agent,] message)", True, True),
    "sent": ("sent([agent,] message)", True, True),
}
STL_NAMES = frozenset({*TEMPORAL, "implies", *SIGNAL_FUNCTIONS})


class _F(_C):
    """A compiled condition: its formula node (robustness), not a boolean closure."""

    __slots__ = ("node",)

    def __init__(self, node: N.Node) -> None:
        super().__init__(lambda ctx: None, True)
        self.node = node


class _FormulaCompiler(_Compiler):
    def __init__(self, source: str, catalog: Catalog) -> None:
        super().__init__(source, catalog.bare_symbols())
        self.catalog = catalog
        self._allowed: set[int] = set()

    # -- whitelist ------------------------------------------------------------------------
    def _check(self, root: ast.expr) -> None:
        for node in ast.walk(root):
            if not isinstance(node, ast.Call):
                if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                    self._allowed.add(id(node))  # agent.x, box.theta
                continue
            f = node.func
            if (
                isinstance(f, ast.Subscript)
                and isinstance(f.value, ast.Name)
                and f.value.id in TEMPORAL
            ):
                self._allowed.update({id(f), id(f.slice)})
            if isinstance(f, ast.Name) and f.id in SIGNAL_FUNCTIONS:
                self._allowed.update(
                    id(a) for a in ast.walk(node) if a is not node and isinstance(a, ast.Attribute)
                )
        super()._check(root)

    def _problem(self, node: Any) -> _Problem | None:
        if id(node) in self._allowed:
            return None
        if isinstance(node, ast.Call):
            f = node.func
            name = (
                f.value.id
                if isinstance(f, ast.Subscript) and isinstance(f.value, ast.Name)
                else f.id
                if isinstance(f, ast.Name)
                else None
            )
            if name in STL_NAMES:
                return self._arity(node, name)
        return super()._problem(node)

    def _arity(self, node: ast.Call, name: str) -> _Problem | None:
        start, end = self.pos(node)
        if node.keywords:
            return 0, start, end, "keyword arguments are not allowed", "pass arguments by position"
        n = len(node.args)
        if name in TEMPORAL or name == "implies":
            want = TEMPORAL.get(name, 2)
            usage = {
                "always": "always[a, b](phi)",
                "eventually": "eventually[a, b](phi)",
                "until": "until[a, b](phi, psi)",
                "implies": "implies(phi, psi)",
            }[name]
            return (
                None
                if n == want
                else (
                    1,
                    start,
                    end,
                    f"wrong number of arguments ({n}) in call to {name}",
                    f"usage: {usage}",
                )
            )
        usage, agent_first, _ = SIGNAL_FUNCTIONS[name]
        ok = n == 1 or (agent_first and n == 2)
        if ok and all(dotted_name(a) is not None for a in node.args):
            return None
        if ok:
            bad = next(a for a in node.args if dotted_name(a) is None)
            return (1, *self.pos(bad), f"{name}() takes names, not expressions", f"usage: {usage}")
        return (
            1,
            start,
            end,
            f"wrong number of arguments ({n}) in call to {name}",
            f"usage: {usage}",
        )

    # -- compilation ----------------------------------------------------------------------
    def compile(self, node: ast.expr) -> _C:
        if isinstance(node, ast.Compare):
            return self._compare_formula(node)
        if isinstance(node, ast.BoolOp):
            kids = [
                self.cond(v, "'and'" if isinstance(node.op, ast.And) else "'or'")
                for v in node.values
            ]
            cls = N.And if isinstance(node.op, ast.And) else N.Or
            return _F(cls(self.text(node), kids))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return _F(N.Not(self.text(node), [self.cond(node.operand, "'not'")]))
        if isinstance(node, ast.Constant) and isinstance(node.value, bool):
            return _F(N.Const(self.text(node), value=bool(node.value)))
        if isinstance(node, ast.Attribute):
            return _C(self._signal(node), False)
        if isinstance(node, ast.Call):
            f = node.func
            head = f.value if isinstance(f, ast.Subscript) else f
            assert isinstance(head, ast.Name)  # (the whitelist passed only these: F[0, 5](...))
            name = head.id
            if name in TEMPORAL or name == "implies":
                return self._temporal(node, name)
            if name in SIGNAL_FUNCTIONS:
                return self._signal_function(node, name)
        return super().compile(node)

    def name(self, name: str, start: int, end: int) -> _C:
        if name in ("true", "false") and name not in self.symbols:  # type: ignore[operator]  # (given its symbols)
            return _F(N.Const(name, value=name == "true"))
        try:
            return super().name(name, start, end)
        except ExpressionError as exc:
            hint = self.catalog.bare_hint(name)
            if hint and exc.message.startswith("unknown name"):
                raise self.error(exc.message, start, end, hint) from None
            raise

    def text(self, node: ast.expr) -> str:
        return self._balanced(*self.pos(node))

    def cond(self, node: ast.expr, user: str) -> N.Node:
        return self.typed(node, True, user).node  # type: ignore[attr-defined]  # (a condition: an _F)

    def _compare_formula(self, node: ast.Compare) -> _C:
        operands = [node.left, *node.comparators]
        values = [self.typed(o, False, "a comparison") for o in operands]
        for o, v in zip(operands, values, strict=True):
            if v.const and isinstance(v.value, float) and math.isnan(v.value):  # no margin
                raise self.error(
                    f"'{self.text(o)}' is not a number (nan): a comparison with it has no margin",
                    *self.pos(o),
                )
        preds: list[N.Node] = []
        for i, op in enumerate(node.ops):
            a, b = operands[i], operands[i + 1]
            text = (
                self._balanced(self.pos(a)[0], self.pos(b)[1])
                if len(node.ops) > 1
                else self.text(node)
            )
            sym = {
                ast.Lt: "<",
                ast.LtE: "<=",
                ast.Gt: ">",
                ast.GtE: ">=",
                ast.Eq: "==",
                ast.NotEq: "!=",
            }[type(op)]
            preds.append(
                N.Predicate(
                    text,
                    lhs=values[i].fn,
                    rhs=values[i + 1].fn,
                    op=sym,
                    continuous=self._continuous(a, b),
                )
            )
        return _F(preds[0] if len(preds) == 1 else N.And(self.text(node), preds))

    def _continuous(self, *operands: ast.expr) -> bool:
        """Whether a comparison's margin moves continuously between grid points: not when
        an operand counts modes or roles or reads a discrete variable (they jump at
        instants)."""
        for n in (n for o in operands for n in ast.walk(o)):
            if (
                isinstance(n, ast.Call)
                and isinstance(n.func, ast.Name)
                and n.func.id in SIGNAL_FUNCTIONS
            ):
                return False
            name = (
                f"{n.value.id}.{n.attr}"
                if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)
                else n.id
                if isinstance(n, ast.Name)
                else None
            )
            if name is not None and self.catalog.is_variable(name):
                return False
        return True

    def _temporal(self, node: ast.Call, name: str) -> _C:
        args = [self.cond(a, f"{name}()") for a in node.args]
        if name == "implies":
            return _F(N.Implies(self.text(node), args))
        lo, hi = 0.0, math.inf
        if isinstance(node.func, ast.Subscript):
            lo, hi = self._window(node.func)
        cls = {"always": N.Always, "eventually": N.Eventually, "until": N.Until}[name]
        return _F(cls(self.text(node), args, lo, hi))

    def _window(self, sub: ast.Subscript) -> tuple[float, float]:
        start, end = self.pos(sub)
        start = self.source.index("[", self.pos(sub.value)[1], end)
        elts = sub.slice.elts if isinstance(sub.slice, ast.Tuple) else [sub.slice]
        usage = "write a window as [a, b] with 0 <= a <= b, e.g. always[0, 10](x < 1)"
        if len(elts) != 2:
            raise self.error("a window needs two bounds", start, end, usage)
        bounds = []
        for e in elts:
            c = self.typed(e, False, "a window bound")
            if not c.const:
                raise self.error("window bounds must be numbers", *self.pos(e), usage)
            value = float(c.value)
            written_inf = isinstance(e, ast.Name) and e.id == "inf"
            if not math.isfinite(value) and not written_inf:  # 1/0, 1e999: not a number
                raise self.error(
                    f"window bounds must be numbers; this one is {value:g}",
                    *self.pos(e),
                    "an endless window is written inf, e.g. always[0, inf](x < 1)",
                )
            bounds.append(value)
        lo, hi = bounds
        if not (math.isfinite(lo) and lo >= 0) or math.isnan(hi) or hi < lo:
            raise self.error(
                f"bad window [{lo:g}, {hi:g}]"
                + (": its start is after its end" if hi < lo else ""),
                start,
                end,
                usage,
            )
        return lo, hi

    def _signal(self, node: ast.Attribute) -> Any:
        text = dotted_name(node)
        getter, problem = self.catalog.dotted(text or "")
        if getter is None:
            raise self.error(problem[0], *self.pos(node), problem[1])
        return getter

    def _signal_function(self, node: ast.Call, name: str) -> _C:
        _, _, is_cond = SIGNAL_FUNCTIONS[name]
        args = [(dotted_name(a) or "", *self.pos(a)) for a in node.args]
        getter, problem = self.catalog.function(name, args)
        if getter is None:
            start, end, message, hint = problem
            raise self.error(message, start, end, hint)
        if is_cond:
            return _F(N.Flag(self.text(node), get=getter))
        return _C(getter, False)


def compile_formula(source: str, catalog: Catalog) -> N.Node:
    """Compile requirement text into a formula tree (raises :class:`ExpressionError`)."""
    comp = _FormulaCompiler(source, catalog)
    tree = comp.parse(0)
    result = comp.compile(tree)
    if not result.cond:
        raise comp.error(
            "a requirement must be a condition, e.g. 'always(x <= 22)', not a number",
            *comp.pos(tree),
        )
    return result.node  # type: ignore[attr-defined]  # (a condition: an _F)

"""Formula trees and their quantitative semantics (robustness) on a run's signals.

Robustness follows the usual STL definitions: a comparison ``a <= b`` has robustness
``b - a`` (``a >= b``: ``a - b``; strict comparisons the same), ``not`` negates, ``and`` is
the minimum, ``or`` the maximum, ``implies(p, q)`` is ``max(-p, q)``; a Boolean signal
(``in_mode``, ``received``, ``==``, ``!=``, ``true``) is ``+inf`` where it holds and ``-inf``
where not. The temporal operators are :mod:`.robustness`'s. Every array is ``(n, K)``:
instances by the points of each instance's time grid. A formula is *satisfied* when its
robustness at t = 0 is ``>= 0`` (0 is the boundary, where strict and non-strict
comparisons cannot be told apart by a margin).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

INF = np.inf


@dataclass(eq=False)
class Node:
    """One sub-formula: its source text (what a verdict names as failing) and children."""

    source: str
    children: list[Node] = field(default_factory=list)

    def rho(self, sig: Any) -> np.ndarray:
        cached = sig.memo.get(id(self))
        if cached is None:
            cached = sig.memo[id(self)] = self._rho(sig)
        return cached

    def _rho(self, sig: Any) -> np.ndarray:  # pragma: no cover - every subclass has one
        raise NotImplementedError

    def rho0(self, sig: Any) -> np.ndarray:
        """Robustness at t = 0 only, per instance: a requirement's value."""
        return self.rho(sig)[:, 0]

    def is_boundary_continuous(self) -> bool:
        """Whether a failure of this node can begin between grid points (see
        :func:`_continuous`, defined after the node kinds it tells apart)."""
        return _continuous(self)

    def blame(self, sig: Any, i: int, k: int) -> tuple[float, str]:
        """(time, sub-formula) that first makes this node fail at grid point ``k`` of
        instance ``i`` (where its robustness is negative)."""
        return float(sig.t[i, k]), self.source


def _full(sig: Any, value: Any) -> np.ndarray:
    """``value`` as floats of the grid's shape (no copy when it already is one)."""
    value = np.asarray(value, dtype=float)
    return value if value.shape == sig.shape else np.broadcast_to(value, sig.shape)


@dataclass(eq=False)
class Const(Node):
    value: bool = True

    def _rho(self, sig: Any) -> np.ndarray:
        return np.full(sig.shape, INF if self.value else -INF)


@dataclass(eq=False)
class Flag(Node):
    """A Boolean signal: in_mode, in_role, received, sent."""

    get: Callable[[Any], np.ndarray] | None = None

    def _rho(self, sig: Any) -> np.ndarray:
        return np.where(np.broadcast_to(self.get(sig), sig.shape), INF, -INF)  # type: ignore[misc]  # (built with its getter)


@dataclass(eq=False)
class Predicate(Node):
    lhs: Callable[[Any], Any] | None = None
    rhs: Callable[[Any], Any] | None = None
    op: str = "<="
    continuous: bool = True  # False when an operand counts modes (it jumps)

    def _rho(self, sig: Any) -> np.ndarray:
        with np.errstate(all="ignore"):
            a, b = _full(sig, self.lhs(sig)), _full(sig, self.rhs(sig))  # type: ignore[misc]  # (built with both sides)
            if self.op in ("==", "!="):
                return np.where((a == b) == (self.op == "=="), INF, -INF)
            out = b - a if self.op in ("<", "<=") else a - b
            if np.isinf(a).any() and np.isinf(b).any():
                # inf - inf (two unbounded sides) has no margin: count it as the boundary
                out = np.where(np.isnan(out) & ~np.isnan(a) & ~np.isnan(b), 0.0, out)
        return out


@dataclass(eq=False)
class Not(Node):
    def _rho(self, sig: Any) -> np.ndarray:
        return -self.children[0].rho(sig)


@dataclass(eq=False)
class And(Node):
    def _rho(self, sig: Any) -> np.ndarray:
        return np.minimum.reduce([c.rho(sig) for c in self.children])

    def blame(self, sig: Any, i: int, k: int) -> tuple[float, str]:
        worst = min(self.children, key=lambda c: c.rho(sig)[i, k])
        return worst.blame(sig, i, k)


@dataclass(eq=False)
class Or(Node):
    def _rho(self, sig: Any) -> np.ndarray:
        return np.maximum.reduce([c.rho(sig) for c in self.children])


@dataclass(eq=False)
class Implies(Node):
    def _rho(self, sig: Any) -> np.ndarray:
        return np.maximum(-self.children[0].rho(sig), self.children[1].rho(sig))

    def blame(self, sig: Any, i: int, k: int) -> tuple[float, str]:
        return self.children[1].blame(sig, i, k)  # the premise held, the conclusion failed


@dataclass(eq=False)
class Temporal(Node):
    lo: float = 0.0
    hi: float = INF

    def window(self, sig: Any, i: int, k: int) -> np.ndarray:
        """Grid indices of instance ``i`` inside the window of grid point ``k``."""
        t = sig.t[i]
        return np.flatnonzero((t >= t[k] + self.lo) & (t <= t[k] + self.hi) & np.isfinite(t))

    def _whole_run(self, sig: Any, op: Any, identity: float) -> np.ndarray | None:
        """At t = 0, a window ``[0, inf)`` is the whole run: one reduction per row (the
        value :func:`.robustness.always` would give there, without the other points)."""
        if self.lo != 0 or self.hi != INF:
            return None
        body = self.children[0].rho(sig)
        return op.reduce(np.where(np.isfinite(sig.t), body, identity), axis=1)


@dataclass(eq=False)
class Always(Temporal):
    def _rho(self, sig: Any) -> np.ndarray:
        from hybridteam.requirements import robustness as R

        return R.always(sig.t, self.children[0].rho(sig), self.lo, self.hi)

    def rho0(self, sig: Any) -> np.ndarray:
        whole = self._whole_run(sig, np.minimum, INF)
        return super().rho0(sig) if whole is None else whole

    def blame(self, sig: Any, i: int, k: int) -> tuple[float, str]:
        """The first failing point in the window. Where the failure starts between two
        grid points, it starts at the earlier one if that one sits exactly on the
        boundary (robustness 0: a located crossing)."""
        body = self.children[0]
        rho = body.rho(sig)[i]
        win = self.window(sig, i, k)
        bad = win[rho[win] < 0]
        j = int(bad[0])
        t_fail, failed = body.blame(sig, i, j)
        if (
            j > win[0]
            and np.isfinite(rho[j - 1])
            and body.is_boundary_continuous()
            and t_fail == sig.t[i, j]
        ):
            # a continuous margin turned negative between two grid points: where the
            # segment between them crosses zero (at t[j-1] itself on a located crossing)
            t0, t1 = sig.t[i, j - 1], sig.t[i, j]
            t_fail = float(t0 + (t1 - t0) * rho[j - 1] / (rho[j - 1] - rho[j]))
        return t_fail, failed


@dataclass(eq=False)
class Eventually(Temporal):
    def _rho(self, sig: Any) -> np.ndarray:
        from hybridteam.requirements import robustness as R

        return R.eventually(sig.t, self.children[0].rho(sig), self.lo, self.hi)

    def rho0(self, sig: Any) -> np.ndarray:
        whole = self._whole_run(sig, np.maximum, -INF)
        return super().rho0(sig) if whole is None else whole

    def blame(self, sig: Any, i: int, k: int) -> tuple[float, str]:
        """Never held within the window: the failure is certain at the window's end (or
        the run's, when the run ended first)."""
        end = min(float(sig.t[i, k]) + self.hi, float(sig.t_end[i]))
        return end, self.source


@dataclass(eq=False)
class Until(Temporal):
    def _rho(self, sig: Any) -> np.ndarray:
        from hybridteam.requirements import robustness as R

        return R.until(
            sig.t, self.children[0].rho(sig), self.children[1].rho(sig), self.lo, self.hi
        )


def _continuous(node: Node) -> bool:
    """Whether a failure of ``node`` can begin between grid points (its robustness moves
    continuously): comparisons of sampled states do, Boolean signals and counts jump at
    grid points (transition and message instants are on the grid)."""
    if isinstance(node, Predicate):
        return node.continuous and node.op not in ("==", "!=")
    if isinstance(node, Flag | Const | Temporal):
        return False
    return all(_continuous(c) for c in node.children)

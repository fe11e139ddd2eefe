"""Plants: the continuous part of an agent (state, inputs, kinematics).

Kinematic plants integrate *exactly* under a zero-order-held input: a sampled control law
holds ``u`` over a control period, and the unicycle's arc or the holonomic base's straight
line is then known in closed form. Exactness matters for guards: a guard crossing located on
the closed form is located on the true trajectory, not on a numerical approximation of it.

The generic flow plant has no inputs; each mode gives ``dx/dt`` as expressions and the
engine integrates it with the Runge–Kutta scheme in :mod:`hybridteam.dynamics.rk`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from hybridteam.arrays import count_true, every, some
from hybridteam.floatpaths import FLOAT_PATHS, ON_FLOATS, Ops, float_form

#: The operations :func:`arc` is written over for arrays: numpy's, and whether any or every
#: row of a mask is true (:func:`~hybridteam.arrays.some`, :func:`~hybridteam.arrays.every`),
#: which its float form reads as the one truth it has. ``cos_heading`` and ``sin_heading``
#: (of the mid-arc heading) are numpy's here; a unicycle's own namespace remembers them
#: (:class:`Unchanged`).
ARRAYS = SimpleNamespace(
    sin=np.sin,
    cos=np.cos,
    cos_heading=np.cos,
    sin_heading=np.sin,
    where=np.where,
    true_divide=np.true_divide,
    some=some,
    every=every,
)

#: Up to this many distinct shapes of headings an :class:`Unchanged` remembers (an
#: ensemble's steps, its crossing checks' points, a few more as instances end).
SHAPES = 4
#: Below this many elements an :class:`Unchanged` computes without looking: comparing and
#: keeping cost about 3 µs a call, what numpy's cosine of some 300 doubles costs.
FEWEST = 256


class Unchanged:
    """An elementwise function (numpy's ``cos`` or ``sin``) that remembers its last array
    in and out for each shape, and computes again only the elements whose argument changed
    since, compared bit for bit: the same values.

    A unicycle driving straight keeps its heading, so the mid-arc heading of its next step
    is the one before (``th + 0``), and its cosine and sine are two of the arc's three
    transcendental functions, most of its cost at an ensemble's size. What it keeps are
    read-only arrays that belong to the plant (one compiled agent), not to a run: rows are
    matched by position and bits only, so any caller gets what numpy gives.
    """

    __slots__ = ("fn", "last")

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray]) -> None:
        self.fn = fn
        self.last: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, a: Any) -> Any:
        if not isinstance(a, np.ndarray) or a.dtype != np.float64 or a.size < FEWEST:
            return self.fn(a)
        bits = np.ascontiguousarray(a).view(np.int64)
        last = self.last
        seen = last.pop(a.shape, None)  # (re-entered below: the shapes in the order used)
        if seen is None:
            out = self.fn(a)
        else:
            changed = bits != seen[0]
            n = count_true(changed)
            if n == 0:
                last[a.shape] = seen
                return seen[1]
            if 2 * n > a.size:
                out = self.fn(a)
            else:
                out = seen[1].copy()
                out[changed] = self.fn(a[changed])
        out.flags.writeable = False
        if len(last) >= SHAPES:  # the least recently used shape leaves
            last.pop(next(iter(last), ()), None)
        last[a.shape] = (bits.copy(), out)  # (a copy: the caller may reuse its array)
        return out


@dataclass(frozen=True)
class Plant:
    """Kinematics of one agent: names of its state and input components."""

    kind: str
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]

    @property
    def exact(self) -> bool:
        """Whether :meth:`propagate` gives the exact flow under a held input."""
        return bool(self.input_names)

    def derivative(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def propagate(self, x: np.ndarray, u: np.ndarray, h: np.ndarray) -> np.ndarray:
        raise NotImplementedError  # pragma: no cover


class Unicycle(Plant):
    """Differential drive: state (x, y, theta), input (v, omega) in the body frame."""

    #: the operations its arcs are computed with (:data:`ARRAYS`, the heading's cosine
    #: and sine remembered by :class:`Unchanged`): set once, by ``__init__``
    ops: SimpleNamespace

    def __init__(self) -> None:
        super().__init__("unicycle", ("x", "y", "theta"), ("v", "omega"))
        # its own arc operations: the heading's cosine and sine remembered (Unchanged)
        ops = SimpleNamespace(**vars(ARRAYS))
        ops.cos_heading, ops.sin_heading = Unchanged(np.cos), Unchanged(np.sin)
        object.__setattr__(self, "ops", ops)

    def derivative(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        th = x[:, 2]
        out = np.empty((x.shape[0], 3))  # np.stack's values, without its checks
        out[:, 0], out[:, 1], out[:, 2] = u[:, 0] * np.cos(th), u[:, 0] * np.sin(th), u[:, 1]
        return out

    def propagate(self, x: np.ndarray, u: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Exact arc: chord length ``v h sin(a)/a`` (a = omega h / 2) along the mid-arc heading.

        Straight lines and arcs share one code path: ``sin(a)/a`` is exact in floating
        point for any nonzero ``a`` (for tiny ``a``, ``sin(a)`` rounds to ``a`` itself) and is
        set to its limit 1 at ``a = 0``, so there is no branch on small turn rates.
        """
        if x.shape[0] <= FEW_ARCS and FLOAT_PATHS.on:
            return _arcs_few(x, u, h)
        out = np.empty_like(x)
        out[:, 0], out[:, 1], out[:, 2] = arc(
            x[:, 0], x[:, 1], x[:, 2], u[:, 0], u[:, 1], h, self.ops
        )
        return out


def arc(
    px: Any, py: Any, th: Any, v: Any, w: Any, h: Any, ops: Ops = ARRAYS
) -> tuple[Any, Any, Any]:
    """The pose after driving at ``v`` turning at ``w`` for ``h`` from ``(px, py, th)``
    (:meth:`Unicycle.propagate`), written once over ``ops``: :data:`ARRAYS` (numpy, one
    element per row), and the float form :func:`_arc_on_floats` made from this source.

    The ratio ``sin(a)/a`` is divided only where ``a`` is nonzero (its divisor 1 elsewhere,
    so the arrays need no error state) and is its limit 1 at 0. Where no row turns (a
    straight drive: every ``a`` zero) the ratio is 1 throughout, and ``chord * 1`` is
    ``chord`` bit for bit: the sine and the selections are skipped, a third of the arc's
    cost. Where every row turns the selections keep every quotient and are skipped too;
    each row still gets the same operations on the same doubles.
    """
    half = 0.5 * w * h
    chord = v * h
    turning = half != 0
    if ops.some(turning):
        ratio = ops.sin(half)
        if ops.every(turning):
            ratio = ops.true_divide(ratio, half)
        else:
            ratio = ops.where(turning, ops.true_divide(ratio, ops.where(turning, half, 1.0)), 1.0)
        chord = chord * ratio
    mid = th + half
    return px + chord * ops.cos_heading(mid), py + chord * ops.sin_heading(mid), th + w * h


_arc_on_floats = float_form(
    arc,
    {
        **ON_FLOATS,
        "some": bool,
        "every": bool,
        "cos_heading": ON_FLOATS["cos"],
        "sin_heading": ON_FLOATS["sin"],
    },
)

#: up to this many rows, :meth:`Unicycle.propagate` runs on Python floats (:func:`_arcs_few`)
#: while the float paths are on (:data:`hybridteam.floatpaths.FLOAT_PATHS`)
FEW_ARCS = 8


def _arcs_few(x: np.ndarray, u: np.ndarray, h: np.ndarray) -> np.ndarray:
    """:meth:`Unicycle.propagate` for a few rows (a single run's step, or its crossing
    checks): :func:`arc`'s float form row by row.

    The array version makes about twenty numpy calls, each costing its dispatch (about
    1 µs) whatever the number of rows; on floats the same IEEE operations run in the same
    order, and the sines and cosines are numpy's own, so each row has the array version's
    bits.
    """
    steps = np.asarray(h, dtype=float)  # one step for every row, or one per row
    hs = steps.tolist() if steps.ndim else [float(steps)] * x.shape[0]
    out = [
        _arc_on_floats(px, py, th, v, w, hh)
        for (px, py, th), (v, w), hh in zip(x.tolist(), u.tolist(), hs, strict=True)
    ]
    return np.array(out, dtype=float).reshape(-1, 3)


class Holonomic(Plant):
    """Omni-directional base: state (x, y, theta), input (vx, vy, omega) in the world frame."""

    def __init__(self) -> None:
        super().__init__("holonomic", ("x", "y", "theta"), ("vx", "vy", "omega"))

    def derivative(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return u.copy()

    def propagate(self, x: np.ndarray, u: np.ndarray, h: np.ndarray) -> np.ndarray:
        return x + u * h[:, None]


class Flow(Plant):
    """A classical hybrid automaton's state vector; modes define its derivative."""

    def __init__(self, state_names: tuple[str, ...]) -> None:
        super().__init__("flow", tuple(state_names), ())


class NoPlant(Plant):
    """No body at all: an agent that only thinks and talks (a human operator)."""

    def __init__(self) -> None:
        super().__init__("none", (), ())

    @property
    def exact(self) -> bool:
        return True

    def derivative(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.zeros_like(x)

    def propagate(self, x: np.ndarray, u: np.ndarray, h: np.ndarray) -> np.ndarray:
        return x.copy()


KINEMATICS: dict[str, Callable[[], Plant]] = {"unicycle": Unicycle, "holonomic": Holonomic}


def make_plant(kind: str, state_names: tuple[str, ...] = ()) -> Plant:
    """Build a plant by kind name (``unicycle``, ``holonomic`` or ``flow``)."""
    if kind == "flow":
        return Flow(state_names)
    if kind == "none":
        return NoPlant()
    return KINEMATICS[kind]()


def saturate(u: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Actuator limits: clip each input component into ``[lower, upper]``."""
    return np.minimum(np.maximum(u, lower), upper)

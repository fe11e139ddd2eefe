"""The unicycle's exact arc: closed-form poses, the array and float forms bit for bit, and
the work a straight drive skips (the ratio ``sin(a)/a`` is 1 where no row turns)."""

from __future__ import annotations

import math
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from hybridteam.dynamics import plants
from hybridteam.dynamics.plants import ARRAYS, Unchanged, Unicycle, _arc_on_floats, arc
from hybridteam.floatpaths import FLOAT_PATHS


def _counting() -> tuple[SimpleNamespace, dict[str, int]]:
    """:data:`ARRAYS` with a count of each operation's calls."""
    calls: dict[str, int] = {}

    def counted(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            calls[name] = calls.get(name, 0) + 1
            return fn(*args)

        return call

    return SimpleNamespace(**{k: counted(k, f) for k, f in vars(ARRAYS).items()}), calls


def test_straight_rows_skip_the_ratio_and_land_where_the_line_ends() -> None:
    ops, calls = _counting()
    px, py, th = np.array([1.0, -2.0]), np.array([2.0, 0.5]), np.array([0.0, 0.0])
    v, w, h = np.array([2.0, -1.0]), np.zeros(2), np.array([0.5, 0.25])
    x, y, t = arc(px, py, th, v, w, h, ops)
    # heading 0: x advances by v h exactly, y and the heading stay
    assert x.tolist() == [2.0, -2.25] and y.tolist() == [2.0, 0.5] and t.tolist() == [0.0, 0.0]
    # only the mid-arc heading's cosine and sine: no sin(a), no selection, no quotient
    assert "sin" not in calls and calls.get("sin_heading") == calls.get("cos_heading") == 1
    assert "where" not in calls and "true_divide" not in calls


def test_turning_rows_select_only_when_some_row_goes_straight() -> None:
    ops, calls = _counting()
    arc(*(np.array([0.0, 0.0]),) * 3, np.ones(2), np.array([1.0, 2.0]), np.full(2, 0.1), ops)
    assert calls.get("sin") == 1 and calls.get("true_divide") == 1 and "where" not in calls
    ops, calls = _counting()
    arc(*(np.array([0.0, 0.0]),) * 3, np.ones(2), np.array([1.0, 0.0]), np.full(2, 0.1), ops)
    assert calls.get("where") == 2


def test_quarter_circle_and_the_forms_agree_bit_for_bit() -> None:
    # v = 1, omega = pi/2 for 1 s from the origin heading +x: a quarter of the circle of
    # radius 2/pi, ending at (2/pi, 2/pi) heading +y
    one = np.zeros(1)
    x, y, t = arc(one, one, one, one + 1.0, one + math.pi / 2, one + 1.0, ARRAYS)
    assert math.isclose(x[0], 2 / math.pi, rel_tol=1e-15)
    assert math.isclose(y[0], 2 / math.pi, rel_tol=1e-15)
    assert t[0] == math.pi / 2
    rng = np.random.default_rng(7)
    m = 40
    xs = rng.normal(size=(m, 3))
    us = rng.normal(size=(m, 2))
    us[::3, 1] = 0.0  # straight rows among turning ones
    us[1, 1] = -0.0
    hs = rng.uniform(0.0, 0.2, m)
    hs[5] = 0.0
    plant = Unicycle()
    mixed = plant.propagate(xs, us, hs)  # (more rows than the float path takes)
    with FLOAT_PATHS.off():
        few = np.concatenate(
            [plant.propagate(xs[k : k + 4], us[k : k + 4], hs[k : k + 4]) for k in range(0, m, 4)]
        )
    rows = [_arc_on_floats(*xs[k].tolist(), *us[k].tolist(), float(hs[k])) for k in range(m)]
    straight = plant.propagate(xs[::3], us[::3], hs[::3])  # no row turns
    turning = plant.propagate(xs[2::3], us[2::3], hs[2::3])  # every row turns
    expect = np.array(rows)
    assert mixed.tobytes() == expect.tobytes() == few.tobytes()
    assert straight.tobytes() == expect[::3].tobytes()
    assert turning.tobytes() == expect[2::3].tobytes()


def test_unchanged_headings_are_not_computed_again_and_give_numpy_bits(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(plants, "FEWEST", 2)  # (small arrays to read)
    seen: list[int] = []

    def cos(a: np.ndarray) -> np.ndarray:
        seen.append(a.size)
        return np.cos(a)

    fn = Unchanged(cos)
    first = np.array([0.0, 1.0, 2.0, 3.0])
    assert fn(first).tobytes() == np.cos(first).tobytes() and seen == [4]
    assert fn(first.copy()).tobytes() == np.cos(first).tobytes() and seen == [4]  # none again
    # one heading moved, and +0.0 became -0.0 (equal as numbers, not as bits): those two
    moved = np.array([-0.0, 1.0, 2.5, 3.0])
    assert fn(moved).tobytes() == np.cos(moved).tobytes() and seen == [4, 2]
    # another shape is remembered apart; most changed: all computed at once
    assert fn(np.ones(3)).tobytes() == np.cos(np.ones(3)).tobytes() and seen == [4, 2, 3]
    assert fn(moved + 1.0).tobytes() == np.cos(moved + 1.0).tobytes() and seen == [4, 2, 3, 4]
    assert not fn(moved + 1.0).flags.writeable  # (what it keeps cannot be written through)


def test_a_straight_drive_repeated_gives_the_fresh_arcs_bits() -> None:
    rng = np.random.default_rng(3)
    m = 300
    x = rng.normal(size=(m, 3))
    x[0, 2] = -0.0
    u = np.column_stack([rng.uniform(0.1, 1.0, m), np.zeros(m)])
    u[::4, 1] = 0.7  # some rows turn
    h = np.full(m, 0.1)
    plant = Unicycle()
    for _ in range(4):
        nxt = plant.propagate(x, u, h)
        assert nxt.tobytes() == Unicycle().propagate(x, u, h).tobytes()  # (a fresh plant)
        x = nxt

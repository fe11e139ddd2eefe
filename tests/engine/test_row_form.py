"""Atoms on one instance's Python floats (``Atom.row``): a single run's crossing search
evaluates them there instead of on one-element arrays, and must get the same bits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hybridteam as ht
from hybridteam.engine.compile.compiled import Ctx, Row
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.compile.scope import symbols
from hybridteam.expr.compiler import compile_expression
from hybridteam.floatpaths import FLOAT_PATHS
from tests.conftest import EXAMPLES

SYMS = symbols({"x": 0, "y": 1}, {"n": 0}, {"k": 0})

names = st.sampled_from(["x", "y", "n", "k", "t", "t_in_mode"])
numbers = st.sampled_from(["0", "0.0", "1", "2.5", "1e-300", "1e308", "3"])
arithmetic = st.recursive(
    names | numbers,
    lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/"]), inner).map(
            lambda p: f"({p[0]} {p[1]} {p[2]})"
        ),
        inner.map(lambda e: f"-{e}"),
        st.lists(inner, min_size=3, max_size=4).map(" - ".join),
    ),  # a chain: one fold
    max_leaves=8,
)
values = st.sampled_from(
    [0.0, -0.0, 1.0, -2.5, 1e-310, 3e300, -3e300, np.inf, -np.inf, np.nan, 0.1, 7.0]
)


@settings(max_examples=300, deadline=None)
@given(
    arithmetic,
    st.sampled_from(["<", "<=", ">", ">="]),
    arithmetic,
    st.lists(values, min_size=6, max_size=6),
)
def test_an_atom_on_floats_gives_the_bits_of_its_array_evaluation(lhs, op, rhs, vals):
    (atom,) = compile_expression(f"{lhs} {op} {rhs}", SYMS, condition=True).atoms
    assert atom.row is not None
    x, y, n, k, t, t_in = vals
    ctx = Ctx(np.array([[x, y]]), np.array([[n]]), np.array([[k]]), np.array([t]), np.array([t_in]))
    with np.errstate(all="ignore"):
        truth, margin = atom.truth_and_margin(ctx)
        r_truth, r_margin = atom.row(Row([x, y], [n], [k], t, t_in))
    assert type(r_truth) is bool and type(r_margin) is float
    assert r_truth == bool(np.asarray(truth).reshape(-1)[0])
    expected = np.asarray(margin, float).reshape(-1)[0]
    if np.isnan(expected):  # NaN's sign and payload follow the operand order of the CPU's
        assert np.isnan(r_margin)  # instruction; the search only asks whether it is NaN
    else:
        assert np.float64(r_margin).tobytes() == expected.tobytes()


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(arithmetic, st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), arithmetic),
        min_size=1,
        max_size=4,
    ),
    st.lists(st.sampled_from(["and", "or", "and not"]), min_size=3, max_size=3),
    st.lists(values, min_size=6, max_size=6),
)
def test_a_condition_on_floats_gives_its_array_truth(comparisons, words, vals):
    """Guards and invariants (comparisons joined by and, or, not; ``true``) on floats,
    as a crossing search judges a flip's guard."""
    parts = [f"{lhs} {op} {rhs}" for lhs, op, rhs in comparisons]
    source = parts[0]
    for word, part in zip(words, parts[1:], strict=False):
        source = f"({source}) {word} ({part})"
    expr = compile_expression(f"true and ({source})", SYMS, condition=True)
    assert expr.row is not None
    x, y, n, k, t, t_in = vals
    ctx = Ctx(np.array([[x, y]]), np.array([[n]]), np.array([[k]]), np.array([t]), np.array([t_in]))
    with np.errstate(all="ignore"):
        expected = bool(np.asarray(expr(ctx)).reshape(-1)[0])
    got = expr.row(Row([x, y], [n], [k], t, t_in))
    assert type(got) is bool and got == expected


@pytest.mark.parametrize(
    "source", ["sin(x) < 1", "x ** 2 < 1", "x % 2 < 1", "abs(x) < 1", "max(x, y) < 1"]
)
def test_atoms_with_other_operations_have_no_float_form(source):
    """Functions, powers and remainders may round differently on floats than numpy's
    array loops do: they keep the array evaluation."""
    (atom,) = compile_expression(source, SYMS, condition=True).atoms
    assert atom.row is None


def test_names_without_a_reader_give_no_float_form():
    syms = {**SYMS, "w": lambda c: c.x[:, 0]}  # a bare getter, as message fields are
    (atom,) = compile_expression("w + x < 1", syms, condition=True).atoms
    assert atom.row is None


SWING = """
team: swing
parameters: {k: 0.75}
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    initial: Out
    modes:
      Out:
        flow: {x: 1 + 0.5 * x}
        transitions: [{to: Back, guard: t_in_mode + x >= k}]
      Back:
        flow: {x: -x}
        transitions: [{to: Out, guard: x - t_in_mode / 4 <= 0.1 * t / 3}]
simulation: {duration: 6.0, sample_period: 0.5}
"""


@pytest.mark.parametrize(
    ("name", "duration"),
    [
        ("bouncing_ball.yaml", 3.0),
        ("thermostat.yaml", 60.0),
        ("water_tanks.yaml", None),
        ("swing", None),
    ],
)
def test_the_float_search_changes_no_bit_of_a_run(team_from_yaml, name, duration):
    """A single run's search on floats (checkpoints, dense search, judgement) against the
    same search on one-element arrays (the public switch off): byte-identical traces.
    The swing's guards read the time, the time in the mode (entered at other times than
    0), parameters and quotients."""
    if name == "swing":
        team = team_from_yaml(SWING)
    else:
        team = dataclasses.replace(ht.load(EXAMPLES / "automata" / name), requirements=())
    # every watched atom and guard has a float form: with the switch on, the search runs
    # on floats (the switch is the only difference between the two runs)
    agents = compile_team(team).agents
    assert all(ca.row_watches and ca.row_owners for ca in agents if ca.watches)
    assert any(ca.watches for ca in agents)
    assert FLOAT_PATHS.on
    fast = ht.simulate(team, duration=duration)
    if name == "swing":
        assert len(fast.transitions) > 8
    with FLOAT_PATHS.off():
        slow = ht.simulate(team, duration=duration)
    assert FLOAT_PATHS.on  # (restored)
    assert fast.to_json() == slow.to_json()

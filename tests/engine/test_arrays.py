"""The engine's array helpers give what the numpy expressions they stand for give."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.arrays import all_finite, distinct, gather, sinc, union


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(1, 40),
    width=st.integers(0, 4),
    depth=st.integers(1, 3),
    picks=st.lists(st.integers(-40, 39), max_size=30),
    seed=st.integers(0, 2**32 - 1),
)
def test_gather_equals_fancy_indexing(
    n: int, width: int, depth: int, picks: list[int], seed: int
) -> None:
    shape = (n,) + (width,) * (depth - 1)
    a = np.random.default_rng(seed).normal(size=shape)
    idx = np.array([p % n - (n if p < 0 else 0) for p in picks], np.intp)
    got = gather(a, idx)
    want = a[idx]
    assert got.shape == want.shape and got.dtype == want.dtype
    assert got.tobytes() == want.tobytes()
    got[...] = 7.0  # a copy, as fancy indexing gives: the source is untouched
    assert a[idx].tobytes() == want.tobytes()


def test_gather_of_a_slice_is_the_view_basic_indexing_gives() -> None:
    a = np.arange(12.0).reshape(4, 3)
    v = gather(a, slice(1, 3))
    assert np.shares_memory(v, a) and v.tolist() == a[1:3].tolist()


def test_gather_reads_a_transposed_view_and_refuses_rows_out_of_range() -> None:
    a = np.arange(12.0).reshape(4, 3)
    assert gather(a.T, np.array([2, 0])).tolist() == [a[:, 2].tolist(), a[:, 0].tolist()]
    with pytest.raises(IndexError):
        gather(a, np.array([4]))


@settings(max_examples=150, deadline=None)
@given(
    values=st.lists(
        st.one_of(st.floats(), st.sampled_from([np.inf, -np.inf, np.nan, 0.0])),
        min_size=0,
        max_size=30,
    ),
    width=st.integers(1, 3),
)
def test_all_finite_equals_isfinite_all(values: list[float], width: int) -> None:
    """On floats for a few numbers (a single run's), on arrays beyond: the same answer."""
    x = np.array(values[: len(values) // width * width], float).reshape(-1, width)
    assert all_finite(x) == bool(np.isfinite(x).all())


@settings(max_examples=150, deadline=None)
@given(values=st.lists(st.integers(0, 12), min_size=1, max_size=300))
def test_distinct_equals_unique(values: list[int]) -> None:
    """The drivers an ensemble's instances are under, counted rather than sorted."""
    v = np.array(values, np.intp)
    got = distinct(v)
    assert got == np.unique(v).tolist() and all(type(d) is int for d in got)


@settings(max_examples=150, deadline=None)
@given(
    values=st.lists(
        st.one_of(st.floats(), st.sampled_from([0.0, -0.0, 1e-300, np.inf])),
        min_size=1,
        max_size=20,
    )
)
def test_sinc_equals_numpys_bit_for_bit(values: list[float]) -> None:
    """The dead reckoning's arc factor, written out without np.sinc's wrapper."""
    x = np.array(values, float)
    with np.errstate(all="ignore"):
        assert sinc(x).tobytes() == np.sinc(x).tobytes()


@settings(max_examples=200, deadline=None)
@given(
    a=st.sets(st.integers(0, 2000), max_size=300),
    b=st.sets(st.integers(0, 2000), max_size=300),
)
def test_union_equals_union1d(a: set[int], b: set[int]) -> None:
    """Few indices or many (an ensemble's, marked in a mask), the same sorted indices."""
    left, right = (np.array(sorted(s), np.intp) for s in (a, b))
    got, want = union(left, right), np.union1d(left, right)
    assert got.dtype == want.dtype and got.tolist() == want.tolist() == sorted(a | b)

"""Small array helpers for the hot paths of the engine and the world components.

``np.broadcast_to`` costs several microseconds of Python-level checks per call, which the
engine pays tens of thousands of times in a single run for values that already have the
shape wanted (an expression of the state) or are one number (an expression of
parameters). These helpers take the short way in those two cases and give the same values.

Likewise ``ndarray.any()``/``.all()`` and ``np.flatnonzero`` pass through numpy's Python-level
wrappers (about 1 µs a call, whatever the size), and so does ``np.count_nonzero`` (0.4 µs),
while its C function and ``ndarray.nonzero`` cost about 0.1 µs. A single run asks "any?" a
dozen times per step, so :func:`some`, :func:`every` and :func:`where_true` are those C
calls, and :func:`filled` is ``np.full`` (about 1.3 µs) as an ``empty`` and a ``fill``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: no instance: an empty index, read-only, shared where an engine step has none to give
NO_INDEX = np.empty(0, np.intp)
NO_INDEX.flags.writeable = False


def spread(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` with ``shape``: itself when it has it, else broadcast (read-only). One
    number is filled into a new read-only array, not viewed through ``np.broadcast_to``:
    the same values, without its Python-level checks."""
    a = np.asarray(value)
    if a.shape == shape:
        return a
    if a.ndim == 0:
        out = np.empty(shape, a.dtype)
        out.fill(a)
        out.flags.writeable = False
        return out
    return np.broadcast_to(a, shape)


def sinc(x: np.ndarray) -> np.ndarray:
    """``np.sinc(x)`` of a float array (``sin(pi x) / (pi x)``, 1 at 0) by numpy's own
    operations, without its Python-level checks: ``y = pi x``, the machine epsilon where
    that is 0, ``sin(y) / y`` (a law's dead reckoning asks at every tick)."""
    y = np.pi * x
    y = np.where(y, y, np.finfo(float).eps)
    return np.sin(y) / y


def floats(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """A new float array of ``shape`` holding ``value`` (broadcast)."""
    a = np.asarray(value, dtype=float)
    if a.shape == shape:
        return a.copy()
    if a.ndim == 0:  # np.full without its wrapper
        out = np.empty(shape)
        out.fill(a)
        return out
    return np.broadcast_to(a, shape).copy()


try:  # the C function behind np.count_nonzero's array-function dispatch (same counts)
    from numpy._core._multiarray_umath import count_nonzero as _count
except ImportError:  # pragma: no cover - numpy 1.x keeps it under numpy.core
    _count = np.count_nonzero


def some(a: np.ndarray) -> bool:
    """Whether any element of ``a`` is true (nonzero): ``a.any()``, without its wrapper."""
    return _count(a) > 0


def count_true(a: np.ndarray) -> int:
    """How many elements of ``a`` are true (nonzero): ``np.count_nonzero(a)``."""
    return _count(a)


def every(a: np.ndarray) -> bool:
    """Whether every element of ``a`` is true (nonzero): ``a.all()``, without its wrapper."""
    return _count(a) == a.size


def all_finite(x: np.ndarray) -> bool:
    """Whether every element of ``x`` is a finite number. A single run's few numbers are
    checked on floats: ``np.isfinite`` and a count cost their dispatch, about 1 µs, for
    three numbers (``math.isfinite`` gives the same answer)."""
    if x.size <= 12:
        return all(map(math.isfinite, x.ravel().tolist()))
    return every(np.isfinite(x))


def where_true(a: np.ndarray) -> np.ndarray:
    """Indices of the true elements of a 1-D array: ``np.flatnonzero(a)``, one C call."""
    return a.nonzero()[0]


def gather(a: np.ndarray, idx: np.ndarray | slice) -> np.ndarray:
    """``a[idx]`` for an array ``a`` of two or more dimensions and an integer index array
    or a slice (not a mask).

    For an index array this is ``a.take(idx, 0)``: the same copy, but numpy 2 sets up a
    general index iterator for ``a[idx]`` on an array of two or more dimensions, which
    costs four times as much (2.4 against 0.6 µs for one row; 14 against 3 µs for 500
    rows of five). A slice gives the view ``a[idx]`` gives. (On a 1-D array ``a[idx]``
    takes numpy's fast path and is the quicker of the two; so is ``a[:, j][idx]`` for a
    column, where ``a[idx, j]`` mixes an integer and an array and is slow.)
    """
    return a[idx] if isinstance(idx, slice) else a.take(idx, 0)


def filled(size: int | tuple[int, ...], value: float, dtype: type = float) -> np.ndarray:
    """A new array of ``size`` (a length or a shape) copies of ``value``: ``np.full``,
    without its wrapper."""
    out: np.ndarray = np.empty(size, dtype)
    out.fill(value)
    return out


def distinct(values: np.ndarray) -> list[int]:
    """The sorted distinct values of a non-empty array of small non-negative integers
    (indices: the drivers of an ensemble's instances), as ``np.unique(values)`` gives them;
    one comparison when they are all equal (the usual case: every instance under one
    driver), else a count per value, not ``np.unique``'s sort (6 against 33 µs for a
    thousand)."""
    first = values[0]
    if every(values == first):
        return [int(first)]
    return np.flatnonzero(np.bincount(values)).tolist()


def union(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.union1d`` of two sorted, duplicate-free index arrays, the short way when one
    is empty or both are the same. Many indices (an ensemble's) are marked in a mask and
    read back in order, not sorted: 8 against 40 µs for two of a thousand."""
    if not b.size or (a.size == b.size and every(a == b)):
        return a
    if not a.size:
        return b
    if a.size + b.size <= 32:
        return np.union1d(a, b)
    mark = np.zeros(max(a.max(), b.max()) + 1, bool)
    mark[a] = True
    mark[b] = True
    return mark.nonzero()[0]

"""A response property's backward peeling, compiled (numba): what :func:`.properties._response`
does with scipy's sparse arrays, in the memory of one reversed subgraph.

The psi-free subgraph's reverse is built straight from the edges' sparse-row view (a
counting pass, then a placing pass, the offsets shifted in place: no copy of the forward
subgraph, no float or mark per edge), and the states that cannot reach a dead end or a
cycle among free states are peeled off with a stack. At hundreds of millions of states
the scipy path holds the forward subgraph, its reverse and their marks at once (about
five times the reverse alone); this is what lets a check of that size fit. The scipy path
stays where numba is not installed, and ``tests/verify/test_verify_peel.py`` compares the
two on every verify test model and mutant.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _count(row, dst, free, rev_ptr, out) -> None:
    """Per free state, its free successors' edges (``out``), and per free state the
    edges into it from free states (``rev_ptr[v + 1]``)."""
    for u in range(free.size):
        if free[u]:
            c = 0
            for e in range(row[u], row[u + 1]):
                v = dst[e]
                if free[v]:
                    rev_ptr[v + 1] += 1
                    c += 1
            out[u] = c


@njit(cache=True, nogil=True)
def _place(row, dst, free, rev_ptr, rev_idx) -> None:
    """Each edge between free states at its destination's place in the reverse, each
    destination's sources in the order of their edges; ``rev_ptr`` holds the counts'
    prefix sums (each destination's start) on the way in and its offsets on the way
    out (used as cursors, then shifted back by one destination)."""
    for u in range(free.size):
        if free[u]:
            for e in range(row[u], row[u + 1]):
                v = dst[e]
                if free[v]:
                    rev_idx[rev_ptr[v]] = u
                    rev_ptr[v] += 1
    for v in range(free.size, 0, -1):
        rev_ptr[v] = rev_ptr[v - 1]
    rev_ptr[0] = 0


@njit(cache=True)
def _peel(rev_ptr, rev_idx, out, free, dead) -> np.ndarray:
    """The free states with a path among free states to a dead one or into a cycle:
    the others peeled off backwards (a free state, not dead, whose free successors'
    edges are all peeled; ``out`` counts them down)."""
    gone = np.zeros(free.size, np.bool_)
    stack = np.empty(1024, np.int64)
    top = 0
    for u in range(free.size):
        if free[u] and out[u] == 0 and not dead[u]:
            gone[u] = True
            if top == stack.size:
                stack = np.concatenate((stack, np.empty(stack.size, np.int64)))
            stack[top] = u
            top += 1
    while top:
        top -= 1
        v = stack[top]
        for e in range(rev_ptr[v], rev_ptr[v + 1]):
            u = rev_idx[e]
            out[u] -= 1
            if out[u] == 0 and not dead[u] and not gone[u]:
                gone[u] = True
                if top == stack.size:
                    stack = np.concatenate((stack, np.empty(stack.size, np.int64)))
                stack[top] = u
                top += 1
    return free & ~gone


def reverse(
    row: np.ndarray, dst: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(rev_ptr, rev_idx, out)``: the subgraph of the edges between ``free`` states,
    reversed (``rev_idx[rev_ptr[v]:rev_ptr[v + 1]]``: the sources of v's edges,
    duplicates possible), and each state's out-degree in the subgraph."""
    n = free.size
    rev_ptr = np.zeros(n + 1, np.int32)  # (64-bit offsets past 2**31 edges)
    out = np.zeros(n, np.int32)
    _count(row, dst, free, rev_ptr, out)
    if int(out.sum(dtype=np.int64)) >= 2**31:
        rev_ptr = rev_ptr.astype(np.int64)
    np.cumsum(rev_ptr, out=rev_ptr)
    rev_idx = np.zeros(int(rev_ptr[-1]), np.int32 if n < 2**31 else np.int64)
    _place(row, dst, free, rev_ptr, rev_idx)
    return rev_ptr, rev_idx, out


def reaching(
    row: np.ndarray, dst: np.ndarray, free: np.ndarray, dead: np.ndarray
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The ``free`` states with a path among free states to a ``dead`` one or into a
    cycle (those included), and the reversed subgraph ``(rev_ptr, rev_idx)`` (a
    violation's lasso is traced on it)."""
    rev_ptr, rev_idx, out = reverse(row, dst, free)
    return _peel(rev_ptr, rev_idx, out, free, dead), (rev_ptr, rev_idx)

"""Bracket narrowing for crossing searches: Illinois (regula falsi, Anderson–Björck).

:func:`illinois` narrows many brackets at once, one array operation per step of the
method for all of them. A single run has one bracket, and there numpy's cost is per call
(about 1 µs, 3 µs for ``np.where``), not per element: the fifty-odd array operations of a
round cost far more than the trial point itself. So the last open bracket is finished by
:func:`_finish_one` on Python floats, the same operations in the same order on the same
IEEE doubles: the same bits as the array rounds would give (``tests/test_illinois.py`` compares
the two on random brackets), so a single run still equals its ensemble member.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hybridteam.arrays import some, where_true

MAX_ITER = 200

Evaluator = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``ev(positions, tau) -> (truth, margin)`` of one atom for some of a search's candidates."""


def illinois(ev: Evaluator, lo: np.ndarray, hi: np.ndarray, truth0: np.ndarray,
             tol: np.ndarray, m_lo: np.ndarray | None = None, m_hi: np.ndarray | None = None,
             *, scalar: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Narrow ``[lo, hi]`` (original truth at lo, flipped at hi) to ``tol``; return it
    (``lo`` and ``hi`` are updated in place).

    Regula falsi with the Anderson–Björck correction. Trial points are kept at least half
    a tolerance inside the bracket: when the crossing sits at an end (a strict comparison
    starting exactly on its boundary, or a margin of 1e-12 at one end) the next trial
    collapses the bracket at once instead of crawling. A bisection replaces the secant
    whenever three rounds failed to halve the bracket, which bounds the worst case.
    ``scalar=False`` keeps the array rounds to the end (for the tests that compare).
    """
    size = lo.size
    everyone = np.arange(size)
    if m_lo is None or some(np.isnan(m_lo)):
        need = everyone if m_lo is None else where_true(np.isnan(m_lo))
        m_lo = np.empty(size) if m_lo is None else m_lo
        m_hi = np.empty(size) if m_hi is None else m_hi
        # both ends in one evaluation (rows are independent: the same values as two)
        ends = ev(np.concatenate([need, need]), np.concatenate([lo[need], hi[need]]))[1]
        m_lo[need], m_hi[need] = ends[: need.size], ends[need.size:]
    ma, mb = m_lo, m_hi
    assert mb is not None
    kept = np.zeros(size, np.int8)  # +1: hi survived last round, -1: lo survived
    slow = np.zeros(size, np.int8)  # rounds in a row that did not halve the bracket
    for done in range(MAX_ITER):
        open_ = where_true(hi - lo > tol)
        if open_.size == 0:
            break
        if open_.size == 1 and scalar:
            _finish_one(ev, int(open_[0]), lo, hi, ma, mb, truth0, tol, kept, slow,
                        MAX_ITER - done)
            break
        # while every bracket is open (a single run's one bracket, mostly), views, not copies
        k: slice | np.ndarray = slice(None) if open_.size == size else open_
        a_, b_, fa, fb, tl = lo[k], hi[k], ma[k], mb[k], tol[k]
        width = b_ - a_
        c = b_ - fb * width / (fb - fa)  # (the run ignores floating-point errors)
        c = np.where(np.isfinite(c) & (slow[k] < 3), c, 0.5 * (a_ + b_))
        c = np.minimum(np.maximum(c, a_ + 0.5 * tl), b_ - 0.5 * tl)  # np.clip's values
        tc, mc = ev(open_, c)
        to_lo = tc == truth0[k]  # c has the original truth: it becomes the new lo
        scale = np.where(to_lo, 1 - mc / fa, 1 - mc / fb)
        new_lo, new_hi = np.where(to_lo, c, a_), np.where(to_lo, b_, c)
        slow[k] = np.where(new_hi - new_lo > 0.5 * width, slow[k] + 1, 0)
        survivor = np.where(to_lo, np.int8(1), np.int8(-1))
        again = kept[k] == survivor
        # Anderson–Björck: the end that survives again has its value scaled by
        # 1 - f(c)/f(replaced end) (0.5 when that is not positive), which pulls the next
        # secant across the root instead of creeping from one side as regula falsi does
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, 0.5)
        new_ma = np.where(to_lo, mc, np.where(again, scale * fa, fa))
        mb[k] = np.where(to_lo, np.where(again, scale * fb, fb), mc)
        ma[k], lo[k], hi[k] = new_ma, new_lo, new_hi
        kept[k] = survivor
    return lo, hi


def _finish_one(ev: Evaluator, i: int, lo: np.ndarray, hi: np.ndarray, ma: np.ndarray,
                mb: np.ndarray, truth0: np.ndarray, tol: np.ndarray, kept: np.ndarray,
                slow: np.ndarray, rounds: int) -> None:
    """The rounds of :func:`illinois` for bracket ``i`` alone, on Python floats (at most
    ``rounds`` of them); writes its final ends into ``lo`` and ``hi``.

    Each line is the array round's for one element. Where numpy divides by zero (inf or
    NaN, replaced by the round), Python raises, so those quotients are NaN here;
    ``np.maximum``/``np.minimum`` return their second argument on ties, and so do the
    conditionals that stand for them (the same bits, ``-0.0`` included).
    """
    a, b, fa, fb = float(lo[i]), float(hi[i]), float(ma[i]), float(mb[i])
    tl, t0 = float(tol[i]), bool(truth0[i])
    survived, sl = int(kept[i]), int(slow[i])
    pos = np.array([i])
    for _ in range(rounds):
        if not b - a > tl:
            break
        width = b - a
        den = fb - fa
        c = b - fb * width / den if den != 0.0 else math.nan
        if not (math.isfinite(c) and sl < 3):
            c = 0.5 * (a + b)
        low, high = a + 0.5 * tl, b - 0.5 * tl
        c = c if c > low else low
        c = c if c < high else high
        tc, mc_ = ev(pos, np.array([c]))
        to_lo, mc = bool(tc[0]) == t0, float(mc_[0])
        end = fa if to_lo else fb
        scale = 1 - mc / end if end != 0.0 else math.nan
        new_lo, new_hi = (c, b) if to_lo else (a, c)
        sl = sl + 1 if new_hi - new_lo > 0.5 * width else 0
        survivor = 1 if to_lo else -1
        again = survived == survivor
        if not (math.isfinite(scale) and scale > 0):
            scale = 0.5
        if to_lo:
            fa, fb = mc, (scale * fb if again else fb)
        else:
            fa, fb = (scale * fa if again else fa), mc
        a, b, survived = new_lo, new_hi, survivor
    lo[i], hi[i] = a, b

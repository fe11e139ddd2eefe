"""Bracket narrowing for crossing searches: Illinois (regula falsi, Anderson–Björck).

:func:`illinois` narrows many brackets at once, one array operation per step of the
method for all of them. A single run has one bracket, and there numpy's cost is per call
(about 1 µs, 3 µs for ``np.where``), not per element: the fifty-odd array operations of a
round cost far more than the trial points themselves. So once only a few brackets are open
(a single run's one, the handful an ensemble's instances cross in one step), they are
finished by :func:`_finish_few` on Python floats, the same operations in the same order on
the same IEEE doubles: the same bits as the array rounds would give
(``tests/test_illinois.py`` compares the two on random brackets), so a single run still
equals its ensemble member.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hybridteam.arrays import some, where_true
from hybridteam.floatpaths import FLOAT_PATHS

MAX_ITER = 200
#: Up to this many open brackets, :func:`illinois` finishes them on Python floats
#: (:func:`_finish_few`): a round of array operations costs about fifty dispatches
#: whatever the number of brackets, a bracket's round on floats a few microseconds.
FEW = 16

Evaluator = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``ev(positions, tau) -> (truth, margin)`` of one atom for some of a search's candidates."""
OneEvaluator = Callable[[float], tuple[bool, float]]
"""``one(tau) -> (truth, margin)``: an :data:`Evaluator` of a search with one candidate,
on Python floats, giving the bits ``ev`` gives (see ``segment.Segment.dense_one``)."""


def illinois(ev: Evaluator, lo: np.ndarray, hi: np.ndarray, truth0: np.ndarray,
             tol: np.ndarray, m_lo: np.ndarray | None = None, m_hi: np.ndarray | None = None,
             *, scalar: bool = True, one: OneEvaluator | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Narrow ``[lo, hi]`` (original truth at lo, flipped at hi) to ``tol``; return it
    (``lo`` and ``hi`` are updated in place).

    Regula falsi with the Anderson–Björck correction. Trial points are kept at least half
    a tolerance inside the bracket: when the crossing sits at an end (a strict comparison
    starting exactly on its boundary, or a margin of 1e-12 at one end) the next trial
    collapses the bracket at once instead of crawling. A bisection replaces the secant
    whenever three rounds failed to halve the bracket, which bounds the worst case.
    ``scalar=False`` keeps the array rounds to the end (for the tests that compare).
    ``one``, for a search with one bracket and no margins known, narrows it on floats
    throughout (:func:`illinois_one`: the same bits).
    """
    size = lo.size
    if one is not None and size == 1 and m_lo is None and scalar:
        lo[0], hi[0] = illinois_one(one, float(lo[0]), float(hi[0]), bool(truth0[0]),
                                    float(tol[0]))
        return lo, hi
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
        if open_.size <= FEW and scalar and FLOAT_PATHS.on:
            _finish_few(ev, open_, lo, hi, ma, mb, truth0, tol, kept, slow, MAX_ITER - done)
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


def _finish_few(ev: Evaluator, brackets: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                ma: np.ndarray, mb: np.ndarray, truth0: np.ndarray, tol: np.ndarray,
                kept: np.ndarray, slow: np.ndarray, rounds: int) -> None:
    """The rounds of :func:`illinois` for the open ``brackets`` (a few of them), each on
    Python floats, at most ``rounds`` of them; writes their final ends into ``lo`` and
    ``hi``. The trial points of one round are evaluated in one call, as the array round
    evaluates them; :func:`_trial` and :func:`_update` are the array round's lines for one
    element (the same bits, ``-0.0`` included). A bracket that closes leaves the next
    rounds, as it leaves the array rounds' open brackets.
    """
    rows = brackets.tolist()
    a_s, b_s = lo[brackets].tolist(), hi[brackets].tolist()
    fa_s, fb_s = ma[brackets].tolist(), mb[brackets].tolist()
    tls, t0s = tol[brackets].tolist(), truth0[brackets].tolist()
    survived_s, sl_s = kept[brackets].tolist(), slow[brackets].tolist()
    going = list(range(len(rows)))
    for _ in range(rounds):
        going = [j for j in going if b_s[j] - a_s[j] > tls[j]]
        if not going:
            break
        cs = [_trial(a_s[j], b_s[j], fa_s[j], fb_s[j], tls[j], sl_s[j]) for j in going]
        tc, mc_ = ev(np.array([rows[j] for j in going]), np.array(cs))
        for j, c, tcj, mc in zip(going, cs, tc.tolist(), mc_.tolist(), strict=True):
            a_s[j], b_s[j], fa_s[j], fb_s[j], survived_s[j], sl_s[j] = _update(
                a_s[j], b_s[j], fa_s[j], fb_s[j], c, tcj == t0s[j], mc, survived_s[j],
                sl_s[j])
    lo[brackets], hi[brackets] = a_s, b_s


def _trial(a: float, b: float, fa: float, fb: float, tol: float, slow: int) -> float:
    """A round's trial point for one bracket on floats: the array round's secant, the
    bisection after three slow rounds or where the secant is not a number, kept half a
    tolerance inside (``np.maximum``/``np.minimum`` return their second argument on ties,
    and so do these conditionals)."""
    den = fb - fa
    c = b - fb * (b - a) / den if den != 0.0 else math.nan
    if not (math.isfinite(c) and slow < 3):
        c = 0.5 * (a + b)
    low, high = a + 0.5 * tol, b - 0.5 * tol
    c = c if c > low else low
    return c if c < high else high


def _update(a: float, b: float, fa: float, fb: float, c: float, to_lo: bool, mc: float,
            survived: int, slow: int) -> tuple[float, float, float, float, int, int]:
    """One bracket after its trial point ``c`` (margin ``mc``; ``to_lo``: it has the
    original truth): its ends, their values (Anderson–Björck's scaling of the end that
    survives again), which end survived and how many rounds in a row failed to halve it.
    Where numpy divides by zero (inf or NaN, replaced by the round), Python raises, so
    that quotient is NaN here."""
    width = b - a
    end = fa if to_lo else fb
    scale = 1 - mc / end if end != 0.0 else math.nan
    new_lo, new_hi = (c, b) if to_lo else (a, c)
    slow = slow + 1 if new_hi - new_lo > 0.5 * width else 0
    survivor = 1 if to_lo else -1
    again = survived == survivor
    if not (math.isfinite(scale) and scale > 0):
        scale = 0.5
    if to_lo:
        fa, fb = mc, (scale * fb if again else fb)
    else:
        fa, fb = (scale * fa if again else fa), mc
    return new_lo, new_hi, fa, fb, survivor, slow


def illinois_one(one: OneEvaluator, lo: float, hi: float, truth0: bool, tol: float
                 ) -> tuple[float, float]:
    """:func:`illinois` for one bracket, on Python floats throughout (a single run's
    search: the array set-up of :func:`illinois` costs more than its rounds). The same
    rounds on the same doubles, so the same bits (``tests/test_illinois.py``)."""
    fa, fb = one(lo)[1], one(hi)[1]
    survived = slow = 0
    for _ in range(MAX_ITER):
        if not hi - lo > tol:
            break
        c = _trial(lo, hi, fa, fb, tol, slow)
        tc, mc = one(c)
        lo, hi, fa, fb, survived, slow = _update(lo, hi, fa, fb, c, tc == truth0, mc,
                                                 survived, slow)
    return lo, hi

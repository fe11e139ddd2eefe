"""Bracket narrowing for crossing searches: Illinois (regula falsi, Anderson–Björck).

:func:`illinois` narrows many brackets at once, one array operation per step of the
method for all of them. A single run has one bracket, and there numpy's cost is per call
(about 1 µs, 3 µs for ``np.where``), not per element: the fifty-odd array operations of a
round cost far more than the trial points themselves. So once only a few brackets are open
(a single run's one, the handful an ensemble's instances cross in one step), they are
finished by :func:`_finish_few` on Python floats. A round is written once
(:func:`_trial`, :func:`_update`, over an operations namespace ``ops``: numpy itself for
the array rounds), and its float form is generated from that source
(:func:`~hybridteam.floatpaths.float_form`): the same operations in the same order on the
same IEEE doubles, so the same bits as the array rounds would give
(``tests/engine/test_illinois.py`` compares the two on random brackets), and a single run still
equals its ensemble member. A change to the method is made in one place.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from hybridteam.arrays import some, where_true
from hybridteam.floatpaths import FLOAT_PATHS, Ops, float_form

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


def illinois(
    ev: Evaluator,
    lo: np.ndarray,
    hi: np.ndarray,
    truth0: np.ndarray,
    tol: np.ndarray,
    m_lo: np.ndarray | None = None,
    m_hi: np.ndarray | None = None,
    *,
    scalar: bool = True,
    one: OneEvaluator | None = None,
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
        lo[0], hi[0] = illinois_one(one, float(lo[0]), float(hi[0]), bool(truth0[0]), float(tol[0]))
        return lo, hi
    everyone = np.arange(size)
    if m_lo is None or some(np.isnan(m_lo)):
        need = everyone if m_lo is None else where_true(np.isnan(m_lo))
        m_lo = np.empty(size) if m_lo is None else m_lo
        m_hi = np.empty(size) if m_hi is None else m_hi
        # both ends in one evaluation (rows are independent: the same values as two)
        ends = ev(np.concatenate([need, need]), np.concatenate([lo[need], hi[need]]))[1]
        m_lo[need], m_hi[need] = ends[: need.size], ends[need.size :]
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
        a_, b_, fa, fb = lo[k], hi[k], ma[k], mb[k]
        c = _trial(np, a_, b_, fa, fb, tol[k], slow[k])
        tc, mc = ev(open_, c)
        lo[k], hi[k], ma[k], mb[k], kept[k], slow[k] = _update(
            np, a_, b_, fa, fb, c, tc == truth0[k], mc, kept[k], slow[k]
        )
    return lo, hi


def _finish_few(
    ev: Evaluator,
    brackets: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    ma: np.ndarray,
    mb: np.ndarray,
    truth0: np.ndarray,
    tol: np.ndarray,
    kept: np.ndarray,
    slow: np.ndarray,
    rounds: int,
) -> None:
    """The rounds of :func:`illinois` for the open ``brackets`` (a few of them), each on
    Python floats, at most ``rounds`` of them; writes their final ends into ``lo`` and
    ``hi``. The trial points of one round are evaluated in one call, as the array round
    evaluates them; each bracket's round is the float form of the array round's
    :func:`_trial` and :func:`_update` (the same bits, ``-0.0`` included). A bracket that
    closes leaves the next rounds, as it leaves the array rounds' open brackets.
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
        cs = [_trial_on_floats(a_s[j], b_s[j], fa_s[j], fb_s[j], tls[j], sl_s[j]) for j in going]
        tc, mc_ = ev(np.array([rows[j] for j in going]), np.array(cs))
        for j, c, tcj, mc in zip(going, cs, tc.tolist(), mc_.tolist(), strict=True):
            a_s[j], b_s[j], fa_s[j], fb_s[j], survived_s[j], sl_s[j] = _update_on_floats(
                a_s[j], b_s[j], fa_s[j], fb_s[j], c, tcj == t0s[j], mc, survived_s[j], sl_s[j]
            )
    lo[brackets], hi[brackets] = a_s, b_s


def _trial(ops: Ops, a: Any, b: Any, fa: Any, fb: Any, tol: Any, slow: Any) -> Any:
    """A round's trial points: the secant (the bisection after three slow rounds or where
    the secant is not a number), kept half a tolerance inside the bracket. (The run
    ignores floating-point errors: a secant through equal margins is NaN.)"""
    c = b - ops.true_divide(fb * (b - a), fb - fa)
    c = ops.where(ops.isfinite(c) & (slow < 3), c, 0.5 * (a + b))
    return ops.minimum(ops.maximum(c, a + 0.5 * tol), b - 0.5 * tol)


def _update(
    ops: Ops,
    a: Any,
    b: Any,
    fa: Any,
    fb: Any,
    c: Any,
    to_lo: Any,
    mc: Any,
    survived: Any,
    slow: Any,
) -> tuple[Any, Any, Any, Any, Any, Any]:
    """The brackets after their trial points ``c`` (margins ``mc``; ``to_lo``: ``c`` has
    the original truth and becomes the new lo): their ends, the ends' values, which end
    survived (+1 hi, -1 lo) and how many rounds in a row failed to halve each bracket.

    Anderson–Björck: the end that survives again has its value scaled by
    1 - f(c)/f(replaced end) (0.5 when that is not positive), which pulls the next secant
    across the root instead of creeping from one side as regula falsi does."""
    width = b - a
    scale = ops.where(to_lo, 1 - ops.true_divide(mc, fa), 1 - ops.true_divide(mc, fb))
    new_lo, new_hi = ops.where(to_lo, c, a), ops.where(to_lo, b, c)
    slow = ops.where(new_hi - new_lo > 0.5 * width, slow + 1, 0)
    survivor = ops.where(to_lo, 1, -1)
    again = survived == survivor
    scale = ops.where(ops.isfinite(scale) & (scale > 0), scale, 0.5)
    new_fa = ops.where(to_lo, mc, ops.where(again, scale * fa, fa))
    new_fb = ops.where(to_lo, ops.where(again, scale * fb, fb), mc)
    return new_lo, new_hi, new_fa, new_fb, survivor, slow


#: :func:`_trial` and :func:`_update` for one bracket on Python floats, generated from their
#: source (:func:`~hybridteam.floatpaths.float_form`: numpy's operations written out as
#: expressions, without a call each, which the array set-up of a round would cost more than)
_trial_on_floats = float_form(_trial)
_update_on_floats = float_form(_update)


def illinois_one(
    one: OneEvaluator, lo: float, hi: float, truth0: bool, tol: float
) -> tuple[float, float]:
    """:func:`illinois` for one bracket, on Python floats throughout (a single run's
    search: the array set-up of :func:`illinois` costs more than its rounds). The float
    form of the same rounds, so the same bits (``tests/engine/test_illinois.py``)."""
    fa, fb = one(lo)[1], one(hi)[1]
    survived = slow = 0
    for _ in range(MAX_ITER):
        if not hi - lo > tol:
            break
        c = _trial_on_floats(lo, hi, fa, fb, tol, slow)
        tc, mc = one(c)
        lo, hi, fa, fb, survived, slow = _update_on_floats(
            lo, hi, fa, fb, c, tc == truth0, mc, survived, slow
        )
    return lo, hi

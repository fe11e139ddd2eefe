"""Range checks on values a model computes at run time: delays, rates, link settings.

Expressions of parameters are checked where they are evaluated, per instance, because an
ensemble or a study gives each instance its own parameters: ``after: 2*d`` is a fine delay
until a study sets ``d = -1``. A value out of range is a mistake in the model (or in the
values it was run with), not a numerical accident, so it stops the run with a
:class:`~hybridteam.errors.ModelError` carrying the document path of the expression —
the command line turns it into ``file:line:column`` — and naming the instance, rather
than letting a NaN delay stall the event queue or a negative latency deliver messages
before they were sent.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import spread
from hybridteam.errors import DocPath, ModelError

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CTransition, Ctx


def require(
    values: np.ndarray,
    where: DocPath,
    what: str,
    source: str,
    *,
    low: float = -np.inf,
    high: float = np.inf,
    open_low: bool = False,
    instances: np.ndarray | None = None,
) -> np.ndarray:
    """``values`` if every one is a finite number in ``[low, high]`` (``(low, high]`` with
    ``open_low``); else a :class:`ModelError` at ``where`` naming the first bad instance.
    ``instances`` are the instance numbers of the values (default ``0..m-1``)."""
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > low if open_low else v >= low) & (v <= high)
    if ok.all():
        return v
    k = int(np.flatnonzero(~np.broadcast_to(ok, v.shape).ravel())[0])
    bad = float(v.ravel()[k])
    i = k if instances is None else int(np.asarray(instances).ravel()[k])
    bound = {
        (True, True): "any number",
        (True, False): f"a number <= {high:g}",
        (False, True): f"a number {'>' if open_low else '>='} {low:g}",
    }.get((low == -np.inf, high == np.inf), f"a number in [{low:g}, {high:g}]")
    text = f"'{source}' " if source and source != repr(bad) else ""
    raise ModelError(where, f"{what} {text}is {bad} in instance {i}; it must be {bound}")


def transition_delay(tr: CTransition, ctx: Ctx, instances: np.ndarray) -> np.ndarray:
    """The ``after:`` delay of ``tr`` for ``instances`` (evaluated in ``ctx``, one row
    each): a :class:`ModelError` unless each is a finite number >= 0. Entering the mode
    checks it per instance; validation checks a delay of parameters alone on the team's
    own values with this same check, so ``validate`` refuses what ``run`` refuses."""
    return require(
        spread(tr.after(ctx), instances.shape),  # type: ignore[misc]  # (called for after: only)
        (*tr.origin, "after"),
        "the delay",
        tr.after.source,  # type: ignore[union-attr]  # (ditto)
        low=0.0,
        instances=instances,
    )

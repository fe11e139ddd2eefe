"""Small array helpers for the engine's hot path.

``np.broadcast_to`` costs several microseconds of Python-level checks per call, which the
engine pays tens of thousands of times in a single run for values that already have the
shape wanted (an expression of the state) or are one number (an expression of
parameters). These helpers take the short way in those two cases and give the same values.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def spread(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` with ``shape``: itself when it has it, else broadcast (a read-only view)."""
    a = np.asarray(value)
    return a if a.shape == shape else np.broadcast_to(a, shape)


def floats(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """A new float array of ``shape`` holding ``value`` (broadcast)."""
    a = np.asarray(value, dtype=float)
    if a.shape == shape:
        return a.copy()
    return np.full(shape, a) if a.ndim == 0 else np.broadcast_to(a, shape).copy()

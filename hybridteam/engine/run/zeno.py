"""The Zeno check's memory: each agent's latest transition times, per instance.

A run whose agent takes more than ``zeno.max_transitions`` transitions within
``zeno.window`` seconds is stopped as Zeno (:mod:`.discrete` ends it and says why). That
needs the time of the transition that many before the latest, per agent and instance: a
ring of the last ``max_transitions`` times, which :class:`ZenoWindow` keeps and only its
own methods write.
"""

from __future__ import annotations

import numpy as np


class ZenoWindow:
    """Per agent, a ring ``(n, max_transitions)`` of its latest transition times in each
    instance (``-inf`` where fewer were taken) and where the next one is written."""

    __slots__ = ("ptr", "ring", "window")

    def __init__(self, n: int, agents: int, max_transitions: int, window: float) -> None:
        self.ring = [np.full((n, max_transitions), -np.inf) for _ in range(agents)]
        self.ptr = [np.zeros(n, np.intp) for _ in range(agents)]
        self.window = window

    def fired(self, agent: int, sub: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Note that ``agent`` took a transition in instances ``sub`` at times ``t``; the
        instances of ``sub`` where it is within the window of the one ``max_transitions``
        before it (Zeno)."""
        ring, ptr = self.ring[agent], self.ptr[agent]
        pos = ptr[sub]
        old = ring[sub, pos]
        ring[sub, pos] = t
        ptr[sub] = (pos + 1) % ring.shape[1]
        return sub[(t - old) <= self.window]

    def clear(self) -> None:
        """Forget every transition (a new batch of runs in the same arrays). Where the
        next time is written does not matter then: every slot holds ``-inf``."""
        for ring, ptr in zip(self.ring, self.ptr, strict=True):
            ring[:] = -np.inf
            ptr[:] = 0

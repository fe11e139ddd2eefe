"""Random draws that are a function of (seed, component, counters) — not of call order.

Every random component (a network link's loss and jitter, a sensor's noise) gets a 64-bit
key from ``numpy.random.SeedSequence(seed)`` spawned with the component's stable name, and
each draw is a SplitMix64 hash of that key and the draw's own counters (for a message: the
sender's message number, the receiver, which quantity). Why not one ``Generator`` per
component: an ensemble instance must draw exactly what the same model and seed draw in a
single run, whatever its neighbours do, and draws must be vectorized over instances. A
counter-based hash gives both — instance ``i``'s draws depend only on its own counters —
and it is the standard construction of counter-based generators (Salmon et al., 2011).
"""

from __future__ import annotations

import zlib

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 2.0 ** -53


def component_key(seed: int, component: str) -> np.uint64:
    """The key of a named component: ``SeedSequence(seed)`` spawned at a stable index."""
    index = zlib.crc32(component.encode("utf-8"))
    state = np.random.SeedSequence(entropy=seed, spawn_key=(index,)).generate_state(
        2, np.uint64)
    return np.uint64(state[0] ^ (state[1] << np.uint64(1)))


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer: a bijection on 64-bit words with strong avalanche."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def bits(key: np.uint64, *counters: np.ndarray | int) -> np.ndarray:
    """64 random bits per element for the given counters (broadcast together)."""
    with np.errstate(over="ignore"):
        z = np.asarray(key, dtype=np.uint64)
        for c in counters:
            c = np.asarray(c).astype(np.uint64)
            z = _mix(z + _GOLDEN * (c + np.uint64(1)))
    return z


def uniform(key: np.uint64, *counters: np.ndarray | int) -> np.ndarray:
    """Uniform draws in [0, 1) with 53 random bits, one per element of the counters."""
    return (bits(key, *counters) >> np.uint64(11)).astype(np.float64) * _TO_UNIT

"""Random draws that are a function of (seed, component, counters) — not of call order.

Every random component (a network link's loss and jitter, a sensor's noise) gets a 64-bit
key from ``numpy.random.SeedSequence(seed)`` spawned with the component's stable name, and
each draw is a SplitMix64 hash of that key and the draw's own counters (for a message: the
sender's message number, the receiver, which quantity). Why not one ``Generator`` per
component: an ensemble instance must draw exactly what the same model and seed draw in a
single run, whatever its neighbours do, and draws must be vectorized over instances. A
counter-based hash gives both — instance ``i``'s draws depend only on its own counters —
and it is the standard construction of counter-based generators (Salmon et al., 2011).

An ensemble may also give every instance its own seed (a parameter study runs each member
and repetition under a seed of its own, packed into ensembles of any size): keys are then
an ``(n,)`` array and each instance hashes with its own key, so instance ``i`` draws exactly
what a single run with seed ``seeds[i]`` draws.
"""

from __future__ import annotations

import numbers
import zlib
from collections.abc import Sequence

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 2.0**-53


def component_key(seed: int, component: str) -> np.uint64:
    """The key of a named component: ``SeedSequence(seed)`` spawned at a stable index."""
    index = zlib.crc32(component.encode("utf-8"))
    state = np.random.SeedSequence(entropy=seed, spawn_key=(index,)).generate_state(2, np.uint64)
    return np.uint64(state[0] ^ (state[1] << np.uint64(1)))


def seed_value(seed: int | Sequence[int] | np.ndarray, n: int) -> int | list[int]:
    """A simulation's seed as plain Python: one int, or a list of ``n`` ints (one per instance).

    Plain ints because the seed goes into the trace's JSON metadata; checked here so a wrong
    length fails before anything runs rather than deep inside the network.
    """
    if isinstance(seed, numbers.Integral):
        if seed < 0:
            raise ValueError(f"seed must be >= 0, got {seed}")
        return int(seed)
    values = np.asarray(seed)
    if values.ndim != 1 or values.size != n:
        raise ValueError(
            f"seed: expected one integer or {n} integers (one per instance), "
            f"got shape {values.shape}"
        )
    out = []
    for s in values.tolist():
        if not isinstance(s, numbers.Integral) or isinstance(s, bool) or s < 0:
            raise ValueError(f"seed: every per-instance seed must be an integer >= 0, got {s!r}")
        out.append(int(s))
    return out


def instance_keys(seed: int | Sequence[int], component: str, n: int) -> np.ndarray:
    """A component's key for each of ``n`` instances: ``(n,)`` uint64.

    With one seed every instance shares the key (as before per-instance seeds existed); with
    ``n`` seeds, instance ``i`` gets ``component_key(seeds[i], component)``.
    """
    value = seed_value(seed, n)
    if isinstance(value, int):
        return np.full(n, component_key(value, component), dtype=np.uint64)
    cache: dict[int, np.uint64] = {}  # repetitions of one seed: derive its key once
    for s in value:
        if s not in cache:
            cache[s] = component_key(s, component)
    return np.array([cache[s] for s in value], dtype=np.uint64)


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer: a bijection on 64-bit words with strong avalanche."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def bits(key: np.uint64 | np.ndarray, *counters: np.ndarray | int) -> np.ndarray:
    """64 random bits per element for the given counters (broadcast together).

    ``key`` may be one key or an array of keys, one per element (per-instance seeds): the
    hash is elementwise, so an element's bits depend only on its own key and counters.
    """
    with np.errstate(over="ignore"):
        z = np.asarray(key, dtype=np.uint64)
        for c in counters:
            c = np.asarray(c).astype(np.uint64)
            z = _mix(z + _GOLDEN * (c + np.uint64(1)))
    return z


def uniform(key: np.uint64 | np.ndarray, *counters: np.ndarray | int) -> np.ndarray:
    """Uniform draws in [0, 1) with 53 random bits, one per element of the counters."""
    return (bits(key, *counters) >> np.uint64(11)).astype(np.float64) * _TO_UNIT

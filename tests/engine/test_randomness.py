"""A single run's draws hashed on Python ints are the array version's, bit for bit.

A copy's loss and jitter are ``uniform(key, sender, receiver, seq, LOSS or JITTER)``; a
single run's send hashes them on ints (:func:`mix_one`, :func:`unit`), about twenty times
faster than numpy's dispatches on one element. A trace is a pure function of the model and
the seed, so the two must agree on every key and counter, including counters numpy's cast
to ``uint64`` wraps (negative ones, ``2**63`` and above).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from hybridteam.engine.run.randomness import component_key, mix_one, uniform, unit

KEYS = st.integers(0, 2**64 - 1)
COUNTERS = st.lists(st.integers(-(2**63), 2**63 - 1), min_size=1, max_size=5)


@given(KEYS, COUNTERS)
def test_draws_on_ints_are_the_arrays_draws(key, counters):
    z = key
    for c in counters:
        z = mix_one(z, c)
    want = uniform(np.uint64(key), *(np.int64(c) for c in counters))
    assert unit(z) == float(want)


@given(KEYS, st.integers(2**63, 2**64 - 1))
def test_counters_past_int64_wrap_as_numpy_casts_them(key, counter):
    assert unit(mix_one(key, counter)) == float(uniform(np.uint64(key), np.uint64(counter)))


def test_a_copys_draws_for_each_receiver_share_the_senders_step():
    """What ``Network._send_one`` does: the key and sender's step once, then the
    receiver, the sequence number and which draw."""
    key = int(component_key(7, "network"))
    by_sender = mix_one(key, 2)
    for r in range(4):
        for seq in (0, 1, 1000):
            for which in (0, 1):
                got = unit(mix_one(mix_one(mix_one(by_sender, r), seq), which))
                assert got == float(uniform(np.uint64(key), 2, r, np.array([seq]), which)[0])

"""The counter-based draws: a single element hashed on Python integers gives the bits the
array hash gives (a single run draws one element per message; an ensemble, arrays)."""

from __future__ import annotations

import numpy as np

from hybridteam.engine.run.randomness import bits, component_key, uniform

#: SplitMix64 seeded with 0: its first output is its finalizer of the golden gamma, the
#: published reference value (Steele, Lea and Flood, 2014; Vigna's splitmix64.c)
_SPLITMIX_FIRST = 0xE220A8397B1DCDAF


def test_one_counter_is_splitmix64_on_both_paths() -> None:
    # bits(key 0, counter 0) = mix(0 + golden * 1): SplitMix64's first output from seed 0
    one = bits(np.zeros(1, np.uint64), 0)
    many = bits(np.zeros(3, np.uint64), np.zeros(3, np.int64))
    assert one.dtype == np.uint64 and one.shape == (1,)
    assert int(one[0]) == _SPLITMIX_FIRST
    assert [int(b) for b in many] == [_SPLITMIX_FIRST] * 3
    # ... and the uniform draw is its top 53 bits over 2**53
    assert uniform(np.zeros(1, np.uint64), 0)[0] == (_SPLITMIX_FIRST >> 11) / 2.0**53


def test_single_element_draws_equal_the_array_hash() -> None:
    rng = np.random.default_rng(4)
    keys = [component_key(s, "link") for s in range(5)] + [np.uint64(2**64 - 1)]
    counters = [0, 1, 2, 7, 2**31, 2**62, -1, -5]  # negative ones wrap as astype does
    for key in keys:
        for _ in range(20):
            sender, receiver, which = (int(c) for c in rng.choice(counters, 3))
            seq = np.array([int(rng.choice(counters))], np.int64)
            one_key = np.array([key], np.uint64)
            # the same draw as element 1 of an ensemble's arrays (the array hash)
            arr_key, arr_seq = np.array([key, key ^ np.uint64(1)], np.uint64), np.r_[seq, 3]
            got_bits = bits(one_key, sender, receiver, seq, which)
            want_bits = bits(arr_key, sender, receiver, arr_seq, which)[:1]
            assert got_bits.tobytes() == want_bits.tobytes()
            got = uniform(one_key, sender, receiver, seq, which)
            want = uniform(arr_key, sender, receiver, arr_seq, which)[:1]
            assert got.dtype == np.float64 and got.shape == (1,)
            assert got.tobytes() == want.tobytes()
            assert 0.0 <= got[0] < 1.0

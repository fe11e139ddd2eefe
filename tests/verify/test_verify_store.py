"""The explorer's compact store: states come back as they went in, keys are found again
across table growth, edges keep their first choice, and verdicts do not depend on how
many states are evaluated at once."""

from __future__ import annotations

import random

import pytest

from hybridteam.verify import Options, verify
from hybridteam.verify.machine import Copy, State
from hybridteam.verify.properties import check
from hybridteam.verify.store import Edges, Keys, Store
from tests.verify.test_verify import roles_team


def test_keys_are_numbered_in_order_and_found_after_the_table_grows():
    rng = random.Random(5)
    keys = Keys()
    words = list(
        dict.fromkeys(
            bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40))) for _ in range(5000)
        )
    )
    for k, w in enumerate(words):
        assert keys.get(w) is None
        assert keys.add(w) == k
    assert keys.mask + 1 >= 2 * len(words)  # it grew from 1,024 slots
    assert all(keys.get(w) == k and keys[k] == w for k, w in enumerate(words))
    assert keys.get(b"not a key at all, longer than any") is None


def test_states_decode_to_what_was_stored():
    copy = Copy(0, 1, "control", "request", 0, (("priority", 2.0),))
    states = [
        State(
            ((b"\x01\x00", (1.0,)), (b"\x00\x01", ())),
            (copy, copy),
            (),
            ((1, 0, 0),),
            1,
            0,
            0,
            (1, 0),
        ),
        State(((b"\x01\x00", (1.0,)), (b"\x01\x01", ())), (), (), (), 2, 1, 0, (0, 0)),
    ]
    store = Store(agents=2)
    for s in states:
        key, k = store.find(s)
        assert k is None
        store.add(key)
    assert [store[k] for k in range(2)] == states and list(store) == states
    assert store.find(states[1])[1] == 1
    # agents' part numbers by state (the first state's copy and seen triple are parts 2, 3)
    assert store.agent_parts.tolist() == [0, 1, 0, 4]
    with pytest.raises(IndexError):
        store[2]


def test_many_parts_switch_the_keys_to_four_byte_numbers():
    store = Store(agents=1)
    for v in range(70_000):  # more distinct agent parts than two bytes can number
        key, k = store.find(State(((b"\x01", (float(v),)),), (), (), (), 0, 0, 0, (0,)))
        if k is None:
            store.add(key)
    assert store.keys[0][:1] == b"H" and store.keys[69_999][:1] == b"I"
    assert store[69_999].agents[0] == (b"\x01", (69_999.0,))


def test_edges_keep_the_first_choice_between_two_states():
    e = Edges()
    e.add(0, 2, ("deliver", 0))
    e.add(1, 0, ("timer", 0))
    e.add(0, 2, ("lose", 0))
    e.add(0, 1, ("scenario",))
    e.freeze(3)
    assert e.successors(0) == [2, 1] and e.successors(2) == []
    assert e.choice(0, 2) == ("deliver", 0) and e.choice(2, 0, "none") == "none"
    assert e.out_degree().tolist() == [3, 1, 0]


def test_verdicts_do_not_depend_on_the_evaluation_block(tmp_path):
    """Two robots, one loss (12,783 states): the same verdicts, violating states and
    others when formulas are evaluated a thousand states at a time."""
    extra = "  b_never_asks: always(not in_mode(b, Requesting))\n"
    team = roles_team(tmp_path, "ba", extra=extra, without_c=True)
    whole = verify(team, Options(losses=1), replay=False)
    props = [v.prop for v in whole.verdicts]
    blocks = check(props, whole.skeleton, whole.graph, block=1000)
    assert len(whole.graph.states) > 10_000
    got = [(v.prop.name, v.holds, v.state, v.others) for v in blocks]
    assert got == [(v.prop.name, v.holds, v.state, v.others) for v in whole.verdicts]
    asks = next(v for v in whole.verdicts if v.prop.name == "b_never_asks")
    assert asks.holds is False and max(asks.others) > 1000  # violations beyond one block

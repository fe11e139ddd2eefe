"""The live wire format (hybridteam/live/wire.py): what a datagram must be, and that
nothing else gets through the decoder but one WireError naming why."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.network import Message
from hybridteam.live.wire import KEYS, MAX_BYTES, Codec, WireError, declarations

TEAM = Path(__file__).parents[1] / "fixtures" / "live" / "handshake.yaml"
REQUESTER, GRANTER = 0, 1


@pytest.fixture(scope="module")
def cteam():
    return compile_team(ht.load(TEAM))


def request(codec: Codec, number: int = 0, /, **change) -> bytes:
    """A genuine 'request' of the requester with sequence number ``number``, then
    ``change`` written over its keys (``seq=`` among them: a key, not the number)."""
    data = json.loads(
        codec.encode(
            Message(REQUESTER, GRANTER, number, 1.0, "control", "request", {"need": 2.0}),
            -0.0,
            1.5e9,
        )
    )
    data.update(change)
    return json.dumps(data).encode()


def test_the_team_declares_its_messages(cteam):
    """Types, sockets and fields from the fixture's sends, and the acks' ``id``."""
    assert declarations(cteam) == {
        "ack": {"sockets": ["control", "data"], "fields": ["id"]},
        "done": {"sockets": ["control"], "fields": []},
        "grant": {"sockets": ["control"], "fields": ["amount"]},
        "request": {"sockets": ["control"], "fields": ["need"]},
    }


def test_a_datagram_round_trips(cteam):
    codec = Codec(cteam)
    msg = Message(GRANTER, -1, 7, 2.0, "control", "ack", {"id": 3.0}, -1, "ack")
    dg = codec.decode(codec.encode(msg, 0.0, 1234.5))
    assert (
        dg.sender,
        dg.to,
        dg.seq,
        dg.type,
        dg.socket,
        dg.fields,
        dg.msg_id,
        dg.note,
        dg.rank,
        dg.sent,
    ) == (GRANTER, -1, 7, "ack", "control", {"id": 3.0}, -1, "ack", 0.0, 1234.5)
    assert set(json.loads(codec.encode(msg, 0.0, 1.0))) == KEYS


def test_a_replayed_sequence_number_is_refused(cteam):
    codec = Codec(cteam)
    codec.decode(request(codec, 4))
    for seq in (4, 3, 0):
        with pytest.raises(WireError) as err:
            codec.decode(request(codec, seq))
        assert err.value.reason == "replayed"
    assert codec.decode(request(codec, 5)).seq == 5  # later numbers still pass


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"ht": 2}, "version"),  # the version before this one
        ({"ht": 4}, "version"),
        ({"ht": True}, "version"),  # a bool is not a version number
        ({"team": "another team"}, "foreign team"),
        ({"digest": "0" * 16}, "foreign team"),  # same name, other message declarations
        ({"from": "intruder"}, "forged"),
        ({"to": "nobody"}, "forged"),
        ({"to": "requester"}, "forged"),  # to its own sender
        ({"type": "launch"}, "forged"),  # a type the team does not declare
        ({"socket": "data"}, "forged"),  # 'request' is sent on control only
        ({"socket": ["control"]}, "forged"),
        ({"fields": {"need": "__import__('os')"}}, "forged"),  # a field that is not a number
        ({"fields": {"need": True}}, "forged"),
        ({"fields": {"need": 10**400}}, "forged"),  # beyond any float
        ({"fields": {"speed": 1.0}}, "forged"),  # a field 'request' does not declare
        ({"seq": -1}, "forged"),
        ({"seq": 1.0}, "forged"),
        ({"id": -2}, "forged"),
        ({"note": "reboot"}, "forged"),
        ({"note": {}}, "forged"),
        ({"sent": "yesterday"}, "forged"),
        ({"extra": 1}, "malformed"),
    ],
)
def test_a_datagram_not_of_this_team_is_refused_with_its_reason(cteam, change, reason):
    codec = Codec(cteam)
    with pytest.raises(WireError) as err:
        codec.decode(request(codec, **change))
    assert err.value.reason == reason
    assert codec.last_seq == {}  # a refused datagram leaves the sequence numbers alone


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", "malformed"),
        (b"\xff\xfe", "malformed"),
        (b"[1, 2]", "malformed"),
        (b'{"ht": 3}', "malformed"),
        (b'{"ht": NaN}', "malformed"),
        (b"[" * 5000 + b"]" * 5000, "oversized"),
        (b"[" * 4000 + b"]" * 4000, "malformed"),  # deeper than the parser recurses
        (b" " * (MAX_BYTES + 1), "oversized"),
    ],
)
def test_bytes_that_are_no_datagram_are_refused(cteam, data, reason):
    with pytest.raises(WireError) as err:
        Codec(cteam).decode(data)
    assert err.value.reason == reason


def test_missing_and_non_finite_values_are_refused(cteam):
    codec = Codec(cteam)
    genuine = json.loads(request(codec))
    for key in sorted(KEYS - {"ht"}):
        data = {k: v for k, v in genuine.items() if k != key}
        with pytest.raises(WireError, match="missing or not expected"):
            codec.decode(json.dumps(data).encode())
    for value in (float("inf"), float("nan")):  # JSON has neither: json.dumps writes them
        with pytest.raises(WireError) as err:
            codec.decode(request(codec, sent=value))
        assert err.value.reason == "malformed"
    assert codec.decode(request(codec, sent=1e308)).sent == 1e308


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_random_bytes_only_ever_raise_wire_errors(cteam, data):
    with contextlib.suppress(WireError):  # anything else fails the test
        Codec(cteam).decode(data)


@settings(max_examples=400, deadline=None)
@given(st.sampled_from(sorted(KEYS)), json_values)
def test_any_value_in_any_key_is_accepted_or_refused_never_a_crash(cteam, key, value):
    """A genuine datagram with one key set to any JSON value: decoded (then every value
    has its declared kind) or one WireError."""
    codec = Codec(cteam)
    try:
        dg = codec.decode(request(codec, **{key: value}))
    except WireError:
        return
    assert isinstance(dg.seq, int) and dg.seq >= 0
    assert all(isinstance(v, float) for v in dg.fields.values())
    assert dg.type in codec.messages and dg.note in ("", "retransmission", "ack")

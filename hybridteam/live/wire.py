"""The wire format of a live team: one datagram per message, JSON, versioned.

Every datagram names the wire version, the team (its name and a digest of its message
declarations), the sender, the sender's datagram number, the message type, the addressee,
the socket, the fields, the acknowledged layer's id and note, the same-instant rank and
the send time on the sender's wall clock (the table is in docs/live.md).

Datagrams come from a network anyone can write to, so :class:`Codec.decode` trusts
nothing: a datagram that is too large, not JSON, of another version or team, with a key
missing or extra, a sender or addressee not in the team, a message type or field the team
does not declare, a value of the wrong kind (a field that is not a finite number), or a
sequence number already seen from its sender raises one :class:`WireError` naming the
reason, which the receiver counts and drops. Nothing in a datagram is evaluated: it is
parsed by :func:`json.loads` into plain values and checked key by key.

Version 2 adds the world process's two kinds (docs/live.md, *The world process*): an
agent's ``@pose`` to the world process (its plant state and variables by name) and the
world process's ``@world`` to one agent (what it senses, events raised for it, an outcome
concluded), with ``@world`` as their other end; no team name can begin with ``@``.
Version 3 numbers the answer: a reading's ``id`` is the sequence number of the pose it
answers (-1: a reading no pose asked for), so that an agent's process can tell the world's
answer to this instant's pose from an older one (docs/live.md, *What a law reads*).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.reliable import ACK

#: The wire version this code speaks; a receiver refuses every other.
VERSION = 3
#: The largest datagram accepted (bytes): one message is a few hundred.
MAX_BYTES = 8192
KEYS = frozenset(
    {
        "ht",
        "team",
        "digest",
        "from",
        "seq",
        "type",
        "to",
        "socket",
        "fields",
        "id",
        "note",
        "rank",
        "sent",
    }
)
NOTES = frozenset({"", "retransmission", "ack"})
#: Why a datagram was dropped: the reasons :class:`WireError` carries, in this order.
REASONS = ("oversized", "malformed", "version", "foreign team", "forged", "replayed")
#: The world process's name on the wire, and its index in a :class:`Datagram`.
WORLD, WORLD_INDEX = "@world", -2
#: The world kinds: an agent's pose to the world process, the world's reading for an agent.
POSE, READING = "@pose", "@world"


class WireError(ValueError):
    """A datagram that is not one of this team's: ``reason`` is one of :data:`REASONS`."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True)
class Datagram:
    """A checked datagram: agents as the team's indices (``to`` -1: every other agent);
    a reading's ``msg_id`` is the number of the pose it answers (-1: none)."""

    sender: int
    to: int
    seq: int
    type: str
    socket: str
    fields: dict[str, float]
    msg_id: int
    note: str
    rank: float
    sent: float


def declarations(cteam: CTeam) -> dict[str, dict[str, list[str]]]:
    """Every message type the team's agents can send: its sockets and field names (the
    union over the sends and streams of that type), and the acknowledged layer's ``ack``."""
    found: dict[str, tuple[set[str], set[str]]] = {ACK: ({"control", "data"}, {"id"})}
    for ca in cteam.agents:
        for tr in ca.transitions:
            for act in tr.actions:
                if act.kind == "send":
                    sockets, fields = found.setdefault(act.name, (set(), set()))
                    sockets.add(act.socket)
                    fields.update(act.fields)
        for cs in ca.streams:
            sockets, fields = found.setdefault(cs.message, (set(), set()))
            sockets.add(cs.socket)
            fields.update(cs.fields)
    return {
        name: {"sockets": sorted(s), "fields": sorted(f)} for name, (s, f) in sorted(found.items())
    }


def wire_mismatch(cteam: CTeam, wire: CTeam) -> str | None:
    """Why a process running ``cteam`` cannot speak ``wire``'s identity, or None: it must
    have the same team name and agents (in order), and every message it can send must be
    declared by ``wire`` with the same sockets and fields (it may send fewer: a drifted
    protocol that no longer sends ``accept`` still speaks the team's wire)."""
    if cteam.team.name != wire.team.name:
        return f"the team is '{cteam.team.name}', the wire team '{wire.team.name}'"
    mine, theirs = [ca.name for ca in cteam.agents], [ca.name for ca in wire.agents]
    if mine != theirs:
        return f"the agents are {', '.join(mine)}, the wire team's {', '.join(theirs)}"
    known = declarations(wire)
    for name, decl in declarations(cteam).items():
        if name not in known:
            return f"message '{name}' is not one the wire team declares"
        if decl != known[name]:
            return (
                f"message '{name}' has sockets {', '.join(decl['sockets'])} and fields "
                f"{', '.join(decl['fields']) or '(none)'}; the wire team's has "
                f"{', '.join(known[name]['sockets'])} and "
                f"{', '.join(known[name]['fields']) or '(none)'}"
            )
    return None


class Codec:
    """Encodes this team's messages and decodes (checks) datagrams that claim to be."""

    def __init__(
        self, cteam: CTeam, senses: frozenset[str] = frozenset(), wire: CTeam | None = None
    ) -> None:
        """``senses``: the names the team's world components let a robot sense (what a
        reading may carry). ``wire``: a test aid, the team whose identity (name, agents,
        message declarations, digest) this codec speaks and accepts instead of
        ``cteam``'s, as a robot whose code drifted from its model does (check
        :func:`wire_mismatch` first)."""
        identity = cteam if wire is None else wire
        self.team = identity.team.name
        #: what each agent's pose may carry (plant state and variables), the events each
        #: may be raised, and the names a reading may carry
        self.pose_names = [
            frozenset(ca.state_index) | frozenset(ca.var_index) for ca in cteam.agents
        ]
        self.events = [frozenset(ca.triggered) for ca in cteam.agents]
        self.senses = senses
        self.agents = [ca.name for ca in cteam.agents]
        self.index = {name: a for a, name in enumerate(self.agents)}
        self.messages = declarations(identity)
        canonical = json.dumps(
            {"agents": self.agents, "messages": self.messages},
            sort_keys=True,
            separators=(",", ":"),
        )
        self.digest = hashlib.sha256(canonical.encode()).hexdigest()[:16]
        self._sockets = {k: frozenset(v["sockets"]) for k, v in self.messages.items()}
        self._fields = {k: frozenset(v["fields"]) for k, v in self.messages.items()}
        #: the last sequence number accepted from each sender (replays are refused)
        self.last_seq: dict[int | tuple[str, int], int] = {}

    # ------------------------------------------------------------------ sending
    def encode(self, msg: Message, rank: float, sent: float) -> bytes:
        """One datagram for ``msg`` (``msg.receiver`` -1: every other agent), sent at wall
        time ``sent``."""
        return json.dumps(
            {
                "ht": VERSION,
                "team": self.team,
                "digest": self.digest,
                "from": self.agents[msg.sender],
                "seq": msg.seq,
                "type": msg.type,
                "to": None if msg.receiver < 0 else self.agents[msg.receiver],
                "socket": msg.socket,
                "fields": msg.fields,
                "id": msg.msg_id,
                "note": msg.note,
                "rank": rank,
                "sent": sent,
            },
            separators=(",", ":"),
            allow_nan=False,
        ).encode()

    def encode_world(
        self,
        kind: str,
        sender: int,
        to: int,
        seq: int,
        fields: dict[str, float],
        sent: float,
        answers: int = -1,
    ) -> bytes:
        """One datagram of a world kind: ``POSE`` from agent ``sender`` (``to`` is
        WORLD_INDEX), or ``READING`` from the world process (``sender`` WORLD_INDEX) to
        agent ``to``, answering the pose numbered ``answers`` (-1: none; its ``id``)."""
        name = {WORLD_INDEX: WORLD, **dict(enumerate(self.agents))}
        return json.dumps(
            {
                "ht": VERSION,
                "team": self.team,
                "digest": self.digest,
                "from": name[sender],
                "seq": seq,
                "type": kind,
                "to": name[to],
                "socket": "data",
                "fields": fields,
                "id": answers,
                "note": "",
                "rank": 0.0,
                "sent": sent,
            },
            separators=(",", ":"),
            allow_nan=False,
        ).encode()

    # ------------------------------------------------------------------ receiving
    def decode(self, data: bytes) -> Datagram:
        """The checked datagram, or :class:`WireError`; a datagram accepted advances its
        sender's sequence number (a later copy of it is a replay)."""
        if len(data) > MAX_BYTES:
            raise WireError("oversized", f"{len(data)} bytes (at most {MAX_BYTES})")
        try:
            obj = json.loads(data.decode("utf-8"), parse_constant=_no_constant)
        except (ValueError, RecursionError) as exc:  # (UnicodeDecodeError is a ValueError)
            raise WireError("malformed", f"not a JSON datagram ({type(exc).__name__})") from None
        if not isinstance(obj, dict):
            raise WireError("malformed", "not a JSON object")
        if _integer(obj.get("ht")) is None or obj.get("ht") != VERSION:
            raise WireError("version", f"wire version {_show(obj.get('ht'))}, this is {VERSION}")
        if obj.keys() != KEYS:
            raise WireError(
                "malformed",
                "keys "
                + ", ".join(sorted(str(k) for k in obj.keys() ^ KEYS)[:4])
                + " missing or not expected",
            )
        if obj["team"] != self.team or obj["digest"] != self.digest:
            raise WireError("foreign team", f"team {_show(obj['team'])} {_show(obj['digest'])}")
        type_ = obj["type"]
        if type_ in (POSE, READING):
            return self._decode_world(obj, type_)
        sender = self._agent(obj["from"], "sender")
        to = -1 if obj["to"] is None else self._agent(obj["to"], "addressee")
        if to == sender:
            raise WireError("forged", "a message to its own sender")
        seq = _integer(obj["seq"])
        if seq is None or seq < 0:
            raise WireError("forged", f"sequence number {_show(obj['seq'])}")
        if not isinstance(type_, str) or type_ not in self.messages:
            raise WireError("forged", f"message type {_show(type_)} is not the team's")
        if not isinstance(obj["socket"], str) or obj["socket"] not in self._sockets[type_]:
            raise WireError("forged", f"socket {_show(obj['socket'])} for {type_}")
        fields = obj["fields"]
        if not isinstance(fields, dict) or not fields.keys() <= self._fields[type_]:
            raise WireError("forged", f"fields of {type_} that the team does not declare")
        values = {k: _number(v, f"field {k}") for k, v in fields.items()}
        msg_id = _integer(obj["id"])
        if msg_id is None or msg_id < -1:
            raise WireError("forged", f"message id {_show(obj['id'])}")
        if not isinstance(obj["note"], str) or obj["note"] not in NOTES:
            raise WireError("forged", f"note {_show(obj['note'])}")
        rank, sent = _number(obj["rank"], "rank"), _number(obj["sent"], "send time")
        if seq <= self.last_seq.get(sender, -1):
            raise WireError(
                "replayed", f"sequence number {seq} of '{self.agents[sender]}' already seen"
            )
        self.last_seq[sender] = seq
        return Datagram(
            sender, to, seq, type_, obj["socket"], values, msg_id, obj["note"], rank, sent
        )

    def _decode_world(self, obj: dict, kind: str) -> Datagram:
        """A pose (an agent's, for the world process) or a reading (the world process's,
        for one agent), checked field by field against what the team has."""
        if kind == POSE:
            sender, to = self._agent(obj["from"], "sender"), obj["to"]
            if to != WORLD:
                raise WireError("forged", f"a pose to {_show(to)}, not {WORLD}")
        else:
            sender, to = obj["from"], self._agent(obj["to"], "addressee")
            if sender != WORLD:
                raise WireError("forged", f"a reading from {_show(sender)}, not {WORLD}")
            sender = WORLD_INDEX
        seq = _integer(obj["seq"])
        if seq is None or seq < 0:
            raise WireError("forged", f"sequence number {_show(obj['seq'])}")
        answers = _integer(obj["id"])
        if (
            obj["socket"] != "data"
            or obj["note"] != ""
            or answers is None
            or answers < -1
            or (kind == POSE and answers != -1)
        ):
            raise WireError("forged", f"socket, id or note of a {kind}")
        fields = obj["fields"]
        if not isinstance(fields, dict):
            raise WireError("forged", f"fields of a {kind} that are not an object")
        agent = sender if kind == POSE else to
        for key in fields:
            if not self._world_field(kind, agent, key):
                raise WireError(
                    "forged", f"field {_show(key)} of a {kind} for '{self.agents[agent]}'"
                )
        if kind == READING:
            _check_vectors(fields)
        values = {k: _number(v, f"field {k}") for k, v in fields.items()}
        rank, sent = _number(obj["rank"], "rank"), _number(obj["sent"], "send time")
        key = (kind, sender)  # (its own numbering: a process counts its poses apart)
        if seq <= self.last_seq.get(key, -1):
            raise WireError("replayed", f"{kind} {seq} already seen")
        self.last_seq[key] = seq
        return Datagram(
            sender,
            WORLD_INDEX if kind == POSE else to,
            seq,
            kind,
            "data",
            values,
            answers,
            "",
            rank,
            sent,
        )

    def _world_field(self, kind: str, agent: int, key: object) -> bool:
        """Whether ``key`` may be a field of a ``kind`` datagram about ``agent``."""
        if not isinstance(key, str):
            return False
        if kind == POSE:
            return key in self.pose_names[agent]
        head, _, tail = key.partition(".")
        if head == "event":
            return tail in self.events[agent]
        if head == "outcome":
            return tail.isidentifier()
        return head in self.senses and (tail == "" or (tail.isascii() and tail.isdigit()))

    def _agent(self, name: object, what: str) -> int:
        if not isinstance(name, str) or name not in self.index:
            raise WireError("forged", f"{what} {_show(name)} is not an agent of the team")
        return self.index[name]


def _check_vectors(fields: dict) -> None:
    """A reading's sensed names are each one number (``name``) or a whole vector
    (``name.0`` ... ``name.k``, no index missing), else :class:`WireError`."""
    indices: dict[str, list[int]] = {}
    for key in fields:
        head, dot, tail = key.partition(".")
        if head not in ("event", "outcome"):
            indices.setdefault(head, []).append(int(tail) if dot else -1)
    for name, got in indices.items():
        if sorted(got) != ([-1] if -1 in got else list(range(len(got)))):
            raise WireError(
                "forged", f"reading of {_show(name)} is not one number or a whole vector"
            )


def _no_constant(name: str) -> float:
    """``json.loads``'s hook for ``NaN`` and ``Infinity``: refused (not numbers here)."""
    raise ValueError(f"{name} is not allowed")


def _integer(value: object) -> int | None:
    """``value`` if it is an int (not a bool), else None."""
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _number(value: object, what: str) -> float:
    """A finite number (int or float, not a bool) as a float, else :class:`WireError`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WireError("forged", f"{what} is not a number")
    try:
        out = float(value)
    except OverflowError:  # an integer beyond any float
        raise WireError("forged", f"{what} is out of range") from None
    if not math.isfinite(out):
        raise WireError("forged", f"{what} is not finite")
    return out


def _show(value: object) -> str:
    """A short, printable picture of a value from a datagram (for log lines)."""
    text = ascii(value)
    return text[:40] + ("..." if len(text) > 40 else "")

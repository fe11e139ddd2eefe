"""Acknowledged control messages: sequence ids, acks, retransmission, duplicate suppression.

The medium (:mod:`hybridteam.engine.run.network`) only offers datagrams that may be lost. A protocol
that declares ``ack: {timeout, retries}`` for a message type gets, from this layer, what the
architecture paper's control messages had: each message carries an id unique per sender;
every receiver that gets a copy answers with an ``ack`` datagram (lossy too); the sender
keeps the message in an outbox and resends it to every receiver that has not acknowledged
it after ``timeout``, at most ``retries`` times, after which the sending agent gets the
local event ``<type>_undeliverable``. A receiver acts on a message once: later copies (a
retransmission after a lost ack) are acknowledged again but withheld from its modes, and
recorded with reason ``duplicate``.

Timers are ordinary events (kind ``TIMER``, after local events at the same instant), so a
run stays a pure function of model and seed, and the bookkeeping is per instance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.engine.run.events import LOCAL, TIMER

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.network import Message

ACK = "ack"


@dataclass
class Pending:
    type: str
    socket: str
    fields: dict[str, np.ndarray]  # one value per instance (length-1 arrays)
    waiting: set[int]  # receivers that have not acknowledged yet
    retries_left: int
    timeout: float
    rank: float


class Reliable:
    """Outboxes and duplicate filters of every agent in every instance."""

    def __init__(self, ens: Ensemble) -> None:
        self.ens = ens
        self.next_id = [np.zeros(ens.n, np.int64) for _ in ens.cteam.agents]
        self.outbox: dict[tuple[int, int, int], Pending] = {}  # (instance, sender, id)
        self.seen: set[tuple[int, int, int, int]] = set()  # (instance, receiver, sender, id)

    def send(
        self,
        idx: np.ndarray,
        sender: int,
        to: int | np.ndarray | None,
        socket: str,
        type_: str,
        fields: dict[str, np.ndarray],
        timeout: np.ndarray,
        retries: np.ndarray,
        rank: np.ndarray | None,
    ) -> None:
        """Send an acknowledged message from ``sender`` in instances ``idx``."""
        ens = self.ens
        ids = self.next_id[sender][idx].copy()
        self.next_id[sender][idx] += 1
        count = len(ens.cteam.agents)
        if to is None:
            targets = np.full(idx.size, -1)
        elif isinstance(to, np.ndarray):
            targets = to
        else:
            targets = np.full(idx.size, to)
        ranks = np.zeros(idx.size) if rank is None else rank
        for j, i in enumerate(idx.tolist()):
            tgt = int(targets[j])
            waiting = {tgt} if tgt >= 0 else {r for r in range(count) if r != sender}
            self.outbox[(i, sender, int(ids[j]))] = Pending(
                type_,
                socket,
                {f: v[j : j + 1].copy() for f, v in fields.items()},
                waiting,
                int(retries[j]),
                float(timeout[j]),
                float(ranks[j]),
            )
        ens.network.send(idx, ens.t[idx], sender, to, socket, type_, fields, msg_id=ids, rank=rank)
        ens.queue.push_each(
            idx, ens.t[idx] + timeout, TIMER, sender, "retransmit", [int(k) for k in ids]
        )

    def on_timer(self, inst: np.ndarray, sender: int, ids: list[int]) -> None:
        """An ack timeout: resend to whoever has not acknowledged, or give up."""
        ens = self.ens
        for i, k in zip(inst.tolist(), ids, strict=True):
            entry = self.outbox.get((i, sender, k))
            if entry is None:
                continue  # everyone acknowledged in time
            one = np.array([i])
            if entry.retries_left <= 0:
                del self.outbox[(i, sender, k)]
                ens.queue.push(one, ens.t[one], LOCAL, sender, f"{entry.type}_undeliverable")
                continue
            entry.retries_left -= 1
            for r in sorted(entry.waiting):
                ens.network.send(
                    one,
                    ens.t[one],
                    sender,
                    r,
                    entry.socket,
                    entry.type,
                    entry.fields,
                    msg_id=np.array([k]),
                    note="retransmission",
                    rank=np.array([entry.rank]),
                )
            ens.queue.push_each(one, ens.t[one] + entry.timeout, TIMER, sender, "retransmit", [k])

    def screen(self, i: int, msg: Message, t: float) -> str | None:
        """Called for each copy that reached its receiver: acknowledge, filter duplicates.

        Returns why the copy is withheld from the receiver's modes, or None to dispatch it.
        """
        ens = self.ens
        if msg.type == ACK:
            key = (i, msg.receiver, int(msg.fields["id"]))
            entry = self.outbox.get(key)
            if entry is not None:
                entry.waiting.discard(msg.sender)
                if not entry.waiting:
                    del self.outbox[key]
            return "ack"
        if msg.msg_id < 0:
            return None
        one = np.array([i])
        ens.network.send(
            one,
            np.array([t]),
            msg.receiver,
            msg.sender,
            msg.socket,
            ACK,
            {"id": np.array([float(msg.msg_id)])},
            note="ack",
        )
        key4 = (i, msg.receiver, msg.sender, msg.msg_id)
        if not ens.cteam.agents[msg.sender].policies[msg.type].dedupe:
            return None
        if key4 in self.seen:
            return "duplicate"
        self.seen.add(key4)
        return None

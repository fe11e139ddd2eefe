"""The broadcast medium: datagrams on named sockets over lossy, delayed links.

As on the architecture paper's IPX network, every message is a datagram broadcast to all
other agents (or addressed to one, which the others ignore) with no delivery guarantee:
each copy to a receiver is independently delayed (latency plus uniform jitter) and lost
with the link's probability, and a receiver that can process only so many messages per
second drops the excess (the paper's Scout took 8 of 20 data messages a second). Every
copy is recorded once its fate is known — delivered at its arrival time, or lost with the
reason (``loss``, ``rate limit``, ``run ended``).

Acknowledgements, retransmission and role assignment are protocol matters built on top of
this medium; nothing here retries anything. Link settings are expressions of team
parameters, evaluated per instance, so an ensemble can sweep latency or loss in one call.
Random draws are counter-based (:mod:`hybridteam.engine.run.randomness`): a copy's fate depends
only on the seed, the link and the sender's own message number, so an ensemble instance
draws exactly what the same single run draws. The seed may be one per instance (a key per
instance), so an ensemble can also pack runs that a study gives different seeds.

The network is the engine's seam for a real medium. Implementing another: a class with
:meth:`Outlet.send`, set as the run's ``Network.outlet`` (``sim.ensemble.network``) before
the run starts. Every send of the run is then handed to it, once, instead of being scheduled
on the simulated links; each copy that comes back from the medium is put on the event queue
with :meth:`Network.arrive` (by the clock seam, :mod:`~hybridteam.engine.run.clock`, which
is where a run waits), and from there it is received as a simulated copy is: rate limits,
the acknowledged layer's screen, the record. The live implementation is
:class:`hybridteam.live.clock.WireOutlet` (``hybridteam/live/clock.py``: each message
encoded as one datagram, :mod:`hybridteam.live.wire`, on a transport).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from hybridteam.arrays import filled, some
from hybridteam.engine.compile.settings import check_network, evaluate_setting
from hybridteam.engine.compile.values import require
from hybridteam.engine.run.events import MESSAGE
from hybridteam.engine.run.overrides import (
    LINK_SETTINGS,
    Link,
    key_problem,
    network_targets,
    override_values,
)
from hybridteam.engine.run.randomness import instance_keys, mix_one, uniform, unit
from hybridteam.errors import ModelError, ModelErrors
from hybridteam.model import Team

if TYPE_CHECKING:
    from hybridteam.engine.run.record import Recorder

LOSS, JITTER = 0, 1  # which draw of a copy


class Message:
    """One copy in flight, as carried by the event queue to its receiver.

    ``msg_id`` names an acknowledged message across its retransmissions (-1 for a plain
    datagram); ``note`` is recorded as the copy's reason (``retransmission``, ``ack``).
    """

    __slots__ = (
        "fields",
        "msg_id",
        "note",
        "receiver",
        "sender",
        "seq",
        "socket",
        "t_send",
        "type",
    )

    def __init__(
        self,
        sender: int,
        receiver: int,
        seq: int,
        t_send: float,
        socket: str,
        type_: str,
        fields: dict[str, float],
        msg_id: int = -1,
        note: str = "",
    ) -> None:
        self.sender, self.receiver, self.seq, self.t_send = sender, receiver, seq, t_send
        self.socket, self.type, self.fields = socket, type_, fields
        self.msg_id, self.note = msg_id, note


class Outlet(Protocol):
    """Where a live run's sends go instead of the simulated medium (:mod:`hybridteam.live`).

    Every send of the run (data and control messages, acks, retransmissions, stream
    copies) is handed over once, as the :class:`Message` it is, with ``receiver`` the
    addressee (-1: every other agent) and ``rank`` its same-instant order. The outlet puts
    it on the wire; what arrives comes back through :meth:`Network.arrive`."""

    def send(self, msg: Message, rank: float) -> None: ...


class Network:
    """The medium of one simulation: per-link arrays over the ensemble, and counters."""

    def __init__(
        self,
        team: Team,
        n: int,
        seed: int | Sequence[int],
        team_params: dict[str, np.ndarray],
        queue,
        recorder: Recorder,
        settings: Mapping[str, Any] | None = None,
    ) -> None:
        """``settings``: network override keys (``network.jitter``, ...) and their values,
        which replace what the team's ``network:`` block says (ValueError for a bad one)."""
        errors = check_network(team)
        if errors:
            raise ModelErrors(errors)
        self.n = n
        self.queue, self.rec = queue, recorder
        self.names = [a.name for a in team.agents]
        self.keys = instance_keys(seed, "network", n)  # (n,): one key per instance
        count = len(self.names)
        self.count = [np.zeros(n, np.int64) for _ in range(count)]
        net = team.network
        index = {name: k for k, name in enumerate(self.names)}
        given = _given(team, settings or {}, n)
        # the default link once, and the links the team names: not one per pair of agents
        self.default = _link(net.default, team_params, n, given.get(None, {}))
        self.links: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {
            (index[s], index[r]): _link(spec, team_params, n, given.get((s, r), {}))
            for (s, r), spec in net.links.items()
            if s != r
        }
        self.limits: dict[tuple[int, str], float] = {}
        for agent, per_socket in net.rate_limits.items():
            for socket, rate in per_socket.items():
                self.limits[(self.names.index(agent), socket)] = float(rate)
        self.last_accept: dict[tuple[int, str], np.ndarray] = {}
        #: a replay's script (:class:`hybridteam.verify.runs.Script`): when set, it decides
        #: the fate and arrival times of every copy but the streams' instead of the links
        #: (single runs only)
        self.script: Any = None
        #: a live run's outlet (:class:`Outlet`): when set, every send goes to it instead
        #: of the links (single runs only), and nothing is known to be in flight
        self.outlet: Outlet | None = None

    # ------------------------------------------------------------------ sending
    def send(
        self,
        idx: np.ndarray,
        t: np.ndarray,
        sender: int,
        to: int | np.ndarray | None,
        socket: str,
        type_: str,
        fields: dict[str, np.ndarray],
        *,
        msg_id: np.ndarray | None = None,
        note: str = "",
        rank: np.ndarray | None = None,
    ) -> None:
        """Broadcast (``to`` None), or address one agent (an index, or one per instance;
        a negative index broadcasts). ``rank`` orders same-instant arrivals (lower first)."""
        if (
            idx.size == 1
            and self.outlet is None
            and (self.script is None or type_ in self.script.streams)
        ):
            i = int(idx[0])
            count = self.count[sender]
            seq_i = int(count[i])
            count[i] = seq_i + 1
            self._send_one(
                i,
                float(t[0]) if np.ndim(t) else float(t),
                sender,
                to,
                socket,
                type_,
                fields,
                seq_i,
                -1 if msg_id is None else int(msg_id[0]),
                note,
                0.0 if rank is None else float(rank[0]),
            )
            return
        seq = self.count[sender][idx].copy()
        self.count[sender][idx] += 1
        ids = filled(idx.size, -1, np.int64) if msg_id is None else msg_id
        if self.outlet is not None:
            target = int(to[0]) if isinstance(to, np.ndarray) else -1 if to is None else to
            self.outlet.send(
                Message(
                    sender,
                    max(target, -1),
                    int(seq[0]),
                    float(t[0]),
                    socket,
                    type_,
                    {f: float(v[0]) for f, v in fields.items()},
                    int(ids[0]),
                    note,
                ),
                0.0 if rank is None else float(rank[0]),
            )
            return
        if self.script is not None and type_ not in self.script.streams:
            self._scripted(
                t,
                sender,
                to,
                socket,
                type_,
                fields,
                int(seq[0]),
                int(ids[0]),
                note,
                0.0 if rank is None else float(rank[0]),
            )
            return
        if to is None:
            receivers = [
                (r, filled(idx.size, True, bool)) for r in range(len(self.names)) if r != sender
            ]
        elif isinstance(to, np.ndarray):
            receivers = [(r, (to == r) | (to < 0)) for r in range(len(self.names)) if r != sender]
        else:
            receivers = [(to, filled(idx.size, True, bool))]
        for r, mine in receivers:
            if not some(mine):
                continue
            inst, ts, k, ids_r = idx[mine], t[mine], seq[mine], ids[mine]
            latency, jitter, loss = (a[inst] for a in self.links.get((sender, r), self.default))
            key = self.keys[inst]
            # a draw is a pure function of (key, link, counter): where the link cannot lose
            # or delay a copy its outcome is known without hashing (lost: u < 0 is false;
            # jitter 0 * u is 0 for every u in [0, 1)), so the draws are skipped
            lost = (
                uniform(key, sender, r, k, LOSS) < loss if some(loss) else np.zeros(inst.size, bool)
            )
            u_jit = uniform(key, sender, r, k, JITTER) if some(jitter) else np.zeros(inst.size)
            t_recv = ts + latency + jitter * u_jit
            if some(lost):
                self.rec.message(
                    inst[lost],
                    k[lost],
                    sender,
                    r,
                    socket,
                    type_,
                    ts[lost],
                    np.full(int(lost.sum()), np.nan),
                    "lost",
                    "loss" + (f" ({note})" if note else ""),
                    ids_r[lost],
                )
            ok = ~lost
            if some(ok):
                values = {f: v[mine][ok].tolist() for f, v in fields.items()}
                payloads = [
                    Message(
                        sender,
                        r,
                        kj,
                        tj,
                        socket,
                        type_,
                        {f: vs[j] for f, vs in values.items()},
                        idj,
                        note,
                    )
                    for j, (kj, tj, idj) in enumerate(
                        zip(k[ok].tolist(), ts[ok].tolist(), ids_r[ok].tolist(), strict=True)
                    )
                ]
                self.queue.push_each(
                    inst[ok],
                    t_recv[ok],
                    MESSAGE,
                    r,
                    type_,
                    payloads,
                    rank=0.0 if rank is None else rank[mine][ok],
                )

    def _send_one(
        self,
        i: int,
        ts: float,
        sender: int,
        to,
        socket: str,
        type_: str,
        fields: dict[str, np.ndarray],
        seq: int,
        msg_id: int,
        note: str,
        rank: float,
    ) -> None:
        """:meth:`send` for one instance ``i`` (a single run's every message): the same
        draws and arithmetic on scalars, without the masks and broadcasts an ensemble
        needs; the draws hashed on ints (:func:`.randomness.mix_one`, the same bits)."""
        values = {f: v[0].item() for f, v in fields.items()}
        # the draws of uniform(key, sender, r, seq, LOSS or JITTER), hashed on ints: the
        # key and sender's step is every receiver's
        by_sender = mix_one(int(self.keys[i]), sender)
        for r in self._receivers_of_one(sender, to):
            latency, jitter, loss = (float(a[i]) for a in self.links.get((sender, r), self.default))
            copy = mix_one(mix_one(by_sender, r), seq) if loss > 0.0 or jitter > 0.0 else 0
            if loss > 0.0 and unit(mix_one(copy, LOSS)) < loss:
                self.rec.message_row(
                    i,
                    seq,
                    sender,
                    r,
                    socket,
                    type_,
                    ts,
                    math.nan,
                    "lost",
                    "loss" + (f" ({note})" if note else ""),
                    msg_id,
                )
                continue
            u = unit(mix_one(copy, JITTER)) if jitter > 0.0 else 0.0
            msg = Message(sender, r, seq, ts, socket, type_, dict(values), msg_id, note)
            self.queue.push_one(i, ts + latency + jitter * u, MESSAGE, r, type_, msg, rank)

    def _receivers_of_one(self, sender: int, to) -> list[int]:
        """The receivers of a send in one instance (``to`` as :meth:`send` takes it)."""
        target = int(to[0]) if isinstance(to, np.ndarray) else to
        if target is None or target < 0:
            return [r for r in range(len(self.names)) if r != sender]
        return [target]

    def _scripted(
        self,
        t: np.ndarray,
        sender: int,
        to,
        socket: str,
        type_: str,
        fields: dict[str, np.ndarray],
        seq: int,
        msg_id: int,
        note: str,
        rank: float,
    ) -> None:
        """A send in a replay (one instance): each copy arrives at the times the script
        gives it (several for a duplicated copy, +inf: still in flight when the run ends),
        or is lost when it gives none."""
        one = np.array([0])
        values = {f: float(v[0]) for f, v in fields.items()}
        for r in self._receivers_of_one(sender, to):
            times = self.script.arrivals(sender, r, type_)
            if not times:
                self.rec.message(
                    one,
                    np.array([seq]),
                    sender,
                    r,
                    socket,
                    type_,
                    t[:1],
                    np.array([np.nan]),
                    "lost",
                    "loss (replay)",
                    np.array([msg_id]),
                )
            for when in times:
                msg = Message(
                    sender, r, seq, float(t[0]), socket, type_, dict(values), msg_id, note
                )
                self.queue.push_each(one, np.array([when]), MESSAGE, r, type_, [msg], rank=rank)

    # ------------------------------------------------------------------ receiving
    def arrive(self, i: int, msg: Message, t: float, rank: float = 0.0) -> None:
        """A copy that came from outside the run (a live run's transport) reaches
        ``msg.receiver`` of instance ``i`` at time ``t``: queued as a message event, to be
        received (rate limits, the protocol's screen, the record) as a simulated one is."""
        self.queue.push_each(
            np.array([i]), np.array([t]), MESSAGE, msg.receiver, msg.type, [msg], rank=rank
        )

    def receive(
        self,
        inst: np.ndarray,
        t: np.ndarray,
        messages: list[Message],
        screen: Callable[[int, Message, float], str | None] | None = None,
    ) -> np.ndarray:
        """Arrivals at their receivers: apply rate limits, record; returns which are kept.

        Arrivals are processed in time order, so a receiver busy with the previous message
        (less than 1/rate ago) drops this one, as an overloaded robot would. ``screen``
        (the protocol layer) sees each copy that got through and may withhold it from the
        receiver's modes, returning the reason (an acknowledgement, a duplicate).
        """
        keep = filled(inst.size, True, bool)
        for j, (i, ti, msg) in enumerate(zip(inst.tolist(), t.tolist(), messages, strict=True)):
            keep[j] = self.receive_one(i, ti, msg, screen)
        return keep

    def receive_one(
        self,
        i: int,
        t: float,
        msg: Message,
        screen: Callable[[int, Message, float], str | None] | None = None,
    ) -> bool:
        """:meth:`receive` for one copy, on plain numbers (a stream's every copy is
        received alone): whether it is kept."""
        key = (msg.receiver, msg.socket)
        if key not in self.limits:
            key = (msg.receiver, "*")
        keep = True
        if key in self.limits:
            last = self.last_accept.setdefault(key, np.full(self.n, -np.inf))
            if t - last[i] < 1.0 / self.limits[key] - 1e-12:
                keep = False
            else:
                last[i] = t
        status, reason = (
            ("delivered", msg.note)
            if keep
            else ("lost", "rate limit" + (f" ({msg.note})" if msg.note else ""))
        )
        if keep and screen is not None:
            withheld = screen(i, msg, t)
            if withheld is not None:
                keep = False
                reason = withheld
        self.record(i, msg, t, status, reason)
        return keep

    def record(self, i: int, msg: Message, t_recv: float, status: str, reason: str) -> None:
        """One copy's row in the trace's message table."""
        self.rec.message_row(
            i,
            msg.seq,
            msg.sender,
            msg.receiver,
            msg.socket,
            msg.type,
            msg.t_send,
            t_recv,
            status,
            reason,
            msg.msg_id,
        )

    def close(self, pending: list[tuple[int, Any]]) -> None:
        """Copies still in flight when the run ends: recorded as lost, reason 'run ended'."""
        for i, msg in pending:
            self.record(i, msg, np.nan, "lost", "run ended")


def _link(
    spec, team_params: dict[str, np.ndarray], n: int, given: Mapping[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A link's latency, jitter and loss per instance (``given``: overridden ones), each
    checked for its range."""
    return tuple(  # type: ignore[return-value]  # (three names, three arrays)
        given[what]
        if what in given
        else require(
            evaluate_setting(getattr(spec, what), team_params, n),
            (*spec.where, what),
            f"the link's {what}",
            str(getattr(spec, what)),
            low=0.0,
            high=1.0 if what == "loss" else np.inf,
        )
        for what in LINK_SETTINGS
    )


def _given(team: Team, settings: Mapping[str, Any], n: int) -> dict[Link, dict[str, np.ndarray]]:
    """Overridden settings per link, each ``n`` values checked for its range; ValueError
    names a key that is no setting, or a value out of range, as an override (not at the
    file's line, which it replaces)."""
    targets = network_targets(team.network)
    out: dict[Link, dict[str, np.ndarray]] = {}
    for key, value in settings.items():
        if key not in targets:
            raise ValueError(key_problem((), key, team.network))
        link, what = targets[key]
        values = np.broadcast_to(override_values(key, value, n), (n,)).copy()
        try:
            require(
                values, (), f"override '{key}'", "", low=0.0, high=1.0 if what == "loss" else np.inf
            )
        except ModelError as exc:
            raise ValueError(exc.message) from None
        out.setdefault(link, {})[what] = values
    return out

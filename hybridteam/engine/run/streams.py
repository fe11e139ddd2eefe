"""Data streams: periodic messages and what receivers make of them (estimates).

The architecture paper's robots broadcast their estimated pose and intended velocity at
20 Hz; a follower's law reads the latest copy from its leader (the paper's x̂_l, v̂_l), not
the leader's true state. A stream is declared by a protocol: message type, rate, the modes
it is sent in, and its fields as expressions at the sender (which may read the held inputs
as ``u_<input>``). Each receiver keeps, per stream type and per sender, the newest copy by
send time, with its arrival time; laws read it through :meth:`LawContext.estimate`, and
expressions through ``est_<type>_<field>``, ``est_<type>_age`` and ``est_<type>_sender``
(the most recently received copy of that type).

Data copies are ordinary network messages (lossy, delayed, rate-limited, recorded), so a
Scout limited to 8 Hz really sees every third of 20 messages.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import filled, floats, some, spread, where_true
from hybridteam.engine.compile.values import require

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CStream
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.network import Message


class Inbox:
    """One agent's latest copy of each stream type, per sender, over the ensemble."""

    def __init__(self, n: int, agents: int, fields: dict[str, list[str]]) -> None:
        self.fields = fields
        self.index = {t: {f: j for j, f in enumerate(fs)} for t, fs in fields.items()}
        self.values = {t: np.full((n, agents, len(fs)), np.nan) for t, fs in fields.items()}
        self.sent = {t: np.full((n, agents), -np.inf) for t in fields}
        self.latest = {t: np.full(n, -1, np.intp) for t in fields}

    def deliver(self, i: int, msg: Message) -> None:
        """Keep a copy if it is newer (by send time) than the one held from its sender."""
        t, sender, t_send = msg.type, msg.sender, msg.t_send
        sent = self.sent[t]
        if t_send <= sent[i, sender]:
            return  # an older copy overtaken by a newer one (jitter): ignore it
        sent[i, sender] = t_send
        # (one write of the whole row: this is every stream copy's cost)
        get = msg.fields.get
        self.values[t][i, sender] = [get(f, np.nan) for f in self.fields[t]]
        latest = self.latest[t]
        held = latest[i]
        if held < 0 or t_send >= sent[i, held]:
            latest[i] = sender

    def view(self, idx: np.ndarray | slice) -> InboxView:
        return InboxView(self, idx)


class InboxView:
    """An inbox restricted to the instances a context is evaluated on (a law's
    :class:`~hybridteam.laws.StreamInbox`)."""

    __slots__ = ("box", "idx")

    def __init__(self, box: Inbox, idx: np.ndarray | slice) -> None:
        self.box, self.idx = box, idx

    def carries(self, type_: str) -> bool:
        """Whether some protocol of the team sends stream ``type_``."""
        return type_ in self.box.fields

    def sender(self, type_: str, sender: np.ndarray | None = None) -> np.ndarray:
        """The chosen sender per instance: the given one, else the most recent (-1: none)."""
        if sender is None:
            return self.box.latest[type_][self.idx]
        return spread(sender, self.box.latest[type_][self.idx].shape).astype(np.intp)

    def field(self, type_: str, name: str, sender: np.ndarray | None = None) -> np.ndarray:
        """A field of the chosen sender's latest copy (NaN where nothing has arrived)."""
        values = self.box.values[type_][..., self.box.index[type_][name]]
        return self._gather(values, self.sender(type_, sender), np.nan)

    def fields(self, type_: str, who: np.ndarray) -> dict[str, np.ndarray]:
        """Every field of the latest copies from senders ``who`` (as :meth:`sender` gives
        them): :meth:`field` of each, gathered in one pass (a law reads them all)."""
        every_field = self._gather(self.box.values[type_], who, np.nan)  # (m, fields)
        return {f: every_field[:, j] for f, j in self.box.index[type_].items()}

    def sent(self, type_: str, sender: np.ndarray | None = None) -> np.ndarray:
        """Send time of the chosen sender's latest copy (-inf where nothing has arrived)."""
        return self._gather(self.box.sent[type_], self.sender(type_, sender), -np.inf)

    def _gather(self, per_sender: np.ndarray, who: np.ndarray, missing: float) -> np.ndarray:
        """``per_sender[instance, who]`` for these instances (with any trailing axes, such as
        a copy's fields); ``missing`` where who < 0."""
        table = per_sender[self.idx]
        out = filled((*who.shape, *per_sender.shape[2:]), missing)
        rows = where_true(who >= 0)
        out[rows] = table[rows, who[rows]]
        return out


class Streams:
    """Sending side: when each agent's streams are due, and the sends themselves.

    A stream sends its first copy where it starts (its mode is entered) and then every
    ``1 / rate``: copy ``k`` is due at ``start + k * period``, counted from the start rather
    than by adding the period to the last copy's time. The sum drifts by a rounding per
    copy (copy 165 of a 20 Hz stream started at 0 left at 8.249999999999982 s), which set the
    copies of a stream started on a law's ticks a femtosecond beside those ticks: two instants,
    each running the world and the discrete phase, where the model has one, and event
    times such as ``8.249999999999982`` where the model says 8.25. Counted from a start at
    0, copy ``k`` is due at ``k * period``, the very float of a law's ``k``-th tick at that
    period (:func:`~hybridteam.engine.run.drivers.next_ticks`).
    """

    def __init__(self, ens: Ensemble, streams: list[list[CStream]]) -> None:
        self.ens = ens
        self.streams = streams
        self.due = [[np.full(ens.n, np.inf) for _ in mine] for mine in streams]
        #: where each stream last started, and the copies it has sent since (a float:
        #: ``start + copies * period`` is then one multiplication and one addition)
        self.start = [[np.full(ens.n, np.nan) for _ in mine] for mine in streams]
        self.copies = [[np.zeros(ens.n) for _ in mine] for mine in streams]
        self.periods = [[np.full(ens.n, np.nan) for _ in mine] for mine in streams]
        self.next = np.full(ens.n, np.inf)

    @property
    def any(self) -> bool:
        return any(self.streams)

    def update(self, idx: np.ndarray, config: np.ndarray | None = None) -> None:
        """After an instant: start streams whose modes were entered (first copy now), stop
        those whose modes were left, and send every copy that is due. ``config``: the
        instances of ``idx`` whose configuration may have changed (None: any); elsewhere
        a stream is on exactly where its next copy is due at a finite time."""
        ens = self.ens
        if idx.size == 0 or not self.any:
            return
        t = ens.t[idx]
        steady = config is not None and config.size == 0
        if steady and not some(self.next[idx] <= t):
            # no mode entered or left, and no copy due (``next`` is the earliest ``due``,
            # which only this method moves): nothing is sent, nothing is rescheduled —
            # a message arrival's instant, or a law's tick between copies
            return
        for a, mine in enumerate(self.streams):
            if not mine:
                continue
            st = ens.states[a]
            active = None if steady else st.active[idx]
            for s, cs in enumerate(mine):
                due = self.due[a][s]
                if steady:  # on where due is finite, and t >= inf never holds
                    send = t >= due[idx]
                else:
                    assert active is not None  # (None only when steady)
                    on = active[:, cs.modes].any(axis=1) if cs.modes else np.ones(idx.size, bool)
                    was = np.isfinite(due[idx])
                    due[idx[~on]] = np.inf
                    start = on & ~was
                    due[idx[start]] = t[start]
                    self._count_from(a, s, idx[start], t[start])
                    send = on & (t >= due[idx])
                if some(send):
                    sub = idx[send]
                    ctx = st.ctx(sub, ens.t[sub])
                    ctx.u = st.u[sub]
                    fields = {f: floats(e(ctx), sub.shape) for f, e in cs.fields.items()}
                    ens.network.send(sub, ens.t[sub], a, None, cs.socket, cs.message, fields)
                    self._next_copy(a, s, cs, sub, ctx)
        nxt = filled(idx.size, np.inf)
        for per_agent in self.due:
            for due in per_agent:
                np.minimum(nxt, due[idx], out=nxt)
        self.next[idx] = nxt

    def _count_from(self, a: int, s: int, rows: np.ndarray, t: np.ndarray) -> None:
        """Count stream ``s`` of agent ``a``'s copies afresh from ``t`` in ``rows``."""
        self.start[a][s][rows] = t
        self.copies[a][s][rows] = 0.0

    def _next_copy(self, a: int, s: int, cs: CStream, sub: np.ndarray, ctx) -> None:
        """Schedule the copy after the ones instances ``sub`` just sent: copy ``k`` is due
        at ``start + k * period``.

        A rate that reads only parameters is evaluated (and checked) at an instance's first
        copy and kept. One that reads variables or the state is evaluated at every copy;
        where it changed, the count starts again from this copy, so the next is one new
        period on (as adding the period did).
        """
        kept = self.periods[a][s]
        period = kept[sub]
        if not cs.fixed_rate or some(np.isnan(period)):
            period = require(
                spread(cs.period(ctx), sub.shape),
                (*cs.where, "rate"),
                "1 / rate",
                cs.rate_text,
                low=0.0,
                open_low=True,
                instances=sub,
            )
            new = ~(period == kept[sub])  # (NaN: the first copy)
            if some(new):
                moved = sub[new]
                self._count_from(a, s, moved, self.ens.t[moved])
                kept[moved] = period[new]
        copies = self.copies[a][s]
        copies[sub] += 1.0
        self.due[a][s][sub] = self.start[a][s][sub] + copies[sub] * period

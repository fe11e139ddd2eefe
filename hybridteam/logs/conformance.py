"""Conformance of a recorded run to its team: did the robots do what the model says?

A recording (a live run's merged trace, a trace imported from a rosbag2, or a simulation's
own) is replayed into the model with the engine's own semantics, through the seams a live
process uses (:mod:`hybridteam.live`), so there is one interpreter of the team:

- every agent is hosted (:func:`~hybridteam.live.hosting.hosted_team`: the same refusal of
  what a live process cannot run, world components);
- the network's outlet (:class:`ReplayOutlet`) takes every send of the model and keeps it
  out of the medium: what an agent receives is what the log says reached it, nothing else;
- a scripted clock on simulated time (:class:`ReplayClock`) queues each copy the log
  records as received (delivered, or turned away by a rate limit) with
  :meth:`~hybridteam.engine.run.network.Network.arrive`, at its logged receive time, in the
  log's order; the engine then receives it as it receives a simulated copy (rate limits,
  acknowledgements, duplicates, triggered transitions);
- scenario events as logged: the team's scenario, each event at the time the log shows
  its agent taking it (a transition caused by ``event:NAME``, matched in order), and at
  the team's time where the log shows none (an event no transition took leaves no trace).

So each agent's run depends on its own logged arrivals only: its teammates' behaviour
reaches it as the log says it did, and one run of all agents is each agent replayed alone.
One thing a log does not hold is a message's content (its fields): a copy's fields are
those the sender's model gave that message (matched by sender and sequence number) when it
sent it, which is before the logged arrival in a run that conforms; a copy whose sender's
model never sent it carries no fields (a guard reading one is false, as for a missing
field). Plants are driven by the model's own laws, not by logged commands.

The comparison, per agent: the mode sequence (each logged transition against the model's
in order, from the initial mode on), the time shift of each matched transition (log minus
model: positive when the robot was late), and for planar robots two pose deviations kept
apart: the largest distance of a logged position from the robot's plant driven by the
logged commands (:mod:`.commanded`: does the body move as its model says under what it
was told?), and from the replay's trajectory at the logged sample times (the model
sampled on the log's grid when its times are one, else read linearly between the model's
samples: where would the model's own laws have taken it?). The first divergence is the
earliest moment, over agents, where the two disagree: another transition, one missing on
either side, or a matched one more than ``tolerance`` seconds apart; a model transition at
the recording's last instant, which the log cannot show, is none.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from hybridteam.engine.compile.compiled import CAgent
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.reliable import ACK
from hybridteam.engine.run.simulator import Simulator
from hybridteam.live.hosting import HostingError, hosted_team
from hybridteam.live.wire import declarations
from hybridteam.logs import LogError
from hybridteam.logs.commanded import CommandedPath, NoPoseCheck, PoseDeviation, commanded_path
from hybridteam.logs.export import PLANAR
from hybridteam.model import Team
from hybridteam.trace import Table, Trace

#: Seconds a matched transition may be early or late before it counts as a divergence
DEFAULT_TOLERANCE = 0.1
SUMMARY_COLUMNS = (
    "agent",
    "logged",
    "model",
    "matched",
    "max_shift",
    "max_pose_deviation",
    "max_replay_deviation",
    "diverges_at",
    "expected",
    "observed",
    "why",
)


@dataclasses.dataclass(frozen=True)
class Divergence:
    """Where an agent's log first disagrees with the model: at ``t`` the model is in (or
    goes to) ``expected`` and the log in ``observed``; ``why`` names the message, event
    or guard behind the transition in question."""

    t: float
    agent: str
    expected: str
    observed: str
    why: str

    def line(self) -> str:
        return (
            f"first divergence at t={self.t:.6g} s, agent {self.agent}: the model is "
            f"in {self.expected}, the log in {self.observed} ({self.why})"
        )


@dataclasses.dataclass(frozen=True)
class AgentConformance:
    """One agent's comparison. ``shifts``: per matched transition (the initial mode
    included), ``(model t, log t - model t, target)``; ``commanded``: its plant under the
    logged commands (None without a kinematic plant, or when ``no_pose_check`` says why
    the log does not allow it); ``max_replay_deviation``: the largest distance of a logged
    position from the replay's (None without one)."""

    agent: str
    logged: int
    model: int
    shifts: list[tuple[float, float, str]]
    max_replay_deviation: float | None
    divergence: Divergence | None
    commanded: CommandedPath | None = dataclasses.field(default=None, repr=False)
    no_pose_check: str = ""

    @property
    def matched(self) -> int:
        return len(self.shifts)

    @property
    def max_pose_deviation(self) -> float | None:
        """The largest distance (m) of a logged position from the plant driven by the
        logged commands; None when there is no such check for this agent."""
        return None if self.commanded is None else self.commanded.deviation.distance

    @property
    def max_shift(self) -> float:
        return max((abs(s) for _, s, _ in self.shifts), default=0.0)


@dataclasses.dataclass(frozen=True)
class Conformance:
    """The comparison of instance ``instance`` of a recorded run (``log``) with its
    model's replay (``model``, one instance)."""

    agents: list[AgentConformance]
    tolerance: float
    model: Trace
    log: Trace
    instance: int = 0

    @property
    def first(self) -> Divergence | None:
        """The earliest divergence over agents (agent order breaks ties)."""
        found = [a.divergence for a in self.agents if a.divergence is not None]
        return min(found, key=lambda d: d.t) if found else None

    @property
    def conformant(self) -> bool:
        return self.first is None

    def table(self) -> Table:
        """A row per agent (:data:`SUMMARY_COLUMNS`)."""
        rows: dict[str, list[Any]] = {c: [] for c in SUMMARY_COLUMNS}
        for a in self.agents:
            d = a.divergence
            for column, value in (
                ("agent", a.agent),
                ("logged", a.logged),
                ("model", a.model),
                ("matched", a.matched),
                ("max_shift", a.max_shift),
                ("max_pose_deviation", a.max_pose_deviation),
                ("max_replay_deviation", a.max_replay_deviation),
                ("diverges_at", None if d is None else d.t),
                ("expected", None if d is None else d.expected),
                ("observed", None if d is None else d.observed),
                ("why", None if d is None else d.why),
            ):
                rows[column].append(value)
        return Table(SUMMARY_COLUMNS, rows)

    def lines(self) -> list[str]:
        """The report ``hybridteam check --conformance`` prints."""
        head = (
            "agent",
            "transitions (log/model)",
            "matched",
            "max |shift| s",
            "max pose deviation m",
            "max replay deviation m",
        )
        body = [
            (
                a.agent,
                f"{a.logged}/{a.model}",
                str(a.matched),
                f"{a.max_shift:.3g}",
                _metres(a.max_pose_deviation),
                _metres(a.max_replay_deviation),
            )
            for a in self.agents
        ]
        widths = [max(len(r[k]) for r in (head, *body)) for k in range(len(head))]
        out = [
            "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in (head, *body)
        ]
        out += [
            f"{a.agent}: no pose check under commands: {a.no_pose_check}"
            for a in self.agents
            if a.no_pose_check
        ]
        first = self.first
        if first is None:
            out.append(
                f"conformant: every agent's mode sequence is the model's, each "
                f"transition within {self.tolerance:g} s"
            )
        else:
            out.append(f"DIVERGENT: {first.line()}")
        return out

    def deviation(self, agent: str) -> PoseDeviation | None:
        """Where ``agent``'s logged position is farthest from its plant driven by the
        logged commands (planar robots whose log has commands)."""
        found = next(a.commanded for a in self.agents if a.agent == agent)
        return None if found is None else found.deviation

    def replay_deviation(self, agent: str) -> PoseDeviation | None:
        """Where ``agent``'s logged position is farthest from the replay's (planar
        robots)."""
        return largest_replay_deviation(self.log, self.instance, self.model, agent)

    def write_timeline(self, path: str | os.PathLike, **kw: Any) -> Path:
        """The log's mode bars and the model's, per agent, the first divergence marked
        (:func:`hybridteam.export.overlay.write_overlay_timeline`; ``kw``: ``window``,
        ``agents``, ``top`` as for a timeline)."""
        from hybridteam.export.overlay import write_overlay_timeline

        return write_overlay_timeline(self, path, **kw)

    def write_plot(self, path: str | os.PathLike, **kw: Any) -> Path:
        """The model's paths over the log's, the largest deviation marked
        (:func:`hybridteam.export.overlay.write_overlay_plot`; ``kw`` as for a plot)."""
        from hybridteam.export.overlay import write_overlay_plot

        return write_overlay_plot(self, path, **kw)


class ReplayClock:
    """The engine's clock seam on simulated time: before the first step it queues every
    copy the log records as received, at its receive time; then the loop runs as a
    simulation's does (no waiting), quiet stream copies held as a simulation holds them."""

    simulated_time = True

    def __init__(self, copies: list[tuple[float, Message]]) -> None:
        self.copies = copies
        self.queued = False

    def advance(self, ens: Ensemble) -> None:
        if self.queued:
            return
        self.queued = True
        for rank, (t, msg) in enumerate(self.copies):  # the log's order at equal times
            ens.network.arrive(0, msg, t, float(rank))


class ReplayOutlet:
    """The network's outlet in a replay: keeps the model's sends out of the medium, and
    gives each logged copy of a message the fields the sender's model sent it with."""

    def __init__(self, waiting: dict[tuple[int, int], list[Message]]) -> None:
        self.waiting = waiting
        #: every send of the model, in order (the model's side of the messages)
        self.sent: list[Message] = []

    def send(self, msg: Message, rank: float) -> None:
        self.sent.append(msg)
        for copy in self.waiting.pop((msg.sender, msg.seq), ()):
            if copy.type == msg.type:
                copy.fields.clear()
                copy.fields.update(msg.fields)


def conformance(
    run: Trace, team: Team, instance: int = 0, tolerance: float = DEFAULT_TOLERANCE
) -> Conformance:
    """Replay instance ``instance`` of ``run`` into ``team`` and compare (module
    docstring); a :class:`LogError` (one line) for a run of another team or a team a
    replay cannot run."""
    check_same_team(run, team)
    if not 0 <= instance < run.n:
        raise LogError(f"instance {instance}: the run has instances 0..{run.n - 1}")
    period = regular_period(run.sample_times)
    if period is not None:  # the model sampled where the log is (samples change no run)
        team = dataclasses.replace(
            team, simulation=dataclasses.replace(team.simulation, sample_period=period)
        )
    full = compile_team(team)
    names = [ca.name for ca in full.agents]
    try:
        cteam = hosted_team(full, names)
    except HostingError as exc:
        raise LogError(f"cannot replay: {exc}") from None
    cteam = dataclasses.replace(
        cteam, scenario=logged_scenario(run, instance, cteam.scenario, names)
    )
    copies, waiting = logged_copies(run, instance, names, declarations(full))
    clock = ReplayClock(copies)
    end = replay_duration(run, instance)
    seed = run.meta.get("seed", team.simulation.seed)
    sim = Simulator(
        cteam, 1, seed=seed if isinstance(seed, int) else seed[instance], duration=end, clock=clock
    )
    sim.ensemble.network.outlet = ReplayOutlet(waiting)
    model = sim.run()
    arrivals = copies_by_receiver(copies, names)
    agents = [
        compare_agent(run, instance, model, ca, arrivals.get(ca.name, []), tolerance, end)
        for ca in full.agents
    ]
    return Conformance(agents, tolerance, model, run, instance)


def check_same_team(run: Trace, team: Team) -> None:
    """LogError unless ``run`` is a run of ``team`` (its name and its agents)."""
    if run.meta.get("team") != team.name:
        raise LogError(f"a run of team '{run.meta.get('team')}', not '{team.name}'")
    names = [a.name for a in team.agents]
    if run.agents != names:
        raise LogError(
            f"the run's agents ({', '.join(run.agents)}) are not those of team "
            f"'{team.name}' ({', '.join(names)})"
        )


def regular_period(times: np.ndarray) -> float | None:
    """The period of sample times ``0, P, 2 P, ...`` (to 1 ns), else None."""
    if times.size < 2 or abs(times[0]) > 1e-9:
        return None
    period = float(times[-1] - times[0]) / (times.size - 1)
    grid = np.arange(times.size) * period
    return period if period > 0 and float(np.max(np.abs(times - grid))) <= 1e-9 else None


def replay_duration(run: Trace, instance: int) -> float:
    """How long the recording lasted: its outcome's time, else its header's duration."""
    from hybridteam.api import Run

    outcomes = run.diagnostics if isinstance(run, Run) else run.outcomes
    t = outcomes[instance].get("t") if instance < len(outcomes) else None
    if isinstance(t, (int, float)) and math.isfinite(t) and t > 0:
        return float(t)
    return float(run.meta["duration"])


def logged_scenario(
    run: Trace, instance: int, scenario: list[tuple[float, int, str]], names: list[str]
) -> list[tuple[float, int, str]]:
    """The team's scenario events at the times the log has them taken (module docstring)."""
    taken: dict[tuple[int, str], list[float]] = defaultdict(list)
    for k, name in enumerate(names):
        for t, _source, _target, cause, _guard in _transitions(run, instance, name):
            if not cause.startswith("event:"):
                continue
            seen = taken[(k, cause.removeprefix("event:"))]
            if not seen or seen[-1] != t:  # (one event taken in parallel regions: once)
                seen.append(t)
    out = []
    for t, agent, event in scenario:
        times = taken.get((agent, event))
        out.append((times.pop(0) if times else t, agent, event))
    out.sort(key=lambda s: (s[0], s[1]))
    return out


def logged_copies(
    run: Trace, instance: int, names: list[str], types: dict[str, dict[str, list[str]]]
) -> tuple[list[tuple[float, Message]], dict[tuple[int, int], list[Message]]]:
    """Every copy the log has reaching its receiver (a finite receive time), as a
    :class:`Message` in the log's order, its fields (``types``: the team's declarations)
    unknown (NaN) until the sender's model sends it; and the same copies by (sender index,
    sequence number), for the outlet to fill in."""
    m = run.messages
    index = {name: k for k, name in enumerate(names)}
    copies: list[tuple[float, Message]] = []
    waiting: dict[tuple[int, int], list[Message]] = defaultdict(list)
    for row in range(len(m)):
        t_recv = float(m["t_recv"][row])
        if int(m["instance"][row]) != instance or not math.isfinite(t_recv):
            continue
        who = str(m["sender"][row]), str(m["receiver"][row])
        for name in who:
            if name not in index:
                raise LogError(
                    f"message at t={t_recv:g} s: '{name}' is not an agent of the "
                    "team: a log of another team?"
                )
        sender, receiver = index[who[0]], index[who[1]]
        type_ = str(m["type"][row])
        note = str(m["reason"][row]) if m["status"][row] == "delivered" else ""
        # an acknowledgement whose message the model never sent acknowledges nothing
        fields = {
            f: -1.0 if type_ == ACK else math.nan for f in types.get(type_, {}).get("fields", ())
        }
        msg = Message(
            sender,
            receiver,
            int(m["seq"][row]),
            float(m["t_send"][row]),
            str(m["socket"][row]),
            type_,
            fields,
            int(m["msg_id"][row]),
            note,
        )
        copies.append((t_recv, msg))
        waiting[(sender, msg.seq)].append(msg)
    return copies, waiting


def copies_by_receiver(
    copies: list[tuple[float, Message]], names: list[str]
) -> dict[str, list[tuple[float, Message]]]:
    out: dict[str, list[tuple[float, Message]]] = defaultdict(list)
    for t, msg in copies:
        out[names[msg.receiver]].append((t, msg))
    return out


def _transitions(trace: Trace, instance: int, agent: str) -> list[tuple]:
    """``(t, source, target, cause, guard)`` of one agent's transitions, in order."""
    tr = trace.transitions
    rows = np.flatnonzero((tr["instance"] == instance) & (tr["agent"] == agent))
    return [
        (
            float(tr["t"][k]),
            str(tr["source"][k]),
            str(tr["target"][k]),
            str(tr["cause"][k]),
            str(tr["guard"][k]),
        )
        for k in rows
    ]


def compare_agent(
    run: Trace,
    instance: int,
    model: Trace,
    ca: CAgent,
    arrivals: list[tuple[float, Message]],
    tolerance: float,
    end: float,
) -> AgentConformance:
    """One agent's mode sequence, shifts, pose deviation and first divergence; ``end``:
    when the recording ends."""
    agent = ca.name
    logged = _transitions(run, instance, agent)
    expected = _transitions(model, 0, agent)
    names = model.agents
    shifts: list[tuple[float, float, str]] = []
    divergence = None
    for k in range(max(len(logged), len(expected))):
        lg = logged[k] if k < len(logged) else None
        md = expected[k] if k < len(expected) else None
        if lg is None and md is not None and md[0] >= end:
            break  # at the recording's last instant: what the robot did is not in it
        if lg is not None and md is not None and lg[1:3] == md[1:3]:
            shift = lg[0] - md[0]
            if abs(shift) > tolerance:
                divergence = _diverged(
                    ca, md, lg, names, arrivals, f"{shift:+.6g} s from the model's time"
                )
                break
            shifts.append((md[0], shift, md[2]))
            continue
        divergence = _diverged(ca, md, lg, names, arrivals, "")
        break
    try:
        commanded, unchecked = commanded_path(run, instance, ca), ""
    except NoPoseCheck as exc:
        commanded, unchecked = None, str(exc)
    return AgentConformance(
        agent,
        len(logged),
        len(expected),
        shifts,
        replay_deviation(run, instance, model, agent),
        divergence,
        commanded,
        unchecked,
    )


def _metres(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g}"


def _diverged(
    ca: CAgent,
    md: tuple | None,
    lg: tuple | None,
    names: list[str],
    arrivals: list[tuple[float, Message]],
    note: str,
) -> Divergence:
    """The divergence at the earlier of the model's transition ``md`` and the log's
    ``lg`` (either may be missing): there one side has moved and the other not yet."""
    agent = ca.name
    if md is not None and (lg is None or md[0] <= lg[0]):
        t, model_mode = md[0], md[2]
        # both leave the same mode at this instant for different ones: the log's target
        # is what it did instead; otherwise, at t, the log is still in its source
        log_mode = md[1] if lg is None else lg[2] if lg[0] == md[0] else lg[1]
        why = "the model's transition " + _cause(md, agent, names, arrivals)
        if lg is None:
            why += "; the log has no further transition"
        elif lg[1:3] == md[1:3]:
            why += f"; the log's is at t={lg[0]:.6g} ({note})"
        else:
            why += f"; the log's next is {lg[1]} -> {lg[2]} at t={lg[0]:.6g}"
    else:
        assert lg is not None
        t, log_mode = lg[0], lg[2]
        model_mode = lg[1] if md is None else md[1]
        why = f"the log's transition {lg[1]} -> {lg[2]} ({_plain_cause(lg)})"
        if md is None:
            why += "; the model takes no further transition"
        elif lg[1:3] == md[1:3]:
            why += f" comes {note}"
        else:
            why += f"; the model's next is {md[1]} -> {md[2]} at t={md[0]:.6g}"
        if md is None or lg[1:3] != md[1:3]:
            why += _model_side(ca, lg)
    return Divergence(t, agent, model_mode or "(none)", log_mode or "(none)", why)


def _model_side(ca: CAgent, lg: tuple) -> str:
    """What the model has for the log's transition ``lg`` that it did not take: its own
    transitions between the same modes on the same message or event, and their guards."""
    trigger = lg[3].split(":", 1)[1] if lg[3].startswith(("message:", "event:")) else None
    paths = [m.path for m in ca.modes]

    def within(path: str, mode: str) -> bool:  # a transition of a parent, into a parent
        return mode == path or mode.startswith(path + ".")

    same = [
        tr
        for tr in ca.transitions
        if not tr.internal and within(paths[tr.source], lg[1]) and within(paths[tr.target], lg[2])
    ]
    if not same:
        return f"; the model has no transition {lg[1]} -> {lg[2]}"
    guarded = [tr.guard_text for tr in same if tr.on == trigger and tr.guard_text]
    if guarded:
        return "; the model's guard " + " or ".join(guarded) + " did not hold"
    return ""


def _plain_cause(tr: tuple) -> str:
    return tr[3] + (f", guard {tr[4]}" if tr[4] else "")


def _cause(tr: tuple, agent: str, names: list[str], arrivals: list[tuple[float, Message]]) -> str:
    """A model transition with what explains it: for a message, the logged copy."""
    text = f"{tr[1] or '(start)'} -> {tr[2]} ({_plain_cause(tr)}"
    if tr[3].startswith("message:"):
        type_ = tr[3].split(":", 1)[1]
        got = [(t, m) for t, m in arrivals if m.type == type_ and t <= tr[0]]
        if got:
            t, m = got[-1]
            text += (
                f"; the log has '{type_}' from {names[m.sender]} sent at "
                f"t={m.t_send:.6g}, reaching {agent} at t={t:.6g}"
            )
    return text + ")"


def replay_deviation(run: Trace, instance: int, model: Trace, agent: str) -> float | None:
    """For a planar robot, the largest distance (m) of a logged position from the
    replay's trajectory (linear between its samples) at the logged sample times the
    model covers; None for another agent or no such sample."""
    worst = largest_replay_deviation(run, instance, model, agent)
    return None if worst is None else worst.distance


def largest_replay_deviation(
    run: Trace, instance: int, model: Trace, agent: str
) -> PoseDeviation | None:
    """The logged sample of :func:`replay_deviation`: its time and both positions there
    (the first such sample where several are as far), for a view to mark it."""
    info = next(a for a in run.meta["agents"] if a["name"] == agent)
    if (
        info["plant"] not in PLANAR
        or info["state"][:2] != ["x", "y"]
        or agent not in run.samples
        or agent not in model.samples
    ):
        return None
    logged = run.samples[agent][:, instance, :2]
    mine = model.samples[agent][:, 0, :2]
    have = ~np.isnan(mine).any(axis=1)
    if not have.any():
        return None
    times = model.sample_times[have]
    at = run.sample_times
    ok = ~np.isnan(logged).any(axis=1) & (at >= times[0]) & (at <= times[-1])
    if not ok.any():
        return None
    x = np.interp(at[ok], times, mine[have, 0])
    y = np.interp(at[ok], times, mine[have, 1])
    distance = np.hypot(logged[ok, 0] - x, logged[ok, 1] - y)
    k = int(np.argmax(distance))
    row = np.flatnonzero(ok)[k]
    return PoseDeviation(
        float(distance[k]),
        float(at[row]),
        (float(logged[row, 0]), float(logged[row, 1])),
        (float(x[k]), float(y[k])),
    )

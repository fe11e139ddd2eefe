"""A ``verify`` counterexample's losses as scripted drops of a live run (docs/live.md).

``hybridteam verify`` writes, for each violation a run of the simulator reproduces, that
run as ``OUT/<property>/trace.json`` beside ``OUT/verify.json``: its message table has a
row for every copy the path sends, and the copies the path loses are ``lost`` with the
reason ``loss (replay)``. A live process drops "the ``n``-th datagram of a message type
that arrives for an agent here" (``--drop-copy TYPE:N``, :class:`.clock.WallClock`), so
each lost copy becomes, at its receiver's process, the number its datagram has among
those of its type that reach the process, counted in the order they were sent (on one
machine's loopback, the order they arrive). ``--losses-from`` gives each process the drops
of the copies lost on their way to its agents (``launch``: one agent each): the live team
meets exactly the losses the counterexample names, and nothing but a loss is scripted
(the moments are the live run's own).

Nothing here reads a file: the command reads ``verify.json`` and the trace with the
checks every file handed over gets, and hands them here.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.live.wire import declarations
from hybridteam.trace import Trace

#: The reason the replay's scripted network gives a copy its path loses.
REPLAY_LOSS = "loss (replay)"


class CounterexampleError(ValueError):
    """A counterexample that cannot be replayed live: one line, saying why."""


@dataclass(frozen=True)
class Loss:
    """One datagram the counterexample loses on its way to a process's agents: the
    ``copy``-th of its ``type`` that reaches the agents ``process`` hosts (counting from
    1), sent by ``sender`` to ``receivers`` (those of them it was lost to)."""

    sender: str
    receivers: tuple[str, ...]
    type: str
    copy: int
    t_send: float
    process: tuple[str, ...]

    @property
    def text(self) -> str:
        return (
            f"{self.sender} -> {', '.join(self.receivers)}: {self.type} sent at "
            f"t={self.t_send:.6g} s is dropped at {', '.join(self.process)}'s process "
            f"(--drop-copy {self.type}:{self.copy})"
        )


def locate(path: str | Path) -> tuple[Path, Path, str | None]:
    """Where verify wrote what ``path`` names: (the counterexample's trace, the
    ``verify.json`` beside it, the property), ``path`` being a counterexample's folder
    (``OUT/deadlock``) or its ``trace.json``; the property is None when ``path`` is the
    verify output folder itself (the caller names its counterexamples)."""
    given = Path(path)
    if (given / "verify.json").is_file():
        return given / "trace.json", given / "verify.json", None
    folder = given.parent if given.name == "trace.json" else given
    return folder / "trace.json", folder.parent / "verify.json", folder.name


def check_verdict(summary: object, name: str | None, where: Path) -> None:
    """CounterexampleError unless verify's summary ``summary`` (read from ``where``) has a
    counterexample of property ``name`` that a run reproduced; for ``name`` None, the
    error names the counterexamples there are."""
    props = summary.get("properties") if isinstance(summary, dict) else None
    if not isinstance(props, dict) or not all(isinstance(p, dict) for p in props.values()):
        raise CounterexampleError(f"{where}: not what 'hybridteam verify' writes (no 'properties')")
    found = [p for p, v in props.items() if _reproduced(v)]
    if name is None:
        folder = where.parent
        raise CounterexampleError(
            f"{folder} is verify's output folder: give one of its counterexamples ("
            + ", ".join(str(folder / p) for p in found)
            + ")"
            if found
            else f"{folder}: verify found no counterexample there ("
            + ", ".join(f"{p}: {v.get('verdict')}" for p, v in props.items())
            + ")"
        )
    if name not in props:
        raise CounterexampleError(
            f"{where} has no property '{name}' (its properties: {', '.join(props)})"
        )
    verdict = props[name]
    if verdict.get("verdict") != "violated":
        raise CounterexampleError(
            f"'{name}' {verdict.get('verdict')} ({where}): there is no counterexample to replay"
        )
    if not _reproduced(verdict):
        replay = verdict.get("replay")
        why = (
            "it was not replayed (--no-replay)"
            if not isinstance(replay, dict)
            else f"no run of the simulator shows it ({replay.get('verdict')})"
        )
        raise CounterexampleError(
            f"'{name}' is violated in the skeleton only ({where}): "
            f"{why}, so there is no run to replay"
        )


def _reproduced(verdict: dict) -> bool:
    replay = verdict.get("replay")
    return isinstance(replay, dict) and replay.get("verdict") == "reproduced"


def losses(trace: Trace, cteam: CTeam, here: Collection[str]) -> list[Loss]:
    """The datagrams the counterexample's run ``trace`` loses on their way to the agents
    ``here`` (one live process's), each numbered among the datagrams of its type that
    reach an agent here, in the order they were sent, as :class:`.clock.WallClock` counts
    them (a datagram: one send, whatever the number of its receivers here).

    CounterexampleError for a run of another team, or one whose losses a live run cannot
    script: a copy the path duplicates (a live run drops datagrams, it does not make
    them), a type the team does not declare, a datagram lost to one agent here and not to
    another (the process drops it for all of them), or a lost datagram whose number is
    not defined (another sender's datagram of the type sent to this process at the same
    moment: which arrives first is the network's choice)."""
    names = [ca.name for ca in cteam.agents]
    theirs = [a["name"] for a in trace.meta.get("agents", [])]
    if trace.meta.get("team") != cteam.team.name or theirs != names:
        raise CounterexampleError(
            f"a counterexample of team '{trace.meta.get('team')}' (agents "
            f"{', '.join(theirs)}), not of this team '{cteam.team.name}' (agents "
            f"{', '.join(names)})"
        )
    streams = {cs.message for ca in cteam.agents for cs in ca.streams}
    rows = [r for r in trace.messages if r.type not in streams]
    datagrams: dict[tuple[str, int], list] = {}  # (sender, seq) -> its copies here
    seen: set[tuple[str, str, int]] = set()
    for r in rows:
        key = (r.sender, r.receiver, int(r.seq))
        if key in seen:
            raise CounterexampleError(
                f"{r.sender} -> {r.receiver}: {r.type} sent at t={r.t_send:.6g} s is "
                "duplicated: a live run can drop a datagram, not duplicate one"
            )
        seen.add(key)
        if r.receiver in here:
            datagrams.setdefault((r.sender, int(r.seq)), []).append(r)
    declared = declarations(cteam)
    process = tuple(n for n in names if n in here)
    out = []
    for (sender, seq), copies in datagrams.items():
        lost = [r.receiver for r in copies if r.status == "lost" and r.reason == REPLAY_LOSS]
        if not lost:
            continue
        kind, t_send = copies[0].type, copies[0].t_send
        if len(lost) < len(copies):
            raise CounterexampleError(
                f"{sender} -> {', '.join(lost)}: {kind} is lost, and reaches "
                f"{', '.join(r.receiver for r in copies if r.receiver not in lost)} in the "
                "same process: a process drops a datagram for all its agents"
            )
        if kind not in declared:
            raise CounterexampleError(
                f"it loses a copy of '{kind}', a type this team "
                f"does not declare (its types: {', '.join(declared)})"
            )
        same = [(s, q, c[0].t_send) for (s, q), c in datagrams.items() if c[0].type == kind]
        tied = next(((s, q) for s, q, t in same if t == t_send and s != sender), None)
        if tied is not None:
            raise CounterexampleError(
                f"{sender} -> {', '.join(lost)}: {kind} is lost, and {tied[0]}'s '{kind}' "
                f"to {', '.join(r.receiver for r in datagrams[tied])} was sent at the same "
                f"moment (t={t_send:.6g} s): which of them arrives first live, and so "
                "which copy is lost, is not defined"
            )
        # (sent earlier, or at the same moment by the same sender, numbered before it)
        before = sum(
            1 for s, q, t in same if t < t_send or (t == t_send and s == sender and q < seq)
        )
        out.append(Loss(sender, tuple(lost), kind, before + 1, float(t_send), process))
    return out


def drops(found: list[Loss]) -> dict[str, set[int]]:
    """The losses as a process's scripted drops, ``{type: {n, ...}}`` (``--drop-copy``)."""
    out: dict[str, set[int]] = {}
    for loss in found:
        out.setdefault(loss.type, set()).add(loss.copy)
    return out

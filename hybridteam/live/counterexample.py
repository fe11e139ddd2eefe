"""A ``verify`` counterexample's losses as scripted drops of a live run (docs/live.md).

``hybridteam verify`` writes, for each violation a run of the simulator reproduces, that
run as ``OUT/<property>/trace.json`` beside ``OUT/verify.json``: its message table has a
row for every copy the path sends, and the copies the path loses are ``lost`` with the
reason ``loss (replay)``. A live process drops "the ``n``-th copy of a message type that
arrives for an agent here" (``--drop-copy TYPE:N``, :class:`.clock.WallClock`), so each
lost copy becomes, at its receiver's process, the number it has among the copies of its
type that receiver is sent, counted in the order they were sent (on one machine's
loopback, the order they arrive). ``hybridteam launch --losses-from`` gives each agent's
process the drops of the copies lost on their way to it: the live team meets exactly the
losses the counterexample names, and nothing but a loss is scripted (the moments are the
live run's own).

Nothing here reads a file: the command reads ``verify.json`` and the trace with the
checks every file handed over gets, and hands them here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hybridteam.engine.compiled import CTeam
from hybridteam.live.wire import declarations
from hybridteam.trace import Trace

#: The reason the replay's scripted network gives a copy its path loses.
REPLAY_LOSS = "loss (replay)"


class CounterexampleError(ValueError):
    """A counterexample that cannot be replayed live: one line, saying why."""


@dataclass(frozen=True)
class Loss:
    """One copy the counterexample loses: the ``copy``-th of its ``type`` sent to
    ``receiver`` (counting from 1)."""

    sender: str
    receiver: str
    type: str
    copy: int
    t_send: float

    @property
    def text(self) -> str:
        return f"{self.sender} -> {self.receiver}: {self.type} (copy {self.copy} of " \
               f"'{self.type}' to {self.receiver}, sent at t={self.t_send:.6g} s)"


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
        raise CounterexampleError(f"{where}: not what 'hybridteam verify' writes (no "
                                  "'properties')")
    found = [p for p, v in props.items() if _reproduced(v)]
    if name is None:
        folder = where.parent
        raise CounterexampleError(
            f"{folder} is verify's output folder: give one of its counterexamples ("
            + ", ".join(str(folder / p) for p in found) + ")" if found else
            f"{folder}: verify found no counterexample there ("
            + ", ".join(f"{p}: {v.get('verdict')}" for p, v in props.items()) + ")")
    if name not in props:
        raise CounterexampleError(f"{where} has no property '{name}' (its properties: "
                                  f"{', '.join(props)})")
    verdict = props[name]
    if verdict.get("verdict") != "violated":
        raise CounterexampleError(f"'{name}' {verdict.get('verdict')} ({where}): there is "
                                  "no counterexample to replay")
    if not _reproduced(verdict):
        replay = verdict.get("replay")
        why = "it was not replayed (--no-replay)" if not isinstance(replay, dict) else \
            f"no run of the simulator shows it ({replay.get('verdict')})"
        raise CounterexampleError(f"'{name}' is violated in the skeleton only ({where}): "
                                  f"{why}, so there is no run to replay")


def _reproduced(verdict: dict) -> bool:
    replay = verdict.get("replay")
    return isinstance(replay, dict) and replay.get("verdict") == "reproduced"


def losses(trace: Trace, cteam: CTeam) -> list[Loss]:
    """The copies the counterexample's run ``trace`` loses, each with its number among
    the copies of its type sent to its receiver; CounterexampleError for a run of another
    team, or one whose losses a live run cannot script: a copy the path duplicates (a live
    run drops datagrams, it does not make them), a type the team does not declare, or a
    lost copy whose number is not defined (another sender's copy of the type sent to the
    same receiver at the same moment: which arrives first is the network's choice)."""
    names = [ca.name for ca in cteam.agents]
    theirs = [a["name"] for a in trace.meta.get("agents", [])]
    if trace.meta.get("team") != cteam.team.name or theirs != names:
        raise CounterexampleError(
            f"a counterexample of team '{trace.meta.get('team')}' (agents "
            f"{', '.join(theirs)}), not of this team '{cteam.team.name}' (agents "
            f"{', '.join(names)})")
    streams = {cs.message for ca in cteam.agents for cs in ca.streams}
    rows = [r for r in trace.messages if r.type not in streams]
    sent: dict[tuple[str, str, int], int] = {}
    for r in rows:
        key = (r.sender, r.receiver, int(r.seq))
        sent[key] = sent.get(key, 0) + 1
        if sent[key] > 1:
            raise CounterexampleError(
                f"{r.sender} -> {r.receiver}: {r.type} sent at t={r.t_send:.6g} s is "
                "duplicated: a live run can drop a datagram, not duplicate one")
    declared = declarations(cteam)
    out = []
    for lost in (r for r in rows if r.status == "lost" and r.reason == REPLAY_LOSS):
        if lost.type not in declared:
            raise CounterexampleError(f"it loses a copy of '{lost.type}', a type this team "
                                      f"does not declare (its types: {', '.join(declared)})")
        same = [r for r in rows if r.receiver == lost.receiver and r.type == lost.type]
        if any(r.t_send == lost.t_send and r.sender != lost.sender for r in same):
            raise CounterexampleError(
                f"{lost.sender} -> {lost.receiver}: {lost.type} is lost, and another "
                f"sender's '{lost.type}' to {lost.receiver} was sent at the same moment "
                f"(t={lost.t_send:.6g} s): which is which copy live is not defined")
        # (sent earlier, or at the same moment by the same sender, numbered before it)
        before = sum(1 for r in same if r.t_send < lost.t_send or (
            r.t_send == lost.t_send and r.sender == lost.sender and r.seq < lost.seq))
        out.append(Loss(lost.sender, lost.receiver, lost.type, before + 1,
                        float(lost.t_send)))
    return out


def drops_by_agent(found: list[Loss]) -> dict[str, dict[str, set[int]]]:
    """The losses as each receiving agent's scripted drops: ``{agent: {type: {n}}}``."""
    out: dict[str, dict[str, set[int]]] = {}
    for loss in found:
        out.setdefault(loss.receiver, {}).setdefault(loss.type, set()).add(loss.copy)
    return out

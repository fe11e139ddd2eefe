"""``hybridteam verify TEAM.yaml [-p NAME] [--losses K] [--order any|fifo] -o OUT``.

Explores every behaviour of the team's discrete skeleton (message orders, losses, timeouts)
and checks its properties: the team's requirements that have a meaning without a clock,
and ``deadlock``. Prints what the skeleton abstracts, progress (states/s, frontier), one
verdict line per property and, for each violation, the shortest counterexample as a
message sequence. Each counterexample is replayed in the simulator (a scripted network
loses and delivers exactly the path's copies at moments that respect every timeout); a
reproduced one is written as an ordinary run (``OUT/<property>/trace.json``, timeline and
sequence chart), one the simulator cannot follow is reported as spurious, with the reason.
Writes ``OUT/verify.json``. Exit status: 0 when every property checked holds, 1 on a
violation a run reproduces (or any violation with ``--no-replay``), 2 on bad input, 3 when
the only violations are spurious (the skeleton's, not the simulator's), 4 when ``--spin``
was asked and SPIN's verdict differs from ours on some property, or ``--spin-rules`` was
asked and SPIN's own exploration of the team's rules differs from ours.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    output_folder,
)
from hybridteam.progress import MODES
from hybridteam.verify.bounds import DEFAULT_MAX_VALUES
from hybridteam.verify.storage import DEFAULT_BITSTATE_MB, DEFAULT_HASH_FUNCTIONS, STORAGES

EXIT_VIOLATED = 1
EXIT_SPURIOUS = 3
EXIT_SPIN_DISAGREES = 4


def register(sub) -> dict:
    ve = sub.add_parser(
        "verify",
        help="check a team's protocol logic under every message order and loss",
        description="Explores the team's discrete skeleton exhaustively (every message order, "
        "loss up to --losses, timeout and guard over time or state) and checks its "
        "requirements of the forms always(phi) and always(implies(phi, eventually(psi))), "
        "and deadlock; replays each counterexample in the simulator. Exit 0: every property "
        "holds; 1: a violation a run reproduces; 2: bad input; 3: only spurious violations.",
    )
    ve.add_argument("team", metavar="TEAM.yaml")
    ve.add_argument(
        "--property",
        "-p",
        action="append",
        default=None,
        metavar="NAME",
        help="check only this property (a requirement's name, or deadlock); "
        "repeat for more (default: all)",
    )
    ve.add_argument(
        "--losses",
        type=int,
        default=2,
        metavar="K",
        help="copies the network may lose on one path (default 2)",
    )
    ve.add_argument(
        "--duplicates",
        type=int,
        default=0,
        metavar="D",
        help="copies the network may duplicate on one path (default 0)",
    )
    ve.add_argument(
        "--order",
        choices=("any", "fifo"),
        default="any",
        help="any: any copy in flight may arrive next (default); fifo: in "
        "sending order on each link",
    )
    ve.add_argument(
        "--ack-timing",
        choices=("bounded", "any"),
        default="bounded",
        help="bounded: an ack timeout expires only once every copy and ack of "
        "its message has arrived or been lost (ack timeouts exceed the round "
        "trip; default); any: at any moment",
    )
    ve.add_argument(
        "--timeouts",
        choices=("any", "own", "long"),
        default="any",
        help="any: an after: timeout may expire at any moment (default); own: "
        "only once the agent's own messages are settled (none of its copies but "
        "acks in flight, nothing awaiting acks); long: only once nothing at all "
        "is in flight or unacknowledged. own and long are timing assumptions: "
        "they leave behaviours out",
    )
    ve.add_argument(
        "--max-states",
        type=int,
        default=2_000_000,
        metavar="N",
        help="stop exploring beyond N states; verdicts then say 'bounded' (default 2,000,000)",
    )
    ve.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GB",
        help="stop exploring when this process holds more memory, and take the "
        "engine's states in batches that fit in half of it (default 4 GB, as "
        "for run; a team whose single state does not fit is refused)",
    )
    ve.add_argument(
        "--max-values",
        type=int,
        default=DEFAULT_MAX_VALUES,
        metavar="N",
        help="stop exploring once a discrete variable has taken more than N "
        "different values: a variable that keeps growing (a counter) makes the "
        f"skeleton infinite (default {DEFAULT_MAX_VALUES})",
    )
    ve.add_argument(
        "--storage",
        choices=STORAGES,
        default="exact",
        help="exact: keep every state (exhaustive; default); hashcompact: a 64-bit hash "
        "per state; bitstate: a few bits per state in a fixed bit array (--bitstate-mb). "
        "hashcompact and bitstate are PARTIAL searches (a state whose hash meets another's "
        "is not explored), reported with their estimated coverage; they check invariants "
        "and deadlock, not responses (docs/verify.md)",
    )
    ve.add_argument(
        "--bitstate-mb",
        type=float,
        default=None,
        metavar="MB",
        help=f"the bit array of --storage bitstate, in MB (default {DEFAULT_BITSTATE_MB:g})",
    )
    ve.add_argument(
        "--hash-functions",
        type=int,
        default=None,
        metavar="K",
        help=f"bits set per state with --storage bitstate (default {DEFAULT_HASH_FUNCTIONS})",
    )
    ve.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="cores computing successors (default 1): threads of the compiled loop, or "
        "worker processes of the Python loop; the states, edges and verdicts are the same "
        "for any N",
    )
    ve.add_argument(
        "--symmetry",
        choices=("on", "off"),
        default="on",
        help="on: agents interchangeable where the properties allow it are explored "
        "once per arrangement, and the states counted are representatives (default); "
        "off: every state (docs/verify.md)",
    )
    ve.add_argument(
        "--por",
        choices=("basic", "ample"),
        default="basic",
        help="partial-order reduction. basic: a copy no mode can see is explored "
        "alone first (default); ample: also, from each state, only the choices of "
        "one agent nothing else can reach while no property reads it (needs "
        "--ack-timing bounded, --timeouts any, --order any; docs/verify.md)",
    )
    ve.add_argument(
        "--reference",
        action="store_true",
        help="compute every successor with the engine (load, run, read back) instead "
        "of the reaction tables it fills: the same exploration, slower; a cross-check",
    )
    ve.add_argument(
        "--kernel",
        choices=("auto", "on", "off"),
        default="auto",
        help="auto: explore with the compiled loop (numba, the extra hybridteam[fast]) "
        "where it is installed and the options allow it (exact storage, one job, no "
        "symmetry or ample reduction, not --reference), else in Python (default); on: "
        "the same, and an error without numba; off: in Python. The same states, edges "
        "and verdicts either way (docs/verify.md)",
    )
    ve.add_argument(
        "--no-replay", action="store_true", help="do not replay counterexamples in the simulator"
    )
    ve.add_argument(
        "--spin",
        action="store_true",
        help="a second opinion: export the explored skeleton as Promela "
        "(OUT/spin/skeleton.pml) and have SPIN check each invariant and "
        "response property on it; needs 'spin' and a C compiler (skipped "
        "with a note otherwise); exit 4 if SPIN disagrees with a verdict",
    )
    ve.add_argument(
        "--spin-rules",
        action="store_true",
        help="an independent second explorer: export the team's rules (not the "
        "explored graph) to Promela (OUT/spin-rules/rules.pml), let SPIN "
        "explore them and compare the reachable mode configurations, dead "
        "ends and the deadlock verdict with ours; needs 'spin' and a C "
        "compiler; exit 4 if they differ, 2 for a model it does not "
        "translate (docs/verify.md)",
    )
    ve.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    ve.add_argument(
        "--progress",
        choices=MODES,
        default="auto",
        help="auto (a line every few seconds), log, bar (the same lines) or none",
    )
    return {"verify": cmd_verify}


def _check(args) -> None:
    if args.kernel == "on":
        from hybridteam.verify.kernel import numba_available

        if not numba_available():
            raise UsageError("--kernel on: numba is not installed: pip install 'hybridteam[fast]'")
        for refused, option in (
            (args.reference, "--reference"),
            (args.storage != "exact", f"--storage {args.storage}"),
            (args.por == "ample", "--por ample"),
        ):
            if refused:
                raise UsageError(f"--kernel on: the compiled loop does not serve {option}")
    for name in ("losses", "duplicates"):
        if getattr(args, name) < 0:
            raise UsageError(f"--{name} must be 0 or more, got {getattr(args, name)}")
    if args.max_states < 1:
        raise UsageError(f"--max-states must be at least 1, got {args.max_states}")
    if args.max_values < 1:
        raise UsageError(f"--max-values must be at least 1, got {args.max_values}")
    if args.max_memory is not None and not 0 < args.max_memory < math.inf:
        raise UsageError(f"--max-memory must be a finite number > 0, got {args.max_memory}")
    if args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, got {args.jobs}")
    if args.storage != "bitstate":
        for name in ("bitstate_mb", "hash_functions"):
            if getattr(args, name) is not None:
                flag = "--" + name.replace("_", "-")
                raise UsageError(f"{flag} applies to --storage bitstate, not {args.storage}")
    if args.bitstate_mb is not None and not 0 < args.bitstate_mb <= 1e6:
        raise UsageError(f"--bitstate-mb must be a number of MB > 0, got {args.bitstate_mb}")
    if args.storage == "bitstate":
        from hybridteam.engine.run.budget import memory_limit

        limit = memory_limit(None if args.max_memory is None else args.max_memory * 1e9)
        mb = DEFAULT_BITSTATE_MB if args.bitstate_mb is None else args.bitstate_mb
        if mb * 2**20 > limit / 2:
            raise UsageError(
                f"--bitstate-mb {mb:g}: the bit array would take more than half of the "
                f"memory limit of {limit / 1e9:g} GB (--max-memory raises it)"
            )
    if args.hash_functions is not None and not 1 <= args.hash_functions <= 32:
        raise UsageError(f"--hash-functions must be 1 to 32, got {args.hash_functions}")
    if args.storage != "exact":
        for flag in ("spin", "spin_rules"):
            if getattr(args, flag):
                raise UsageError(
                    f"--{flag.replace('_', '-')} compares a whole exploration: it needs "
                    f"--storage exact, not {args.storage} (a partial search)"
                )
    if args.por == "ample":
        clash = [
            f"--{name.replace('_', '-')} {getattr(args, name)}"
            for name, needed in (("ack_timing", "bounded"), ("timeouts", "any"), ("order", "any"))
            if getattr(args, name) != needed
        ]
        if clash:
            raise UsageError(
                f"--por ample needs --ack-timing bounded, --timeouts any and --order any "
                f"(arrivals then change only their receiver), got {', '.join(clash)}"
            )
    if args.spin_rules:
        from hybridteam.verify import spin

        why = spin.missing()
        if why:
            raise UsageError(f"--spin-rules: {why}")


def cmd_verify(args) -> int:
    from hybridteam.engine.run.budget import ResourceError
    from hybridteam.errors import did_you_mean
    from hybridteam.verify import NotInPartialSearch, Options, UnknownProperty, verify

    _check(args)
    out = output_folder(args.output)
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    opts = Options(
        losses=args.losses,
        duplicates=args.duplicates,
        order=args.order,
        max_states=args.max_states,
        ack_timing=args.ack_timing,
        timeouts=args.timeouts,
        max_values=args.max_values,
        # SPIN's own exploration is compared configuration by configuration: it needs
        # every reachable state
        symmetry="off" if args.spin_rules else args.symmetry,
        por="basic" if args.spin_rules else args.por,
        reference=args.reference,
        max_memory=None if args.max_memory is None else args.max_memory * 1e9,
        storage=args.storage,
        bitstate_mb=DEFAULT_BITSTATE_MB if args.bitstate_mb is None else args.bitstate_mb,
        hash_functions=(
            DEFAULT_HASH_FUNCTIONS if args.hash_functions is None else args.hash_functions
        ),
        jobs=args.jobs,
        kernel=args.kernel,
    )
    try:
        report = verify(
            team,
            opts,
            args.property,
            _progress(args.progress),
            replay=False,
            note=_note(args.progress),
        )
    except ResourceError as exc:  # refused before anything was allocated
        raise UsageError(str(exc)) from None
    except NotInPartialSearch as exc:
        raise UsageError(f"--property: {exc}") from None
    except UnknownProperty as exc:
        hint = did_you_mean(exc.name, exc.known)
        raise UsageError(
            f"--property: '{exc.name}' is not a property of {args.team} (its "
            f"properties: {', '.join(exc.known)})" + (f"; {hint}" if hint else "")
        ) from None
    rules = _rules(report, opts) if args.spin_rules else None
    if report.graph.bound is not None and args.progress != "none":  # before the replays
        print(f"hybridteam: verify: stopped: {report.graph.bound}", file=sys.stderr, flush=True)
    if not args.no_replay:
        for v in report.violated:
            if args.progress != "none":
                print(
                    f"hybridteam: verify: replaying {v.prop.name}'s counterexample in the "
                    "simulator",
                    file=sys.stderr,
                    flush=True,
                )
            report.replay(v, progress=_replay_progress(v.prop.name, args.progress))
    out.mkdir(parents=True, exist_ok=True)
    files = {v.prop.name: _write_run(report, v, out) for v in report.reproduced}
    _print(report, args.team, files)
    from hybridteam.trace import write_atomic

    summary = report.summary()
    for name, written in files.items():
        summary["properties"][name]["replay"]["files"] = written
    disagree = False
    if args.spin:
        summary["spin"], disagree = _spin(report, out)
    if rules is not None:
        summary["spin_rules"], differ = _spin_rules(report, opts, rules, out)
        disagree |= differ
    write_atomic(out / "verify.json", json.dumps(summary, indent=1) + "\n")
    print(f"wrote {out / 'verify.json'}")
    if disagree:
        return EXIT_SPIN_DISAGREES
    if not report.violated:
        return EXIT_OK
    return EXIT_VIOLATED if report.reproduced or args.no_replay else EXIT_SPURIOUS


def _spin(report, out) -> tuple[dict, bool]:
    """SPIN's opinion per compared property, printed; and whether it disagrees anywhere."""
    from hybridteam.verify import spin

    try:
        opinions = spin.cross_check(report, out / "spin")
    except RuntimeError as exc:
        print(f"spin: skipped: {exc}")
        return {"skipped": str(exc)}, False
    for o in opinions:
        word = (
            "agrees" if o.agrees else "DISAGREES" if o.spin is not None else "no verdict"
        ) + f" ({'holds' if o.ours else 'violated'})"
        print(f"spin: {o.name}: {word}" + (f": {o.note}" if o.note else ""))
    return (
        {
            o.name: {"ours": o.ours, "spin": o.spin, "agrees": o.agrees, "note": o.note}
            for o in opinions
        },
        any(o.spin is not None and not o.agrees for o in opinions),
    )


def _rules(report, opts) -> str:
    """The Promela rules of the team, or a usage error naming what is not translated."""
    from hybridteam.verify import promela

    try:
        return promela.prepare(report, opts)
    except promela.Unsupported as exc:
        raise UsageError(f"--spin-rules: not translated: {exc}") from None


def _spin_rules(report, opts, rules: str, out) -> tuple[dict, bool]:
    """Both explorers' configuration counts and deadlock verdicts, SPIN's verdicts on the
    invariants and responses it decided on the rules, and where they differ."""
    from hybridteam.verify import promela

    try:
        c = promela.compare(report, opts, out / "spin-rules", promela=rules)
    except RuntimeError as exc:
        print(f"spin-rules: failed: {exc}")
        return {"failed": str(exc)}, True
    diff = c.differences()
    for who, e in (("ours", c.ours), ("SPIN", c.spin)):
        print(
            f"spin-rules: {who}: {len(e.configurations)} mode configurations, "
            f"{len(e.dead_ends)} at dead ends, deadlock "
            f"{'holds' if e.deadlock else 'violated'}"
        )
    for name, holds in c.spin.verdicts.items():
        print(f"spin-rules: {name}: SPIN {'holds' if holds else 'violated'} on the rules")
    for name, why in c.spin.undecided.items():
        print(f"spin-rules: {name}: not decided by SPIN: {why}")
    print("spin-rules: " + ("the explorers agree" if not diff else "DIFFER: " + "; ".join(diff)))
    return (
        {
            "ours": len(c.ours.configurations),
            "spin": len(c.spin.configurations),
            "deadlock": {"ours": c.ours.deadlock, "spin": c.spin.deadlock},
            "verdicts": {
                n: {"ours": c.ours.verdicts.get(n), "spin": h} for n, h in c.spin.verdicts.items()
            },
            "states": {"ours": c.ours.states, "spin": c.spin.states},
            "differences": diff,
        },
        bool(diff),
    )


def _write_run(report, v, out) -> list[str]:
    """A reproduced counterexample as an ordinary run: trace, timeline, sequence chart."""
    from hybridteam.export.sequence import sequence_chart
    from hybridteam.export.timeline import write_timeline
    from hybridteam.trace import write_atomic

    run = report.replays[v.prop.name][1].run
    folder = out / v.prop.name
    folder.mkdir(parents=True, exist_ok=True)
    run.to_json(folder / "trace.json")
    write_timeline(run, folder / "timeline.png")
    write_atomic(folder / "sequence.mmd", sequence_chart(run, "mermaid"))
    return [str(folder / name) for name in ("trace.json", "timeline.png", "sequence.mmd")]


def _progress(mode: str):
    if mode == "none":
        return None
    state = {"last": 0.0}

    def show(states: int, frontier: int, depth: int, seconds: float) -> None:
        now = time.perf_counter()
        if now - state["last"] < 5.0 and frontier:
            return
        state["last"] = now
        rate = states / seconds if seconds > 0 else 0.0
        print(
            f"hybridteam: verify: {states:,} states, frontier {frontier:,}, depth {depth}, "
            f"{rate:,.0f} states/s, {seconds:.1f} s{_memory()}",
            file=sys.stderr,
            flush=True,
        )

    return show


def _note(mode: str) -> Callable[[str], None] | None:
    """A line on stderr for what the explorer says before it starts (the compiled loop
    being compiled)."""
    if mode == "none":
        return None
    return lambda text: print(f"hybridteam: verify: {text}", file=sys.stderr, flush=True)


def _memory() -> str:
    """``, 1.2 GB in memory`` (this process's resident size), where the system tells it:
    a long check's memory is what decides whether it can finish."""
    from hybridteam.engine.run.budget import resident_bytes

    resident = resident_bytes()
    return "" if resident is None else f", {resident / 1e9:.1f} GB in memory"


def _replay_progress(name: str, mode: str):
    """A line every 5 s while a property's counterexamples are being replayed."""
    if mode == "none":
        return None
    state = {"last": 0.0}

    def show(tried: int, seconds: float) -> None:
        if seconds - state["last"] >= 5.0:
            state["last"] = seconds
            print(
                f"hybridteam: verify: {name}: {tried} counterexample(s) replayed, none "
                f"reproduced yet, {seconds:.0f} s",
                file=sys.stderr,
                flush=True,
            )

    return show


def _search(g) -> str:
    """How complete the exploration was, in words."""
    if g.coverage is not None:
        return g.coverage.words()
    return "exhaustive" if g.exhaustive else "bounded: not exhaustive"


def _print(report, path: str, files: dict[str, list[str]]) -> None:
    from hybridteam.verify import word as verdict_word

    g = report.graph
    print(
        f"{path}: skeleton of {len(g.states):,} states, {g.transitions:,} steps, "
        f"{g.seconds:.1f} s ({_search(g)};"
        f" losses <= {report.options.losses}, duplicates <= {report.options.duplicates}, "
        f"order {report.options.order}; {g.explorer})"
    )
    if g.bound is not None:
        print(f"  stopped: {g.bound}")
    if report.symmetry is not None and report.symmetry.active:
        names = [ca.name for ca in report.skeleton.original.agents]
        print(f"  symmetry: {report.symmetry.describe(names)}: states counted up to it")
    if report.options.por == "ample":
        print("  partial-order reduction: ample sets (--por ample): states counted are kept ones")
    for note in report.skeleton.notes:
        print(f"  abstracted: {note}")
    for v in report.verdicts:
        word = {None: "NOT CHECKED", True: verdict_word(v, g), False: "VIOLATED"}[v.holds]
        print(f"{v.prop.name}: {word}" + (f" ({v.message})" if v.message else ""))
        if v.holds is False:
            if v.prop.name in report.replays:
                _, r, tried = report.replays[v.prop.name]
                print(
                    f"  replayed in the simulator: {r.verdict.upper()}: {r.reason}"
                    + (
                        f" (the shortest of {tried} counterexamples tried)"
                        if tried > 1 and r.reproduced
                        else f" ({tried} counterexamples tried)"
                        if tried > 1
                        else ""
                    )
                )
            for line in report.counterexample(v):
                print(f"  {line}")
            if v.prop.name in files:
                print(f"  the run: {', '.join(files[v.prop.name])}")
            more = report.configurations(v)[1:]
            if more and v.prop.kind != "response":
                print(f"  {len(more)} other violating configuration(s) (all in verify.json):")
                for text in more[:5]:
                    print(f"    {text}")

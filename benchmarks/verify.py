"""Verification: states per second and the full check time of the role protocol.

Teams of 2, 3 and 4 robots and the operator: the first robot leads, every other follows
it and asks for the leadership once, then the leader resigns (the scenario's events, in
that order, at moments of the explorer's choosing). Each is verified with 0 and 1 losses
(any order), every property of ``examples/protocols/roles_verify.yaml`` (one leader, each
request answered) and deadlock; a check that reaches ``--max-states`` says "bounded".
``--scenario request`` keeps only the second robot's request, ``resign`` only the
resignation (each protocol exchange alone, e.g. three robots with two losses). Each
check runs in a process of its own, so "peak MB" is that check's; "B/state" is the peak's
growth during the check per state explored.

    python benchmarks/verify.py [--max-states 1000000] [--robots 2 3 4] [--losses 0 1]
        [--scenario all|request|resign] [--timeouts any|own|long] [--reference]
        [--storage exact|hashcompact|bitstate] [--jobs N]

``--compare successors`` (or ``--compare`` alone) instead times the same checks in one
invocation: the compiled loop (``--kernel on``), the Python loop over the reaction tables
(``--kernel off``), the reference explorer (the engine for every successor,
``--reference``; left out with ``--no-reference``) and SPIN exploring the protocol's rules
(the Promela export of :mod:`hybridteam.verify.promela`, sized by
:func:`~hybridteam.verify.promela.room` from our exploration so no copy overflows,
compiled without printing), and prints states per second and the ratios of the compiled
loop to each. SPIN's states are not ours (it keeps ids, outboxes and filters
unrenumbered; the export applies our canonical form and our invisible-copy-first rule, so
its counts come within a few per cent of ours), so both the rates and the times to the
verdict are printed; SPIN runs only on the checks whose exploration is exhaustive (its
rules have no state bound).

    python benchmarks/verify.py --compare [--checks 2:0:all 3:0:all 2:1:all 3:2:resign]
        [--spin-on 2:0:all] [--max-states N]

``--compare successors`` with ``--jobs N`` gives the compiled loop N threads (the other
explorers one process each). ``--compare jobs`` times each check with ``--jobs 1`` and
with ``--jobs N`` (2 unless told; the compiled loop's threads where numba is installed,
else the Python loop's worker processes), alternating, twice each, and prints the
speedup (the best time of one against the best of the other, in this invocation: on a
machine others use too, the ratio is what carries over, not the seconds; the CPU seconds,
the check's process and its workers together, say what the threads or the pool cost
beyond one process). ``--compare storage`` runs each
check with every storage mode and prints their states, time and peak memory side by side.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

from hybridteam import load
from hybridteam.verify import Options, promela, spin, verify
from hybridteam.verify.kernel import numba_available
from hybridteam.verify.storage import STORAGES

NAMES = "abcdefgh"


def team_text(robots: int, scenario: str = "all") -> str:
    """``robots`` robots on the role protocol, the operator, and their requirements;
    ``scenario``: every request and the resignation, only the first request, or only
    the resignation."""
    lines = [f"team: roles_{robots}", "agents:"]
    for k in range(robots):
        name = NAMES[k]
        lines += [
            f"  {name}:",
            f"    plant: {{kind: unicycle, state: {{x: {-k}, y: 0, theta: 0}}}}",
        ]
        if k:
            lines.append("    variables: {leader: id_a}")
        lines += [
            "    modes:",
            "      Transport:",
            "        protocol: role_assignment",
            f"        initial: {'Lead' if k == 0 else 'Follow'}",
            "        roles:",
            "          lead: {inputs: {v: 0.1, omega: 0}}",
            "          follow: {inputs: {v: 0.1, omega: 0}}",
        ]
    lines += ["  operator:", "    operator: role_assignment", "scenario:"]
    asking = {"all": range(1, robots), "request": range(1, 2), "resign": range(0)}[scenario]
    lines += [f"  - {{at: {k}, agent: {NAMES[k]}, raise: want_lead}}" for k in asking]
    if scenario != "request":
        lines.append(f"  - {{at: {robots}, agent: a, raise: resign}}")
    lines += ["requirements:", "  one_leader: always(count_in_role(lead) <= 1)"]
    lines += [
        f"  {NAMES[k]}_answered: always(implies(in_mode({NAMES[k]}, Requesting), "
        f"eventually(in_role({NAMES[k]}, lead) or in_mode({NAMES[k]}, Follow) or "
        f"in_mode({NAMES[k]}, Operated))))"
        for k in range(1, robots)
    ]
    lines += ["simulation:", "  duration: 10"]
    return "\n".join(lines) + "\n"


def one(robots: int, losses: int, args: argparse.Namespace) -> dict:
    """One check, in this process (peak memory is this process's): its figures."""
    opts = Options(
        losses=losses,
        max_states=args.max_states,
        timeouts=args.timeouts,
        reference=args.reference,
        storage=args.storage,
        jobs=args.jobs,
        kernel=args.kernel,
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"roles_{robots}.yaml"
        path.write_text(team_text(robots, args.scenario))
        team = load(path)
        if args.kernel != "off" and numba_available():
            # numba and the compiled loop it loads take a fixed ~100 MB: in before the base
            verify(team, Options(losses=0, max_states=100, kernel=args.kernel), replay=False)
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # before checking
        r = verify(team, opts, replay=False)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        g = r.graph
        rules = None
        if args.rules and g.exhaustive and args.timeouts == "any":
            rules = promela.export(
                r.skeleton, losses, 0, ack_timing=opts.ack_timing, **promela.room(g.states)
            )
    bad = [v.prop.name for v in r.violated]
    word = (
        ("VIOLATED: " + ", ".join(bad))
        if bad
        else (
            "all hold"
            if g.exhaustive
            else "none violated (partial)"
            if g.coverage is not None and g.bound is None
            else "none violated (bounded)"
        )
    )
    return {
        "states": len(g.states),
        "steps": g.transitions,
        "seconds": g.seconds,
        "peak": peak,
        "per_state": (peak - base) * 1048576 / len(g.states),
        "verdict": word,
        "rules": rules,
        "explorer": g.explorer,
    }


def row(robots: int, losses: int, f: dict) -> str:
    return (
        f"{robots:>6} {losses:>6} {f['states']:>10,} {f['steps']:>10,} "
        f"{f['seconds']:>8.1f} {f['states'] / f['seconds']:>9,.0f} {f['peak']:>8,.0f} "
        f"{f['per_state']:>8,.0f}  {f['verdict']}"
    )


def spin_rate(rules: str, timeout: float) -> tuple[int, float] | str:
    """SPIN's exhaustive search of ``rules``: (states stored, seconds of search), or why
    there is none. Compiled as :func:`~hybridteam.verify.promela.run_spin` does but
    without ``-DPRINTF`` (printing each step would slow SPIN down)."""
    why = spin.missing()
    if why:
        return why
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "rules.pml").write_text(rules)
        steps = [
            ["spin", "-o2", "-a", "rules.pml"],
            [
                "cc",
                "-O1",
                "-DNOREDUCE",
                "-DSAFETY",
                "-DVECTORSZ=4096",
                "-DMEMLIM=3000",  # MB: stop rather than take the shared machine's memory
                "-o",
                "pan",
                "pan.c",
            ],
            ["./pan", "-E", "-m10000000"],
        ]
        try:
            for cmd in steps:
                done = subprocess.run(
                    cmd, cwd=tmp, capture_output=True, text=True, timeout=timeout, check=True
                )
        except subprocess.TimeoutExpired:
            return f"over {timeout:g} s"
        except subprocess.CalledProcessError as exc:
            return f"{exc.cmd[0]} failed"
    text = done.stdout
    states = re.search(r"([0-9.e+]+) states, stored", text)
    seconds = re.search(r"elapsed time ([0-9.e+]+) seconds", text)
    if "errors: 0" not in text or states is None or seconds is None:
        return "search incomplete"
    return int(float(states.group(1))), max(float(seconds.group(1)), 1e-3)


def compare(args: argparse.Namespace) -> None:
    """The compiled loop, the Python loop, the reference and SPIN on each check, in this
    one invocation."""
    print(
        f"{'check':>14} {'explorer':>9} {'states':>10} {'seconds':>8} {'states/s':>9} "
        f"{'peak MB':>8} {'B/state':>8}  verdict",
        flush=True,
    )
    for check in args.checks:
        robots, losses, scenario = check.split(":")
        rest = ["--max-states", str(args.max_states), "--scenario", scenario]
        rest += ["--timeouts", args.timeouts, "--json"]
        figures = {}
        explorers = [
            ("kernel", ["--kernel", "on", "--rules", "--jobs", str(args.jobs)]),
            ("tables", ["--kernel", "off"]),
            *([] if args.no_reference else [("reference", ["--reference"])]),
        ]
        for who, extra in explorers:
            out = subprocess.run(
                [sys.executable, __file__, "--one", robots, losses, *rest, *extra],
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            f = figures[who] = json.loads(out)
            print(
                f"{check:>14} {who:>9} {f['states']:>10,} {f['seconds']:>8.1f} "
                f"{f['states'] / f['seconds']:>9,.0f} {f['peak']:>8,.0f} "
                f"{f['per_state']:>8,.0f}  {f['verdict']}",
                flush=True,
            )
        ours = figures["kernel"]
        rate = ours["states"] / ours["seconds"]
        line = f"{check:>14}"
        for who in list(figures)[1:]:
            ref = figures[who]
            same = (ours["states"], ours["steps"], ours["verdict"]) == (
                ref["states"],
                ref["steps"],
                ref["verdict"],
            )
            line += (
                f" kernel/{who}: {rate / (ref['states'] / ref['seconds']):.1f}x states/s, "
                f"{ours['per_state'] / max(ref['per_state'], 1):.2f}x B/state "
                f"({'same states, steps and verdicts' if same else 'DIFFERENT'});"
            )
        got = (
            "not asked (--spin-on)"
            if check not in args.spin_on
            else spin_rate(ours["rules"], args.spin_timeout)
            if ours["rules"]
            else "bounded"
        )
        if isinstance(got, str):
            line += f" SPIN: {got}"
        else:
            states, seconds = got
            line += (
                f" SPIN: {states:,} states in {seconds:.1f} s = {states / seconds:,.0f} "
                f"states/s; ours/SPIN {rate / (states / seconds):.2f}x states/s, and "
                f"{seconds / ours['seconds']:.2f}x SPIN's speed to the verdict"
            )
        print(line, flush=True)


def _cpu() -> float:
    """CPU seconds of this process's finished children (and theirs: a check's workers)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _check_args(args: argparse.Namespace) -> list[str]:
    """The options every check's own process is given: its bound, scenario and timeouts."""
    return [
        "--max-states",
        str(args.max_states),
        "--scenario",
        args.scenario,
        "--timeouts",
        args.timeouts,
    ]


def compare_runs(args: argparse.Namespace) -> None:
    """Each check with ``--jobs 1`` against ``--jobs N`` (alternating, twice each), or
    with each storage mode: seconds, and the ratio to the first of them."""
    base = [sys.executable, __file__, *_check_args(args)]
    if args.compare == "jobs":
        jobs = args.jobs if args.jobs > 1 else 2
        variants = [["--jobs", "1"], ["--jobs", str(jobs)]] * 2
    else:
        variants = [["--storage", s] for s in STORAGES]
    print(f"{'variant':>22} {'seconds':>8} {'ratio':>6} {'CPU s':>6}  row", flush=True)
    for robots in args.robots:
        for losses in args.losses:
            best: dict[str, float] = {}
            for variant in variants:
                before = _cpu()
                row = subprocess.run(
                    [*base, *variant, "--one", str(robots), str(losses)],
                    check=True,
                    capture_output=True,
                    text=True,
                ).stdout.strip()
                cpu = _cpu() - before  # the check's process and its workers
                name = " ".join(variant)
                seconds = float(row.split()[4])
                best[name] = min(seconds, best.get(name, seconds))
                first = best[" ".join(variants[0])]
                ratio = first / seconds if seconds else math.nan  # (under 0.05 s: too short)
                print(
                    f"{name:>22} {seconds:>8.1f} {ratio:>6.2f} {cpu:>6.1f}  {row}",
                    flush=True,
                )
            if args.compare == "jobs":
                one_, many = (best[" ".join(v)] for v in variants[:2])
                print(
                    f"robots {robots}, losses {losses}: --jobs {jobs} is {one_ / many:.2f}x "
                    f"--jobs 1 (best of two each: {one_:.1f} s against {many:.1f} s)",
                    flush=True,
                )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[2, 3, 4])
    ap.add_argument("--losses", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--max-states", type=int, default=1_000_000)
    ap.add_argument("--scenario", choices=("all", "request", "resign"), default="all")
    ap.add_argument("--timeouts", choices=("any", "own", "long"), default="any")
    ap.add_argument("--reference", action="store_true", help="the engine for every successor")
    ap.add_argument("--storage", choices=STORAGES, default="exact")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument(
        "--kernel", choices=("auto", "on", "off"), default="auto", help="the compiled loop"
    )
    ap.add_argument(
        "--compare",
        nargs="?",
        const="successors",
        choices=("successors", "jobs", "storage"),
        default=None,
        help="successors: tables vs reference vs SPIN; jobs: --jobs 1 vs N; storage: each mode",
    )
    ap.add_argument(
        "--checks",
        nargs="+",
        default=["2:0:all", "3:0:all", "2:1:all", "3:2:resign"],
        help="ROBOTS:LOSSES:SCENARIO of each --compare check",
    )
    ap.add_argument(
        "--spin-on",
        nargs="*",
        default=["2:0:all"],
        help="the checks SPIN explores too (its unreduced search grows fast)",
    )
    ap.add_argument("--spin-timeout", type=float, default=600.0)
    ap.add_argument(
        "--no-reference", action="store_true", help="--compare without the reference explorer"
    )
    ap.add_argument("--one", type=int, nargs=2, help=argparse.SUPPRESS)  # robots, losses
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--rules", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        f = one(*args.one, args)
        print(json.dumps(f) if args.json else row(*args.one, f), flush=True)
        return
    if args.compare == "successors":
        compare(args)
        return
    if args.compare:
        compare_runs(args)
        return
    print(
        f"{'robots':>6} {'losses':>6} {'states':>10} {'steps':>10} {'seconds':>8} "
        f"{'states/s':>9} {'peak MB':>8} {'B/state':>8}  verdict",
        flush=True,
    )
    # each check in a process of its own, so its peak memory is its own
    rest = [
        *_check_args(args),
        *(["--reference"] if args.reference else []),
        *("--storage", args.storage, "--jobs", str(args.jobs), "--kernel", args.kernel),
    ]
    for robots in args.robots:
        for losses in args.losses:
            subprocess.run(
                [sys.executable, __file__, "--one", str(robots), str(losses), *rest], check=True
            )


if __name__ == "__main__":
    main()

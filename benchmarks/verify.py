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
        [--scenario all|request|resign] [--timeouts any|own|long]
        [--storage exact|hashcompact|bitstate] [--jobs N] [--compare jobs|storage]

``--compare jobs`` times each check with ``--jobs 1`` and with ``--jobs N`` (2 unless
told), alternating, twice each, and prints the speedup (the best time of one against the
best of the other, in this invocation: on a machine others use too, the ratio is what
carries over, not the seconds; the CPU seconds, the check's process and its workers
together, say what the pool costs beyond one process). ``--compare storage`` runs each
check with every storage mode and prints their states, time and peak memory side by side.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

from hybridteam import load
from hybridteam.verify import Options, verify
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


def one(robots: int, losses: int, args: argparse.Namespace) -> str:
    """One check, in this process: its table row (peak memory is this process's)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"roles_{robots}.yaml"
        path.write_text(team_text(robots, args.scenario))
        team = load(path)
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # before checking
        r = verify(
            team,
            Options(
                losses=losses,
                max_states=args.max_states,
                timeouts=args.timeouts,
                storage=args.storage,
                jobs=args.jobs,
            ),
            replay=False,
        )
    g = r.graph
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
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return (
        f"{robots:>6} {losses:>6} {len(g.states):>10,} {g.transitions:>10,} "
        f"{g.seconds:>8.1f} {len(g.states) / g.seconds:>9,.0f} {peak:>8,.0f} "
        f"{(peak - base) * 1048576 / len(g.states):>8,.0f}  {word}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[2, 3, 4])
    ap.add_argument("--losses", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--max-states", type=int, default=1_000_000)
    ap.add_argument("--scenario", choices=("all", "request", "resign"), default="all")
    ap.add_argument("--timeouts", choices=("any", "own", "long"), default="any")
    ap.add_argument("--storage", choices=STORAGES, default="exact")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--compare", choices=("jobs", "storage"), default=None)
    ap.add_argument("--one", type=int, nargs=2, help=argparse.SUPPRESS)  # robots, losses
    args = ap.parse_args()
    if args.one:
        print(one(*args.one, args), flush=True)
        return
    if args.compare:
        compare(args)
        return
    print(
        f"{'robots':>6} {'losses':>6} {'states':>10} {'steps':>10} {'seconds':>8} "
        f"{'states/s':>9} {'peak MB':>8} {'B/state':>8}  verdict",
        flush=True,
    )
    # each check in a process of its own, so its peak memory is its own
    rest = [
        "--max-states",
        str(args.max_states),
        "--scenario",
        args.scenario,
        "--timeouts",
        args.timeouts,
    ]
    for robots in args.robots:
        for losses in args.losses:
            subprocess.run(
                [sys.executable, __file__, "--one", str(robots), str(losses), *rest], check=True
            )


def _cpu() -> float:
    """CPU seconds of this process's finished children (and theirs: a check's workers)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def compare(args: argparse.Namespace) -> None:
    """Each check with ``--jobs 1`` against ``--jobs N`` (alternating, twice each), or
    with each storage mode: seconds, and the ratio to the first of them."""
    base = [
        sys.executable,
        __file__,
        "--max-states",
        str(args.max_states),
        "--scenario",
        args.scenario,
        "--timeouts",
        args.timeouts,
    ]
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
                print(
                    f"{name:>22} {seconds:>8.1f} {first / seconds:>6.2f} {cpu:>6.1f}  {row}",
                    flush=True,
                )
            if args.compare == "jobs":
                one_, many = (best[" ".join(v)] for v in variants[:2])
                print(
                    f"robots {robots}, losses {losses}: --jobs {jobs} is {one_ / many:.2f}x "
                    f"--jobs 1 (best of two each: {one_:.1f} s against {many:.1f} s)",
                    flush=True,
                )


if __name__ == "__main__":
    main()

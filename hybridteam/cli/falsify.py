"""``hybridteam falsify TEAM.yaml --requirement NAME --vary KEY=LO:HI [...] -o OUT``.

Searches override values (and seeds) for a run that violates a requirement, each
generation simulated as one ensemble; writes ``OUT/falsify.json`` (resumable: run the same
command again), ``OUT/convergence.png`` and, for the best candidate found, ``OUT/replay/``
(an ordinary run folder) with the ``hybridteam run`` command line that reproduces it.
Exit status: 0 when a violation was found, 1 when the budget ran out without one, 2 on
bad input.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    add_workers,
    check_connect_timeout,
    check_workers,
    load_team_or_report,
    output_folder,
    write_run_folder,
)
from hybridteam.progress import MODES

EXIT_NOT_FOUND = 1


def register(sub) -> dict:
    fa = sub.add_parser(
        "falsify",
        help="search parameters and seeds for a run that breaks a requirement",
        description="Minimises a requirement's robustness over override values (and seeds); "
        "each generation runs as one ensemble. Exit 0: a violating run was found (replayed "
        "in OUT/replay); 1: none within the budget; 2: bad input.",
    )
    fa.add_argument("team", metavar="TEAM.yaml")
    fa.add_argument(
        "--requirement",
        "-r",
        required=True,
        metavar="NAME",
        help="a requirement of the team (its requirements: section)",
    )
    fa.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY=LO:HI",
        help="an override key (team parameter, agent.parameter or a network "
        "setting: network.loss, ...) and its range; repeat for more",
    )
    fa.add_argument(
        "--seeds",
        type=int,
        default=1,
        metavar="N",
        help="also search the run's seed among N seeds from the team's (default 1: "
        "the team's seed only)",
    )
    fa.add_argument(
        "--budget", type=int, default=300, metavar="N", help="at most N simulations (default 300)"
    )
    fa.add_argument(
        "--method",
        choices=("de", "random"),
        default="de",
        help="de: differential evolution, robustness-guided (default); random: uniform draws",
    )
    fa.add_argument(
        "--population",
        type=int,
        default=20,
        metavar="P",
        help="candidates per generation, simulated as one ensemble (default 20)",
    )
    fa.add_argument(
        "--search-seed",
        type=int,
        default=0,
        metavar="S",
        help="the search's own random seed (default 0)",
    )
    fa.add_argument(
        "--keep-going",
        action="store_true",
        help="use the whole budget, not stopping at the first violation",
    )
    add_workers(fa)
    fa.add_argument("--no-replay", action="store_true", help="do not write OUT/replay")
    fa.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    fa.add_argument(
        "--progress",
        choices=MODES,
        default="auto",
        help="auto (a bar on a terminal, lines otherwise), bar, log or none",
    )
    return {"falsify": cmd_falsify}


def _varies(items: list[str]):
    from hybridteam.falsify.search import Vary

    if not items:
        raise UsageError("give at least one --vary KEY=LO:HI")
    out = []
    for item in items:
        key, eq, rng = item.partition("=")
        lo, colon, hi = rng.partition(":")
        try:
            a, b = float(lo), float(hi)
        except ValueError:
            a = b = math.nan
        if not (eq and colon and key.strip()) or not (math.isfinite(a) and math.isfinite(b)):
            raise UsageError(f"--vary {item!r}: expected KEY=LO:HI with numbers, e.g. p_loss=0:0.5")
        if not a < b:
            raise UsageError(f"--vary {item!r}: LO must be below HI")
        if not math.isfinite(b - a):  # the search draws LO + (HI - LO) * u
            raise UsageError(
                f"--vary {item!r}: the range is too wide (HI - LO is beyond the largest number)"
            )
        out.append(Vary(key.strip(), a, b))
    keys = [v.key for v in out]
    if len(set(keys)) < len(keys):
        raise UsageError("--vary: each key once")
    return out


def _check(args: argparse.Namespace, team, varies) -> None:
    """Numbers, the requirement's name and the keys, before anything runs."""
    from hybridteam.api import simulate
    from hybridteam.errors import ModelError, did_you_mean

    for flag, value, least in (
        ("--budget", args.budget, 1),
        ("--population", args.population, 2),
        ("--seeds", args.seeds, 1),
    ):
        if value < least:
            raise UsageError(f"{flag} must be at least {least}, got {value}")
    check_workers(args.workers)
    check_connect_timeout(args.connect_timeout)
    _check_generation(team, args.population)
    names = [r.name for r in team.requirements]
    if args.requirement not in names:
        hint = did_you_mean(args.requirement, names)
        raise UsageError(
            f"the team has no requirement '{args.requirement}'"
            + (f"; {hint}" if hint else f" (its requirements: {', '.join(names) or 'none'})")
        )
    for v in varies:  # a zero-length run at each end of each range checks key and values
        for value in (v.lo, v.hi):
            try:
                simulate(team, duration=0.0, overrides={v.key: value})
            except (ValueError, ModelError) as exc:
                raise UsageError(f"--vary {v.key}={v.lo:g}:{v.hi:g}: {exc}") from None


def _check_generation(team, population: int) -> None:
    """A generation runs as one ensemble (and the optimiser keeps a row per candidate):
    refuse a population whose ensemble exceeds the memory limit, before allocating it."""
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.budget import ResourceError, memory_estimate, memory_limit

    sim = team.simulation
    nbytes, _ = memory_estimate(compile_team(team), population, sim.duration, sim.output_period())
    try:
        limit = memory_limit()
    except ResourceError as exc:
        raise UsageError(str(exc)) from None
    if nbytes > limit:
        raise UsageError(
            f"--population {population:,}: a generation runs as one ensemble, "
            f"which would need about {nbytes / 1e9:,.1f} GB of memory, more than "
            f"the limit of {limit / 1e9:,.1f} GB (HYBRIDTEAM_MAX_MEMORY_GB): give a "
            "smaller --population"
        )


def cmd_falsify(args: argparse.Namespace) -> int:
    from hybridteam.falsify import output as O
    from hybridteam.falsify.evaluate import Evaluator
    from hybridteam.falsify.search import run_search
    from hybridteam.progress import reporter
    from hybridteam.sweep.store import StudyError

    varies = _varies(args.vary)
    out = output_folder(args.output)
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    _check(args, team, varies)
    formula = next(r.formula for r in team.requirements if r.name == args.requirement)
    settings = O.settings_of(
        args.requirement,
        formula,
        varies,
        args.seeds,
        team.simulation.seed,
        args.method,
        args.population,
        args.search_seed,
    )
    key = O.digest(Path(args.team).read_text(encoding="utf-8"), settings)
    record = O.read_record(out, key) if out.exists() else []
    if isinstance(record, str):
        raise UsageError(record)
    # connect first: a scheduler that cannot be reached leaves no folder behind
    try:
        evaluator = Evaluator(
            team,
            args.requirement,
            [v.key for v in varies],
            workers=args.workers,
            scheduler=args.scheduler,
            connect_timeout=args.connect_timeout,
        )
    except StudyError as exc:  # the scheduler cannot be reached
        raise UsageError(str(exc)) from None
    out.mkdir(parents=True, exist_ok=True)
    shown = reporter(args.progress, args.budget, f"falsify {args.requirement}", "sim")
    best = [math.inf]

    def progress(search) -> None:
        O.write_record(out, key, settings, search)
        if shown is not None:
            shown.update(len(search.generations[-1].seeds))
            best[0] = float(search.best_so_far()[-1])
            if hasattr(shown, "set_postfix_str"):
                shown.set_postfix_str(f"best robustness {best[0]:.4g}")

    try:
        search = run_search(
            varies,
            args.seeds,
            team.simulation.seed,
            evaluator,
            budget=args.budget,
            method=args.method,
            population=args.population,
            search_seed=args.search_seed,
            record=record,
            on_generation=progress,
            stop_on_violation=not args.keep_going,
        )
    finally:
        evaluator.close()
        if shown is not None:
            shown.close()
    return _finish(args, team, out, key, settings, search)


def _finish(args, team, out: Path, key: str, settings: dict, search) -> int:
    from hybridteam.falsify import output as O

    if not search.generations:
        raise UsageError("nothing was simulated")
    i = search.best()
    replay = O.replay_args(args.team, search, i, out)
    extra: dict[str, Any] = {"replay": O.command_line(replay)}
    rho = float(search.flat()[2][i])
    if not args.no_replay:
        extra["replayed_robustness"] = _replay(team, search, i, out, args.requirement)
    O.write_record(out, key, settings, search, extra)
    title = f"{team.name}: {args.requirement} ({args.method}, {search.evaluations} simulations)"
    O.write_convergence(out, search, title)
    first = search.first_falsified()
    x, seeds, _, outcomes = search.flat()
    values = ", ".join(f"{v.key}={x[i, j]:.6g}" for j, v in enumerate(search.varies))
    verdict = (
        f"violated after {first} simulations"
        if first is not None
        else f"not violated in {search.evaluations} simulations"
    )
    print(
        f"{args.requirement}: {verdict}; best robustness {rho:.6g} at {values}, seed "
        f"{int(seeds[i])} (outcome {outcomes[i]})"
    )
    print(f"replay: {extra['replay']}")
    print(
        f"wrote {out}/ (falsify.json, convergence.png"
        + ("" if args.no_replay else ", replay/")
        + ")"
    )
    return EXIT_OK if first is not None else EXIT_NOT_FOUND


def _replay(team, search, i: int, out: Path, requirement: str) -> float | str:
    """Run the best candidate alone into OUT/replay, as ``hybridteam run`` would; returns
    its robustness (the search's, when the replay is exact)."""
    from hybridteam.api import simulate
    from hybridteam.falsify.output import _json

    x, seeds, _, _ = search.flat()
    overrides = {v.key: float(x[i, j]) for j, v in enumerate(search.varies)}
    run = simulate(team, seed=int(seeds[i]), overrides=overrides)
    summary = run.summary()
    write_run_folder(out / "replay", team, run, summary, views=True)
    value = run.diagnostics[0]["requirements"][requirement]["robustness"]
    searched = _json(float(search.flat()[2][i]))
    if value != searched:
        print(
            f"hybridteam: note: the replay's robustness {value} differs from the search's "
            f"{searched}",
            file=sys.stderr,
        )
    return value

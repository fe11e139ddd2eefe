"""Wall time of the ladder paper's Section 5 robustness study: seven factors, every run.

The seven study files of ``examples/ladder`` (lookahead, alpha, kc, orsp, kr, speed,
springs; population S of 100 pairs, ladder lengths 240..480) run one after the other, as
the loop in ``examples/ladder/README.md`` runs them, through
:func:`hybridteam.sweep.run_study` on a local process pool — the whole path a user takes:
planning, chunk tasks shipped to workers, the ladder's vectorized stepper, chunk files,
the results table. A robot-step is one control period of one robot, so a run of ``s``
steps is ``2 s`` robot-steps. Budget (issue 7): all seven on
2 local workers within 60 s on this 2-core machine.

``--serial`` also runs them in this process, for the speed-up of the pool. The machine is
noisy, so compare figures printed by one invocation: each study runs under every mode in
turn (pool, one process, Dask) before the next study starts, so a slow spell falls on all
modes alike rather than on whichever ran in it. ``--dask`` also runs them on a Dask
``LocalCluster`` of 2 worker processes with nannies, as users run one (needs
``hybridteam[dask]``; budget: at least 1.7x one process, as the pool is);
``HYBRIDTEAM_KEEP_MALLOC=1`` shows it without the workers' malloc fix
(:func:`hybridteam.sweep.worker.restore_malloc`). ``--all`` also runs ``all.yaml`` (the
seven factors as one study, one pool) and checks its table rows against the seven.
``--keep DIR`` leaves the output folders in DIR (for ``hybridteam report``).

    python benchmarks/study.py [--serial] [--dask] [--all] [--chunk K] [--keep DIR]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

from hybridteam.sweep import load_study, run_study
from hybridteam.sweep.plan import Plan
from hybridteam.sweep.table import collect_runs

LADDER = Path(__file__).resolve().parents[1] / "examples" / "ladder"
FACTORS = ("lookahead", "alpha", "kc", "orsp", "kr", "speed", "springs")
BUDGET_S = 60.0


def cpu_seconds() -> float:
    """CPU time of this process and its finished children (the pool's workers, once shut
    down): the work done, which other load on a noisy machine does not inflate."""
    me, kids = (resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def run_one(
    name: str, out: Path, workers: int | None, chunk: int | None, scheduler: str | None = None
) -> tuple[float, float, int, int, list[str]]:
    """Run one study into ``out/<name>``: (wall s, CPU s here and in finished children,
    runs, robot-steps, results rows)."""
    study = load_study(LADDER / f"{name}.yaml")  # loading is not timed: it checks files
    folder = out / name
    t0, c0 = time.perf_counter(), cpu_seconds()
    result = run_study(study, folder, workers=workers, chunk=chunk, scheduler=scheduler)
    seconds, cpu = time.perf_counter() - t0, cpu_seconds() - c0
    done = collect_runs(result.plan, folder)
    rows = (folder / "results.csv").read_text().splitlines()[1:]
    steps = 2 * int(sum(done["t_end"]))  # one step is one time unit
    return seconds, cpu, result.plan.runs, steps, rows


def report(label: str, wall: float, runs: int, steps: int, cpu: float | None) -> None:
    verdict = "within" if wall <= BUDGET_S else "OVER"
    print(
        f"{label}: {runs} runs in {wall:.2f} s — {runs / wall:,.0f} runs/s, "
        f"{steps / wall / 1e6:.2f} M robot-steps/s ({steps / 1e6:.1f} M robot-steps); "
        f"{verdict} the {BUDGET_S:.0f} s budget"
        + (f"; {cpu:.1f} s CPU in this process and the pool's" if cpu is not None else "")
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--serial", action="store_true", help="also run in this process")
    parser.add_argument("--all", action="store_true", help="also run all.yaml as one study")
    parser.add_argument(
        "--dask",
        action="store_true",
        help="also run on a Dask LocalCluster (2 workers with nannies)",
    )
    parser.add_argument(
        "--chunk", type=int, default=None, help="runs per chunk (default the studies' 500)"
    )
    parser.add_argument("--keep", type=Path, default=None, help="keep outputs in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp, ExitStack() as stack:
        out = args.keep or Path(tmp)
        total = sum(Plan(load_study(LADDER / f"{n}.yaml")).runs for n in FACTORS)
        print(f"seven studies of examples/ladder: {total} runs")
        # (label, output folder, workers, scheduler): every study runs under each in turn,
        # so a slow spell of this shared machine falls on all of them alike
        modes = [("2 workers", "workers2", 2, None)]
        if args.serial:
            modes.append(("1 process", "serial", 1, None))
        if args.dask:
            from dask.distributed import LocalCluster

            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
                )
            )
            modes.append(("Dask, 2 workers", "dask", None, cluster.scheduler_address))
            print("Dask: a LocalCluster of 2 worker processes with nannies")
        walls = {label: 0.0 for label, *_ in modes}
        cpus = {label: 0.0 for label, *_ in modes}
        runs = steps = 0
        rows: list[str] = []
        for name in FACTORS:
            line = []
            for label, folder, workers, scheduler in modes:
                wall, cpu, n, k, got = run_one(name, out / folder, workers, args.chunk, scheduler)
                walls[label] += wall
                cpus[label] += cpu
                line.append(f"{label} {wall:6.2f} s")
                if label == "2 workers":
                    runs, steps, rows = runs + n, steps + k, rows + got
                elif got != rows[-len(got) :]:
                    raise SystemExit(f"{name}: {label} gave other results than the pool")
            print(f"  {name:10s} {n:6d} runs: " + ", ".join(line), flush=True)
        for label, *_ in modes:  # (Dask's CPU is spent in its workers: not counted here)
            report(
                label, walls[label], runs, steps, None if label.startswith("Dask") else cpus[label]
            )
        wall2 = walls["2 workers"]
        if args.serial:
            print(f"pool speed-up: x{walls['1 process'] / wall2:.2f}")
        if args.dask:
            wall_d = walls["Dask, 2 workers"]
            print(
                f"Dask against the pool: x{wall2 / wall_d:.2f}"
                + (
                    f"; against one process: x{walls['1 process'] / wall_d:.2f} (budget "
                    f"1.7x: {'met' if walls['1 process'] / wall_d >= 1.7 else 'NOT met'})"
                    if args.serial
                    else ""
                )
            )
        if args.all:
            study = load_study(LADDER / "all.yaml")
            t0, c0 = time.perf_counter(), cpu_seconds()
            result = run_study(study, out / "all", workers=2, chunk=args.chunk)
            wall = time.perf_counter() - t0
            report("all.yaml, 2 workers", wall, result.plan.runs, steps, cpu_seconds() - c0)
            same = (out / "all" / "results.csv").read_text().splitlines()[1:] == rows
            print(f"all.yaml rows equal the seven studies' rows: {same}")


if __name__ == "__main__":
    main()

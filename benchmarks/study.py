"""Wall time of the ladder paper's Section 5 robustness study: seven factors, every run.

The seven study files of ``examples/ladder`` (lookahead, alpha, kc, orsp, kr, speed,
springs; population S of 100 pairs, ladder lengths 240..480) run one after the other, as
the README's loop runs them, through :func:`hybridteam.sweep.run_study` on a local process
pool — the whole path a user takes: planning, chunk tasks shipped to workers, the ladder's
vectorized stepper, chunk files, the results table. A robot-step is one control period of
one robot, so a run of ``s`` steps is ``2 s`` robot-steps. Budget (issue 7): all seven on
2 local workers within 60 s on this 2-core machine.

``--serial`` also runs them in this process, for the speed-up of the pool (the machine is
noisy: compare figures printed by one invocation). ``--dask`` also runs them on a Dask
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
    me, kids = (resource.getrusage(who) for who in (resource.RUSAGE_SELF,
                                                     resource.RUSAGE_CHILDREN))
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def run_all(names: list[str], out: Path, workers: int | None, chunk: int | None,
            scheduler: str | None = None) -> tuple[float, int, int, list[str]]:
    """Run the studies into ``out/<name>``; (wall s, runs, robot-steps, results rows)."""
    wall, runs, steps, rows = 0.0, 0, 0, []
    for name in names:
        study = load_study(LADDER / f"{name}.yaml")  # loading is not timed: it checks files
        folder = out / name
        t0, c0 = time.perf_counter(), cpu_seconds()
        result = run_study(study, folder, workers=workers, chunk=chunk, scheduler=scheduler)
        seconds, cpu = time.perf_counter() - t0, cpu_seconds() - c0
        done = collect_runs(result.plan, folder)
        wall += seconds
        runs += result.plan.runs
        steps += 2 * int(sum(done["t_end"]))  # one step is one time unit
        rows += (folder / "results.csv").read_text().splitlines()[1:]
        print(f"  {name:10s} {result.plan.runs:6d} runs in {len(result.plan.chunks):3d} chunks"
              f"  {seconds:6.2f} s wall, {cpu:6.2f} s CPU")
    return wall, runs, steps, rows


def report(label: str, wall: float, runs: int, steps: int, cpu: float | None) -> None:
    verdict = "within" if wall <= BUDGET_S else "OVER"
    print(f"{label}: {runs} runs in {wall:.2f} s — {runs / wall:,.0f} runs/s, "
          f"{steps / wall / 1e6:.2f} M robot-steps/s ({steps / 1e6:.1f} M robot-steps); "
          f"{verdict} the {BUDGET_S:.0f} s budget"
          + (f"; {cpu:.1f} s CPU in all" if cpu is not None else ""))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--serial", action="store_true", help="also run in this process")
    parser.add_argument("--all", action="store_true", help="also run all.yaml as one study")
    parser.add_argument("--dask", action="store_true",
                        help="also run on a Dask LocalCluster (2 workers with nannies)")
    parser.add_argument("--chunk", type=int, default=None, help="runs per chunk (default "
                        "the studies' 500)")
    parser.add_argument("--keep", type=Path, default=None, help="keep outputs in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp)
        total = sum(Plan(load_study(LADDER / f"{n}.yaml")).runs for n in FACTORS)
        print(f"seven studies of examples/ladder: {total} runs")
        print("2 local workers")
        c0 = cpu_seconds()
        wall2, runs, steps, rows = run_all(list(FACTORS), out / "workers2", 2, args.chunk)
        report("2 workers", wall2, runs, steps, cpu_seconds() - c0)
        if args.serial:
            print("in this process")
            c0 = cpu_seconds()
            wall1, *_ = run_all(list(FACTORS), out / "serial", 1, args.chunk)
            report("1 process", wall1, runs, steps, cpu_seconds() - c0)
            print(f"pool speed-up: x{wall1 / wall2:.2f}")
        if args.dask:
            from dask.distributed import LocalCluster

            print("Dask LocalCluster, 2 worker processes with nannies")
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
                wall_d, *_ = run_all(list(FACTORS), out / "dask", None, args.chunk,
                                     cluster.scheduler_address)
                report("Dask, 2 workers", wall_d, runs, steps, None)  # CPU: in the workers
            print(f"Dask against the pool: x{wall2 / wall_d:.2f}"
                  + (f"; against one process: x{wall1 / wall_d:.2f} (budget 1.7x: "
                     f"{'met' if wall1 / wall_d >= 1.7 else 'NOT met'})" if args.serial
                     else ""))
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

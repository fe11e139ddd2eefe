"""The ladder paper's Section 3 read several ways: the studies and the sample run under each.

Where Section 3 admits more than one reading, the ``ladder`` library has an option
(``Settings.correction``, ``Settings.update``; the ``ladder.corridor`` settings of the same
names). This script runs the study files that bear on the readings (5.6 speeds, 5.2 alpha,
5.3 k_c, 5.7 springs) on population S under each reading, and the Section 4 sample run,
and prints the tables that ``examples/ladder/README.md`` ("Readings of Section 3") quotes:

    python examples/ladder/readings.py -o out/readings            # every reading
    python examples/ladder/readings.py -o out/readings --only scaled distance

Each study goes to ``OUT/<reading>/<study>`` (a normal study folder: ``hybridteam report``
draws it), and ``OUT/readings.md`` collects the tables. About 25 s of CPU per reading and
study file on the vectorized stepper; finished studies are reused when run again.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from hybridteam.modes.ladder import Pairs, Settings, sample_run, simulate

from hybridteam.sweep import load_study, run_study

HERE = Path(__file__).resolve().parent

#: name -> (correction, update, ladder_margin: "about to collide" with the inner walls;
#: None keeps the team's 4)
READINGS = {
    "scaled": ("scaled", "synchronous", None),  # the printed formula (default)
    "distance": ("distance", "synchronous", None),
    "capped": ("capped", "synchronous", None),
    "front_first": ("scaled", "front_first", None),
    "rear_first": ("scaled", "rear_first", None),
    "margin_10": ("scaled", "synchronous", 10.0),
    "margin_15": ("scaled", "synchronous", 15.0),
    "margin_20": ("scaled", "synchronous", 20.0),
}
STUDIES = ("speed", "alpha", "kc", "springs", "lookahead", "orsp", "kr")

#: Section 4, Fig. 8: steps, corner steps, path R1, R2, corner path R1, R2.
PAPER = (855, 378, 1592.86, 1595.63, 640.975, 641.939)


def with_reading(study, correction: str, update: str, margin: float | None):
    """``study`` with its team's ``ladder.corridor`` set to the reading (and both robots'
    ``ladder_margin`` set for the whole population, if given)."""
    world = tuple(
        replace(w, values={**w.values, "correction": correction, "update": update})
        if w.use == "ladder.corridor"
        else w
        for w in study.team.world
    )
    fixed = study.fixed if margin is None else (*study.fixed, ("ladder_margin", margin))
    return replace(study, team=replace(study.team, world=world), fixed=fixed)


def study_table(rows: list[dict]) -> list[str]:
    """Markdown rows of a study's result rows: factor value, success per length, failures
    at the shortest and longest ladder, corner steps at the shortest."""
    lengths = sorted({float(r["ladder_length"]) for r in rows})
    values = list(dict.fromkeys(r["value"] for r in rows))
    out = [
        "| value | "
        + " | ".join(f"{x:g}" for x in lengths)
        + f" | failures {lengths[0]:g} | failures {lengths[-1]:g} | corner steps "
        f"{lengths[0]:g} |",
        "|---" * (len(lengths) + 4) + "|",
    ]
    for v in values:
        by = {float(r["ladder_length"]): r for r in rows if r["value"] == v}
        first, last = by[lengths[0]], by[lengths[-1]]
        out.append(
            f"| {v} | "
            + " | ".join(str(by[x]["success"]) for x in lengths)
            + f" | {first['stuck']} / {first['link_broken']}"
            f" | {last['stuck']} / {last['link_broken']}"
            f" | {first['mean_steps_in_corner']:.0f} |"
        )
    return out


def sample_row(name: str, correction: str, update: str, margin: float | None) -> str:
    scenario = sample_run()
    if margin is not None:
        scenario = replace(
            scenario,
            front=replace(scenario.front, ladder_margin=margin),
            rear=replace(scenario.rear, ladder_margin=margin),
        )
    r = simulate(Pairs.of(scenario), settings=Settings(correction=correction, update=update))
    ours = (r.steps[0], r.corner_steps[0], *r.path[0], *r.corner_path[0])
    dev = " | ".join(f"{100 * (o - p) / p:+.1f}" for o, p in zip(ours, PAPER, strict=True))
    return f"| {name} | {r.outcome_names[0]} | {dev} | {r.max_offset[0].max():.1f} |"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", required=True, help="output folder")
    ap.add_argument(
        "--only",
        nargs="+",
        choices=list(READINGS),
        default=list(READINGS),
        help="readings to run (default: all)",
    )
    ap.add_argument("--studies", nargs="+", choices=STUDIES, default=list(STUDIES))
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    out = Path(args.out)
    lines = [
        "# Section 3 readings",
        "",
        "## Sample run (deviation from the paper, %)",
        "",
        "| reading | outcome | steps | corner | path R1 | path R2 | corner R1 | "
        "corner R2 | largest offset |",
        "|---" * 9 + "|",
    ]
    lines += [sample_row(name, *READINGS[name]) for name in args.only]
    for study_name in args.studies:
        study = load_study(HERE / f"{study_name}.yaml")
        for name in args.only:
            folder = out / name / study_name
            print(f"{name}: {study_name} -> {folder}", file=sys.stderr, flush=True)
            done = run_study(
                with_reading(study, *READINGS[name]), folder, workers=args.workers, progress="auto"
            )
            lines += ["", f"## {study.name}, reading {name}", "", *study_table(done.table.rows)]
    out.mkdir(parents=True, exist_ok=True)
    (out / "readings.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())

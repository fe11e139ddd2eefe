"""Requirements: what checking costs, and how much a guided search saves.

1. Monitor cost (budget: under 20 % of the run's wall time): a 1000-instance ensemble of
   the thermostat (160 s each) with its shipped requirement, and with a second one that
   reads modes through a bounded window, and a 200-instance ensemble of the handover
   protocol with three requirements (roles, messages, distances), simulated with and
   without their requirements, best of five taken alternately, in this one
   invocation.
2. Guided against random search (budget: the guided search needs fewer simulations to its
   first violation, as the median over 10 search seeds), on two problems whose violating
   region is a small corner of the box:
   - thermostat: ``always(x <= 22.1)`` over high in [15, 22.15], K in [0.01, 0.5]
     (violated iff high > 22.1: 0.7 % of the box);
   - water tanks: ``always(x1 <= 4.3)`` over w in [0.5, 1], v1 and v2 in [0.3, 0.7]
     (about 0.5 % of the box: strong inflow, weak drains).

    python benchmarks/requirements.py [--seeds 10] [--budget 600]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import numpy as np

import hybridteam as ht
from hybridteam.falsify.evaluate import Evaluator
from hybridteam.falsify.search import Vary, run_search
from hybridteam.model import Requirement

ROOT = Path(__file__).resolve().parents[1]


def best_of(fn, k: int = 3) -> float:
    times = []
    for _ in range(k):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def interleaved(first, second, k: int = 5) -> tuple[float, float]:
    """Best of ``k`` for each, run alternately, so a slow spell of a noisy machine
    weighs on both sides alike."""
    a, b = [], []
    for _ in range(k):
        a.append(best_of(first, 1))
        b.append(best_of(second, 1))
    return min(a), min(b)


def with_requirements(team, **formulas: str):
    reqs = tuple(
        Requirement(name, text, None, ("requirements", name)) for name, text in formulas.items()
    )
    return dataclasses.replace(team, requirements=reqs)


def monitor_cost() -> None:
    print("1. monitor cost (same ensemble with and without requirements, best of 5, alternating)")
    thermo = ht.load(ROOT / "examples" / "automata" / "thermostat.yaml")
    plain = dataclasses.replace(thermo, requirements=())
    checked = with_requirements(
        plain,
        comfort="always(x >= 17.9 and x <= 22.1)",
        heats="always(eventually[0, 20](in_mode(Heat)))",
    )
    gains = {"thermostat.K": np.linspace(0.08, 0.12, 1000)}
    handover = ht.load(ROOT / "examples" / "protocols" / "handover.yaml")
    lead = with_requirements(
        handover,
        one_leader="always(count_in_role(lead) <= 1)",
        answered="always(implies(sent(labmate, request), "
        "eventually[0, 0.5](received(labmate, grant))))",
        gap="always(hypot(labmate.x - xr4000.x, labmate.y - xr4000.y) <= 1.5)",
    )
    cases = [
        ("thermostat, its comfort", plain, thermo, 1000, gains),
        ("thermostat, + heats", plain, checked, 1000, gains),
        ("handover, n = 200, 8 s", handover, lead, 200, None),
    ]
    for label, a, b, n, over in cases:
        t_plain, t_checked = interleaved(
            lambda a=a, n=n, over=over: ht.simulate(a, n=n, overrides=over),
            lambda b=b, n=n, over=over: ht.simulate(b, n=n, overrides=over),
        )
        extra = t_checked / t_plain - 1
        print(
            f"   {label:30s} without {t_plain:7.3f} s   with {t_checked:7.3f} s   "
            f"+{100 * extra:5.1f} %  (budget +20 %: {'met' if extra < 0.2 else 'MISSED'})"
        )


def problems():
    thermo = ht.load(ROOT / "examples" / "automata" / "thermostat.yaml")
    thermo = with_requirements(
        dataclasses.replace(thermo, requirements=()), upper="always(x <= 22.1)"
    )
    thermo = dataclasses.replace(
        thermo, simulation=dataclasses.replace(thermo.simulation, duration=40.0)
    )
    tanks = ht.load(ROOT / "examples" / "automata" / "water_tanks.yaml")
    tanks = with_requirements(tanks, full="always(x1 <= 4.3)")
    return [
        (
            "thermostat",
            thermo,
            "upper",
            [Vary("thermostat.high", 15.0, 22.15), Vary("thermostat.K", 0.01, 0.5)],
        ),
        (
            "water tanks",
            tanks,
            "full",
            [Vary("w", 0.5, 1.0), Vary("v1", 0.3, 0.7), Vary("v2", 0.3, 0.7)],
        ),
    ]


def guided_vs_random(seeds: int, budget: int) -> None:
    print(
        f"\n2. simulations to the first violation, median over {seeds} search seeds "
        f"(budget {budget}; a search that found nothing counts as {budget + 1})"
    )
    for label, team, req, varies in problems():
        ev = Evaluator(team, req, [v.key for v in varies])
        medians = {}
        for method in ("random", "de"):
            found = []
            start = time.perf_counter()
            for s in range(seeds):
                search = run_search(
                    varies, 1, 0, ev, budget=budget, method=method, population=20, search_seed=s
                )
                first = search.first_falsified()
                found.append(first if first is not None else budget + 1)
            medians[method] = statistics.median(found)
            print(
                f"   {label:12s} {method:6s}  median {medians[method]:6.1f}   "
                f"each: {found}   ({time.perf_counter() - start:.1f} s)"
            )
        ratio = medians["random"] / medians["de"]
        print(
            f"   {label:12s} guided needs {ratio:.1f}x fewer simulations than random "
            f"({'met' if medians['de'] < medians['random'] else 'MISSED'})"
        )


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--budget", type=int, default=600)
    args = ap.parse_args()
    monitor_cost()
    guided_vs_random(args.seeds, args.budget)

"""Robot-steps per second of the ladder stepper, against the scalar reference loop.

A robot-step is one control period of one robot (a pair-step is two). The population is
the paper's random set S (Sec. 4) with a ladder of 450; n = 1, 100 and 1000 pairs run in
one vectorized batch each, and the scalar reference (``reference.run``) runs a few of the
same pairs one by one. Also timed: the single Section 4 sample run. Budget (issue): at
least 1 M robot-steps/s at n = 1000 on this 2-core machine, and the sample run under
0.1 s; the sample through the engine (no requirements) within 2x the vectorized stepper,
the two timed in turn. The machine is noisy, so compare the ratios printed by one run;
each figure is the best of a few repeats.

    python benchmarks/ladder.py
"""

from __future__ import annotations

import time

import numpy as np
from hybridteam.modes.ladder import Pairs, random_pairs, reference, sample_run, simulate


def best_of(repeats: int, fn) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    pop = random_pairs(np.random.default_rng(2024), 1000, length=450.0)
    ref_pairs = 8
    ref_time, ref_steps = 0.0, 0
    for i in range(ref_pairs):
        seconds, res = best_of(2, lambda i=i: reference.run(pop.scenario(i)))
        ref_time += seconds
        ref_steps += 2 * int(res.steps[0])
    ref_rate = ref_steps / ref_time
    print(
        f"scalar reference     {ref_rate / 1e6:8.3f} M robot-steps/s ({ref_pairs} pairs one by one)"
    )
    for n, repeats in ((1, 3), (100, 3), (1000, 2)):
        batch = pop.take(slice(0, n))
        seconds, res = best_of(repeats, lambda batch=batch: simulate(batch))
        rate = 2 * int(res.steps.sum()) / seconds
        print(
            f"vectorized n = {n:5d} {rate / 1e6:8.3f} M robot-steps/s   "
            f"x{rate / ref_rate:6.2f} the reference   ({seconds:.3f} s, "
            f"{int(res.steps.max())} steps for the slowest pair)"
        )
    sample = Pairs.of(sample_run())
    seconds, res = best_of(5, lambda: simulate(sample))
    ref_seconds, _ = best_of(5, lambda: reference.run(sample_run()))
    print(
        f"sample run (Sec. 4)  {seconds * 1e3:8.1f} ms vectorized, {ref_seconds * 1e3:.1f} ms "
        f"reference ({int(res.steps[0])} steps)"
    )
    # the same run as a YAML team through the general engine (modes, events, world component)
    import tempfile
    from pathlib import Path

    from hybridteam.api import load, summaries

    sample_file = Path(__file__).resolve().parents[1] / "examples" / "ladder" / "sample.yaml"
    team = load(sample_file)
    eng_seconds, rows = best_of(3, lambda: summaries(team, 1, accelerate=False))
    # the engine alone: no requirements and no clearance series (which only they read)
    with tempfile.TemporaryDirectory() as tmp:
        bare_file = Path(tmp) / "sample.yaml"
        bare_file.write_text(_without_requirements(sample_file.read_text()))
        bare = load(bare_file)
    # the budget's ratio: the engine and the vectorized stepper timed in turn, best of 7
    # each, so a drift of the machine's speed between them does not enter it
    bare_seconds, vec_seconds = float("inf"), float("inf")
    for _ in range(7):
        bare_seconds = min(
            bare_seconds, best_of(1, lambda: summaries(bare, 1, accelerate=False))[0]
        )
        vec_seconds = min(vec_seconds, best_of(1, lambda: simulate(sample))[0])
    print(
        f"sample run, engine   {bare_seconds * 1e3:8.1f} ms ({rows[0]['steps']} steps; "
        f"x{bare_seconds / vec_seconds:.2f} the vectorized stepper's {vec_seconds * 1e3:.1f} "
        f"ms, timed in turn); with the sample's requirements checked "
        f"{eng_seconds * 1e3:.1f} ms"
    )


def _without_requirements(text: str) -> str:
    """The team file without its requirements: section and the corridor's clearance
    switch (the series only requirements read)."""
    out, skipping = [], False
    for line in text.splitlines(True):
        if line.startswith("requirements:"):
            skipping = True
        elif skipping and line[:1] not in (" ", "\n", "#"):
            skipping = False
        if not skipping and not line.strip().startswith("clearance:"):
            out.append(line)
    return "".join(out)


if __name__ == "__main__":
    main()

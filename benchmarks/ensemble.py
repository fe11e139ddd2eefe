"""Agent-steps per second for n = 1, 100, 1000 unicycles in a two-mode model.

Each instance is one unicycle whose sampled law (10 Hz, zero-order hold) alternates
between driving a left and a right arc every 2 s (``after:``) and switches to a slow mode
when it leaves a disc (a continuous guard on the exact arc). An agent-step is one control
period of one agent. Budget (issue 2): at n = 1000 the cost per instance at least 50x lower
than at n = 1, and at least 2 M agent-steps/s on this 2-core machine. Budget (single-run
speed issue): at most 40 µs per agent-step at n = 1, at least 3 M agent-steps/s at n = 1000.
Budget (issue 48): at least 6 M agent-steps/s at n = 1000.

With ``--base PATH`` (the source tree of an older commit, e.g. ``git archive REV | tar -x
-C PATH``) the same runs also time under that code, each tree in processes of its own
(``benchmarks/teams.py``'s import of a base tree), alternating between the two (ABBA) for
``--repeats`` rounds; each figure is the best over the rounds, and the speed-ups are ratios
measured on one machine in one invocation.

    python benchmarks/ensemble.py [--base PATH] [--repeats N]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import hybridteam as ht
from hybridteam.io.loader import load_team

MODEL = """
team: weave
agents:
  robot:
    plant:
      kind: unicycle
      state: {x: 0.0, y: 0.0, theta: 0.0}
      limits: {v: [-1.0, 1.0], omega: [-1.5, 1.5]}
    parameters: {speed: 0.5, turn: 0.8, radius: 6.0}
    initial: Left
    modes:
      Left:
        inputs: {v: speed, omega: turn}
        period: 0.1
        transitions:
          - {to: Right, after: 2.0}
          - {to: Slow, guard: x*x + y*y >= radius*radius}
      Right:
        inputs: {v: speed, omega: -turn}
        period: 0.1
        transitions:
          - {to: Left, after: 2.0}
          - {to: Slow, guard: x*x + y*y >= radius*radius}
      Slow:
        inputs: {v: 0.2 * speed, omega: 0.0}
        period: 0.1
simulation: {duration: 100.0, sample_period: 1.0}
"""

DURATION = 100.0
PERIOD = 0.1
SIZES = (1, 100, 1000)

#: Run in a child process: the timings of :func:`timings` under the tree ``sys.argv[1]``
#: ('' for this venv's install), imported as ``benchmarks/teams.py`` imports one.
CHILD = """
sys.path.insert(0, {here!r})
import ensemble
print(json.dumps(ensemble.timings(ht.load(sys.argv[3]))))
"""


def overrides(n: int) -> dict[str, np.ndarray]:
    """The ensemble's varied parameters: each instance its own speed and turn rate."""
    rng = np.random.default_rng(0)
    return {"robot.speed": rng.uniform(0.3, 0.8, n), "robot.turn": rng.uniform(0.4, 1.2, n)}


def timings(team: ht.Team) -> dict[str, list[float]]:
    """``{n: [best wall time (s), transitions]}`` for each ensemble size, best of a few runs."""
    # one short run first: the first run of a process pays one-time costs (lazy imports,
    # caches), and n = 1 is timed first; its runs are short, so it takes the best of more
    ht.simulate(team, duration=10.0)
    out = {}
    for n in SIZES:
        best = float("inf")
        for _ in range(2 if n > 1 else 7):
            t0 = time.perf_counter()
            run = ht.simulate(team, n=n, duration=DURATION, overrides=overrides(n))
            best = min(best, time.perf_counter() - t0)
        out[str(n)] = [best, float(len(run.transitions))]
    return out


def timed(base: str, path: Path) -> dict[str, list[float]]:
    """:func:`timings` under ``base`` ('' for this tree's code), in a process of its own."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from teams import TIMER  # (its import of a base tree, written once)

    prelude = TIMER.split("out = {}")[0]
    code = prelude + CHILD.format(here=str(Path(__file__).resolve().parent))
    done = subprocess.run(
        [sys.executable, "-c", code, base, "1", str(path)],
        check=True,
        text=True,
        capture_output=True,
        cwd="/",
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def report(rows: dict[str, list[float]], before: dict[str, list[float]] | None) -> None:
    """Print the table and the budgets (with the base's figures and speed-ups if given)."""
    steps = {n: n * DURATION / PERIOD for n in SIZES}
    base_per = rows["1"][0]
    head = (
        f"{'n':>6}{'wall (s)':>10}{'agent-steps/s':>16}{'s per instance':>16}"
        f"{'per-instance gain':>19}{'transitions':>13}"
    )
    print(head + (f"{'base steps/s':>14}{'speed-up':>10}" if before else ""))
    for n in SIZES:
        wall, ntr = rows[str(n)]
        line = (
            f"{n:>6}{wall:>10.3f}{steps[n] / wall:>16,.0f}{wall / n:>16.5f}"
            f"{base_per / (wall / n):>18.1f}x{int(ntr):>13}"
        )
        if before:
            old = before[str(n)][0]
            line += f"{steps[n] / old:>14,.0f}{old / wall:>9.2f}x"
        print(line)
    wall = rows["1000"][0]
    rate, gain = steps[1000] / wall, base_per / (wall / 1000)
    one = 1e6 * base_per / steps[1]
    print(
        f"\nbudget: per-instance gain at n=1000 >= 50x -> {gain:.1f}x "
        f"({'met' if gain >= 50 else 'NOT met'}); "
        f">= 2 M agent-steps/s -> {rate / 1e6:.2f} M ({'met' if rate >= 2e6 else 'NOT met'})"
    )
    print(
        f"budget: n=1 <= 40 µs per agent-step -> {one:.0f} µs "
        f"({'met' if one <= 40 else 'NOT met'}); n=1000 >= 3 M agent-steps/s -> "
        f"{rate / 1e6:.2f} M ({'met' if rate >= 3e6 else 'NOT met'}); "
        f">= 6 M -> {'met' if rate >= 6e6 else 'NOT met'}"
    )
    if before:
        print(
            f"base: n=1 {1e6 * before['1'][0] / steps[1]:.0f} µs per agent-step, "
            f"n=1000 {steps[1000] / before['1000'][0] / 1e6:.2f} M agent-steps/s"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", metavar="PATH", help="also time the source tree at PATH")
    ap.add_argument("--repeats", type=int, default=5, help="rounds with --base (default 5)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "weave.yaml"
        path.write_text(MODEL)
        if not args.base:
            report(timings(load_team(path)), None)
            return
        base = str(Path(args.base).resolve())
        now: dict[str, list[float]] = {}
        before: dict[str, list[float]] = {}
        for k in range(args.repeats):  # alternated, ABBA (see transport.py)
            pair = [(now, ""), (before, base)]
            for kept, tree in pair[::-1] if k % 2 else pair:
                for n, (wall, ntr) in timed(tree, path).items():
                    if n not in kept or wall < kept[n][0]:
                        kept[n] = [wall, ntr]
    report(now, before)


if __name__ == "__main__":
    main()

"""Event-time error and wall time: hybridteam vs scipy's solve_ivp, at matched accuracy.

For the bouncing ball (20 impacts) and the hysteresis thermostat (50 switches), run
hybridteam at its default settings, then solve_ivp with events (RK45 and DOP853, restarted
at each event as hybrid systems require) over a ladder of tolerances, and compare against
the cheapest solve_ivp configuration that is at least as accurate as hybridteam. The ratio
judged is from hybridteam and every matched configuration timed in turn (best of several
rounds each, against the fastest of them): the table's timings are seconds apart, and a
noisy machine drifts between them.
Budgets: issue 2 asked for no slower than solve_ivp at the same accuracy (ratio <= 1); the
single-run speed issue for within 3x. The engine is timed from a loaded team, as solve_ivp
from its defined right-hand side: reading and checking the YAML file is timed apart.

The thermostat's shipped requirement is left out of every timed run: this measures the
engine against an integrator, and checking requirements is not the integrator's work.

    python benchmarks/automata.py
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import hybridteam as ht

ROOT = Path(__file__).resolve().parents[1]


def load(name: str) -> ht.Team:
    """An example of ``examples/automata`` without its requirements."""
    return dataclasses.replace(ht.load(ROOT / "examples" / "automata" / name), requirements=())


G, E, H0 = 9.81, 0.7, 1.0
K = 0.1


def ball_exact(k: int) -> np.ndarray:
    v1 = math.sqrt(2 * G * H0)
    t = [math.sqrt(2 * H0 / G)]
    for j in range(1, k):
        t.append(t[-1] + 2 * E**j * v1 / G)
    return np.array(t)


def thermostat_exact(k: int) -> np.ndarray:
    t = [math.log(11 / 8) / K]
    for j in range(1, k):
        t.append(t[-1] + (math.log(22 / 18) if j % 2 else math.log(12 / 8)) / K)
    return np.array(t)


#: rounds of hybridteam and the fastest matched solve_ivp timed in turn, for the ratio
INTERLEAVED = 9


def best_of(fn, repeat: int = 3) -> tuple[float, np.ndarray]:
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out  # type: ignore[return-value]


def scipy_ball(method: str, rtol: float, k: int = 20) -> np.ndarray:
    def f(t, y):
        return [y[1], -G]

    def hit(t, y):
        return y[0]

    hit.terminal, hit.direction = True, -1
    t, y, out = 0.0, [H0, 0.0], []
    while len(out) < k:
        sol = solve_ivp(f, (t, 10.0), y, method=method, events=hit, rtol=rtol, atol=rtol * 1e-2)
        t = float(sol.t_events[0][0])
        ye = sol.y_events[0][0]
        out.append(t)
        y = [0.0, -E * ye[1]]
    return np.array(out)


def scipy_thermostat(method: str, rtol: float, k: int = 50) -> np.ndarray:
    heat = [True]

    def f(t, y):
        return [K * (30 - y[0])] if heat[0] else [-K * y[0]]

    def up(t, y):
        return y[0] - 22

    def down(t, y):
        return y[0] - 18

    up.terminal, up.direction = True, 1
    down.terminal, down.direction = True, -1
    t, y, out = 0.0, [19.0], []
    while len(out) < k:
        ev = up if heat[0] else down
        sol = solve_ivp(f, (t, 1e3), y, method=method, events=ev, rtol=rtol, atol=rtol * 1e-2)
        t = float(sol.t_events[0][0])
        y = [float(sol.y_events[0][0][0])]
        out.append(t)
        heat[0] = not heat[0]
    return np.array(out)


def ours(team: ht.Team, k: int, duration: float) -> np.ndarray:
    run = ht.simulate(team, duration=duration)
    tr = run.transitions
    return tr["t"][tr["cause"] != "init"][:k]


def loaded(path: str) -> ht.Team:
    """The example, loaded once; prints how long loading took (not in the comparison)."""
    t0 = time.perf_counter()
    team = load(path)
    print(
        f"\n{path}: loaded and checked in {1e3 * (time.perf_counter() - t0):.1f} ms "
        "(not counted below)"
    )
    return team


def compare(name: str, exact: np.ndarray, our_fn, scipy_fn) -> float:
    t_ours, got = best_of(our_fn)
    err_ours = float(np.max(np.abs(got - exact)))
    print(f"\n{name}: {len(exact)} events")
    print(f"  {'method':<22}{'rtol':>8}{'max |dt| (s)':>16}{'wall (ms)':>12}")
    print(f"  {'hybridteam (default)':<22}{'1e-10':>8}{err_ours:>16.2e}{1e3 * t_ours:>12.1f}")
    matched, configs = math.inf, []
    for method in ("RK45", "DOP853"):
        for rtol in (1e-6, 1e-8, 1e-10, 1e-12, 1e-13):
            wall, got_s = best_of(lambda m=method, r=rtol: scipy_fn(m, r))
            err = float(np.max(np.abs(got_s - exact)))
            mark = ""
            if err <= err_ours:
                matched = min(matched, wall)
                configs.append((method, rtol))
                mark = "  <= our error"
            print(f"  {'solve_ivp ' + method:<22}{rtol:>8.0e}{err:>16.2e}{1e3 * wall:>12.1f}{mark}")
    if not configs:
        print("  no solve_ivp configuration reached hybridteam's accuracy (ratio: n/a)")
        return 0.0
    print(f"  ratio to the fastest matched, from the table: {t_ours / matched:.2f}")
    # the table's timings are seconds apart, and this machine's speed drifts by 2x within a
    # minute: the ratio judged is from hybridteam and every matched configuration timed in
    # turn, best of each, against the fastest of them
    ours_best, theirs = math.inf, dict.fromkeys(configs, math.inf)
    for _ in range(INTERLEAVED):
        ours_best = min(ours_best, best_of(our_fn, 1)[0])
        for c in configs:
            theirs[c] = min(theirs[c], best_of(lambda c=c: scipy_fn(*c), 1)[0])
    (method, rtol), best = min(theirs.items(), key=lambda kv: kv[1])
    ratio = ours_best / best
    print(
        f"  ratio hybridteam / fastest matched solve_ivp ({method} rtol={rtol:.0e}), timed "
        f"in turn, best of {INTERLEAVED} each ({1e3 * ours_best:.1f} / {1e3 * best:.1f} ms): "
        f"{ratio:.2f} (budget 3: {'met' if ratio <= 3 else 'NOT met'}; issue 2's 1: "
        f"{'met' if ratio <= 1 else 'NOT met'})"
    )
    return ratio


def ensemble_table(n: int = 100) -> None:
    """n thermostats with different K: one hybridteam ensemble vs n solve_ivp runs."""
    global K
    team = load("thermostat.yaml")
    gains = np.linspace(0.08, 0.12, n)
    t0 = time.perf_counter()
    run = ht.simulate(
        team, n=n, duration=151.0 * 0.1 / gains.min(), overrides={"thermostat.K": gains}
    )
    ours = time.perf_counter() - t0
    keep = K
    errs_ours = []
    t0 = time.perf_counter()
    for i, k in enumerate(gains):
        K = float(k)
        exact = thermostat_exact(50)
        tr = run.instance(i).transitions
        got = tr["t"][tr["cause"] != "init"][:50]
        errs_ours.append(np.max(np.abs(got - exact[: len(got)])))
    check = time.perf_counter() - t0
    print(f"\nensemble: {n} thermostats (K from 0.08 to 0.12), 50 switches each")
    print(
        f"  hybridteam, one ensemble call        {1e3 * ours:9.1f} ms   max |dt| "
        f"{max(errs_ours):.2e}"
    )
    for rtol in (1e-10, 1e-12):
        errs_scipy = []
        t0 = time.perf_counter()
        for k in gains:
            K = float(k)
            errs_scipy.append(
                np.max(np.abs(scipy_thermostat("DOP853", rtol) - thermostat_exact(50)))
            )
        theirs = time.perf_counter() - t0
        print(
            f"  solve_ivp DOP853 rtol={rtol:.0e}, loop {1e3 * theirs:9.1f} ms   max |dt| "
            f"{max(errs_scipy):.2e}   ratio hybridteam/solve_ivp {ours / theirs:.2f}"
        )
    K = keep
    print(f"  (checking the ensemble's answers took {1e3 * check:.0f} ms, not counted)")


def ball_to_zeno() -> None:
    """Issue 2: run to t = 5 s ends zeno near 2.558633965586 s within a second of wall time."""
    team = load("bouncing_ball.yaml")
    wall, run = best_of(lambda: ht.simulate(team, duration=5.0))
    t = run.diagnostics[0]["t"]
    print(
        f"\nbouncing ball to t=5 s: outcome {run.outcome} at t={t:.12f} "
        f"(Zeno time 2.558633965586, off by {abs(t - 2.558633965586):.1e} s), "
        f"{len(run.transitions)} transitions, wall {wall:.3f} s (budget 1 s)"
    )


if __name__ == "__main__":
    ball_to_zeno()
    ball = loaded("bouncing_ball.yaml")
    compare(
        "bouncing ball",
        ball_exact(20),
        lambda: ours(ball, 20, ball_exact(20)[-1] + 1e-4),
        scipy_ball,
    )
    thermostat = loaded("thermostat.yaml")
    compare(
        "thermostat", thermostat_exact(50), lambda: ours(thermostat, 50, 151.0), scipy_thermostat
    )
    ensemble_table(100)

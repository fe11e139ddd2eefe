"""Experiment 2 over a lossy network: success rate and completion time, one ensemble call.

Every message (data copies and acknowledged control messages alike) is lost with
probability ``p_loss``. A run succeeds when it ends ``success`` (the Labmate finished its
plan: its final Stop ends the run by the team's end rule; a run whose robots deadlocked and
handed command to the operator ends ``ok`` at the duration instead) and the leadership went
as in the paper — the XR4000 takes it at the obstacle and hands it back; the completion
time is when the run ended. All levels and repetitions are one ensemble of the engine
(instances differ in ``p_loss`` and seed only).

    python examples/transport/loss_sweep.py [--runs 20] [--levels 0 0.1 0.2 0.3 0.4 0.5]
                                            [--retries N]

``--retries`` sets both robots' ``ack_retries`` (the role-assignment protocol's resends
before a control message is reported undeliverable, default 3).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hybridteam.api import load, simulate

TEAM = Path(__file__).with_name("experiment2.yaml")


def completed(run, i: int) -> tuple[bool, float]:
    """(ended in success with the leadership as in the paper, the time the run ended)."""
    one = run.instance(i)
    tr = one.transitions
    rows = list(zip(tr["t"], tr["agent"], tr["source"], tr["target"], strict=True))
    leads = [
        a
        for _t, a, src, tg in rows  # who takes the lead, in order
        if tg.startswith("Transport.Lead") and not src.startswith("Transport.Lead")
    ]
    took_back = "xr4000" in leads and leads[-1] == "labmate"
    row = one.summary()["instances"][0]
    return row["outcome"] == "success" and took_back, row["t_end"]


def operator_took_over(run, i: int) -> bool:
    """Whether a robot gave up on an unacknowledged control message and the operator took
    command (the protocol's deadlock handling: a safe stop, not a success)."""
    tr = run.instance(i).transitions
    return bool(
        np.any((np.asarray(tr["agent"]) == "operator") & (np.asarray(tr["target"]) == "Command"))
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="repetitions per loss level")
    ap.add_argument("--levels", type=float, nargs="+", default=[0, 0.1, 0.2, 0.3, 0.4, 0.5])
    ap.add_argument(
        "--retries",
        type=int,
        default=None,
        help="the robots' ack_retries (default: the protocol's 3)",
    )
    args = ap.parse_args()
    team = load(TEAM)
    loss = np.repeat(args.levels, args.runs)
    seeds = list(range(len(loss)))
    overrides: dict = {"p_loss": loss}
    if args.retries is not None:
        overrides |= {f"{robot}.ack_retries": args.retries for robot in ("xr4000", "labmate")}
    start = time.perf_counter()
    run = simulate(team, seed=seeds, n=len(loss), overrides=overrides)
    wall = time.perf_counter() - start
    retries = "" if args.retries is None else f", ack_retries {args.retries}"
    print(f"{len(loss)} runs of {TEAM.name}{retries} in one ensemble: {wall:.1f} s wall\n")
    print(
        "| message loss | runs | success | mean completion time (s) | outcomes | "
        "operator took over |"
    )
    print("|---:|---:|---:|---:|---|---:|")
    for p in args.levels:
        idx = np.flatnonzero(loss == p)
        done = [completed(run, int(i)) for i in idx]
        outcomes = [run.outcomes[int(i)] for i in idx]
        success = [d[0] for d in done]
        times = [d[1] for d in done if d[0]]
        counts = {o: outcomes.count(o) for o in sorted(set(outcomes))}
        mean = f"{np.mean(times):.2f}" if times else "—"
        operated = sum(operator_took_over(run, int(i)) for i in idx)
        print(
            f"| {p:.0%} | {len(idx)} | {sum(success) / len(idx):.0%} | {mean} "
            f"| {', '.join(f'{k} {v}' for k, v in counts.items())} | {operated} |"
        )


if __name__ == "__main__":
    main()

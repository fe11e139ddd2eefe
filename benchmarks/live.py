"""A live team's cost and timeliness: CPU per agent, reaction to arrivals, clock jitter.

Launches a team with ``hybridteam launch`` (one process per agent over loopback UDP, at the
wall clock's own pace unless ``--time-scale`` says otherwise) and prints what each process
recorded of its run (``meta.live``): CPU seconds over wall seconds of the run (start-up
excluded), the wall time from the arrival of a datagram that can change a mode (a message
that is no stream's copy, an event the world process raises) to the end of the step that
handled it (its mode change, when it causes one; a stream's copy changes no mode and is not
counted: it may wait for a tick's world answer, docs/live.md), and how late each instant the
loop slept for was taken (the jitter of a control period). For a team with world components
(e.g. ``examples/transport/experiment2.yaml``) each agent's process also says how long the
world process's answers to its ticks' poses took (p99) and how many ticks read an older
reading because the answer came late (docs/live.md, *What a law reads*); the world process's
row is ``@world``, apart from the agents' budgets (it stands in for the robots' physics).
The default team is the protocol handover example (20 Hz laws and streams, the role
protocol, an operator). Budgets (issue 44): per-agent CPU at most 5 % of one core; arrival
to mode change p99 at most 5 ms; control-period jitter p99 at most 2 ms. A loaded machine
(other processes on its cores) misses them for reasons not of this code: run it on a quiet
one.

    python benchmarks/live.py [TEAM.yaml] [--time-scale K]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEAM = ROOT / "examples" / "protocols" / "handover.yaml"
CPU, REACTION, JITTER = 5.0, 5.0, 2.0  # %, ms, ms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("team", nargs="?", default=str(TEAM))
    parser.add_argument("--time-scale", type=float, default=1.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [
                sys.executable,
                "-m",
                "hybridteam.cli",
                "launch",
                args.team,
                "--time-scale",
                repr(args.time_scale),
                "--log-level",
                "warning",
                "-o",
                tmp,
            ],
            check=True,
        )
        merged = json.loads((Path(tmp) / "trace.json").read_text())
    print(
        f"{Path(args.team).name}, time scale {args.time_scale:g}: "
        f"{merged['outcomes'][0]['outcome']}"
    )
    print(
        f"  {'agent':<12}{'CPU %':>8}{'reaction p99 ms':>17}{'(n)':>7}"
        f"{'jitter p99 ms':>15}{'(n)':>7}{'answer p99 ms':>15}{'late':>7}"
    )
    worst = [0.0, 0.0, 0.0]
    for p in merged["meta"]["live"]["processes"]:
        cpu = 100 * p["cpu_s"] / p["wall_s"]
        reaction, late = p["reaction_ms"], p["late_ms"]
        answer = (
            f"{p['world_answer_ms'].get('p99', 0):15.3f}{p['world_late']:7d}"
            if "world_answer_ms" in p
            else ""
        )
        print(
            f"  {', '.join(p['agents']) or '@world':<12}{cpu:8.2f}"
            f"{reaction.get('p99', 0):17.3f}{reaction['count']:7d}"
            f"{late.get('p99', 0):15.3f}{late['count']:7d}{answer}"
        )
        if p.get("world"):
            continue
        worst = [
            max(worst[0], cpu),
            max(worst[1], reaction.get("p99", 0)),
            max(worst[2], late.get("p99", 0)),
        ]
    for what, value, budget, unit in (
        ("CPU per agent", worst[0], CPU, "%"),
        ("arrival to mode change p99", worst[1], REACTION, "ms"),
        ("control-period jitter p99", worst[2], JITTER, "ms"),
    ):
        verdict = "met" if value <= budget else "NOT met"
        print(
            f"budget: {what} <= {budget:g} {unit} -> {value:.3g} {unit} ({verdict}; the "
            "agents' processes)"
        )


if __name__ == "__main__":
    main()

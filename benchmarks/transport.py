"""Single runs of the architecture paper's three experiments: wall time and real-time factor.

Most runs a user makes are single runs while editing a team, so this is the engine's
per-step cost as a user meets it. Each experiment runs once in this process (best of
``--repeats``); with ``--before REV`` the same experiment files also run under the code of
commit REV, installed into a virtual environment of its own (cached under
``.benchmarks/``), in the same invocation, so the speed-up is a ratio on one noisy machine;
the repeats alternate between the two codes, so a slow spell falls on both alike.
Budget (single-run speed issue): experiment 2 at least 4x faster than the commit before the
issue and at least 40x faster than real time.

The engine is timed on copies of the experiments without their ``requirements_from:``
line (older commits do not know it, and checking requirements is not the engine's
per-step cost); a last column times the files as shipped, requirements checked.

    python benchmarks/transport.py [--before REV] [--repeats N] [--only experiment2]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "transport"
NAMES = ("experiment1", "experiment2", "experiment3")

#: Run in the other interpreter: times each file given, prints JSON {name: [wall, t_end]}.
TIMER = """
import json, sys, time
import hybridteam as ht
out = {}
for path in sys.argv[2:]:
    team = ht.load(path)
    ht.simulate(team, duration=1.0)  # warm: each repeat is a process of its own
    best, t_end = float("inf"), 0.0
    for _ in range(int(sys.argv[1])):
        t0 = time.perf_counter()
        run = ht.simulate(team)
        best = min(best, time.perf_counter() - t0)
        t_end = run.summary()["instances"][0]["t_end"]
    out[path] = [best, t_end]
print(json.dumps(out))
"""


def interpreter_for(rev: str) -> Path:
    """A virtual environment with hybridteam as of ``rev`` installed (built once)."""
    sha = subprocess.run(
        ["git", "rev-parse", rev], cwd=ROOT, check=True, text=True, capture_output=True
    ).stdout.strip()
    home = ROOT / ".benchmarks" / f"hybridteam-{sha[:12]}"
    python = home / "venv" / "bin" / "python"
    if python.exists():
        return python
    print(f"building a venv for {rev} ({sha[:12]}) in {home} ...", file=sys.stderr)
    tree = home / "tree"
    subprocess.run(
        ["git", "worktree", "add", "--detach", "-f", str(tree), sha],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    venv.create(home / "venv", with_pip=True)
    subprocess.run([str(python), "-m", "pip", "install", "-q", str(tree)], check=True, cwd=home)
    return python


def timed(python: str, files: list[Path], repeats: int) -> dict[str, list[float]]:
    done = subprocess.run(
        [python, "-c", TIMER, str(repeats), *map(str, files)],
        check=True,
        text=True,
        capture_output=True,
        cwd="/",
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def best_of(best: dict[str, list[float]], new: dict[str, list[float]]) -> None:
    """Keep the faster of two timings of each file."""
    for path, (wall, t_end) in new.items():
        if path not in best or wall < best[path][0]:
            best[path] = [wall, t_end]


def engine_only(folder: Path) -> Path:
    """A copy of the experiments' folder whose team files include no requirements."""
    copy = Path(shutil.copytree(EXAMPLES, folder / "transport"))
    for path in copy.glob("experiment*.yaml"):
        lines = path.read_text().splitlines(keepends=True)
        path.write_text("".join(x for x in lines if not x.startswith("requirements_from:")))
    return copy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", metavar="REV", help="also time the code of this commit")
    ap.add_argument("--repeats", type=int, default=1, help="best of N runs (default 1)")
    ap.add_argument("--only", choices=NAMES, action="append", help="experiments to run")
    args = ap.parse_args()
    names = args.only or NAMES
    with tempfile.TemporaryDirectory() as tmp:
        plain = engine_only(Path(tmp))
        files = [plain / f"{name}.yaml" for name in names]
        older = str(interpreter_for(args.before)) if args.before else None
        now: dict[str, list[float]] = {}
        before: dict[str, list[float]] = {}
        # alternated, so a slow spell falls on both alike, and in ABBA order: on this
        # machine the second process of a pair runs faster than the first
        for k in range(args.repeats):
            pair = [(now, sys.executable)] + ([(before, older)] if older else [])
            for kept, python in pair[::-1] if k % 2 else pair:
                best_of(kept, timed(python, files, 1))
    shipped = timed(sys.executable, [EXAMPLES / f"{name}.yaml" for name in names], args.repeats)
    head = f"{'experiment':<13}{'simulated (s)':>14}{'wall (s)':>10}{'x real time':>13}"
    if before:
        head += f"{'wall before':>13}{'speed-up':>10}"
    print(head + f"{'with requirements (s)':>23}")
    for path in files:
        wall, t_end = now[str(path)]
        line = f"{path.stem:<13}{t_end:>14.2f}{wall:>10.2f}{t_end / wall:>13.1f}"
        if before:
            old = before[str(path)][0]
            line += f"{old:>13.2f}{old / wall:>9.2f}x"
        print(line + f"{shipped[str(EXAMPLES / path.name)][0]:>23.2f}")
    if "experiment2" in names:
        path = str(plain / "experiment2.yaml")
        wall, t_end = now[path]
        verdict = [
            f"experiment 2 at {t_end / wall:.1f}x real time (budget 40x: "
            f"{'met' if t_end / wall >= 40 else 'NOT met'})"
        ]
        if before:
            gain = before[path][0] / wall
            verdict.append(
                f"{gain:.2f}x faster than {args.before} (budget 4x: "
                f"{'met' if gain >= 4 else 'NOT met'})"
            )
        print("\nbudget: " + "; ".join(verdict))


if __name__ == "__main__":
    main()

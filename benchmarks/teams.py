"""Single runs of realistic teams: the transport experiments and a jittered doorway team.

The engine's cost per simulated second grows with what a team holds (range rings,
carried payloads, obstacles) and with how many instants its network makes: jitter makes
every copy's arrival an instant of its own. This times, best of ``--repeats``, the three
experiments of ``benchmarks/transport.py``, the doorway team of ``examples/doorway`` (three
robots carry a beam through a door; 10 ms jitter, 20 % loss) and its twin without jitter,
and prints each one's real-time factor and the jittered / jitter-free wall-time ratio.
Budget (issue 48): a jittered team costs at most 1.3x its jitter-free twin.

With ``--base PATH`` (the source tree of an older commit, e.g. ``git archive REV | tar -x
-C PATH``) the same team files also run under that code, in this interpreter with ``PATH``
first on its import path, in the same invocation: the repeats alternate between the two
codes (ABBA, as ``transport.py`` does), and the speed-ups are ratios on one machine.

With ``--profile NAME`` it profiles that team instead (cProfile, one run after a warm-up,
under each tree): its instants, Python calls per instant, the top functions by own time,
and the world components' share — the profile that says where an instant's cost goes.

    python benchmarks/teams.py [--base PATH] [--repeats N] [--only doorway]
    python benchmarks/teams.py --profile experiment3 [--base PATH]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from transport import best_of, engine_only

ROOT = Path(__file__).resolve().parents[1]
DOORWAY = ROOT / "examples" / "doorway" / "beam.yaml"
NAMES = ("experiment1", "experiment2", "experiment3", "doorway", "doorway_no_jitter")

#: Run in a child process: with a base tree, imports hybridteam (and its mode libraries)
#: from there rather than from this venv's editable install; then as transport.py's timer.
TIMER = """
import json, sys, time
base = sys.argv[1]
if base:
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f)]
    sys.path.insert(0, base)
import hybridteam as ht
if base:  # modes/ and protocols/ are shipped inside the package (see pyproject.toml)
    import importlib.util
    for sub in ("modes", "protocols"):
        spec = importlib.util.spec_from_file_location(
            f"hybridteam.{sub}", f"{base}/{sub}/__init__.py",
            submodule_search_locations=[f"{base}/{sub}"])
        sys.modules[spec.name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[spec.name])
assert not base or ht.__file__.startswith(base), ht.__file__
out = {}
for path in sys.argv[3:]:
    team = ht.load(path)
    ht.simulate(team, duration=1.0)  # warm
    best, t_end = float("inf"), 0.0
    for _ in range(int(sys.argv[2])):
        t0 = time.perf_counter()
        run = ht.simulate(team)
        best = min(best, time.perf_counter() - t0)
        t_end = run.summary()["instances"][0]["t_end"]
    out[path] = [best, t_end]
print(json.dumps(out))
"""

#: The timer's imports, then one profiled run of the team file ``sys.argv[3]``.
PROFILER = (
    TIMER.split("out = {}")[0]
    + """
import cProfile, io, pstats
team = ht.load(sys.argv[3])
ht.simulate(team, duration=1.0)  # warm
profile = cProfile.Profile()
profile.enable()
run = ht.simulate(team)
profile.disable()
stats = pstats.Stats(profile)
instants = sum(v[1] for k, v in stats.stats.items() if k[2] == "_instant")
calls = sum(v[1] for v in stats.stats.values())
world = max(
    (v[3] for k, v in stats.stats.items() if k[0].endswith("run/world.py") and k[2] == "update"),
    default=0.0,
)
print(f"t_end {run.summary()['instances'][0]['t_end']:.2f} s; {instants} instants; "
      f"{calls / instants:.0f} calls per instant; {stats.total_tt:.2f} s profiled, "
      f"the world components' update {world:.2f} s ({world / stats.total_tt:.0%})")
text = io.StringIO()
pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(12)
print(chr(10).join(x for x in text.getvalue().splitlines() if "(" in x or "ncalls" in x))
"""
)


def timed(base: str, files: list[Path], repeats: int) -> dict[str, list[float]]:
    """Best-of-``repeats`` wall time and end time of each file, under ``base`` ('' for this
    tree's code), in a process of its own."""
    done = subprocess.run(
        [sys.executable, "-c", TIMER, base, str(repeats), *map(str, files)],
        check=True,
        text=True,
        capture_output=True,
        cwd="/",
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def profiled(base: str, path: Path) -> str:
    """The profile summary of one run of ``path`` under ``base`` ('' for this tree)."""
    done = subprocess.run(
        [sys.executable, "-c", PROFILER, base, "1", str(path)],
        check=True,
        text=True,
        capture_output=True,
        cwd="/",
    )
    return done.stdout


def team_files(folder: Path) -> dict[str, Path]:
    """Every benchmark team, written into ``folder``: the experiments without their
    requirements (not the engine's cost), the doorway team as shipped, and its twin
    whose network has no jitter (the one line changed)."""
    plain = engine_only(folder)
    files = {name: plain / f"{name}.yaml" for name in NAMES[:3]}
    text = DOORWAY.read_text()
    if "\n  jitter: 0.01\n" not in text:
        raise SystemExit(f"{DOORWAY} no longer has 'jitter: 0.01' under network:")
    files["doorway"] = folder / "doorway.yaml"
    files["doorway"].write_text(text)
    files["doorway_no_jitter"] = folder / "doorway_no_jitter.yaml"
    files["doorway_no_jitter"].write_text(text.replace("\n  jitter: 0.01\n", "\n  jitter: 0.0\n"))
    return files


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", metavar="PATH", help="also time the source tree at PATH")
    ap.add_argument("--repeats", type=int, default=1, help="best of N runs (default 1)")
    ap.add_argument("--only", choices=NAMES, action="append", help="teams to run")
    ap.add_argument("--profile", choices=NAMES, help="profile this team instead of timing")
    args = ap.parse_args()
    names = args.only or NAMES
    base = str(Path(args.base).resolve()) if args.base else ""
    if args.profile:
        with tempfile.TemporaryDirectory() as tmp:
            path = team_files(Path(tmp))[args.profile]
            for label, tree in [("base", base)] * bool(base) + [("this tree", "")]:
                print(f"== {args.profile}, {label}:\n{profiled(tree, path)}")
        return
    now: dict[str, list[float]] = {}
    before: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        every = team_files(Path(tmp))
        files = [every[name] for name in names]
        for k in range(args.repeats):  # alternated, ABBA (see transport.py)
            pair = [(now, "")] + ([(before, base)] if base else [])
            for kept, tree in pair[::-1] if k % 2 else pair:
                best_of(kept, timed(tree, files, 1))
    head = f"{'team':<19}{'simulated (s)':>14}{'wall (s)':>10}{'x real time':>13}"
    print(head + (f"{'wall base':>11}{'speed-up':>10}" if base else ""))
    for name, path in zip(names, files, strict=True):
        wall, t_end = now[str(path)]
        line = f"{name:<19}{t_end:>14.2f}{wall:>10.2f}{t_end / wall:>13.1f}"
        if base:
            old = before[str(path)][0]
            line += f"{old:>11.2f}{old / wall:>9.2f}x"
        print(line)
    if {"doorway", "doorway_no_jitter"} <= set(names):
        for label, kept in [("", now)] + ([(" (base)", before)] if base else []):
            # per simulated second: the two runs need not end at the same time
            cost = [
                kept[str(every[n])][0] / kept[str(every[n])][1]
                for n in ("doorway", "doorway_no_jitter")
            ]
            ratio = cost[0] / cost[1]
            print(
                f"jittered / jitter-free cost per simulated second{label}: {ratio:.2f}x"
                f" (budget 1.3x: {'met' if ratio <= 1.3 else 'NOT met'})"
            )


if __name__ == "__main__":
    main()

"""A third-party mode library, from outside: ``examples/extending`` is pip-installed as its
own package and its team runs through the engine and through its batch fast path.

The library imports only ``hybridteam.library`` (the layering test checks the shipped
libraries; this one is read here). Installing goes to a private folder put on the path of
subprocesses, so the test environment itself is not changed.
"""

from __future__ import annotations

import ast
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "extending"


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The example library installed (pip, from a copy: no build files in the repo)."""
    root = tmp_path_factory.mktemp("extending")
    source = root / "src"
    shutil.copytree(
        EXAMPLE, source, ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info", "out")
    )
    target = root / "site"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--target",
            str(target),
            str(source),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert (target / "hybridteam_docking" / "station.py").is_file()
    return target


def run(site: Path, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run(args, capture_output=True, text=True, env=env, cwd=cwd)


def test_the_library_imports_only_the_public_api():
    for path in (EXAMPLE / "hybridteam_docking").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module]
                if isinstance(node, ast.ImportFrom) and not node.level
                else []
            )
            for name in names:
                assert (
                    not name or not name.startswith("hybridteam") or name == "hybridteam.library"
                ), (path.name, name)


def test_a_team_runs_on_the_installed_library(site, tmp_path):
    out = tmp_path / "out"
    proc = run(
        site,
        sys.executable,
        "-m",
        "hybridteam.cli",
        "run",
        str(EXAMPLE / "team.yaml"),
        "-o",
        str(out),
        "--quiet",
        "--no-views",
    )
    assert proc.returncode == 0, proc.stderr
    (row,) = json.loads((out / "summary.json").read_text())["instances"]
    assert row["outcome"] == "success"
    # the right robot, by hand: at most vmax = 0.5 m/s straight at the dock while
    # gain * d > vmax, i.e. d > 0.625 m; then d shrinks by 1 - gain T = 0.92 per period
    # until d <= 0.05 m. Starting 2.5495 m away it moves 0.05 m per period for 39
    # periods (0.5995 m left), then 30 more: docked at 69 periods, 6.9 s.
    d0, gain, vmax, period, radius = math.hypot(2.5, -0.5), 0.8, 0.5, 0.1, 0.05
    saturated = math.ceil((d0 - vmax / gain) / (vmax * period))
    d = d0 - saturated * vmax * period
    geometric = math.ceil(math.log(radius / d) / math.log(1 - gain * period))
    assert saturated + geometric == 69
    assert row["dock_time"][1] == pytest.approx((saturated + geometric) * period, abs=1e-12)
    assert row["closest"][1] == pytest.approx(d * (1 - gain * period) ** geometric, rel=1e-9)
    assert row["t_end"] == max(row["dock_time"])


SCRIPT = """
import json, sys
import numpy as np
import hybridteam as ht
from hybridteam.api import summaries
from hybridteam.engine.run.batch import batch_rows
from hybridteam.engine.compile.compiler import compile_team

team = ht.load(sys.argv[1])
n = 24
rng = np.random.default_rng(5)
overrides = {"gain": rng.uniform(0.3, 2.0, n), "vmax": rng.uniform(0.2, 1.0, n),
             "dock_x": rng.uniform(-1, 1, n), "dock_y": rng.uniform(-1, 1, n)}
overrides["vmax"][:3] = 100.0            # unsaturated: geometric approach
overrides["gain"][3] = 0.01              # too slow to dock in 20 s: the run ends ok
engine = summaries(team, n, overrides, accelerate=False)
fast = summaries(team, n, overrides)
took = batch_rows(compile_team(team), n, overrides, 0) is not None
print(json.dumps({"engine": engine, "batch": fast, "took_batch": took}))
"""


def test_engine_and_batch_path_agree_instance_by_instance(site, tmp_path):
    proc = run(site, sys.executable, "-c", SCRIPT, str(EXAMPLE / "team.yaml"))
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert got["took_batch"]  # the fast path accepted the team
    engine, batch = got["engine"], got["batch"]
    assert [r["outcome"] for r in engine] == [r["outcome"] for r in batch]
    assert {r["outcome"] for r in engine} == {"success", "ok"}  # both endings covered
    for e, b in zip(engine, batch, strict=True):
        assert set(e) == set(b)
        assert e["t_end"] == pytest.approx(b["t_end"], abs=1e-12)
        assert (
            e["dock_time"] == pytest.approx(b["dock_time"], abs=1e-12)
            if None not in e["dock_time"]
            else e["dock_time"] == b["dock_time"]
        )
        assert e["closest"] == pytest.approx(b["closest"], rel=1e-12)


def test_the_fast_path_declines_a_team_it_does_not_compute(site, tmp_path):
    original = (EXAMPLE / "team.yaml").read_text()
    line = "          - {to: Charging, on: docked}\n"
    text = original.replace(line, line + "          - {to: Charging, after: 5.0}\n", 1)
    assert text != original
    path = tmp_path / "timed.yaml"
    path.write_text(text)
    script = (
        "import sys, hybridteam as ht\n"
        "from hybridteam.engine.run.batch import batch_rows\n"
        "from hybridteam.engine.compile.compiler import compile_team\n"
        "print(batch_rows(compile_team(ht.load(sys.argv[1])), 2, {}, 0))\n"
    )
    proc = run(site, sys.executable, "-c", script, str(path))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "None"

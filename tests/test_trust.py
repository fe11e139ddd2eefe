"""A model file never names arbitrary code (the trust rules of hybridteam.lawrefs).

A law reference ``module:function`` may name only a module beside the team file or of an
installed mode library, and only a function registered with ``@law``; everything else is
refused at validation, before anything is imported or called.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

TEAM = """\
team: t
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes:
      Go:
        law: {{use: "{ref}", period: 0.1}}
simulation: {{duration: 1.0}}
"""


def validate(folder: Path, ref: str, env: dict | None = None) -> subprocess.CompletedProcess:
    (folder / "team.yaml").write_text(TEAM.format(ref=ref))
    return subprocess.run(
        [sys.executable, "-m", "hybridteam.cli", "validate", "team.yaml"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=60,
        env=env or dict(os.environ),
        stdin=subprocess.DEVNULL,
    )


@pytest.mark.parametrize(
    "ref",
    [
        "code:interact",
        "builtins:input",
        "os:system",
        "sys:exit",
        "this:s",
        "antigravity:fly",
        "subprocess:run",
        "hybridteam.cli:main",
        "numpy:zeros",
    ],
)
def test_a_model_cannot_name_any_importable_function(tmp_path, ref):
    proc = validate(tmp_path, ref)
    assert proc.returncode == 2
    assert proc.stdout == ""  # nothing ran: no Zen of Python, no console
    module = ref.split(":")[0]
    assert proc.stderr.strip() == (
        f"team.yaml:7:20: agents.r.modes.Go.law.use: module '{module}' is not beside the "
        f"team file (in {tmp_path.resolve()}) nor part of an installed mode library; a model "
        "names Python only there (put the module next to the team file, or install it as a "
        "library)"
    )


def test_nothing_is_imported_from_outside_the_allowed_places(tmp_path):
    """A module on the Python path (not beside the team) that would leave a marker file
    if imported is not imported."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    marker = tmp_path / "imported.marker"
    (elsewhere / "spy.py").write_text(
        textwrap.dedent(f"""
        import pathlib
        pathlib.Path({str(marker)!r}).write_text("spy ran")
        def f(ctx):
            return None
    """)
    )
    model = tmp_path / "model"
    model.mkdir()
    proc = validate(model, "spy:f", env={**os.environ, "PYTHONPATH": str(elsewhere)})
    assert proc.returncode == 2
    assert "module 'spy' is not beside the team file" in proc.stderr
    assert not marker.exists()


def test_an_unregistered_function_beside_the_team_is_refused(tmp_path):
    (tmp_path / "mylaws.py").write_text(
        textwrap.dedent("""
        import numpy as np
        def drive(ctx):
            return np.zeros((ctx.size, 2))
    """)
    )
    proc = validate(tmp_path, "mylaws:drive")
    assert proc.returncode == 2
    assert proc.stderr.strip().endswith(
        "agents.r.modes.Go.law.use: 'mylaws:drive' is not a registered law: decorate the "
        "function with @law(...) from hybridteam.library"
    )


def test_a_registered_law_beside_the_team_is_found_and_kept_private(tmp_path):
    """The team folder's module is loaded under a private name: a ``json.py`` beside the
    team does not replace the standard library's json for the rest of the process."""
    (tmp_path / "json.py").write_text(
        textwrap.dedent("""
        import numpy as np
        from hybridteam.library import law

        @law("mine.drive")
        def drive(ctx):
            return np.column_stack([np.full(ctx.size, 1.0), np.zeros(ctx.size)])
    """)
    )
    (tmp_path / "team.yaml").write_text(TEAM.format(ref="json:drive"))
    script = (
        "import sys, json, hybridteam as ht\n"
        "run = ht.simulate(ht.load(sys.argv[1]))\n"
        "print(round(float(run.samples['r'][-1, 0, 0]), 9), json.dumps([1]))\n"
    )
    elsewhere = tmp_path / "cwd"  # python -c puts its folder on the path: not the team's
    elsewhere.mkdir()
    proc = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "team.yaml")],
        cwd=elsewhere,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["1.0", "[1]"]

"""Project rules that are cheap to check mechanically."""

from __future__ import annotations

import ast
import shutil
import subprocess

import pytest

from tests.conftest import ROOT


def test_framework_never_imports_a_mode_library():
    """hybridteam/ is domain-neutral: mode libraries depend on it, never the reverse."""
    offenders = []
    for path in (ROOT / "hybridteam").rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [
                f"{path.relative_to(ROOT)}: {n}"
                for n in names
                if n.startswith("hybridteam.modes.") or n == "modes" or n.startswith("modes.")
            ]
    assert offenders == []


def test_ruff_is_clean():
    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (it comes with the [test] extra)")
    proc = subprocess.run([ruff, "check", str(ROOT)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_every_framework_package_is_installed():
    """A package missing from pyproject's list works in an editable install and is absent
    from a wheel (``hybridteam verify`` was, once)."""
    import tomllib

    listed = set(
        tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    found = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in (ROOT / "hybridteam").rglob("__init__.py")
    }
    assert found <= listed, sorted(found - listed)

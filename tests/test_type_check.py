"""The type check's contract (issue 46): what mypy checks and how strictly is declared once,
in pyproject.toml, and CI and the pre-commit hooks run exactly that.

mypy itself runs in ``.ci/run`` (half a minute without its cache, too slow for the suite;
under a second with it); these tests pin
the settings that make its verdict mean something, so loosening them is a visible change.
"""

from __future__ import annotations

import shlex
import tomllib

import yaml

from tests.conftest import ROOT


def _mypy_settings() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]


def test_mypy_checks_the_framework_and_the_mode_libraries_strictly_enough():
    settings = _mypy_settings()
    assert set(settings["files"]) == {"hybridteam", "modes"}
    assert settings["python_version"] == "3.11"
    # bodies of unannotated functions are checked too, and no ignore outlives its reason
    assert settings["check_untyped_defs"] is True
    assert settings["warn_unused_ignores"] is True
    # every `# type: ignore` names the error code it silences
    assert "ignore-without-code" in settings["enable_error_code"]
    # nothing is switched off wholesale: no module's errors ignored, no missing import
    # silenced anywhere but per third-party module
    assert "ignore_errors" not in settings
    assert "ignore_missing_imports" not in settings
    for override in settings.get("overrides", []):
        assert "ignore_errors" not in override, override
        modules = override["module"]
        modules = [modules] if isinstance(modules, str) else modules
        assert not any(m.split(".")[0] in ("hybridteam", "modes") for m in modules), modules


def _run_lines() -> list[list[str]]:
    """The commands of ``.ci/run``, each split into its ``&&`` parts."""
    text = (ROOT / ".ci" / "run").read_text()
    lines = [line.strip() for line in text.splitlines()]
    return [
        [part.strip() for part in line.split("&&")]
        for line in lines
        if line and not line.startswith("#")
    ]


def test_ci_runs_exactly_the_configured_mypy_before_the_tests():
    commands = [part for line in _run_lines() for part in line]
    assert "mypy" in commands  # no arguments: the files and settings are pyproject's
    assert commands.index("mypy") < commands.index("python -m pytest")
    # the checker and its stubs come with the extra CI installs before running it
    test_extra = " ".join(
        tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"][
            "test"
        ]
    )
    assert "mypy" in test_extra and "types-PyYAML" in test_extra


def test_pre_commit_runs_the_three_checks_with_the_installed_tools():
    config = yaml.safe_load((ROOT / ".pre-commit-config.yaml").read_text())
    assert [repo["repo"] for repo in config["repos"]] == ["local"]  # nothing fetched
    hooks = {shlex.join(shlex.split(h["entry"])): h for h in config["repos"][0]["hooks"]}
    assert set(hooks) == {"ruff check", "ruff format --check", "mypy"}
    assert all(h["language"] == "system" for h in hooks.values())
    # mypy checks what pyproject names, not just the files of a commit
    assert hooks["mypy"]["pass_filenames"] is False


def test_ci_checks_the_format_with_the_pinned_formatter():
    """``ruff format --check .`` runs in ``.ci/run`` before the tests, with the ruff that
    ``[test]`` pins to one minor version (another version formats differently)."""
    commands = [part for line in _run_lines() for part in line]
    assert "ruff format --check ." in commands
    assert commands.index("ruff format --check .") < commands.index("python -m pytest")
    test_extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]["test"]
    assert any(r.startswith("ruff>=0.17") and "<0.18" in r for r in test_extra)

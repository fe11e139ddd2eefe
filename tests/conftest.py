"""Shared helpers: build teams from YAML text, find examples."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
FIXTURES = Path(__file__).resolve().parent / "fixtures"


@pytest.fixture
def team_from_yaml(tmp_path):
    """Write YAML text to a file and load it as a team (dedented)."""
    from hybridteam import load

    def make(text: str, name: str = "team.yaml"):
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return load(path)

    return make

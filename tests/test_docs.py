"""The recipes of docs/extending.md run as written.

Each ``## `` section's code blocks that start with ``# file: NAME`` are written to a folder
of their own, and the commands of its ``# run this`` blocks are run there (``hybridteam``
and ``python`` are this interpreter's), each expected to succeed.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "extending.md"
BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)


def recipes() -> dict[str, tuple[dict[str, str], list[str]]]:
    out = {}
    for section in re.split(r"^## ", DOC.read_text(), flags=re.M)[1:]:
        title = section.splitlines()[0].strip()
        files, commands = {}, []
        for _lang, body in BLOCK.findall(section):
            first, _, rest = body.partition("\n")
            if first.startswith("# file: "):
                files[first[len("# file: ") :].strip()] = rest
            elif first.strip() == "# run this":
                commands += [c for c in rest.splitlines() if c.strip()]
        if commands:
            out[title] = (files, commands)
    return out


def test_the_doc_has_runnable_recipes():
    assert set(recipes()) == {"1. A law", "2. A world component", "4. A protocol"}


@pytest.mark.parametrize("title", sorted(recipes()))
def test_recipe_runs(title, tmp_path):
    files, commands = recipes()[title]
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # nothing but the folder
    for command in commands:
        words = command.split()
        if words[0] == "hybridteam":
            words = [sys.executable, "-m", "hybridteam.cli", *words[1:]]
        elif words[0] == "python":
            words = [sys.executable, *words[1:]]
        proc = subprocess.run(words, cwd=tmp_path, capture_output=True, text=True, env=env)
        assert proc.returncode == 0, f"{command}\n{proc.stdout}\n{proc.stderr}"

"""The public switch of the float paths (``hybridteam.floatpaths``): what the fast/slow
equivalence tests go through instead of patching private names."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hybridteam.floatpaths import ENV, FLOAT_PATHS


def test_off_is_a_block_and_restores_the_setting_after_an_error():
    assert FLOAT_PATHS.on
    with pytest.raises(RuntimeError), FLOAT_PATHS.off():
        assert not FLOAT_PATHS.on
        raise RuntimeError
    assert FLOAT_PATHS.on


@pytest.mark.parametrize(("value", "on"), [(None, True), ("off", False), (" OFF ", False),
                                           ("0", False), ("on", True), ("1", True)])
def test_the_environment_sets_the_process_switch(value, on):
    env = {k: v for k, v in os.environ.items() if k != ENV}
    if value is not None:
        env[ENV] = value
    out = subprocess.run([sys.executable, "-c", "from hybridteam.library import FLOAT_PATHS;"
                          "print(FLOAT_PATHS.on)"], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == str(on)

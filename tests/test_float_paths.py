"""``hybridteam.floatpaths``: the public switch of the float paths (what the fast/slow
equivalence tests go through instead of patching private names), and the float forms it
generates from an algorithm written once over an operations namespace."""

from __future__ import annotations

import math
import os
import struct
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.floatpaths import ENV, FLOAT_PATHS, float_form


def test_off_is_a_block_and_restores_the_setting_after_an_error():
    assert FLOAT_PATHS.on
    with pytest.raises(RuntimeError), FLOAT_PATHS.off():
        assert not FLOAT_PATHS.on
        raise RuntimeError
    assert FLOAT_PATHS.on


@pytest.mark.parametrize(
    ("value", "on"),
    [(None, True), ("off", False), (" OFF ", False), ("0", False), ("on", True), ("1", True)],
)
def test_the_environment_sets_the_process_switch(value, on):
    env = {k: v for k, v in os.environ.items() if k != ENV}
    if value is not None:
        env[ENV] = value
    out = subprocess.run(
        [sys.executable, "-c", "from hybridteam.library import FLOAT_PATHS;print(FLOAT_PATHS.on)"],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == str(on)


def _kernel(ops, a, b, c):
    """Every operation float_form writes out, each on the result of another (so ties of
    signed zeros, NaN and zero divisors reach them), as an algorithm is written once."""
    q = ops.true_divide(a - c, b)  # inf or NaN where b is 0
    low = ops.minimum(q, ops.maximum(a, c))
    pick = ops.where(ops.isfinite(low) & (low > b), low, b - c)
    return ops.where(a < c, ops.maximum(pick, -c), ops.minimum(-0.0 * a, pick))


_kernel_on_floats = float_form(_kernel)
doubles = st.sampled_from(
    [0.0, -0.0, 1.0, -1.0, 2.5, 1e-310, 1e308, -1e308, math.inf, -math.inf, math.nan]
)


@settings(max_examples=400, deadline=None)
@given(doubles, doubles, doubles)
def test_a_float_form_gives_the_array_versions_bits(a, b, c):
    with np.errstate(all="ignore"):
        want = _kernel(np, np.array([a]), np.array([b]), np.array([c]))[0]
    got = _kernel_on_floats(a, b, c)
    assert type(got) is float
    if math.isnan(want):  # (a NaN's sign follows the CPU's operand order: nothing reads it)
        assert math.isnan(got)
    else:
        assert struct.pack("d", got) == struct.pack("d", want)


def test_the_ties_are_numpys():
    """np.minimum/np.maximum give their second argument on ties of signed zeros (Python's
    min/max their first) and NaN from either side: written out, so do the float forms."""

    def pair(ops, a, b):
        return ops.minimum(a, b), ops.maximum(a, b)

    on_floats = float_form(pair)
    for a, b in [(0.0, -0.0), (-0.0, 0.0), (math.nan, 1.0), (1.0, math.nan)]:
        assert struct.pack("2d", *on_floats(a, b)) == struct.pack(
            "2d", np.minimum(a, b), np.maximum(a, b)
        )
    assert struct.pack("d", min(0.0, -0.0)) != struct.pack("d", np.minimum(0.0, -0.0))


def test_an_operation_without_a_float_form_is_refused_at_import():
    def uses_tan(ops, a):
        return ops.tan(a)

    with pytest.raises(TypeError, match=r"no float form of ops\.tan"):
        float_form(uses_tan)


def test_ops_may_be_a_defaulted_or_keyword_parameter():
    """Array callers keep their signature when ``ops`` defaults to numpy (the ladder's
    law); the float form has no such parameter, wherever it was."""

    def hyp(x, y, scale=2.0, ops=np):
        return scale * ops.sqrt(x * x + y * y)

    def clipped(x, *, ops=np, low=0.0):
        return ops.maximum(x, low)

    assert hyp(np.array([3.0]), np.array([4.0]))[0] == 10.0
    assert float_form(hyp)(3.0, 4.0) == 10.0 and float_form(hyp)(3.0, 4.0, 1.0) == 5.0
    assert float_form(clipped)(-1.0) == 0.0 and float_form(clipped)(-1.0, low=-2.0) == -1.0


def test_a_function_without_ops_is_refused():
    def plain(x):
        return x

    with pytest.raises(TypeError, match="no parameter 'ops'"):
        float_form(plain)
    with pytest.raises(TypeError, match="not a function defined with def"):
        float_form(lambda x, ops: x)
    made_at_a_prompt: dict = {}
    exec("def f(x, ops):\n    return x\n", made_at_a_prompt)  # (no source file to read)
    with pytest.raises(TypeError, match="cannot be read"):
        float_form(made_at_a_prompt["f"])

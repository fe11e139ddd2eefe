"""The transport laws' view of the leader's stream: usable rows, zeros elsewhere, no NaN."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from hybridteam.modes.transport.leader import leader_estimate
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.library import FLOAT_PATHS


class StubContext:
    """What ``leader_estimate`` reads of a law context: the ``leader`` variable and the
    latest ``state`` copy (already dead-reckoned)."""

    def __init__(self, leader, fields, age):
        self.size = len(leader)
        self._leader, self._fields, self._age = np.asarray(leader, float), fields, age

    def get(self, name, default):
        return self._leader if name == "leader" else default

    def estimate(self, message, sender=None, extrapolate=False):
        valid = np.isfinite(self._age)
        return SimpleNamespace(fields=self._fields, age=self._age, valid=valid)


def test_rows_without_a_usable_copy_read_zeros_and_infinities_read_finite():
    big = np.finfo(float).max
    fields = {
        "x": np.array([1.0, 2.0, np.nan]),
        "y": np.array([3.0, 4.0, 5.0]),
        "theta": np.array([0.5, 0.0, 0.0]),
        "v": np.array([0.2, 0.3, 0.4]),
        "vx": np.array([np.inf, 0.1, 0.1]),
        "vy": np.array([-np.inf, 0.0, 0.0]),
        "omega": np.array([0.1, 0.0, 0.0]),
    }
    # row 0: usable (infinite velocity -> the largest finite numbers, as nan_to_num gives);
    # row 1: no leader (-1); row 2: a copy with a NaN x is not usable
    lead = leader_estimate(StubContext([1, -1, 1], fields, np.array([0.1, 0.1, 0.1])))
    assert lead.ok.tolist() == [True, False, False]
    assert lead.x.tolist() == [1.0, 0.0, 0.0] and lead.y.tolist() == [3.0, 0.0, 0.0]
    assert lead.vx.tolist() == [big, 0.0, 0.0] and lead.vy.tolist() == [-big, 0.0, 0.0]
    assert lead.theta.tolist() == [0.5, 0.0, 0.0] and lead.omega.tolist() == [0.1, 0.0, 0.0]
    assert lead.v.tolist() == [0.2, 0.0, 0.0]


@settings(max_examples=400, deadline=None)
@given(
    st.sampled_from([-1.0, 0.0, 1.0, 2.0, 1.5, 2.5, np.nan, np.inf, -np.inf, 1e300]),
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=8, max_size=8),
    st.sets(st.sampled_from(["v", "vx", "vy", "omega"])),
)
def test_a_single_row_on_floats_has_the_array_versions_bits(leader, values, carried):
    """A single run's tick reads its leader on Python floats; with the float paths off it
    takes the array version. Same bits for every field, the usable flag and the leader's
    index, whatever the copy carries (NaN, inf, no velocity at all, a leader variable that
    is no index)."""
    x, y, th, v, vx, vy, omega, age = values
    given_ = {"v": v, "vx": vx, "vy": vy, "omega": omega}
    fields = {k: np.array([a]) for k, a in {"x": x, "y": y, "theta": th}.items()}
    fields |= {k: np.array([given_[k]]) for k in carried}
    ctx = StubContext([leader], fields, np.array([age]))
    with np.errstate(all="ignore"):
        one = leader_estimate(ctx)
        with FLOAT_PATHS.off():
            arrays = leader_estimate(ctx)
    for name in ("ok", "who", "x", "y", "theta", "v", "vx", "vy", "omega"):
        a, b = getattr(one, name), getattr(arrays, name)
        assert a.shape == b.shape == (1,) and a.dtype == b.dtype, name
        assert a.tobytes() == b.tobytes(), name

"""The transport laws' view of the leader's stream: usable rows, zeros elsewhere, no NaN."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from hybridteam.modes.transport.leader import leader_estimate


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

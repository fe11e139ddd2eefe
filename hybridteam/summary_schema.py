"""The format of a run folder's ``summary.json``, checked before the report reads one.

``hybridteam report RUN_FOLDER`` builds a page from files anyone can hand over: a
``summary.json`` may be hand-edited, cut short, or made to break the reader (a list where
the instances belong, a string for a verdict's ``satisfied``). This model says what the
report relies on — the counts and seed, one object per instance with its number and
outcome, each requirement verdict with its fields — so a bad file is refused with the
path of its first bad field. It does not make values safe to show: the report escapes
every value it writes, whatever its type.

Statistics of world components (``min_clearance``, ``collisions`` …) are whatever JSON a
component reports, so an instance accepts other keys of any JSON value.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from hybridteam.trace_schema import first_problem

Count = Annotated[int, Field(ge=0)]


class _Model(BaseModel):
    # JSON has no infinities; a NaN that json.dumps wrote for a statistic is kept (shown)
    model_config = ConfigDict(extra="allow", strict=True)


class Verdict(_Model):
    """One requirement's verdict on one instance (``requirements.check``)."""

    satisfied: bool
    robustness: float | None = None
    violated_at: float | None = None
    failed: str | None = None


class InstanceSummary(_Model):
    instance: Count
    outcome: str
    requirements: dict[str, Verdict] | None = None


class RunSummary(_Model):
    """A whole ``summary.json`` as ``hybridteam run`` writes it (``Run.summary``)."""

    team: str | None = None
    n: Count
    seed: int | list[int]
    duration: Annotated[float, Field(ge=0, allow_inf_nan=False)]
    outcomes: dict[str, Count] = Field(default_factory=dict)
    instances: list[InstanceSummary]


def check_summary(data: Any) -> tuple[tuple, str] | None:
    """The first problem of a parsed ``summary.json``: its path in the file and
    ``"instances[0].outcome: ..."``; None when it is a run summary."""
    return first_problem(RunSummary, data, "a run summary")

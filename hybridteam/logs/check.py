"""A team's requirements on a recorded run: a robot's log, or a trace.

The monitor is the one ``run`` uses (:mod:`hybridteam.requirements`), with the same
semantics, on the recorded signals at their own sample times (irregular in a log: states
are linear between samples, modes and messages exact at their times). Two things a
simulation has and a recording does not: the exact states at events (the monitor then
reads the samples only, as it does between events), and the agents' discrete variables —
a requirement that reads one cannot be checked on a log and says so. Parameters are the
team file's values (a study's overrides are not in a trace).
"""

from __future__ import annotations

from typing import Any

from hybridteam.engine.run.record import variables_key
from hybridteam.logs import LogError
from hybridteam.model import Team
from hybridteam.trace import Table

VARIABLES = variables_key("")  # the suffix of an agent's variables in a run's snapshots
VERDICT_COLUMNS = ("instance", "requirement", "satisfied", "robustness", "violated_at", "failed")


def check_run(run: Any, team: Team) -> list[dict[str, dict[str, Any]]]:
    """Per instance of ``run``: ``{requirement: verdict}`` as ``run`` records them
    (:func:`hybridteam.requirements.check.verdict`); a :class:`LogError` for a
    requirement the recording cannot answer."""
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.logs.team import team_frame
    from hybridteam.requirements.check import RequirementSet, compile_requirements

    requirements = compile_requirements(compile_team(team))
    out: list[dict[str, dict[str, Any]]] = [{} for _ in range(run.n)]
    if not requirements:
        return out
    _meta, params = team_frame(team)
    for req in requirements.requirements:
        one = RequirementSet([req], requirements.events, requirements.catalog)
        try:
            verdicts = one.check(run, params)
        except KeyError as exc:  # the discrete variables a simulation snapshots
            key = str(exc.args[0])
            what = (
                f"the discrete variables of agent '{key.removesuffix(VARIABLES)}'"
                if key.endswith(VARIABLES)
                else repr(key)
            )
            raise LogError(
                f"requirement {req.name}: reads {what}, which a recording does "
                "not have (variables are not logged)"
            ) from None
        for i, v in enumerate(verdicts):
            out[i].update(v)
    return out


def verdict_table(verdicts: list[dict[str, dict[str, Any]]]) -> Table:
    """The verdicts as a table: a row per instance and requirement."""
    rows: dict[str, list[Any]] = {c: [] for c in VERDICT_COLUMNS}
    for i, per in enumerate(verdicts):
        for name, v in per.items():
            for column, value in (
                ("instance", i),
                ("requirement", name),
                ("satisfied", bool(v["satisfied"])),
                ("robustness", v["robustness"]),
                ("violated_at", v.get("violated_at")),
                ("failed", v.get("failed")),
            ):
                rows[column].append(value)
    return Table(VERDICT_COLUMNS, rows)

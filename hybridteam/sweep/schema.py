"""pydantic schema of study files (``kind: study``): what a parameter study may declare.

Only the shape is checked here — keys, types, ranges — so that every mistake is reported
with its ``file:line:column`` by :func:`hybridteam.io.errors.located_errors`, like a team
file's. What needs the team (do the override keys name parameters? do the metrics exist?)
is checked by :mod:`.study` once the team is loaded.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from hybridteam.io.schema import NAME, Strict

#: Columns of the per-setting table that an axis may not be named after.
RESERVED = (
    "factor",
    "value",
    "runs",
    "success_rate",
    "setting",
    "member",
    "repetition",
    "run",
    "seed",
    "outcome",
)

Key = Annotated[str, Field(min_length=1, description="override key: agent.param or param")]
Count = Annotated[int, Field(ge=1)]
#: an integer draw's bounds: what numpy's 64-bit generator can draw between
Integer = Annotated[int, Field(ge=-(2**62), le=2**62)]
Seed = Annotated[int, Field(ge=0)]
#: A factor value: one number for all the factor's keys, or one number per key.
Value = Annotated[float | list[float], Field(union_mode="left_to_right")]


class DrawSchema(Strict):
    """One random parameter of the population, drawn per member.

    ``{uniform: [lo, hi]}`` or ``{integers: [lo, hi]}`` (hi included); ``keys`` sets several
    override keys to the same draw (default: the draw's name is the key).
    """

    keys: list[Key] | None = Field(None, min_length=1)
    uniform: tuple[float, float] | None = None
    integers: tuple[Integer, Integer] | None = None

    @model_validator(mode="after")
    def _one_distribution(self) -> DrawSchema:
        given = [k for k in ("uniform", "integers") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "give exactly one distribution: uniform: [lo, hi] or "
                "integers: [lo, hi]" + (f" (got {' and '.join(given)})" if given else "")
            )
        lo, hi = getattr(self, given[0])
        if not lo <= hi:
            raise ValueError(f"{given[0]}: lo must be <= hi, got [{lo}, {hi}]")
        return self


class PopulationSchema(Strict):
    """The random population every setting is run on (e.g. 100 robot pairs).

    ``set`` fixes parameters for every member (the paper's population S draws some
    parameters and sets others, k_c = sc = 1, to one value); a factor or an axis may vary
    them, as it may vary a draw.
    """

    size: Count = 1
    seed: Seed = 0
    set: dict[Key, float] = Field(
        default_factory=dict, description="override key -> one value for every member"
    )
    draws: dict[Key, DrawSchema] = Field(default_factory=dict)


class _Keyed(Strict):
    """What factors and axes share: the override key (or keys) their values set."""

    key: Key | None = None
    keys: list[Key] | None = Field(None, min_length=1)

    @field_validator("keys")
    @classmethod
    def _not_both(cls, keys: list[str] | None, info: ValidationInfo) -> list[str] | None:
        if keys is not None and info.data.get("key") is not None:
            raise ValueError("give 'key' or 'keys', not both")
        return keys


class FactorSchema(_Keyed):
    """A factor with explicit keys: ``{keys: [R1.alpha, R2.alpha], values: [0.4, 0.8]}``."""

    values: list[Value] = Field(min_length=1)


class AxisSchema(_Keyed):
    """An axis whose column name differs from its key: ``{key: length, values: [...]}``."""

    values: list[float] = Field(min_length=1)


Values = Annotated[list[Value], Field(min_length=1)]
Points = Annotated[list[float], Field(min_length=1)]
FactorSpec = Annotated[Values | FactorSchema, Field(union_mode="left_to_right")]
AxisSpec = Annotated[Points | AxisSchema, Field(union_mode="left_to_right")]


class StudyFile(Strict):
    """A parameter study: a base team, a population, factors, axes and repetitions."""

    kind: Literal["study"]
    team: str = Field(min_length=1, description="team file, relative to the study file")
    name: str | None = Field(None, description="title of the study (default: file name)")
    duration: Annotated[float, Field(ge=0)] | None = Field(
        None, description="simulated seconds per run (default: the team's)"
    )
    population: PopulationSchema = Field(default_factory=PopulationSchema)
    factors: dict[str, FactorSpec] = Field(
        default_factory=dict, description="varied one at a time; none: one 'base' setting"
    )
    axes: dict[str, AxisSpec] = Field(
        default_factory=dict, description="crossed with every factor value; a column each"
    )
    repetitions: Count = 1
    seed: Seed = 0
    success: list[str] = Field(default_factory=lambda: ["ok"], min_length=1)
    outcomes: list[str] = Field(
        default_factory=list, description="outcome count columns always shown, in order"
    )
    metrics: list[str] = Field(
        default_factory=list, description="per-instance summary keys averaged over successes"
    )
    chunk: Count = 500
    accelerate: bool = Field(
        True,
        description="use a mode library's batch simulator when it offers one for the "
        "team (false: always the general engine)",
    )

    @field_validator("axes")
    @classmethod
    def _axis_names(cls, axes: dict[str, object]) -> dict[str, object]:
        for name in axes:
            if not NAME.match(name):
                raise ValueError(
                    f"axis name {name!r} is not a valid column name: use "
                    "letters, digits and _, not starting with a digit"
                )
            if name in RESERVED or name.startswith("mean_"):
                raise ValueError(
                    f"axis name {name!r} is taken by a table column; "
                    "give the axis another name and its key as 'key:'"
                )
        return axes

    @field_validator("metrics")
    @classmethod
    def _metric_names(cls, metrics: list[str]) -> list[str]:
        if len(set(metrics)) != len(metrics):
            raise ValueError("a metric is listed twice")
        return metrics

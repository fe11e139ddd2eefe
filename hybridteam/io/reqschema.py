"""The ``requirements:`` section of a team file (schema only; formulas are compiled with
the team, see :mod:`hybridteam.requirements`)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field


class RequirementSchema(BaseModel):
    """A requirement with a description: ``{formula: "always(x <= 22.1)", description: ...}``
    (or just the formula as a string)."""

    model_config = ConfigDict(extra="forbid")

    formula: str = Field(
        description="a Signal Temporal Logic formula, e.g. 'always(count_in_role(lead) <= 1)'"
    )
    description: str | None = Field(None, description="what it means, for reports")


RequirementEntry = Annotated[str | RequirementSchema, Field(union_mode="left_to_right")]


class RequirementsFile(BaseModel):
    """A file of requirements a team includes (``requirements_from: [FILE]``)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["requirements"] = "requirements"
    description: str | None = None
    requirements: dict[str, RequirementEntry] = Field(
        description="named temporal-logic formulas, as in a team's requirements:"
    )

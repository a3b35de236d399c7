"""Types shared by every scenario schema (scenario.py, and the parameters of each law, which are
their own schema: one home for a parameter, its unit, default and range)."""

from __future__ import annotations

import typing
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Vec3 = tuple[float, float, float]
# Finite: an infinite time, size or modulus is a mistake (inf where it means "none" is
# PositiveOrInf).
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
PositiveOrInf = Annotated[float, Field(gt=0, allow_inf_nan=True)]
# Scenario sections: unknown keys are errors, values are immutable, and every number is finite
# (`tools.0.speed=inf` or a NaN from a spreadsheet is refused up front, not met as exit 3 later).
STRICT = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True, allow_inf_nan=False)
# The same for parameter dataclasses (which are frozen by their decorator).
STRICT_DATACLASS = ConfigDict(extra="forbid", use_attribute_docstrings=True, allow_inf_nan=False)


class Strict(BaseModel):
    model_config = STRICT


def schema_fields(model) -> dict:
    """A schema's fields: a pydantic model's or a pydantic dataclass's (a law's parameters); {} else."""
    return getattr(model, "model_fields", None) or getattr(model, "__pydantic_fields__", None) or {}


def section_schemas(annotation) -> list:
    """The schemas a field's annotation holds (through Optional, lists, unions, Annotated): one for
    a section, several for a choice among sections, none for a plain value."""
    found, stack = [], [annotation]
    while stack:
        t = stack.pop()
        if schema_fields(t):
            found.append(t)
        else:
            stack.extend(typing.get_args(t))
    return found

"""Types shared by every scenario schema (scenario.py, and the parameters of each law, which are
their own schema: one home for a parameter, its unit, default and range)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Vec3 = tuple[float, float, float]
# Finite: an infinite time, size or modulus is a mistake (inf where it means "none" is
# PositiveOrInf).
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
PositiveOrInf = Annotated[float, Field(gt=0)]
# Scenario sections: unknown keys are errors, values are immutable.
STRICT = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)
# The same for parameter dataclasses (which are frozen by their decorator).
STRICT_DATACLASS = ConfigDict(extra="forbid", use_attribute_docstrings=True)


class Strict(BaseModel):
    model_config = STRICT

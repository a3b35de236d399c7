"""Types shared by every scenario schema (scenario/sections.py, and the parameters of each law, which are
their own schema: one home for a parameter, its unit, default and range)."""

from __future__ import annotations

import typing
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

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

    @model_validator(mode="after")
    def _no_unit_slip(self):
        check_unit_slips(self)
        return self


# The least positive value of a key in these units that a solid's input has: below it the value is
# taken for one in the unit named (a strength of 300 meant as MPa nucleated 42 cracks; a penalty of
# 5 meant as N/mm^3). (unit: floor, the unit meant, its factor as written after a number)
UNIT_FLOORS = {"Pa": (1e3, "MPa", "e6"), "N/m^3": (1e6, "N/mm^3", "e9"), "Pa/m": (1e6, "N/mm^3", "e9"),
               "J/(kg K)": (50.0, "kJ/(kg K)", "e3")}  # a specific heat (lead's, the lowest of metals, is 128)


def field_unit(description: str | None) -> str:
    """The unit a field's description starts with ("Pa, ft: ..." -> "Pa"); "" when none or when the
    unit is another key's ("Pa (the property's unit)")."""
    text = (description or "").strip()
    if "the property's unit" in text:
        return ""
    if not text:
        return ""
    unit = text.split(" ")[0]
    if "(" in unit and ")" not in unit and ")" in text:  # a unit with a space in brackets: J/(kg K)
        unit = text[: text.index(")") + 1]
    return unit.rstrip(",;:")


def check_unit_slips(instance) -> None:
    """ValueError naming the first field set below its unit's floor (UNIT_FLOORS) and the value
    meant, the way youngs_modulus and density say so."""
    for name, field in schema_fields(type(instance)).items():
        floor = UNIT_FLOORS.get(field_unit(field.description))
        value = getattr(instance, name, None)
        if floor is None or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        least, meant, factor = floor
        if 0.0 < value < least:
            unit = field_unit(field.description)
            raise ValueError(f"{name} = {value:g} {unit} is below {least:g} {unit}, less than any solid's: if that "
                             f"is {meant}, write {value:g}{factor}")


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


class ScenarioError(ValueError):
    """A scenario that cannot run; the message names the field or file and the fix. Here, below
    every layer that checks a scenario's values (geometry, loading, the methods' set-ups)."""


def resolve_path(file: str, base: Path | None) -> Path:
    """A file named in a scenario: relative paths are taken from the scenario file's folder."""
    path = Path(file)
    if not path.is_absolute() and base is not None:
        path = base / path
    return path

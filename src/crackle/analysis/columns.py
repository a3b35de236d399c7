"""history.csv's column vocabulary beyond the energy terms (analysis.energy.ENERGY_ROLES): a
tool's columns, named in one place, and the unit each column was registered with. Below io and
loading, so that the analyses, the writers and the load cell all read it."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

# A tool's history columns, named here only: tool.NAME.Qx/Qy/Qz for each quantity Q, with its unit:
# its force on the specimen, its displacement, a free tool's velocity.
TOOL_QUANTITIES = {"f": "N", "u": "m", "v": "m/s"}


def tool_column_names(name: str, quantity: str) -> tuple[str, str, str]:
    """The x, y, z history columns of tool `name`'s `quantity` (a key of TOOL_QUANTITIES)."""
    return tuple(f"tool.{name}.{quantity}{axis}" for axis in "xyz")


def tool_magnitude(columns: Mapping, name: str, quantity: str):
    """|quantity| of tool `name` from a history row (a number) or the history's columns (an
    array); a component the history lacks counts as zero."""
    return np.sqrt(sum(np.asarray(columns.get(c, 0.0), float) ** 2 for c in tool_column_names(name, quantity)))


def tool_vector(columns: Mapping, name: str, quantity: str) -> np.ndarray:
    """Tool `name`'s `quantity` as a vector (a history row) or (n, 3) array (the history)."""
    return np.stack([np.asarray(columns[c], float) for c in tool_column_names(name, quantity)], axis=-1)


def tool_column_units(names: Sequence[str]) -> dict[str, str]:
    """The units of the tool columns of tools `names` (TOOL_QUANTITIES)."""
    return {column: unit for name in names for quantity, unit in TOOL_QUANTITIES.items()
            for column in tool_column_names(name, quantity)}


def column_unit(units: Mapping[str, str], name: str) -> str:
    """The unit registered for history column `name`: its own entry, or a family's (a key ending
    in "*" covers the columns it begins: one per crack tip, per pressure); "" if none."""
    if name in units:
        return units[name]
    family = max((key for key in units if key.endswith("*") and name.startswith(key[:-1])), key=len, default=None)
    return "" if family is None else units[family]

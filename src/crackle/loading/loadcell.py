"""The load cell every method reads its tool forces through, and the tool columns of history.csv."""

from __future__ import annotations

import numpy as np


class LoadCell:
    """Each tool's force on the specimen as the mean over the time since the last reading:
    the impulse the compiled step summed into tools.impulse, over that time (a load cell whose
    averaging window is the output interval). With no time elapsed (the first row), the
    instantaneous contact force instead."""

    def __init__(self):
        self._last_time = 0.0

    def read(self, tools, time: float, instantaneous) -> np.ndarray:
        """(n_tools, 3) forces; `instantaneous()` gives the contact forces now."""
        elapsed = time - self._last_time
        forces = tools.impulse.sum(axis=1) / elapsed if elapsed > 0 else instantaneous()
        tools.impulse[:] = 0.0
        self._last_time = time
        return forces


def tool_columns(names, forces: np.ndarray, displacements: np.ndarray) -> dict[str, float]:
    """tool.NAME.fx/fy/fz (N) and tool.NAME.ux/uy/uz (m) for each tool, in history order."""
    row: dict[str, float] = {}
    for name, f, u in zip(names, forces, displacements):
        for axis, k in zip("xyz", range(3)):
            row[f"tool.{name}.f{axis}"] = float(f[k])
        for axis, k in zip("xyz", range(3)):
            row[f"tool.{name}.u{axis}"] = float(u[k])
    return row

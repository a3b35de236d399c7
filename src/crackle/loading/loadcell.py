"""The load cell every method reads its tool forces through, and the tool columns of history.csv."""

from __future__ import annotations

import numpy as np

from ..analysis.columns import tool_column_names
from .arrays import LOAD_CELL_RING, free_tool_work
from .tools import interp_history, tool_contact_totals


class LoadCell:
    """Each tool's force on the specimen as a load cell with a fixed averaging window reads it:
    the mean of the contact force over the last `window` steps, updated after every step by the
    compiled `loading.tools.load_cell_step`. Neither the force in history.csv nor the peak (the
    largest mean over every step, not only over the rows written) depends on how often the
    history is sampled. Before the first step, the instantaneous contact force."""

    def __init__(self, tools):
        self.tools = tools

    @property
    def window(self) -> int:
        return int(self.tools.cell_count[1])

    def set_window(self, steps: int) -> None:
        """Average over `steps` steps (1 to LOAD_CELL_RING); clears what the cell has seen."""
        if not 1 <= steps <= LOAD_CELL_RING:
            raise ValueError(
                f"a load-cell window of {steps} steps is outside 1..{LOAD_CELL_RING}; "
                "shorten run.load_cell_window"
            )
        t = self.tools
        t.cell_ring[:] = 0.0
        t.cell_state[:] = 0.0
        t.cell_count[:] = (0, steps)

    def forces(self, instantaneous) -> np.ndarray:
        """(n_tools, 3) forces (N); `instantaneous()` gives the contact forces now (used before
        the first step)."""
        t = self.tools
        seen = int(t.cell_count[0])
        if seen == 0:
            return instantaneous()
        return t.cell_state[:, :3] / min(seen, self.window)

    def peaks(self) -> tuple[np.ndarray, np.ndarray]:
        """Per tool, the largest magnitude of the windowed force so far (N) and its time (s)."""
        return self.tools.cell_state[:, 3].copy(), self.tools.cell_state[:, 4].copy()


def tool_columns(names, forces: np.ndarray, tools) -> dict[str, float]:
    """tool.NAME.fx/fy/fz (N) and tool.NAME.ux/uy/uz (m) for each tool (`tools`: the Tools
    arrays), and tool.NAME.vx/vy/vz (m/s) for a free one, in history order."""
    row: dict[str, float] = {}
    for j, (name, f, u) in enumerate(zip(names, forces, tools.disp)):
        row.update(zip(tool_column_names(name, "f"), map(float, f)))
        row.update(zip(tool_column_names(name, "u"), map(float, u)))
        if tools.mass[j] > 0.0:
            row.update(zip(tool_column_names(name, "v"), map(float, tools.velocity[j])))
    return row


class ToolSprings:
    """The tool springs of a method's contact points (tet nodes, lattice nodes, particles) at
    output times: their forces and stored energy now (the energy audit's share; the load cell's
    reading before the first step) and the tool columns of a history row."""

    def __init__(self, tools, names):
        self.tools = tools
        self.names = list(names)
        self.force = np.zeros((len(self.names), 3))  # N, per tool, after `measure`
        self.energy = np.zeros(len(self.names))  # J, per tool, after `measure`

    def measure(self, body, time=0.0, dt=None) -> "ToolSprings":
        """The springs at the state of `body` (solver.body.Body's fields). With the step dt: at
        the mid-step positions, points at x - v dt/2 (v: the half-step velocities) and tools half
        a step back from `time`, where the rest of the energy audit pairs potentials with the
        half-step velocities and where the tools' work booked so far ends (measured at x instead,
        a tool's first steps of contact would hold a step more energy than its work: -100 % at
        the first contact)."""
        if dt is None:
            tool_contact_totals(body, self.tools, self.force, self.energy)
            return self
        tools = self.tools
        disp = tools.disp.copy()
        tools.disp[:] -= 0.5 * dt * self._velocity_before(time, dt)
        try:
            tool_contact_totals(body._replace(x=body.x - 0.5 * dt * body.v), tools, self.force, self.energy)
        finally:
            tools.disp[:] = disp
        return self

    def _velocity_before(self, time: float, dt: float) -> np.ndarray:
        """(n_tools, 3) each tool's velocity over the half step before `time` (as tool_velocities)."""
        t = self.tools
        v = np.empty((len(self.names), 3))
        for j in range(len(self.names)):
            if t.mass[j] > 0.0:
                v[j] = t.velocity[j]
            else:
                v[j] = interp_history(time - 0.5 * dt, t.times[j], t.speeds[j], t.n[j]) * t.direction[j]
        return v

    def free_work(self) -> float:
        """The work (J) the free tools have done on the specimen: part of energy.external."""
        return free_tool_work(self.tools)

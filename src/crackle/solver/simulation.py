"""What a method gives the driver (solver.run): the Simulation protocol."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from ..loading.loadcell import LoadCell


class Simulation(Protocol):
    """One method's model and its compiled step, as the driver sees it.

    Histories: `sample` returns one row of history.csv (without `time`): `tool.NAME.f*` (the
    force `load_cell` reads: the mean over its window of steps) and `tool.NAME.u*`, every
    `energy.*` term of the audit (analysis.energy), `broken`, and anything the method adds.
    Events: `new_events` reports each failure once (solver.failures.FailureRecorder).
    """

    method: str  # the registered name (crackle.methods)
    stable_dt: float  # largest stable step (s), without safety factor
    # Optional, `proven_dt` (s) and `proven_dt_how` (a few words): where the method proves a bound
    # on the stable step at set-up (every smaller step is stable), a user's run.dt is accepted up
    # to it (solver.choose_time_step).
    wave_transit: float  # s: a P-wave's time across one element (particle, spacing), the period
    # scale of contact chatter; the default load-cell window is a few of it
    time: float  # simulated time reached (s)
    steps: int  # steps taken
    broken: int  # bonds, links or interfaces failed so far
    load_cell: LoadCell  # over the method's Tools arrays; its kernel calls load_cell_step every step
    warnings: list[str]  # set-up advice (e.g. an under-resolved process zone), shown before the first step

    def describe(self) -> str:
        """The discretisation's size in a few words, e.g. '960 tets, 2,016 interfaces'."""

    def advance(self, n_steps: int, dt: float) -> None:
        """n_steps compiled steps; state updated in place; time = steps x dt. The state after a
        step may not depend on how the steps were split into calls (advance(3) = advance(1) +
        advance(2), bit for bit): outputs and restarts rely on it."""

    def state_is_finite(self) -> bool:
        """False once positions or velocities hold inf or nan."""

    def sample(self, dt: float) -> dict[str, float]:
        """One history row at the current time."""

    def new_events(self) -> tuple[np.ndarray, np.ndarray, list[str], np.ndarray]:
        """Failures since the last call: times, positions (k, 3), mode names, ids."""

    def fields(self) -> dict:
        """Arrays for a ParaView snapshot: `points`, `point_data` ({name: per-point array}) and
        `blocks`, a list of (meshio cell type, connectivity, {name: per-cell array}); optionally
        `component_names` ({array name: names of its columns})."""

    def tool_names(self) -> list[str]:
        """Names of the tools, in the order of their history columns."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corner of the specimen at set-up (for plots)."""

    def summary(self) -> dict:
        """Set-up facts and final results for summary.json: at least `elements`, `particles`
        or `nodes`, and `warnings`."""

    def extra_plots(self, out_dir: Path) -> None:
        """Method-specific plots into out_dir / 'plots' (may do nothing)."""

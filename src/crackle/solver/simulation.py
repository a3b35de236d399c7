"""What a method gives the driver (solver.run): the Simulation protocol."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Protocol

import numpy as np

from ..analysis.energy import ENERGY_ROLES, PREFIX, energy_order
from ..analysis.columns import column_unit, tool_column_units
from .failures import FailureRecorder, material_labels
from ..loading.loadcell import LoadCell, ToolSprings, tool_columns


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
    element_length: float | None  # m: the element (particle diameter, spacing) wave_transit crosses
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

    def extra_plots(self, out_dir: Path, history) -> None:
        """Method-specific plots into out_dir / 'plots' (may do nothing); `history`: the run's
        (io.outputs.RunHistory)."""


# The units of the history columns every run has: the driver's time, and SimulationBase.sample's.
SHARED_HISTORY_UNITS = {"time": "s", **{f"{PREFIX}{name}": "J" for name in ENERGY_ROLES}, "broken": "1", "dt": "s"}


class Probe:
    """A measurement a simulation carries (LAMMPS's compute): it adds its columns to each history
    row (`columns`, from the simulation and the row so far; their units registered in `units`),
    its results to summary.json (`summary`) and its figures (`plots`, named in
    io.plots.RUN_PLOTS). A set-up appends the probes its scenario asks for to `sim.probes`; the
    default of each part is nothing."""

    units: dict[str, str] = {}

    def columns(self, sim, row: dict) -> dict[str, float]:
        return {}

    def summary(self, sim) -> dict:
        return {}

    def plots(self, sim, out_dir: Path) -> None:
        pass


class PeakForceProbe(Probe):
    """A result read from the tools' peak forces: `test.summary(peaks)`, e.g. the nominal
    strengths of a direct tension test (analysis.strength.TensionTest)."""

    def __init__(self, test):
        self.test = test

    def summary(self, sim) -> dict:
        return self.test.summary(sim.load_cell.peaks()[0])


class SimulationBase:
    """The part of the Simulation protocol every method shares, written once: the clock, the
    tools (names, springs, load cell), the energy terms of the shared per-node arrays, the history
    row around them, the set-up's warnings and the default extra plots (none).

    A method's class derives from it, calls `_start_clock_and_tools(tools, tool_names)` in its
    __init__, and gives:
      `body`            the per-node (particle) arrays the shared compiled pieces take: a tuple
                        with solver.body.Body's fields (an attribute; a property where the method
                        replaces them, the shell at a cut)
      `own_energies(dt)`  its stored and dissipated terms ({"elastic": J, "damage": J, ...};
                        "contact" and "friction" add to the shared ones), at mid-step positions
      `own_summary()`   its set-up facts and results for summary.json (`summary` adds the probes',
                        the failures per material and the warnings)
    and `advance`, `broken`, `new_events`, `fields`, `describe`, and `x0` (the points at set-up,
    for `bounds`) or its own `bounds`.
    """

    method: str = ""
    # m: the element size (a particle's diameter, the spacing) wave_transit is the time across, which
    # the driver compares a body's travel in one step with; None: not checked
    element_length: float | None = None
    # J: kinetic (initial velocities) and stored ([initial_stress]: FDEM's tets and faces, the DEM's
    # bonds) energy at t = 0, counted as work put in
    _initial_energy: float = 0.0
    # Several materials ([materials.NAME]): their names in table order (the set-up sets it); the
    # method then gives failed_ids() and failure_materials(ids). None: one material.
    material_names: list[str] | None = None

    @property
    def several_materials(self) -> bool:
        return bool(self.material_names) and len(self.material_names) > 1

    def failure_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(failed, fail_time, fail_mode), one row per element that can fail (a bond, a face, a
        spring, a particle): what `new_events`, `failed_ids` and `broken` read. A method whose
        failures are of another kind (the shell's cuts) gives those three itself."""
        raise NotImplementedError

    def failure_positions(self, ids) -> np.ndarray:
        """Where failures `ids` are on the specimen at set-up (k, 3): events.csv's position."""
        raise NotImplementedError

    def new_events(self):
        """Failures since the last call, each once (solver.failures.FailureRecorder)."""
        failed, fail_time, fail_mode = self.failure_state()
        if self.__dict__.get("_failures") is None:
            self._failures = FailureRecorder(len(failed))
        return self._failures.new(failed, fail_time, fail_mode, self.failure_positions)

    def failed_ids(self) -> np.ndarray:
        return np.flatnonzero(self.failure_state()[0])

    @property
    def broken(self) -> int:
        """Elements failed so far (a method that counts otherwise, links or cuts, gives its own)."""
        return int(np.count_nonzero(self.failure_state()[0]))

    def failure_labels(self, ids) -> list[str] | None:
        """The material each failure `ids` happened in, or the pair "A-B" it parted (events.csv's
        material column); None with one material."""
        if not self.several_materials:
            return None
        return material_labels(*self.failure_materials(ids), self.material_names)

    def failures_by_material(self) -> dict[str, int] | None:
        """Failures so far per material and per pair of materials (summary.json's
        `failures_by_material`); None with one material."""
        if not self.several_materials:
            return None
        return dict(Counter(self.failure_labels(self.failed_ids())))

    def _start_clock_and_tools(self, tools, tool_names, warnings: list[str] | None = None) -> None:
        """Time 0, the tools and their springs and load cell, and the set-up's warnings (a list
        the method's set-up may hold already, else a new one)."""
        self.tools = tools
        self._tool_names = list(tool_names)
        self.time = 0.0
        self.steps = 0
        self._springs = ToolSprings(tools, self._tool_names)
        self.load_cell = LoadCell(tools)
        self.warnings: list[str] = [] if warnings is None else warnings
        self.probes: list[Probe] = []  # the measurements the scenario asks for (set-up)

    def tool_names(self) -> list[str]:
        return list(self._tool_names)

    def fastest_motion(self) -> tuple[float, str]:
        """The fastest speed a tool is driven or launched at, or a point moves at now (m/s), and
        what it is (a tool by name, else "the specimen or a body")."""
        tools = self.tools
        fastest, what = 0.0, ""
        for j, name in enumerate(self._tool_names):
            speed = float(np.max(np.abs(tools.speeds[j, : tools.n[j]]), initial=0.0))
            if speed > fastest:
                fastest, what = speed, f"tool {name}"
        v = self.body.v
        points = float(np.sqrt(np.max(np.einsum("ij,ij->i", v, v), initial=0.0)))
        return (points, "the specimen or a body") if points > fastest else (fastest, what)

    def _advance_on_grid(self, n_steps: int, dt: float, every: int | None, compiled_steps, before=None, after=None):
        """n_steps of `compiled_steps(n, dt)` in pieces that end on the multiples of `every` (None:
        one piece), with `before(dt)` where a piece starts on a multiple and `after(dt)` where it
        ends on one: the checks (contact lists, fracture, crack growth) fall on the same steps
        however a run is split into advance calls, so its state does not depend on the split."""
        end = self.steps + n_steps
        while self.steps < end:
            if before is not None and self.steps % every == 0:
                before(dt)
            stop = end if every is None else min(end, (self.steps // every + 1) * every)
            compiled_steps(stop - self.steps, dt)
            self.steps = stop
            self.time = self.steps * dt  # the step count's time, not a sum of dt
            if after is not None and self.steps % every == 0:
                after(dt)

    def tool_forces(self) -> np.ndarray:
        """Force of each tool on the specimen (N), through the load cell."""
        return self.load_cell.forces(lambda: self._tool_springs().force.copy())

    def state_is_finite(self) -> bool:
        b = self.body
        return bool(np.isfinite(b.x).all() and np.isfinite(b.v).all())

    def where_unstable(self) -> str:
        """Where a run that went unstable moves fastest (the unstable mode is there): the point,
        its position and speed, and what the method says of it (describe_point), for the
        message the run stops with."""
        b = self.body
        speed = np.linalg.norm(b.v, axis=1)
        speed = np.where(np.isfinite(speed), speed, np.inf)
        g = int(np.argmax(speed))
        at = ", ".join(f"{c * 1e3:.4g}" for c in b.x[g])
        return f"; the fastest point: {g} at ({at}) mm, {speed[g]:.3g} m/s{self.describe_point(g)}"

    def describe_point(self, g: int) -> str:
        """A method's account of point g for where_unstable (its element, what acts on it)."""
        return ""

    def kinetic_energy(self) -> float:
        """Of the nodes' translation (a method with rotations adds theirs)."""
        b = self.body
        return float(0.5 * np.sum(b.mass * np.einsum("ij,ij->i", b.v, b.v)))

    def _tool_springs(self, dt: float | None = None) -> ToolSprings:
        """The tool springs now, or with the step dt at mid-step (the energy audit's)."""
        return self._springs.measure(self.body, self.time, dt)

    def external_work(self) -> float:
        """J put in: by the tools, supports, pressures and gravity on the nodes, the free tools, and
        the kinetic energy at t = 0."""
        return float(np.sum(self.body.w_external)) + self._initial_energy + self._springs.free_work()

    def energies(self, dt: float) -> dict[str, float]:
        """The energy.* columns in the order of their roles (analysis.energy.ENERGY_ROLES): kinetic,
        the stored terms, the dissipated ones, the external work; the shared terms (tool springs,
        node friction and damping) joined to the method's own."""
        b = self.body
        own = self.own_energies(dt)
        terms = {"kinetic": self.kinetic_energy(), **own,
                 "contact": own.get("contact", 0.0) + float(np.sum(self._tool_springs(dt).energy)),
                 "friction": own.get("friction", 0.0) + float(np.sum(b.d_friction)),
                 "damping": own.get("damping", 0.0) + float(np.sum(b.w_damping)),
                 "external": self.external_work()}
        return {f"{PREFIX}{name}": terms[name] for name in energy_order(terms)}

    # The units of the columns history_columns adds, registered once with the class that adds
    # them: a name ending in "*" covers the columns it begins (analysis.columns.column_unit).
    HISTORY_UNITS: dict[str, str] = {}

    def history_columns(self, dt: float) -> dict[str, float]:
        """A method's own history columns after `broken` (none by default; units in HISTORY_UNITS)."""
        return {}

    def history_units(self, columns) -> dict[str, str]:
        """{column: unit} of the history `columns` (a row's names), from where each was
        registered: the shared columns, the tools', the method's HISTORY_UNITS and its probes'
        units ("" for a column none registered)."""
        units = {**SHARED_HISTORY_UNITS, **tool_column_units(self._tool_names), **self.HISTORY_UNITS}
        for probe in self.probes:
            units.update(probe.units)
        return {name: column_unit(units, name) for name in columns}

    def sample(self, dt: float) -> dict[str, float]:
        row = tool_columns(self._tool_names, self.tool_forces(), self.tools)
        # dt: the step the method takes now (less than the driver's where it sub-steps: FDEM after
        # its tied phase, the meshfree after a rebuild stiffened it), which `sample` is given.
        row = {**row, **self.energies(dt), "broken": self.broken, "dt": dt, **self.history_columns(dt)}
        for probe in self.probes:
            row.update(probe.columns(self, row))
        return row

    def summary(self) -> dict:
        """summary.json's set-up facts and results, assembled: the method's own (own_summary),
        the probes', the failures per material (None with one material) and the warnings: the
        set-up's, then those the results raise (late_warnings)."""
        out = self.own_summary()
        for probe in self.probes:
            out.update(probe.summary(self))
        out["failures_by_material"] = self.failures_by_material()
        out["warnings"] = [*self.warnings, *self.late_warnings(out)]
        return out

    def own_summary(self) -> dict:
        """The method's set-up facts and results: at least `elements`, `particles` or `nodes`."""
        return {}

    def late_warnings(self, summary: dict) -> list[str]:
        """Warnings the results raise (the method's own_summary in `summary`); none by default."""
        return []

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corner of the specimen's points at set-up (a method whose points have a
        size, or whose set-up positions are elsewhere, gives its own)."""
        return self.x0.min(axis=0), self.x0.max(axis=0)

    def extra_plots(self, out_dir: Path, history) -> None:
        """The probes' figures (a method with figures of its own adds them)."""
        for probe in self.probes:
            probe.plots(self, out_dir)

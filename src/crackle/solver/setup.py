"""The set-up recipe every method follows, written once. A method's build_simulation calls it
with its own pieces, in this order:

    setup = SetUp(scenario, base, planned=(count, "nodes", "lattice.spacing"))  # loading, memory guard
    body = Nodes(**setup.body_arrays(x, mass, area, radius, scale))           # the supports held
    tools = setup.tools_on(body, penalty, element_size, slots, "nodes")       # tool table, seating
    ... the method's stable step, with tool_stiffness(tools, body.area) ...
    sim = MethodSimulation(...)  # _start_clock_and_tools(tools, setup.tool_names, setup.warnings)

A method whose builder is also called without a scenario (DEM's build_dem_simulation, FDEM's
build_fdem_model, the meshfree's build_meshfree_simulation) uses the scenario-free parts:
`tools_on_body`, `tool_stiffness`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..budget import check_model_size
from ..loading.arrays import seat_on_tools, tool_arrays
from ..loading.build import build_loading
from ..scenario import ScenarioError
from .body import body_arrays
from .integrator import support_constraints


def tools_on_body(tools, body, default_penalty: float, contact_depth: float, force_slots: int,
                  what: str = "points"):
    """The tool table (loading.arrays.tool_arrays: a tool without its own penalty gets
    `default_penalty`) and `body` seated on it; returns (table, the seating's set-up notes)."""
    tools = list(tools)
    table = tool_arrays(tools, default_penalty, contact_depth, force_slots)
    return table, seat_on_tools(tools, table, body, what)


def tool_stiffness(table, area) -> np.ndarray:
    """Each point's stiffest tool spring (N/m), the largest penalty times its contact area: what
    the tools add to a stable-step bound (0 without tools)."""
    return np.max(table.penalty, initial=0.0) * area


def supports_on(supports, points: np.ndarray, scale: float):
    """The support table of `points` (solver.integrator.support_constraints), a support that
    cannot hold them refused as the scenario's error."""
    try:
        return support_constraints(supports, points, scale)
    except ValueError as err:
        raise ScenarioError(f"supports: {err}") from None


class SetUp:
    """One method's set-up from its scenario: the loading (tools, supports, pressures), the memory
    guard on the model's planned size, and the set-up notes the run shows before its first step."""

    def __init__(self, scenario, base: Path | None, planned: tuple | None = None):
        """`planned`: (count, what, key[, note]) of budget.check_model_size, or None where the
        method checks its size itself once it knows it."""
        self.scenario = scenario
        self.tools, self.supports, self.pressures = build_loading(scenario, base)
        self.warnings: list[str] = []
        if planned is not None:
            self.check_size(*planned)

    def check_size(self, count: float, what: str, key: str, note: str = "") -> None:
        check_model_size(count, what, key, self.scenario.run.max_memory, note)

    @property
    def tool_names(self) -> list[str]:
        return [t.name for t in self.tools]

    def body_arrays(self, x, mass, area, radius, scale: float, velocity=None) -> dict:
        """solver.body.body_arrays with the scenario's supports held at x (scale: the model's size)."""
        return body_arrays(x, mass, area, radius, supports_on(self.supports, x, scale), velocity)

    def tools_on(self, body, default_penalty: float, contact_depth: float, force_slots: int, what: str = "points"):
        """The scenario's tool table with `body` seated on it (tools_on_body); the notes join the
        set-up's warnings."""
        table, notes = tools_on_body(self.tools, body, default_penalty, contact_depth, force_slots, what)
        self.warnings.extend(notes)
        return table

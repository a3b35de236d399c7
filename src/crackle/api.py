"""Python entry points: build a scenario into a simulation (by its method) and run it."""

from __future__ import annotations

from pathlib import Path

from .methods import get_method
from .scenario import RunSpec, ScenarioBase, ScenarioError, load_scenario
from .solver import RunControl, RunResult, StopConditions, choose_time_step, run


def run_control(run: RunSpec) -> RunControl:
    """The driver's settings from a scenario's [run]."""
    return RunControl(
        end_time=run.end_time,
        dt=run.dt,
        safety=run.safety,
        history_samples=run.history_samples,
        field_frames=run.field_frames,
        stop=StopConditions(run.stop.tool_displacement, run.stop.tool, run.stop.force_drop, run.stop.force_drop_hold),
    )


def build_simulation(scenario: ScenarioBase, base: Path | None = None):
    """The simulation of a validated scenario (built by its method) and the run control; a step
    larger than the stable one is refused here, before any output."""
    sim = get_method(scenario.method).build_simulation(scenario, base)
    control = run_control(scenario.run)
    try:
        choose_time_step(sim.stable_dt, control)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    return sim, control


def run_scenario(source, out_dir=None, overrides: list[str] | None = None, quick: bool = False, progress=None) -> RunResult:
    """Validate, build and run a scenario file or shipped example; returns the result."""
    scenario, base = load_scenario(source, overrides, quick)
    sim, control = build_simulation(scenario, base)
    control.progress = progress
    out = Path(out_dir) if out_dir is not None else Path("crackle-out") / scenario.name
    return run(sim, control, out, scenario_name=scenario.name)

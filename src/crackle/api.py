"""Python entry points: build a scenario into a simulation (by its method) and run it."""

from __future__ import annotations

import tempfile
from pathlib import Path

from .methods import get_method
from .scenario import RunSpec, ScenarioBase, ScenarioError, load_scenario
from .solver import RunControl, RunResult, StopConditions, choose_time_step, load_cell_steps, run


def run_control(run: RunSpec) -> RunControl:
    """The driver's settings from a scenario's [run]."""
    return RunControl(
        end_time=run.end_time,
        dt=run.dt,
        safety=run.safety,
        history_samples=run.history_samples,
        field_frames=run.field_frames,
        load_cell_window=run.load_cell_window,
        stop=StopConditions(run.stop.tool_displacement, run.stop.tool, run.stop.force_drop, run.stop.force_drop_hold),
    )


def build_simulation(scenario: ScenarioBase, base: Path | None = None):
    """The simulation of a validated scenario (built by its method) and the run control; a step
    larger than the stable one is refused here, before any output."""
    sim = get_method(scenario.method).build_simulation(scenario, base)
    control = run_control(scenario.run)
    try:
        load_cell_steps(control, choose_time_step(sim.stable_dt, control), sim.wave_transit)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    return sim, control


def run_scenario(source, out_dir=None, overrides: list[str] | None = None, quick: bool = False, progress=None) -> RunResult:
    """Validate, build and run a scenario file or shipped example; returns the result."""
    scenario, base = load_scenario(source, overrides, quick)
    out = Path(out_dir) if out_dir is not None else Path("crackle-out") / scenario.name
    check_output_folder(out)
    sim, control = build_simulation(scenario, base)
    control.progress = progress
    return run(sim, control, out, scenario_name=scenario.name)


def check_output_folder(out: Path) -> None:
    """Refuse, before any work, an output folder that is a file, lies under a file, or cannot be
    written (itself, or the nearest existing folder it would be made in)."""
    nearest = out
    while not nearest.exists() and nearest != nearest.parent:
        nearest = nearest.parent
    if nearest.exists() and not nearest.is_dir():
        where = "is a file" if nearest == out else f"lies under {nearest}, a file"
        raise ScenarioError(f"--out {out}: {where}; give a folder")
    try:
        # A probe that leaves nothing behind (os.access says yes to root on read-only mounts).
        with tempfile.TemporaryFile(dir=nearest):
            pass
    except OSError as err:
        raise ScenarioError(f"--out {out}: cannot write in {nearest} ({err.strerror}); choose a folder you can write to") from None

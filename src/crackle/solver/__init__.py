"""Explicit time integration shared by every method: the run driver (driver.py), the Simulation
protocol a method gives it (simulation.py), the compiled node update (integrator.py), failure
records (failures.py), the stable step by Lanczos (stability.py) and restart files
(checkpoint.py)."""

from .checkpoint import Checkpoint, CheckpointError, load_checkpoint
from .driver import (DiskFullError, RunControl, RunResult, StopConditions, StoppedAtOnce, UnstableRunError,
                     check_one_step_travel, choose_time_step, load_cell_steps, run, steps_to)
from .simulation import Simulation
from ..analysis.energy import energy_error

__all__ = ["Checkpoint", "CheckpointError", "DiskFullError", "StoppedAtOnce", "RunControl", "RunResult", "Simulation",
           "StopConditions", "UnstableRunError", "check_one_step_travel", "choose_time_step", "energy_error", "load_cell_steps",
           "load_checkpoint", "run", "steps_to"]

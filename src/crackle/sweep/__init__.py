"""Parameter sweeps on Dask (`crackle sweep`): plan.py says what runs, runner.py runs them,
table.py gathers their summaries into one table and plots."""

from .plan import SweepPlan, SweepRun, list_sweeps, make_plan
from .runner import SweepResult, run_sweep

__all__ = ["SweepPlan", "SweepRun", "SweepResult", "list_sweeps", "make_plan", "run_sweep"]

"""Methods by name: what `method = "..."` in a scenario picks.

A method is a package with two names in it:
  Scenario                      its scenario schema: scenario.ScenarioBase plus its own sections
  build_simulation(scenario, base) -> Simulation   (see solver.simulation.Simulation)
Adding a method: its folder, plus one line here. api.py and the command line never import a
method directly.
"""

from __future__ import annotations

import importlib
from types import ModuleType

METHODS = {
    "fdem": "crackle.fdem",
    "lattice": "crackle.lattice",
    "dem": "crackle.dem",
    "meshfree": "crackle.meshfree",
    "shell": "crackle.shell",
}


def get_method(name: str) -> ModuleType:
    """The method package registered as `name`; KeyError with the known names otherwise."""
    if name not in METHODS:
        raise KeyError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    return importlib.import_module(METHODS[name])

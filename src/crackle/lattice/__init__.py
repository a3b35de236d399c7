"""A toy method: a cubic mass-spring lattice. It exists to hold the driver contract (crackle.methods)
to a second method, and is the template a new method starts from: one folder, one registry line,
and everything else (scenario sections, tools, supports, integrator, load cell, failure records,
energy audit, outputs) shared."""

from .setup import Scenario, build_simulation

__all__ = ["Scenario", "build_simulation"]

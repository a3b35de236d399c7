"""FDEM (papers 001, 004): 4-node tets with a zero-thickness interface on every internal face."""

from .setup import Scenario, build_simulation

__all__ = ["Scenario", "build_simulation"]

"""Kirchhoff-Love shells on triangulated mid-surfaces with J-integral fracture mechanics (paper 002)."""

from .setup import Scenario, build_simulation

__all__ = ["Scenario", "build_simulation"]

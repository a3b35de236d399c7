"""Meshfree EFG particles through the wall of thin shells (paper 000): moving least-squares shape
functions with a quadratic basis and the quartic spline kernel in material coordinates, nodal
integration stabilised against the MLS approximation at each particle, explicit dynamics, J2
elasto-visco-plasticity or the thermo-elasto-viscoplastic law (material.py), fracture by link
breaking (fracture.py)."""

from .setup import Scenario, build_simulation

__all__ = ["Scenario", "build_simulation"]

"""Shared set-up for the FDEM physics tests (tests/fdem/test_fdem_law.py, tests/fdem/test_fdem_elastic.py)."""

from __future__ import annotations

import math

import numpy as np

from crackle.fdem.laws import GuoMunjizaLaw
from crackle.materials import Material
from crackle.analysis.energy import relative_imbalance

# Paper 001, Table 1: the rock of the FDEM validation examples.
RHO = 2340.0
E = 26e9
NU = 0.2
FT = 3e6  # tensile strength, Pa
COHESION = 15e6  # Pa
PHI_DEG = 30.0  # friction angle, degrees
GF = 10.0  # mode-I fracture energy, J/m^2
MU_FRICTION = 0.6  # Coulomb coefficient of failed faces (law default)


def rock(**law_overrides) -> Material:
    """Paper 001 Table 1 rock; keyword arguments override fields of the interface law."""
    law = dict(tensile_strength=FT, cohesion=COHESION, friction_angle=PHI_DEG, fracture_energy=GF)
    law.update(law_overrides)
    return Material(RHO, E, NU, GuoMunjizaLaw(**law), name="rock")


def lame() -> tuple[float, float]:
    """Lame constants (lambda, mu) of the rock, from E and nu directly."""
    lam = E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
    mu = E / (2.0 * (1.0 + NU))
    return lam, mu


def p_wave_speed() -> float:
    lam, mu = lame()
    return math.sqrt((lam + 2.0 * mu) / RHO)


def bar_wave_speed() -> float:
    return math.sqrt(E / RHO)


def energy_error(energies: dict[str, float]) -> float:
    """(external - sum of every other energy term) / external, from FdemSimulation.energies."""
    return relative_imbalance(energies)


def rotation(axis, angle_deg: float) -> np.ndarray:
    """Rotation matrix about `axis` by `angle_deg` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * (kx @ kx)

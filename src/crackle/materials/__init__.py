"""Materials: elastic constants plus a fracture law, and the lengths users need.

The fracture laws belong to their methods (FDEM interface laws: crackle.fdem.laws); a material
holds one and reads from it only what every law has (tensile strength, fracture energy, friction).
Every quantity is SI: Pa, kg/m^3, J/m^2, m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

@dataclass(frozen=True)
class Material:
    """An isotropic elastic solid with a fracture law (for FDEM, one of crackle.fdem.laws)."""

    density: float
    youngs_modulus: float
    poissons_ratio: float
    interface: Any = None
    name: str = "material"
    # {property: materials.random_properties.RandomProperty}: what is drawn per fracture site
    random: dict = field(default_factory=dict)

    @property
    def lame_lambda(self) -> float:
        E, nu = self.youngs_modulus, self.poissons_ratio
        return E * nu / ((1 + nu) * (1 - 2 * nu))

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2 * (1 + self.poissons_ratio))

    @property
    def p_wave_speed(self) -> float:
        """Dilatational wave speed sqrt((lambda + 2 mu) / rho) of the 3D continuum."""
        return math.sqrt((self.lame_lambda + 2 * self.shear_modulus) / self.density)

    @property
    def bar_wave_speed(self) -> float:
        """Wave speed sqrt(E / rho) in a slender bar (lateral faces free)."""
        return math.sqrt(self.youngs_modulus / self.density)

    @property
    def s_wave_speed(self) -> float:
        return math.sqrt(self.shear_modulus / self.density)

    @property
    def rayleigh_speed(self) -> float:
        """m/s, c_R ~ c_s (0.862 + 1.14 nu) / (1 + nu) (Viktorov's fit; 0.5 % for 0 <= nu <= 0.5)."""
        nu = self.poissons_ratio
        return self.s_wave_speed * (0.862 + 1.14 * nu) / (1.0 + nu)

    @property
    def process_zone(self) -> "ProcessZone":
        """Process-zone lengths of its interface law (eqs 10-11 of paper 001, 4-5 of paper 004)."""
        law = self.interface
        return process_zone(self.youngs_modulus, law.fracture_energy, law.tensile_strength)


@dataclass(frozen=True)
class ProcessZone:
    """Plastic (process) zone lengths ahead of a tensile crack tip, paper 001 eqs 10-11."""

    plastic_zone_long: float  # Westergaard, long crack: 3 pi E Gf / (32 ft^2)
    plastic_zone_short: float  # Muskhelishvili, short crack: 3 E Gf / (4 ft^2)
    advised_element_size: float  # a third of the long-crack length (paper 001, conclusions)

    def as_dict(self) -> dict:
        return {
            "plastic_zone_long": self.plastic_zone_long,
            "plastic_zone_short": self.plastic_zone_short,
            "advised_element_size": self.advised_element_size,
        }


def process_zone(youngs_modulus: float, fracture_energy: float, tensile_strength: float) -> ProcessZone:
    E, Gf, ft = youngs_modulus, fracture_energy, tensile_strength
    if E <= 0 or Gf <= 0 or ft <= 0:
        raise ValueError("E, Gf and ft must all be positive")
    long_ = 3 * math.pi * E * Gf / (32 * ft**2)
    short = 3 * E * Gf / (4 * ft**2)
    return ProcessZone(long_, short, long_ / 3.0)


__all__ = ["Material", "ProcessZone", "process_zone"]

"""Materials: elastic constants plus an interface (fracture) law, and the lengths users need.

Every quantity is SI: Pa, kg/m^3, J/m^2, m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Softening constants of the Munjiza/Guo curve z(D) (paper 001, eq. 7), fitted to direct-tension
# tests of concrete.
DEFAULT_SOFTENING = (0.63, 1.8, 6.0)

# Interface penalty: p_n = PENALTY_FACTOR * E / h and p_s = PENALTY_FACTOR * G / h, h the smaller
# altitude of the two tets onto the shared face. Each interface then adds about 1/PENALTY_FACTOR
# of a tet's own compliance. Measured softening of the intact exploded mesh in uniaxial tension:
# 2.7 % at 100, 1.4 % at 200, 0.3 % at 1000 (tests/test_fdem_elastic.py checks < 3 % at the
# default). The price is the time step, which shrinks as 1/sqrt(PENALTY_FACTOR) once the
# interfaces are the stiffest part (the usual FDEM trade-off).
DEFAULT_PENALTY_FACTOR = 200.0

# Contact between free surfaces and against tools: penalty per unit area CONTACT_PENALTY_FACTOR *
# E / h (the usual FDEM order of magnitude, ~10 E / h); see fdem.model for why it is softer than
# the interfaces.
CONTACT_PENALTY_FACTOR = 10.0


def softening_z(damage: float, a: float, b: float, c: float) -> float:
    """Remaining fraction of strength at damage D in [0, 1] (paper 001, eq. 7)."""
    d = min(max(damage, 0.0), 1.0)
    decay = 1.0 - (a + b - 1.0) / (a + b) * math.exp(d * (a + c * b) / ((a + b) * (1.0 - a - b)))
    return decay * (a * (1.0 - d) + b * (1.0 - d) ** c)


def softening_integral(a: float, b: float, c: float, n: int = 2000) -> float:
    """Integral of z(D) over D in [0, 1] (Simpson); 0.3863 for the default constants.

    The paper approximates it by 1/3 to get d_c = 3 Gf / f (eq. 5); we use the exact value so
    that a full separation dissipates exactly Gf.
    """
    h = 1.0 / n
    s = softening_z(0.0, a, b, c) + softening_z(1.0, a, b, c)
    for i in range(1, n):
        s += (4 if i % 2 else 2) * softening_z(i * h, a, b, c)
    return s * h / 3.0


@dataclass(frozen=True)
class GuoMunjizaLaw:
    """Guo-Munjiza interface law: Mohr-Coulomb with tension cut-off and z(D) softening (paper 001).

    tensile_strength ft, cohesion c and friction_angle phi (degrees) give the peaks: f_t in
    tension and f_s = c - sigma_n tan(phi) in shear (eq. 3). fracture_energy Gf (mode I) and
    fracture_energy_shear (mode II, defaults to Gf) are the energies one unit area dissipates
    from intact to failed. friction is the Coulomb coefficient between the faces once failed.
    """

    tensile_strength: float
    cohesion: float
    friction_angle: float
    fracture_energy: float
    fracture_energy_shear: float | None = None
    softening: tuple[float, float, float] = DEFAULT_SOFTENING
    friction: float = 0.6
    penalty_factor: float = DEFAULT_PENALTY_FACTOR

    name = "guo-munjiza"

    @property
    def gf_shear(self) -> float:
        return self.fracture_energy if self.fracture_energy_shear is None else self.fracture_energy_shear

    @property
    def softening_area(self) -> float:
        return softening_integral(*self.softening)


# Benzeggagh-Kenane exponent of Camanho & Davila (2002), and the power-law exponent of the
# quadratic (Ye) criterion.
DEFAULT_BK_EXPONENT = 1.45
DEFAULT_POWER_EXPONENT = 2.0


@dataclass(frozen=True)
class BilinearLaw:
    """Bilinear cohesive (traction-separation) law, paper 004; Camanho-Davila mixed mode.

    tensile_strength tn0 and shear_strength ts0 (Pa) are the nominal strengths (initiation when
    max(<tn>/tn0, ts/ts0) = 1, the normal traction counted only in tension); fracture_energy GIc
    and fracture_energy_shear GIIc (J/m^2, GIIc defaults to GIc) the energies a unit area
    dissipates from intact to failed in pure mode I and II; normal_stiffness kn and
    shear_stiffness ks (N/m^3) the initial stiffnesses per unit area, also the contact penalties
    once failed. mixed_mode "bk" (Benzeggagh-Kenane, bk_exponent eta) or "power" (power law,
    power_exponent alpha) gives Gc at a mode mix. friction: Coulomb coefficient once failed.
    """

    tensile_strength: float
    shear_strength: float
    fracture_energy: float
    normal_stiffness: float
    shear_stiffness: float
    fracture_energy_shear: float | None = None
    mixed_mode: str = "bk"
    bk_exponent: float = DEFAULT_BK_EXPONENT
    power_exponent: float = DEFAULT_POWER_EXPONENT
    friction: float = 0.6

    name = "bilinear"

    def __post_init__(self):
        for key in ("tensile_strength", "shear_strength", "fracture_energy", "normal_stiffness",
                    "shear_stiffness", "bk_exponent", "power_exponent"):
            if not getattr(self, key) > 0:
                raise ValueError(f"bilinear law: {key} must be positive (got {getattr(self, key)!r})")
        if self.fracture_energy_shear is not None and not self.fracture_energy_shear > 0:
            raise ValueError(f"bilinear law: fracture_energy_shear must be positive (got {self.fracture_energy_shear!r})")
        if self.friction < 0:
            raise ValueError(f"bilinear law: friction must be >= 0 (got {self.friction!r})")
        if self.mixed_mode not in ("bk", "power"):
            raise ValueError(f"bilinear law: mixed_mode must be 'bk' or 'power' (got {self.mixed_mode!r})")
        problem = bilinear_snap_back(self)
        if problem:
            raise ValueError(f"bilinear law: {problem}")

    @property
    def gf_shear(self) -> float:
        return self.fracture_energy if self.fracture_energy_shear is None else self.fracture_energy_shear

    @property
    def mixed_mode_exponent(self) -> float:
        return self.bk_exponent if self.mixed_mode == "bk" else self.power_exponent


def bilinear_snap_back(law) -> str | None:
    """Why the law's softening would snap back (Gc below the elastic energy t0^2 / 2k at the
    peak, so df < d0) in pure mode I or II, or None."""
    gf2 = law.fracture_energy if law.fracture_energy_shear is None else law.fracture_energy_shear
    for g, g_name, t0, t_name, k, k_name in (
        (law.fracture_energy, "fracture_energy", law.tensile_strength, "tensile_strength", law.normal_stiffness, "normal_stiffness"),
        (gf2, "fracture_energy_shear", law.shear_strength, "shear_strength", law.shear_stiffness, "shear_stiffness"),
    ):
        peak = t0 * t0 / (2.0 * k)
        if g <= peak:
            return (
                f"{g_name} = {g:g} J/m^2 is not above the elastic energy at the peak, "
                f"{t_name}^2 / (2 {k_name}) = {peak:g} J/m^2: the softening would snap back; "
                f"raise {g_name} or {k_name}, or lower {t_name}"
            )
    return None


@dataclass(frozen=True)
class Material:
    """An isotropic elastic solid with an interface law for FDEM."""

    density: float
    youngs_modulus: float
    poissons_ratio: float
    interface: GuoMunjizaLaw | BilinearLaw | None = None
    name: str = "material"

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


__all__ = [
    "BilinearLaw",
    "CONTACT_PENALTY_FACTOR",
    "DEFAULT_PENALTY_FACTOR",
    "DEFAULT_SOFTENING",
    "GuoMunjizaLaw",
    "Material",
    "ProcessZone",
    "process_zone",
    "softening_integral",
    "softening_z",
]

"""Linear cohesive law of Camacho & Ortiz (1996), as Akantu's `cohesive_linear` states it: one
critical stress sigma_c, one fracture energy G_c, the shear weight beta of the effective opening,
and a penalty for the interface's elastic branch and for compression.

* Effective opening delta = sqrt(<dn>^2 + beta^2 |s|^2); effective traction linear up to sigma_c
  at delta_0 = sigma_c / pn, then softening linearly to zero at delta_c = 2 G_c / sigma_c, the
  same G_c in any mode mix; unloading to the origin (secant); compression on the penalty pn.
* The normal traction (t / delta) dn, the shear traction beta^2 (t / delta) s: a face opens when
  (tn / sigma_c)^2 + (ts / (beta sigma_c))^2 = 1, the magnitude of its traction at sigma_c for
  beta = 1.

That is the bilinear law (fdem.laws.bilinear) with kn = pn, ks = beta^2 pn, ts0 = beta sigma_c,
GIc = GIIc = G_c and the quadratic initiation: its row is the bilinear row, and the bilinear
law's compiled pieces (forces, energy, extrinsic insertion) step it. What is this law's own is its
parameters, read as an Akantu or Abaqus user writes them, and its penalty per element,
pn = penalty_factor E / h (h the smaller tet altitude onto the face), as Guo-Munjiza's.
"""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from pydantic import model_validator
from pydantic.dataclasses import dataclass

from ...schema import STRICT_DATACLASS, NonNegative, Positive, check_unit_slips
from . import bilinear
from .bilinear import INITIATIONS, LAW_GF1, LAW_GF2, LAW_INITIATION, LAW_MIX, LAW_MIX_EXP, LAW_TS, MIX_BK
from .guo_munjiza import DEFAULT_PENALTY_FACTOR, EXTRINSIC_PENALTY_FACTOR
from .row import new_row


@dataclass(frozen=True, config=STRICT_DATACLASS)
class LinearLaw:
    """Linear cohesive law (Camacho & Ortiz 1996; Akantu's cohesive_linear): sigma_c, G_c, beta.

    tensile_strength sigma_c (Pa): the peak of the effective traction; fracture_energy G_c
    (J/m^2): dissipated by a unit area from intact to failed, in any mode mix; shear_ratio beta:
    the weight of the slip in the effective opening (the shear strength is beta sigma_c);
    penalty_factor: pn = factor E / h, the elastic branch's stiffness and the contact's once
    failed (the shear's is beta^2 pn); friction: the Coulomb coefficient once failed.
    """

    tensile_strength: Positive
    """Pa, sigma_c: the peak of the effective traction"""
    fracture_energy: Positive
    """J/m^2, G_c: dissipated by a unit area from intact to failed, whatever the mode mix"""
    shear_ratio: Positive = 1.0
    """beta: the effective opening is sqrt(<dn>^2 + beta^2 |s|^2); the shear strength is beta sigma_c"""
    penalty_factor: Positive | None = None
    """interface penalty pn = factor E / h (h: the smaller tet altitude onto the face), the shear's beta^2 pn;
    default 200 intrinsic, 2 extrinsic (as the Guo-Munjiza law's)"""
    friction: NonNegative = 0.6
    """Coulomb coefficient between the faces once failed"""
    insertion: Literal["intrinsic", "extrinsic"] = "intrinsic"
    """"intrinsic": every internal face carries the law from the start; "extrinsic": a face is inserted at
    sigma_c when the traction of its two tets reaches it (Camacho-Ortiz, Akantu's extrinsic cohesive elements)"""
    insertion_stress: Literal["either", "mean"] = "either"
    """extrinsic: the stress a tied face is checked with: "either" (each of its two tets' traction) or "mean"
    (the traction of their mean stress)"""
    law: Literal["linear"] = "linear"
    """picks this law"""

    kind: ClassVar[int] = bilinear.BilinearLaw.kind  # stepped by the bilinear law's compiled pieces
    # Per-face draws would have to move sigma_c, beta sigma_c and both energies together: none.
    RANDOM: ClassVar[dict[str, int]] = {}

    @model_validator(mode="after")
    def _no_unit_slip(self):
        check_unit_slips(self)
        return self

    @property
    def penalty(self) -> float:
        """The penalty factor in use (the default depends on the insertion)."""
        if self.penalty_factor is not None:
            return self.penalty_factor
        return EXTRINSIC_PENALTY_FACTOR if self.insertion == "extrinsic" else DEFAULT_PENALTY_FACTOR

    def table_row(self) -> np.ndarray:
        row = new_row(self.kind, self.tensile_strength, self.friction, self.insertion, self.insertion_stress)
        row[LAW_TS] = self.shear_ratio * self.tensile_strength
        row[LAW_GF1] = row[LAW_GF2] = self.fracture_energy
        row[LAW_MIX] = MIX_BK  # with GIc = GIIc every mix rule gives G_c
        row[LAW_MIX_EXP] = bilinear.DEFAULT_BK_EXPONENT
        row[LAW_INITIATION] = INITIATIONS.index("quadratic")
        return row

    def stiffness(self, youngs_modulus, shear_modulus, altitude):
        """(pn, ps) for every interface: penalty_factor E / h, and beta^2 times it."""
        pn = self.penalty * np.asarray(youngs_modulus, dtype=float) / np.asarray(altitude, dtype=float)
        return pn, self.shear_ratio**2 * pn

    def drawn_rows_problem(self, rows: np.ndarray, pn: np.ndarray, ps: np.ndarray) -> str | None:
        """Why the faces' rows would snap back (G_c <= sigma_c^2 / 2 pn), or None."""
        snaps = rows[:, LAW_GF1] <= rows[:, bilinear.LAW_FT] ** 2 / (2.0 * pn)
        if snaps.any():
            return (f"{int(snaps.sum()):,} of {len(rows):,} faces would snap back (G_c <= sigma_c^2 / 2 pn): raise "
                    "fracture_energy or penalty_factor")
        return None

    @property
    def opens_on_normal_traction(self) -> str | None:
        """Never: a face opens on the magnitude of its traction (the quadratic criterion)."""
        return None

"""The layout of an interface law's row in the law table the kernels read (one row per law in
use, Interfaces.law_table; each interface holds the index of its row). Columns every law fills
come first; a law's own parameters follow from OWN."""

from __future__ import annotations

import numpy as np

# Which law (its KIND), the tensile strength (the weaker side of a two-material interface
# governs), the Coulomb coefficient of the faces once failed (paired contact) and whether the
# interfaces are inserted when the stress reaches the strength (extrinsic, 1.0) or carry the law
# from the start (intrinsic, 0.0); the stress an extrinsic face is checked with (LAW_SAMPLING:
# INSERTION_STRESSES, fdem.extrinsic.try_insert).
LAW_KIND, LAW_FT, LAW_MU, LAW_EXTRINSIC, LAW_SAMPLING = 0, 1, 2, 3, 4
OWN = 5
LAW_COLUMNS = 14

INSERTIONS = ("intrinsic", "extrinsic")
# "either": the traction of each of the face's two tets, the more critical one; "mean": the
# traction of their mean stress.
INSERTION_STRESSES = ("either", "mean")
SAMPLE_EITHER, SAMPLE_MEAN = 0, 1


def new_row(kind: int, tensile_strength: float, friction: float, insertion: str, insertion_stress: str) -> np.ndarray:
    row = np.zeros(LAW_COLUMNS)
    row[LAW_KIND] = kind
    row[LAW_FT] = tensile_strength
    row[LAW_MU] = friction
    row[LAW_EXTRINSIC] = INSERTIONS.index(insertion)
    row[LAW_SAMPLING] = INSERTION_STRESSES.index(insertion_stress)
    return row

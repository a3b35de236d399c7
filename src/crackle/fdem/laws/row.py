"""The layout of an interface law's row in the law table the kernels read (one row per law in
use, Interfaces.law_table; each interface holds the index of its row). Columns every law fills
come first; a law's own parameters follow from OWN."""

from __future__ import annotations

import numpy as np

# Which law (its KIND), the tensile strength (the weaker side of a two-material interface
# governs), the Coulomb coefficient of the faces once failed (paired contact) and whether the
# interfaces are inserted when the stress reaches the strength (extrinsic, 1.0) or carry the law
# from the start (intrinsic, 0.0).
LAW_KIND, LAW_FT, LAW_MU, LAW_EXTRINSIC = 0, 1, 2, 3
OWN = 4
LAW_COLUMNS = 12

INSERTIONS = ("intrinsic", "extrinsic")


def new_row(kind: int, tensile_strength: float, friction: float, insertion: str) -> np.ndarray:
    row = np.zeros(LAW_COLUMNS)
    row[LAW_KIND] = kind
    row[LAW_FT] = tensile_strength
    row[LAW_MU] = friction
    row[LAW_EXTRINSIC] = INSERTIONS.index(insertion)
    return row

"""The layout of an interface law's row in the law table the kernels read (one row per law in
use, Interfaces.law_table; each interface holds the index of its row). Columns every law fills
come first; a law's own parameters follow from OWN."""

from __future__ import annotations

import numpy as np

# Which law (its KIND), the tensile strength (the weaker side of a two-material interface
# governs) and the Coulomb coefficient of the faces once failed (paired contact).
LAW_KIND, LAW_FT, LAW_MU = 0, 1, 2
OWN = 3
LAW_COLUMNS = 12


def new_row(kind: int, tensile_strength: float, friction: float) -> np.ndarray:
    row = np.zeros(LAW_COLUMNS)
    row[LAW_KIND] = kind
    row[LAW_FT] = tensile_strength
    row[LAW_MU] = friction
    return row

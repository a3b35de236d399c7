"""Nominal strengths of the standard strength tests, from the load cell's peak and the specimen.

Direct tension: a specimen pulled by a glued grip or a moving support; its nominal strength is
the grip's peak force
over the mean cross-section normal to the pull (volume / extent along it), and
tensile_strength_ratio compares it with the tensile strength the material was given: 1 for a
bar small against the characteristic length E Gf / ft^2, whatever the mesh and the insertion.
Brazilian disc: the elastic relation 2 F / (pi D t) and the splitting fracture's angle to the
loading axis (analysis.brazilian).
Compression between platens: the modulus read from the platen stress-strain curve
(`platen_modulus`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .brazilian import brazilian_strength, splitting_angle


@dataclass(frozen=True)
class TensionTest:
    """A grip pulling the specimen (a glued tool, or a moving support's tool): tool index, section
    (m^2), the material's ft (Pa)."""

    tool: int
    section: float
    tensile_strength: float

    def summary(self, peaks: np.ndarray) -> dict:
        strength = float(peaks[self.tool]) / self.section
        return {"loaded_area": self.section, "nominal_strength": strength,
                "tensile_strength_ratio": strength / self.tensile_strength}


@dataclass(frozen=True)
class BrazilianTest:
    """A disc between platens: diameter and thickness (m), centre, disc axis, loading axis."""

    diameter: float
    thickness: float
    center: tuple[float, float, float]
    axis: tuple[float, float, float]
    load_axis: tuple[float, float, float]

    def summary(self, peaks: np.ndarray, events: dict) -> dict:
        angle, _ = splitting_angle(events, self.load_axis, 0.5 * self.diameter, self.center, self.axis)
        return {"brazilian_strength": brazilian_strength(float(np.max(peaks, initial=0.0)), self.diameter, self.thickness),
                # JSON has no NaN: None until three tension or mixed failures near the centre.
                "splitting_angle": angle if math.isfinite(angle) else None}


def ahead_of(tool, points: np.ndarray) -> bool:
    """Whether the tool's centre lies beyond the specimen's centroid along the tool's direction:
    moving, it leaves the specimen (a grip that pulls) rather than pressing on it."""
    d = np.asarray(tool.direction, dtype=float)
    return float((np.asarray(tool.center, dtype=float) - points.mean(axis=0)) @ d) > 0.0


def pulling_grip(tools, points: np.ndarray, supports=(), scale: float = 1.0) -> int | None:
    """The first glued, moving tool that lies ahead of the specimen along its direction (it pulls
    the specimen's far end), else the first moving support whose points lie ahead of the
    specimen's centroid along its motion (`scale`: the specimen size, for its selection's
    tolerance), as its tool's index; or None."""
    for j, tool in enumerate(tools):
        if tool.glued and tool.moves and ahead_of(tool, points):
            return j
    centroid = points.mean(axis=0)
    for support in supports:
        if support.tool < 0 or not tools[support.tool].moves:
            continue
        held = points[support.where.mask(points, scale)]
        if len(held) and float((held.mean(axis=0) - centroid) @ np.asarray(tools[support.tool].direction)) > 0.0:
            return support.tool
    return None


def mean_section(volume: float, points: np.ndarray, direction) -> float:
    """The mean cross-section normal to `direction`: volume over the extent along it."""
    d = np.asarray(direction, float)
    along = points @ (d / np.linalg.norm(d))
    return volume / float(along.max() - along.min())


# The stress window of platen_modulus, as fractions of the peak stress: above a seating toe, below
# the bond or crack damage that bends a rock's curve before its peak (ISRM's "average modulus of
# the linear portion").
MODULUS_WINDOW = (0.2, 0.5)


def platen_modulus(strain: np.ndarray, stress: np.ndarray) -> float | None:
    """Pa: the least-squares slope of stress against strain over the rows before the peak stress
    whose stress lies within MODULUS_WINDOW of the peak; None with fewer than three such rows."""
    strain, stress = np.asarray(strain, float), np.asarray(stress, float)
    if len(stress) < 3:
        return None
    peak = int(np.argmax(stress))
    lo, hi = MODULUS_WINDOW[0] * stress[peak], MODULUS_WINDOW[1] * stress[peak]
    rows = np.flatnonzero((stress[:peak] >= lo) & (stress[:peak] <= hi))
    if len(rows) < 3 or np.ptp(strain[rows]) <= 0.0:
        return None
    return float(np.polyfit(strain[rows], stress[rows], 1)[0])

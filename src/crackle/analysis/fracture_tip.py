"""Tip and plastic-zone length of a planar fracture (paper 001, section 3.1).

The paper measures the plastic zone from the actual fracture tip, where the interfaces have
failed, to the point where the stress normal to the fracture reaches ft. In the interface law
that point is where softening starts: the plastic zone is the band of interfaces with an opening
between the peak and the critical one, 0 < D < 1. We therefore measure it on the interfaces of
the fracture plane: tip = the farthest failed one along the growth direction, front = the
farthest damaged-but-intact one ahead of the tip; length = front - tip, along the growth
direction (centroid positions, so the resolution is the element size).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FracturePlane:
    """Where to look: a plane (point, normal) and the growth direction in it."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    direction: tuple[float, float, float]
    tol: float  # m: interface centroids this close to the plane belong to it


def tip_and_plastic_zone(plane: FracturePlane, centroids: np.ndarray, damage: np.ndarray, failed: np.ndarray) -> tuple[float, float]:
    """(tip, plastic-zone length) in m: tip measured along `direction` from `point`.

    centroids (k, 3) of the interfaces, their damage D in [0, 1] and whether each has failed
    (pre-cracks included). With no failed interface on the plane the tip is at -inf and the
    length 0."""
    n = np.asarray(plane.normal, float)
    d = np.asarray(plane.direction, float)
    n /= np.linalg.norm(n)
    d = d - (d @ n) * n
    d /= np.linalg.norm(d)
    rel = centroids - np.asarray(plane.point, float)
    on = np.abs(rel @ n) <= plane.tol
    along = rel @ d
    broken = on & failed
    if not broken.any():
        return -np.inf, 0.0
    tip = float(along[broken].max())
    softening = on & ~failed & (damage > 0.0) & (along > tip)
    front = float(along[softening].max()) if softening.any() else tip
    return tip, front - tip


def propagating_plastic_zone(tips: np.ndarray, lengths: np.ndarray) -> float:
    """The plastic-zone length while the fracture grows: the median over the samples whose tip
    has left its initial position and whose zone is open (nan if there are none)."""
    tips = np.asarray(tips, float)
    lengths = np.asarray(lengths, float)
    moving = np.isfinite(tips) & (tips > tips[0]) & (lengths > 0.0)
    return float(np.median(lengths[moving])) if moving.any() else float("nan")

"""Loading index of a multi-point load (paper 004, section 2.4, eqs 6-7).

The contact forces of N plates on a particle point along unit vectors given by their top
(polar) angle theta and azimuth phi; the 3 x N matrix A of those vectors (eq. 7) has singular
values p1 >= p2 >= p3 (zeros where N < 3), and the index is their spread about their mean,
I = sqrt(sum (p_k - mean p)^2). Two opposite plates give a rank-one A with singular values
(sqrt 2, 0, 0): I = 2 / sqrt 3 for any axis. Four plates along the directions of a regular
tetrahedron give A A^T = (4/3) Id, three equal singular values: I = 0.
"""

from __future__ import annotations

import numpy as np


def loading_directions(polar_deg, azimuth_deg) -> np.ndarray:
    """Eq. 7: the 3 x N matrix of unit force directions from top and azimuth angles (degrees)."""
    theta = np.radians(np.asarray(polar_deg, float))
    phi = np.radians(np.asarray(azimuth_deg, float))
    if theta.shape != phi.shape or theta.ndim != 1 or len(theta) < 1:
        raise ValueError("give one top angle and one azimuth per plate")
    return np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def loading_index(polar_deg, azimuth_deg) -> float:
    """The singular-value spread I of paper 004 for plates at the given angles (degrees)."""
    return loading_index_of(loading_directions(polar_deg, azimuth_deg))


def loading_index_of(directions) -> float:
    """I for force directions given as the columns of a 3 x N matrix (normalised here)."""
    a = np.asarray(directions, float).reshape(3, -1)
    a = a / np.linalg.norm(a, axis=0)
    p = np.zeros(3)
    s = np.linalg.svd(a, compute_uv=False)
    p[: len(s)] = s
    return float(np.sqrt(np.sum((p - p.mean()) ** 2)))

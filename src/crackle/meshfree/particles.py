"""Particles of a plate: a box whose thinnest side is the wall thickness, filled with a grid of
particles, `layers` of them through the thickness (on both faces and evenly between) and a
spacing as close as fits to the asked one along the two in-plane sides (on the edges and evenly
between). Each particle owns the cell of the grid around it (half a cell on a face or edge):
that is its nodal volume (the quadrature weight of nodal integration, and mass = density x
volume) and its contact area is that cell's in-plane area."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PlateParticles:
    X: np.ndarray  # (n, 3) m, material (reference) positions
    volume: np.ndarray  # (n,) m^3
    area: np.ndarray  # (n,) m^2, in-plane cell area (contact area against tools)
    thickness_axis: int  # 0, 1 or 2: the box's thinnest side
    spacing: np.ndarray  # (3,) m, grid step along x, y, z as used
    layers: int
    cell_lo: np.ndarray  # (n, 3) m, lower corner of each particle's cell (its nodal integration domain)
    cell_hi: np.ndarray  # (n, 3) m, upper corner


def plate_particles(origin, size, spacing: float, layers: int) -> PlateParticles:
    """The particle grid of the box [origin, origin + size]; raises ValueError naming what is
    too coarse."""
    size = np.asarray(size, dtype=float)
    origin = np.asarray(origin, dtype=float)
    axis = int(np.argmin(size))
    counts = []
    for k in range(3):
        counts.append(layers if k == axis else int(round(size[k] / spacing)) + 1)
    if min(c for k, c in enumerate(counts) if k != axis) < 3:
        raise ValueError("spacing: fewer than 3 particles along an in-plane side; make it smaller")
    steps = size / (np.array(counts) - 1)
    grids = [origin[k] + steps[k] * np.arange(counts[k]) for k in range(3)]
    # A particle's share of its side: half a step at both ends.
    shares = []
    for k in range(3):
        share = np.full(counts[k], steps[k])
        share[0] = share[-1] = 0.5 * steps[k]
        shares.append(share)
    gx, gy, gz = np.meshgrid(*grids, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    sx, sy, sz = np.meshgrid(*shares, indexing="ij")
    cell = np.stack([sx.ravel(), sy.ravel(), sz.ravel()], axis=1)
    volume = np.prod(cell, axis=1)
    area = volume / cell[:, axis]
    cell_lo = np.maximum(X - 0.5 * steps, origin)
    cell_hi = np.minimum(X + 0.5 * steps, origin + size)
    return PlateParticles(X, volume, area, axis, steps, layers, cell_lo, cell_hi)

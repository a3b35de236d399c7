"""Kinematics of an interface of the exploded FDEM mesh: interface i joins face na[i] (side A)
to face nb[i] (side B), point pair p being nodes na[i, p] and nb[i, p] that start coincident.
Shared by the interface laws (fdem.laws) and the contact of failed pairs (fdem.kernels)."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def mid_normal(x, na, nb, i):
    """Unit normal of the mid-surface of interface i, pointing from side A to side B."""
    a0, a1, a2 = na[i, 0], na[i, 1], na[i, 2]
    b0, b1, b2 = nb[i, 0], nb[i, 1], nb[i, 2]
    p0x = 0.5 * (x[a0, 0] + x[b0, 0])
    p0y = 0.5 * (x[a0, 1] + x[b0, 1])
    p0z = 0.5 * (x[a0, 2] + x[b0, 2])
    ux = 0.5 * (x[a1, 0] + x[b1, 0]) - p0x
    uy = 0.5 * (x[a1, 1] + x[b1, 1]) - p0y
    uz = 0.5 * (x[a1, 2] + x[b1, 2]) - p0z
    wx = 0.5 * (x[a2, 0] + x[b2, 0]) - p0x
    wy = 0.5 * (x[a2, 1] + x[b2, 1]) - p0y
    wz = 0.5 * (x[a2, 2] + x[b2, 2]) - p0z
    nx = uy * wz - uz * wy
    ny = uz * wx - ux * wz
    nz = ux * wy - uy * wx
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * inv, ny * inv, nz * inv


@njit(cache=True, inline="always")
def opening(x, na, nb, i, p, nx, ny, nz):
    """Normal opening and tangential slip vector of point pair p of interface i."""
    a = na[i, p]
    b = nb[i, p]
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    dn = dx * nx + dy * ny + dz * nz
    return dn, dx - dn * nx, dy - dn * ny, dz - dn * nz


@njit(cache=True, inline="always")
def opening_earlier(dn, lag, v, a, b, nx, ny, nz):
    """Normal opening of point pair (a, b) `lag` seconds before dn along this step's motion (v:
    the velocities over the half step that led to dn): lag = dt gives the opening before the
    step, dt / 2 the one at the half step, where the explicit scheme's energies are measured."""
    return dn - lag * ((v[b, 0] - v[a, 0]) * nx + (v[b, 1] - v[a, 1]) * ny + (v[b, 2] - v[a, 2]) * nz)

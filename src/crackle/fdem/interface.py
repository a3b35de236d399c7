"""Kinematics of an interface of the exploded FDEM mesh: interface i joins face na[i] (side A)
to face nb[i] (side B), point pair p being nodes na[i, p] and nb[i, p] that start coincident.
Shared by the interface laws (fdem.laws) and the contact of failed pairs (fdem.kernels)."""

from __future__ import annotations

import math

from numba import njit


# The pairs of a failed face press along the normal of the triangle through their mid-points.
# Where the two faces have turned far from each other (a loose tet spun in a crushed zone), that
# triangle shrinks to nothing, its normal swings from step to step and the turning forces of the
# pressed pairs (turning_forces: dE/dn over its area) grow without bound: a walnut crushed by six
# plates blew up when one such face gave a resting tet 675 m/s in one step. Below this fraction
# of the face's area the faces no longer face each other and their pairs leave paired contact.
MID_FACE_MIN = 0.5


@njit(cache=True, inline="always")
def mid_face(x, na, nb, i):
    """Unit normal of the mid-surface of interface i, pointing from side A to side B, and the
    area of the triangle through its point pairs' mid-points."""
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
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    inv = 1.0 / length
    return nx * inv, ny * inv, nz * inv, 0.5 * length


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


@njit(cache=True, inline="always")
def turning_forces(x, na, nb, i, nx, ny, nz, qx, qy, qz, out):
    """The forces that a potential E(g_p . n) of interface i's point pairs exerts through the
    turn of the mid normal n, for q = dE/dn (the pairs' tractions times their area share times
    their slips, summed): -dE/dm_j on the mid-point m_j of pair j, half of it into out[i, j] for
    each of the pair's two nodes. A failed pair slid along its face (g_p far from normal) feels
    them: without them the penalty force -p_n dn n is not the gradient of the energy the audit
    books, and a pressed pair sliding over a turning face makes energy from nothing (a walnut
    crushed by five plates: -5 % of the work, docs/validation.md)."""
    a0, a1, a2 = na[i, 0], na[i, 1], na[i, 2]
    b0, b1, b2 = nb[i, 0], nb[i, 1], nb[i, 2]
    ux = 0.5 * (x[a1, 0] + x[b1, 0] - x[a0, 0] - x[b0, 0])
    uy = 0.5 * (x[a1, 1] + x[b1, 1] - x[a0, 1] - x[b0, 1])
    uz = 0.5 * (x[a1, 2] + x[b1, 2] - x[a0, 2] - x[b0, 2])
    wx = 0.5 * (x[a2, 0] + x[b2, 0] - x[a0, 0] - x[b0, 0])
    wy = 0.5 * (x[a2, 1] + x[b2, 1] - x[a0, 1] - x[b0, 1])
    wz = 0.5 * (x[a2, 2] + x[b2, 2] - x[a0, 2] - x[b0, 2])
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    # dn = (I - n n^T) dN / |N| with N = u x w: only q's part in the face plane turns E.
    qn = qx * nx + qy * ny + qz * nz
    inv = 1.0 / math.sqrt(cx * cx + cy * cy + cz * cz)
    tx = (qx - qn * nx) * inv
    ty = (qy - qn * ny) * inv
    tz = (qz - qn * nz) * inv
    # dE/dm1 = w x t, dE/dm2 = t x u, dE/dm0 = -(both): E does not change under a translation.
    g1x = wy * tz - wz * ty
    g1y = wz * tx - wx * tz
    g1z = wx * ty - wy * tx
    g2x = ty * uz - tz * uy
    g2y = tz * ux - tx * uz
    g2z = tx * uy - ty * ux
    out[i, 0, 0] = 0.5 * (g1x + g2x)
    out[i, 0, 1] = 0.5 * (g1y + g2y)
    out[i, 0, 2] = 0.5 * (g1z + g2z)
    out[i, 1, 0] = -0.5 * g1x
    out[i, 1, 1] = -0.5 * g1y
    out[i, 1, 2] = -0.5 * g1z
    out[i, 2, 0] = -0.5 * g2x
    out[i, 2, 1] = -0.5 * g2y
    out[i, 2, 2] = -0.5 * g2z

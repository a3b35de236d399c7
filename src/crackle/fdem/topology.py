"""Shared conventions of the exploded FDEM mesh."""

from __future__ import annotations

from numba import njit

from ..geometry import LOCAL_FACE_VERTICES

# Interface states.
INTACT, FAILED, PRECRACK = 0, 1, 2

# Local corners of face f (the face opposite corner f), ordered so that the normal they give
# points out of the tet (geometry's convention). Node 4e+k of the exploded mesh is corner k of
# tet e.
FACE_CORNERS = LOCAL_FACE_VERTICES


@njit(cache=True, inline="always")
def face_corners(face):
    """FACE_CORNERS[face] for compiled code."""
    if face == 0:
        return 1, 2, 3
    if face == 1:
        return 0, 3, 2
    if face == 2:
        return 0, 1, 3
    return 0, 2, 1


@njit(cache=True, inline="always")
def twice_area_vector(x, a, b, q):
    """(x_b - x_a) x (x_q - x_a): twice the area vector of triangle (a, b, q), along its normal."""
    ux = x[b, 0] - x[a, 0]
    uy = x[b, 1] - x[a, 1]
    uz = x[b, 2] - x[a, 2]
    wx = x[q, 0] - x[a, 0]
    wy = x[q, 1] - x[a, 1]
    wz = x[q, 2] - x[a, 2]
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx

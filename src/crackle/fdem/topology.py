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
def edge_vectors(x, a, b, q):
    """x_b - x_a and x_q - x_a (six components): the edges of triangle (a, b, q) from a."""
    return x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2], x[q, 0] - x[a, 0], x[q, 1] - x[a, 1], x[q, 2] - x[a, 2]


@njit(cache=True, inline="always")
def cross(ux, uy, uz, wx, wy, wz):
    """u x w."""
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


@njit(cache=True, inline="always")
def twice_area_vector(x, a, b, q):
    """(x_b - x_a) x (x_q - x_a): twice the area vector of triangle (a, b, q), along its normal."""
    ux, uy, uz, wx, wy, wz = edge_vectors(x, a, b, q)
    return cross(ux, uy, uz, wx, wy, wz)

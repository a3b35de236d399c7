"""Projectiles as solids of revolution: a nose (conical, tangent-ogival, hemispherical or flat) on a
cylindrical shank, as the triangle surface a rigid surface tool is made of.

The meridian runs from the tip (s = 0 along the axis, r = 0; a flat nose: the face's centre) back
to the shank's radius R at s = the nose's length L, then along the shank to the tail at s = the
projectile's length. The noses (L the nose's length):

  conical        r = R s / L
  ogival         a tangent ogive, pointed: the arc of radius rho = (R^2 + L^2) / (2 R) that meets
                 the shank with the same slope; r = sqrt(rho^2 - (L - s)^2) - (rho - R). Its
                 calibre-radius-head psi = rho / (2 R), so L = R sqrt(4 psi - 1); pointed for L >= R
  hemispherical  L = R, r = sqrt(R^2 - (R - s)^2)
  flat           L = 0: a blunt cylinder
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["NOSES", "nose_extent", "nose_profile", "projectile_surface", "projectile_volume"]

NOSES = ("conical", "ogival", "hemispherical", "flat")
SEGMENTS = 96  # around the axis: the facets' chord error is R (1 - cos(pi / 96)) = 5.4e-4 R
NOSE_RINGS = 32  # along a curved or pointed nose


def nose_extent(nose: str, radius: float, nose_length: float | None) -> float:
    """The nose's length along the axis (m): nose_length for a conical or ogival nose, the
    radius for a hemispherical one, 0 for a flat one."""
    if nose == "hemispherical":
        return radius
    if nose == "flat":
        return 0.0
    return float(nose_length)


def nose_profile(nose: str, radius: float, nose_length: float | None = None, rings: int = NOSE_RINGS):
    """The nose's meridian (s, r) from the tip (0, 0) to the shank (L, radius), rings + 1 points
    (a flat nose: the face's centre and its rim)."""
    if nose not in NOSES:
        raise ValueError(f"nose = {nose!r}: one of {', '.join(NOSES)}")
    if nose == "flat":
        return np.array([0.0, 0.0]), np.array([0.0, radius])
    length = nose_extent(nose, radius, nose_length)
    if nose == "hemispherical":
        angle = np.linspace(0.0, 0.5 * math.pi, rings + 1)  # from the pole: even arcs
        return radius * (1.0 - np.cos(angle)), radius * np.sin(angle)
    s = np.linspace(0.0, length, rings + 1)
    if nose == "conical":
        return s, radius * s / length
    if length < radius:
        raise ValueError(f"nose_length = {length:g} m: a pointed tangent ogive is at least as long as its "
                         f"radius {radius:g} m (calibre-radius-head psi >= 0.5)")
    rho = (radius * radius + length * length) / (2.0 * radius)
    r = np.sqrt(np.maximum(rho * rho - (length - s) ** 2, 0.0)) - (rho - radius)
    r[0] = 0.0  # the apex, exactly
    return s, np.maximum(r, 0.0)


def projectile_volume(nose: str, radius: float, length: float, nose_length: float | None = None) -> float:
    """The solid's volume (m^3), closed form: the nose's and the shank's."""
    extent = nose_extent(nose, radius, nose_length)
    shank = math.pi * radius * radius * (length - extent)
    if nose == "conical":
        return shank + math.pi * radius * radius * extent / 3.0
    if nose == "hemispherical":
        return shank + 2.0 / 3.0 * math.pi * radius**3
    if nose == "ogival":
        rho = (radius * radius + extent * extent) / (2.0 * radius)
        return shank + math.pi * (rho * rho * extent - extent**3 / 3.0 - (rho - radius) * rho * rho *
                                  math.asin(extent / rho))
    return shank


def projectile_surface(tip, direction, radius: float, length: float, nose: str, nose_length: float | None = None,
                       segments: int = SEGMENTS, rings: int = NOSE_RINGS) -> tuple[np.ndarray, np.ndarray]:
    """The closed triangle surface (vertices (n, 3) in m, triangles (k, 3)) of the projectile
    whose nose's tip is at `tip` and points along `direction`, wound outwards."""
    extent = nose_extent(nose, radius, nose_length)
    if not length > extent:
        raise ValueError(f"length = {length:g} m: the projectile must be longer than its nose ({extent:g} m)")
    axis = np.asarray(direction, dtype=float)
    axis = axis / np.linalg.norm(axis)
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    s, r = nose_profile(nose, radius, nose_length, rings)
    # The rings after the tip: the nose's, then the tail's rim.
    ring_s = np.append(s[1:], length)
    ring_r = np.append(r[1:], radius)
    angle = 2.0 * math.pi * np.arange(segments) / segments
    around = np.cos(angle)[:, None] * u + np.sin(angle)[:, None] * v  # (segments, 3)
    tip = np.asarray(tip, dtype=float)
    rings_xyz = tip - ring_s[:, None, None] * axis + ring_r[:, None, None] * around[None]
    vertices = np.concatenate([tip[None], rings_xyz.reshape(-1, 3), (tip - length * axis)[None]])
    tail = len(vertices) - 1
    k = np.arange(segments)
    k1 = (k + 1) % segments
    triangles = [np.stack([np.zeros(segments, dtype=np.int64), 1 + k1, 1 + k], axis=1)]  # the tip's fan
    for ring in range(len(ring_s) - 1):
        a, b = 1 + ring * segments, 1 + (ring + 1) * segments
        triangles.append(np.stack([a + k, a + k1, b + k1], axis=1))
        triangles.append(np.stack([a + k, b + k1, b + k], axis=1))
    last = 1 + (len(ring_s) - 1) * segments
    triangles.append(np.stack([np.full(segments, tail), last + k, last + k1], axis=1))  # the tail's fan
    triangles = np.concatenate(triangles)
    p0, p1, p2 = vertices[triangles[:, 0]], vertices[triangles[:, 1]], vertices[triangles[:, 2]]
    if np.einsum("ij,ij->", p0 - tip, np.cross(p1 - tip, p2 - tip)) < 0.0:
        triangles = triangles[:, [0, 2, 1]]  # outwards: a positive enclosed volume
    return vertices, np.ascontiguousarray(triangles)

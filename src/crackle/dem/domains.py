"""The shapes a DEM packing fills (dem.packing): a box, a cylinder, a sphere, or any closed
triangle surface (`from_surface` reads a file).

A domain is any object with `volume` (m^3), `bounds` ((lo, hi), m), `inradius` (m, radius of the
largest ball inside), `signed_distance(points)` (m, negative inside), `normal(points)` (unit
outward gradient of the signed distance) and `description()` (a JSON-able dict).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange
from scipy import ndimage

# Largest voxel grid of a ClosedSurface's distance (70 bytes a voxel at the peak of its build).
MAX_VOXELS = 16_000_000



def _points(points) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must be an (n, 3) array, got shape {p.shape}")
    return p


def _vector(value, name: str) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers (m), got {value!r}")
    return v


def _positive(value, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be a positive length (m), got {value!r}")
    return v


@dataclass(frozen=True, eq=False)
class Box:
    """Axis-aligned box between the corners `lo` and `hi` (m)."""

    lo: np.ndarray
    hi: np.ndarray

    def __post_init__(self):
        lo, hi = _vector(self.lo, "packing.domain: box lo"), _vector(self.hi, "packing.domain: box hi")
        if not np.all(hi > lo):
            raise ValueError(f"packing.domain: box hi {hi.tolist()} must exceed lo {lo.tolist()} on every axis")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @property
    def volume(self) -> float:
        return float(np.prod(self.hi - self.lo))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.lo.copy(), self.hi.copy()

    @property
    def inradius(self) -> float:
        return float(0.5 * np.min(self.hi - self.lo))

    def signed_distance(self, points) -> np.ndarray:
        q = np.abs(_points(points) - 0.5 * (self.lo + self.hi)) - 0.5 * (self.hi - self.lo)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)

    def normal(self, points) -> np.ndarray:
        p = _points(points)
        rel = p - 0.5 * (self.lo + self.hi)
        side = np.where(rel < 0.0, -1.0, 1.0)
        q = np.abs(rel) - 0.5 * (self.hi - self.lo)
        out = np.maximum(q, 0.0)
        length = np.linalg.norm(out, axis=1)
        # Inside: the nearest face's normal; outside: towards the point from the box's nearest point.
        n = np.zeros_like(p)
        rows = np.arange(len(p))
        nearest = np.argmax(q, axis=1)
        n[rows, nearest] = side[rows, nearest]
        far = length > 0.0
        n[far] = out[far] * side[far] / length[far, None]
        return n

    def description(self) -> dict:
        return {"kind": "box", "lo": self.lo.tolist(), "hi": self.hi.tolist()}


@dataclass(frozen=True, eq=False)
class Cylinder:
    """Circular cylinder (a disc is a short one): `center` the middle of its axis (m), `radius`
    and `height` (m), `axis` its direction (any non-zero vector, normalised)."""

    center: np.ndarray
    radius: float
    height: float
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self):
        object.__setattr__(self, "center", _vector(self.center, "packing.domain: cylinder center"))
        object.__setattr__(self, "radius", _positive(self.radius, "packing.domain: cylinder radius"))
        object.__setattr__(self, "height", _positive(self.height, "packing.domain: cylinder height"))
        axis = _vector(self.axis, "packing.domain: cylinder axis")
        if np.linalg.norm(axis) == 0.0:
            raise ValueError("packing.domain: cylinder axis must be a non-zero vector")
        object.__setattr__(self, "axis", axis / np.linalg.norm(axis))

    @property
    def volume(self) -> float:
        return math.pi * self.radius**2 * self.height

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        # A disc's extent along each world axis: its half height along the axis plus its radius
        # across it.
        reach = 0.5 * self.height * np.abs(self.axis) + self.radius * np.sqrt(np.maximum(1.0 - self.axis**2, 0.0))
        return self.center - reach, self.center + reach

    @property
    def inradius(self) -> float:
        return min(self.radius, 0.5 * self.height)

    def _parts(self, points):
        q = _points(points) - self.center
        along = q[:, 0] * self.axis[0] + q[:, 1] * self.axis[1] + q[:, 2] * self.axis[2]  # no BLAS: same bits always
        across = q - along[:, None] * self.axis
        spoke = np.linalg.norm(across, axis=1)
        return along, across, spoke, spoke - self.radius, np.abs(along) - 0.5 * self.height

    def signed_distance(self, points) -> np.ndarray:
        _, _, _, d_radial, d_axial = self._parts(points)
        outside = np.hypot(np.maximum(d_radial, 0.0), np.maximum(d_axial, 0.0))
        return outside + np.minimum(np.maximum(d_radial, d_axial), 0.0)

    def normal(self, points) -> np.ndarray:
        along, across, spoke, d_radial, d_axial = self._parts(points)
        # On the axis any direction across it is a nearest one: take a fixed one.
        fallback = np.cross(self.axis, [1.0, 0.0, 0.0] if abs(self.axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        fallback /= np.linalg.norm(fallback)
        radial = np.where(spoke[:, None] > 0.0, across / np.where(spoke > 0.0, spoke, 1.0)[:, None], fallback)
        axial = np.where(along[:, None] < 0.0, -self.axis, self.axis)
        out_r, out_a = np.maximum(d_radial, 0.0), np.maximum(d_axial, 0.0)
        length = np.hypot(out_r, out_a)
        inside = np.where((d_radial >= d_axial)[:, None], radial, axial)
        safe = np.where(length > 0.0, length, 1.0)[:, None]
        outside = (out_r[:, None] * radial + out_a[:, None] * axial) / safe
        return np.where((length > 0.0)[:, None], outside, inside)

    def description(self) -> dict:
        return {"kind": "cylinder", "center": self.center.tolist(), "radius": self.radius,
                "height": self.height, "axis": self.axis.tolist()}


@dataclass(frozen=True, eq=False)
class Sphere:
    """Ball of `radius` (m) around `center` (m)."""

    center: np.ndarray
    radius: float

    def __post_init__(self):
        object.__setattr__(self, "center", _vector(self.center, "packing.domain: sphere center"))
        object.__setattr__(self, "radius", _positive(self.radius, "packing.domain: sphere radius"))

    @property
    def volume(self) -> float:
        return 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.center - self.radius, self.center + self.radius

    @property
    def inradius(self) -> float:
        return self.radius

    def signed_distance(self, points) -> np.ndarray:
        return np.linalg.norm(_points(points) - self.center, axis=1) - self.radius

    def normal(self, points) -> np.ndarray:
        q = _points(points) - self.center
        length = np.linalg.norm(q, axis=1)
        n = np.zeros_like(q)
        n[:, 0] = 1.0  # the centre itself: any direction
        away = length > 0.0
        n[away] = q[away] / length[away, None]
        return n

    def description(self) -> dict:
        return {"kind": "sphere", "center": self.center.tolist(), "radius": self.radius}


class ClosedSurface:
    """The inside of a closed triangle surface: `vertices` (n, 3, m), `triangles` (k, 3).

    The signed distance is computed once on a voxel grid of `voxel_size` (m; default: the
    longest side / `resolution`) and interpolated trilinearly: inside/outside of each voxel centre
    by ray-casting parity along z, the exact distance to the nearest triangle of the voxels
    within two voxels of the surface, and for the others the exact distance to the triangle
    nearest to their closest such voxel (scipy's Euclidean distance transform) or to a triangle
    sharing a vertex with it. Error: none near flat faces; near a convex edge or corner the
    interpolation under-estimates the depth inside (by up to ~0.35 voxel in a cube), which keeps
    spheres further in; near a concave one it may over-estimate it by a fraction of a voxel."""

    def __init__(self, vertices, triangles, voxel_size: float | None = None, resolution: int = 96, source: str = ""):
        from ..geometry.meshes import surface_arrays, surface_closure

        label = f"packing.domain: surface {source}".rstrip()
        v, t = surface_arrays(vertices, triangles, label)
        if not surface_closure(t)[0]:
            raise ValueError(f"{label} is not closed (every edge must join exactly two triangles)")
        self.vertices, self.triangles, self.source = v, t, source
        p0, p1, p2 = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        self._volume = float(np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0)
        self._lo, self._hi = v.min(axis=0), v.max(axis=0)
        extent = float(np.max(self._hi - self._lo))
        if voxel_size is None:
            if int(resolution) < 8:
                raise ValueError(f"{label}: resolution must be at least 8 voxels, got {resolution}")
            voxel_size = extent / int(resolution)
        self.voxel_size = _positive(voxel_size, f"{label}: voxel_size")
        self._build_grid()

    def _build_grid(self):
        h = self.voxel_size
        pad = 3  # voxels of outside around the surface: the interpolation stays inside the grid
        self._origin = self._lo - pad * h  # corner of the grid; voxel centres at origin + (i + 0.5) h
        dims = np.ceil((self._hi - self._lo) / h).astype(np.int64) + 2 * pad
        if int(np.prod(dims)) > MAX_VOXELS:
            raise ValueError(f"packing.domain: {dims.tolist()} voxels for the surface's distance; raise voxel_size")
        inside = _parity_inside(self.vertices, self.triangles, self._origin, h, dims)
        band_distance, band_triangle = _band_distance(self.vertices, self.triangles, self._origin, h, dims, 2.0 * h)
        in_band = band_triangle >= 0
        # Each voxel away from the surface takes the triangle nearest to its closest band voxel.
        _, nearest = ndimage.distance_transform_edt(~in_band, return_distances=True, return_indices=True)
        triangle_of = band_triangle[nearest[0], nearest[1], nearest[2]]
        # ... or a triangle next to it (sharing a vertex): on a curved surface the nearest one
        # changes between the band and a voxel deeper in.
        corners = self.triangles.ravel()
        ring = (np.argsort(corners, kind="stable") // 3).astype(np.int64)
        ring_start = np.concatenate([[0], np.cumsum(np.bincount(corners, minlength=len(self.vertices)))])
        distance = _distance_to_triangles(self.vertices, self.triangles, self._origin, h, triangle_of, ring_start, ring)
        distance = np.where(in_band, band_distance, distance)
        self._grid = np.where(inside, -distance, distance)
        self._dims = dims

    @property
    def volume(self) -> float:
        return self._volume

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lo.copy(), self._hi.copy()

    @property
    def inradius(self) -> float:
        return float(-self._grid.min())

    def _interpolate(self, points):
        p = _points(points)
        h = self.voxel_size
        # Clamp to the voxel centres; a point beyond them adds its distance to the clamp point.
        first = self._origin + 0.5 * h
        last = self._origin + (self._dims - 0.5) * h
        clamped = np.clip(p, first, last)
        beyond = np.linalg.norm(p - clamped, axis=1)
        u = (clamped - first) / h
        base = np.minimum(np.floor(u).astype(np.int64), self._dims - 2)
        f = u - base
        g = self._grid
        i, j, k = base[:, 0], base[:, 1], base[:, 2]
        c = [[[g[i + a, j + b, k + cc] for cc in (0, 1)] for b in (0, 1)] for a in (0, 1)]
        fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
        # Trilinear value and its exact gradient.
        c00 = c[0][0][0] * (1 - fx) + c[1][0][0] * fx
        c01 = c[0][0][1] * (1 - fx) + c[1][0][1] * fx
        c10 = c[0][1][0] * (1 - fx) + c[1][1][0] * fx
        c11 = c[0][1][1] * (1 - fx) + c[1][1][1] * fx
        c0 = c00 * (1 - fy) + c10 * fy
        c1 = c01 * (1 - fy) + c11 * fy
        value = c0 * (1 - fz) + c1 * fz
        dz = c1 - c0
        dy = (c10 - c00) * (1 - fz) + (c11 - c01) * fz
        dx = ((c[1][0][0] - c[0][0][0]) * (1 - fy) * (1 - fz) + (c[1][1][0] - c[0][1][0]) * fy * (1 - fz)
              + (c[1][0][1] - c[0][0][1]) * (1 - fy) * fz + (c[1][1][1] - c[0][1][1]) * fy * fz)
        gradient = np.stack([dx, dy, dz], axis=1) / h
        return value + beyond, gradient, p - clamped, beyond

    def signed_distance(self, points) -> np.ndarray:
        return self._interpolate(points)[0]

    def normal(self, points) -> np.ndarray:
        _, gradient, offset, beyond = self._interpolate(points)
        length = np.linalg.norm(gradient, axis=1)
        n = np.zeros_like(gradient)
        n[:, 0] = 1.0  # a flat spot of the interpolant (a medial point): any direction
        ok = length > 0.0
        n[ok] = gradient[ok] / length[ok, None]
        far = beyond > 0.0
        n[far] = offset[far] / beyond[far, None]
        return n

    def description(self) -> dict:
        return {"kind": "surface", "source": self.source, "triangles": int(len(self.triangles)),
                "volume": self._volume, "lo": self._lo.tolist(), "hi": self._hi.tolist(),
                "voxel_size": self.voxel_size}


def from_surface(path: str | os.PathLike, scale: float = 1.0, offset=(0.0, 0.0, 0.0), voxel_size: float | None = None,
                 resolution: int = 96) -> ClosedSurface:
    """The inside of the closed surface in a file (STL, OBJ, PLY ...; `scale` 1e-3 for a file in
    mm, then shifted by `offset`, m) as a packing domain."""
    from ..geometry import read_surface

    vertices, triangles = read_surface(path, scale, offset, hint="export the closed surface as triangles, e.g. STL")
    return ClosedSurface(vertices, triangles, voxel_size=voxel_size, resolution=resolution, source=str(path))


@njit(cache=True)
def _edge_side(vertices, a, b, px, py):
    """Side of (px, py) of the xy projection of edge a -> b: +1 left, -1 right. Computed from
    the lower-numbered vertex so that the two triangles of an edge see opposite signs, and a
    point exactly on the line is moved off it by a fixed infinitesimal shift (eps, eps^2): each
    ray crosses a closed surface's triangle fan exactly once."""
    flip = 1.0
    if a > b:
        a, b, flip = b, a, -1.0
    ax, ay = vertices[a, 0], vertices[a, 1]
    ex, ey = vertices[b, 0] - ax, vertices[b, 1] - ay
    side = ex * (py - ay) - ey * (px - ax)
    if side == 0.0:
        side = -ey if ey != 0.0 else ex
    return flip if side > 0.0 else -flip


@njit(cache=True)
def _parity_inside(vertices, triangles, origin, h, dims):
    """Inside (True) or outside of each voxel centre: the parity of the surface crossings of a
    ray from it towards -z."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    crossings = np.zeros((nx, ny, nz + 1), dtype=np.int64)  # crossings between voxel rows, per column
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        x0 = min(vertices[a, 0], min(vertices[b, 0], vertices[c, 0]))
        x1 = max(vertices[a, 0], max(vertices[b, 0], vertices[c, 0]))
        y0 = min(vertices[a, 1], min(vertices[b, 1], vertices[c, 1]))
        y1 = max(vertices[a, 1], max(vertices[b, 1], vertices[c, 1]))
        i0 = max(int(math.floor((x0 - origin[0]) / h - 0.5)), 0)
        i1 = min(int(math.ceil((x1 - origin[0]) / h - 0.5)), nx - 1)
        j0 = max(int(math.floor((y0 - origin[1]) / h - 0.5)), 0)
        j1 = min(int(math.ceil((y1 - origin[1]) / h - 0.5)), ny - 1)
        # Plane of the triangle, for the z of the crossing.
        ux, uy, uz = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
        vx, vy, vz = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
        nnx, nny, nnz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        if nnz == 0.0:
            continue  # parallel to the rays: never crossed
        for i in range(i0, i1 + 1):
            px = origin[0] + (i + 0.5) * h
            for j in range(j0, j1 + 1):
                py = origin[1] + (j + 0.5) * h
                s0 = _edge_side(vertices, a, b, px, py)
                s1 = _edge_side(vertices, b, c, px, py)
                s2 = _edge_side(vertices, c, a, px, py)
                if s0 != s1 or s1 != s2:
                    continue
                z = vertices[a, 2] - (nnx * (px - vertices[a, 0]) + nny * (py - vertices[a, 1])) / nnz
                # Voxel rows with a centre above z see this crossing below them.
                row = int(math.floor((z - origin[2]) / h - 0.5)) + 1
                row = min(max(row, 0), nz)
                crossings[i, j, row] += 1
    inside = np.zeros((nx, ny, nz), dtype=np.bool_)
    for i in range(nx):
        for j in range(ny):
            count = 0
            for k in range(nz):
                count += crossings[i, j, k]
                inside[i, j, k] = count % 2 == 1
    return inside


@njit(cache=True, inline="always")
def _point_triangle_distance(px, py, pz, vertices, a, b, c):
    """Distance (m) from a point to a triangle (closest-point regions of the triangle)."""
    ax, ay, az = vertices[a, 0], vertices[a, 1], vertices[a, 2]
    abx, aby, abz = vertices[b, 0] - ax, vertices[b, 1] - ay, vertices[b, 2] - az
    acx, acy, acz = vertices[c, 0] - ax, vertices[c, 1] - ay, vertices[c, 2] - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return math.sqrt(apx * apx + apy * apy + apz * apz)
    bpx, bpy, bpz = px - vertices[b, 0], py - vertices[b, 1], pz - vertices[b, 2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return math.sqrt(bpx * bpx + bpy * bpy + bpz * bpz)
    cpx, cpy, cpz = px - vertices[c, 0], py - vertices[c, 1], pz - vertices[c, 2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return math.sqrt(cpx * cpx + cpy * cpy + cpz * cpz)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        w = d1 / (d1 - d3)
        qx, qy, qz = apx - w * abx, apy - w * aby, apz - w * abz
        return math.sqrt(qx * qx + qy * qy + qz * qz)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        qx, qy, qz = apx - w * acx, apy - w * acy, apz - w * acz
        return math.sqrt(qx * qx + qy * qy + qz * qz)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bpx - w * (acx - abx), bpy - w * (acy - aby), bpz - w * (acz - abz)
        return math.sqrt(qx * qx + qy * qy + qz * qz)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    qx = apx - abx * v - acx * w
    qy = apy - aby * v - acy * w
    qz = apz - abz * v - acz * w
    return math.sqrt(qx * qx + qy * qy + qz * qz)


@njit(cache=True)
def _band_distance(vertices, triangles, origin, h, dims, band):
    """Exact distance (m) to the nearest triangle and its index for the voxel centres within
    `band` of a triangle's box; elsewhere inf and -1."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    distance = np.full((nx, ny, nz), np.inf)
    nearest = np.full((nx, ny, nz), -1, dtype=np.int64)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        for d in range(3):
            v0 = min(vertices[a, d], min(vertices[b, d], vertices[c, d])) - band
            v1 = max(vertices[a, d], max(vertices[b, d], vertices[c, d])) + band
            lo[d] = max(int(math.floor((v0 - origin[d]) / h - 0.5)), 0)
            hi[d] = min(int(math.ceil((v1 - origin[d]) / h - 0.5)), dims[d] - 1)
        for i in range(lo[0], hi[0] + 1):
            px = origin[0] + (i + 0.5) * h
            for j in range(lo[1], hi[1] + 1):
                py = origin[1] + (j + 0.5) * h
                for k in range(lo[2], hi[2] + 1):
                    pz = origin[2] + (k + 0.5) * h
                    dist = _point_triangle_distance(px, py, pz, vertices, a, b, c)
                    if dist <= band and dist < distance[i, j, k]:
                        distance[i, j, k] = dist
                        nearest[i, j, k] = t
    return distance, nearest


@njit(cache=True, parallel=True)
def _distance_to_triangles(vertices, triangles, origin, h, triangle_of, ring_start, ring):
    """Distance (m) from each voxel centre to the nearest of its given triangle and the
    triangles sharing a vertex with it (those of vertex v: ring[ring_start[v]:ring_start[v + 1]])."""
    nx, ny, nz = triangle_of.shape
    distance = np.empty((nx, ny, nz))
    for i in prange(nx):
        px = origin[0] + (i + 0.5) * h
        for j in range(ny):
            py = origin[1] + (j + 0.5) * h
            for k in range(nz):
                pz = origin[2] + (k + 0.5) * h
                t = triangle_of[i, j, k]
                nearest = np.inf
                for corner in range(3):
                    v = triangles[t, corner]
                    for m in range(ring_start[v], ring_start[v + 1]):
                        u = ring[m]
                        nearest = min(nearest, _point_triangle_distance(px, py, pz, vertices, triangles[u, 0],
                                                                        triangles[u, 1], triangles[u, 2]))
                distance[i, j, k] = nearest
    return distance

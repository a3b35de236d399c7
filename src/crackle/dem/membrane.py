"""A pressure on faces of the DEM sample's box: a flexible membrane on the outermost particles
(PFC's and Yade's flexible-membrane confinement), what `[[pressures]]` with faces = "where"
does for the DEM.

Rule (deterministic, no races): each loaded face (a face of the specimen's box, in its reference
place) is rasterised on a square-ish grid of cells about CELL x the mean radius wide; each
cell's area goes to the outermost particle seen from outside through the cell's centre along the
face's normal (of the spheres the ray meets within DEPTH largest diameters of the face, the one
whose surface it meets furthest out; ties: the lowest particle index), or, where it meets none
(at the box's edges, where rays graze the sample; a gap; a cell beyond a shortened sample's
end), to the particle whose surface lies closest to the cell's centre on the face. A particle's
membrane force is then p(t) x its cells' area along the face's inward normal, each cell's on the
line through the cell, fixed in space: a force and a torque on the particle, a dead load whose
resultant on a face is p x the face's reference area (the cells tile the face) and whose moment
is always the uniform pressure's, however the particles move. Measured on the coarse quick
triaxial at 20 MPa (frictionless platens, nothing else holds the sample's turn about its axis):
with the forces at the particles' centres it spun at 1,000 rad/s; with the lines of action
moving with the particles, at 25 rad/s (a dead load on a turning body whose points of
application turn with it drives the turn further). The particle pass adds the force to the
external force of the shared node update, which books its work into w_external, the audit's
input, and the torque to the spin's, its work booked there too.

Exposure is recomputed (the whole raster, serially, in Python between compiled chunks, on the
contact check's fixed grid of steps) once some particle has moved MOVE x the mean radius
since the last raster: a bulging sample's new outermost particles take the load, and the
state stays independent of the thread count and of how the steps are split into calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from ..loading.arrays import history_tables

# Cell size over the mean radius, and the displacement (over the mean radius) since the last
# raster that triggers a new one.
CELL = 0.25
MOVE = 0.25
# A ray's hit counts within DEPTH largest diameters of the face: at the box's edges a ray grazes the
# sample and would otherwise meet a particle of the far side first.
DEPTH = 1.0

AXES = "xyz"


@dataclass(frozen=True)
class Face:
    """A face of the box: normal along `axis` (0-2), `side` +1 (the face at hi) or -1 (at lo),
    at coordinate `level`; the in-plane axes u, v and their ranges."""

    axis: int
    side: int
    level: float
    u: int
    v: int
    u_range: tuple[float, float]
    v_range: tuple[float, float]

    @property
    def name(self) -> str:
        return f"{AXES[self.axis]} = {self.level:g}"

    @property
    def area(self) -> float:
        return (self.u_range[1] - self.u_range[0]) * (self.v_range[1] - self.v_range[0])

    @property
    def inward(self) -> np.ndarray:
        n = np.zeros(3)
        n[self.axis] = -self.side
        return n

    def corners(self) -> np.ndarray:
        out = np.zeros((4, 3))
        out[:, self.axis] = self.level
        for k, (i, j) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
            out[k, self.u] = self.u_range[i]
            out[k, self.v] = self.v_range[j]
        return out

    def centre(self) -> np.ndarray:
        return self.corners().mean(axis=0)


def box_faces(lo, hi) -> list[Face]:
    """The six faces of the box [lo, hi], in the order x lo, x hi, y lo, y hi, z lo, z hi."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    faces = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for side, level in ((-1, lo[axis]), (1, hi[axis])):
            faces.append(Face(axis, side, float(level), u, v, (float(lo[u]), float(hi[u])),
                              (float(lo[v]), float(hi[v]))))
    return faces


def selected_faces(selection, faces: list[Face], scale: float) -> list[Face]:
    """The faces a loading.Selection names: all four corners on its plane (when it has one) and
    the centre inside its box (when it has one)."""
    on_plane = replace(selection, box_min=None, box_max=None)
    in_box = replace(selection, plane_point=None, plane_normal=None)
    out = []
    for face in faces:
        if selection.plane_point is not None and not on_plane.mask(face.corners(), scale).all():
            continue
        if (selection.box_min is not None or selection.box_max is not None) and \
                not in_box.mask(face.centre()[None, :], scale)[0]:
            continue
        out.append(face)
    return out


@njit(cache=True)
def _raster(s, u, v, r, level, depth, u0, v0, du, dv, nu, nv):
    """Per cell (nu x nv, C order), the particle seen first from outside through its centre
    along the face normal (s: the centres' coordinate along the outward normal, `level` the
    face's; a sphere met deeper than `depth` below the face does not count), or, where the ray
    meets none, the particle whose surface lies closest to the cell's
    centre on the face. Serial."""
    n = s.shape[0]
    owner = np.full(nu * nv, -1, dtype=np.int64)
    height = np.full(nu * nv, level - depth)  # a hit deeper than depth does not count
    for i in range(n):
        ri = r[i]
        a0 = max(0, int(math.ceil((u[i] - ri - u0) / du - 0.5)))
        a1 = min(nu - 1, int(math.floor((u[i] + ri - u0) / du - 0.5)))
        b0 = max(0, int(math.ceil((v[i] - ri - v0) / dv - 0.5)))
        b1 = min(nv - 1, int(math.floor((v[i] + ri - v0) / dv - 0.5)))
        for a in range(a0, a1 + 1):
            cu = u0 + (a + 0.5) * du - u[i]
            for b in range(b0, b1 + 1):
                cv = v0 + (b + 0.5) * dv - v[i]
                d2 = cu * cu + cv * cv
                if d2 < ri * ri:
                    h = s[i] + math.sqrt(ri * ri - d2)
                    c = a * nv + b
                    if h > height[c]:
                        height[c] = h
                        owner[c] = i
    for c in range(nu * nv):
        if owner[c] >= 0:
            continue
        cu = u0 + (c // nv + 0.5) * du
        cv = v0 + (c % nv + 0.5) * dv
        best = np.inf
        for i in range(n):
            gap = math.sqrt((u[i] - cu) ** 2 + (v[i] - cv) ** 2 + (level - s[i]) ** 2) - r[i]
            if gap < best:
                best = gap
                owner[c] = i
    return owner


def face_cells(x: np.ndarray, radius: np.ndarray, face: Face, cell: float, depth: float | None = None):
    """The face's cells: (owner of each cell, the cell's offset from its owner's centre (c, 3),
    the cell's area)."""
    radius = np.asarray(radius, dtype=float)
    depth = DEPTH * 2.0 * float(radius.max()) if depth is None else float(depth)
    (u0, u1), (v0, v1) = face.u_range, face.v_range
    nu = max(1, int(math.ceil((u1 - u0) / cell)))
    nv = max(1, int(math.ceil((v1 - v0) / cell)))
    du, dv = (u1 - u0) / nu, (v1 - v0) / nv
    owner = _raster(np.ascontiguousarray(face.side * x[:, face.axis]), np.ascontiguousarray(x[:, face.u]),
                    np.ascontiguousarray(x[:, face.v]), radius, face.side * face.level, depth,
                    u0, v0, du, dv, nu, nv)
    cu = np.repeat(u0 + (np.arange(nu) + 0.5) * du, nv)
    cv = np.tile(v0 + (np.arange(nv) + 0.5) * dv, nu)
    offset = np.zeros((len(owner), 3))
    offset[:, face.u] = cu - x[owner, face.u]
    offset[:, face.v] = cv - x[owner, face.v]
    # Along the normal: to the sphere's surface where the ray meets it (0 where it does not).
    offset[:, face.axis] = face.side * np.sqrt(np.maximum(radius[owner] ** 2 - offset[:, face.u] ** 2
                                                          - offset[:, face.v] ** 2, 0.0))
    return owner, offset, du * dv


def exposed_areas(x: np.ndarray, radius: np.ndarray, face: Face, cell: float,
                  depth: float | None = None) -> np.ndarray:
    """Per particle, the area (m^2) of `face` it takes (the rasterised rule of the module's
    docstring, cells about `cell` wide, hits within `depth` of the face, default DEPTH largest
    diameters); the areas sum to the face's area."""
    owner, _, area = face_cells(x, radius, face, cell, depth)
    return np.bincount(owner, minlength=len(radius)) * area


def face_loads(x: np.ndarray, radius: np.ndarray, face: Face, cell: float, depth: float | None = None):
    """Per particle, per unit pressure on `face`: its force (n, 3) (area x the inward normal) and
    the first moment of its cells' forces about its centre, sum of d (x) f over its cells (n, 3, 3),
    d from the centre to where the cell's ray meets the sphere (the cell's line of action: the
    face's moments about any axis are those of the uniform pressure)."""
    owner, offset, area = face_cells(x, radius, face, cell, depth)
    n = len(radius)
    force = (np.bincount(owner, minlength=n) * area)[:, None] * face.inward[None, :]
    first = np.zeros((n, 3, 3))
    for i in range(3):
        moments = np.bincount(owner, weights=offset[:, i], minlength=n)
        first[:, i, face.axis] = moments * area * face.inward[face.axis]
    return force, first


def axial(first: np.ndarray) -> np.ndarray:
    """The moment vector, sum of d x f, of first moments sum of d (x) f (..., 3, 3)."""
    return np.stack([first[..., 1, 2] - first[..., 2, 1], first[..., 2, 0] - first[..., 0, 2],
                     first[..., 0, 1] - first[..., 1, 0]], axis=-1)


class Membrane:
    """The DEM's pressures: per pressure, its faces and history; `area` (k, n, 3) each particle's
    area vector per pressure (m^2, along the faces' inward normals) and `moment` (k, n, 3) the
    moment of its cells' forces about its centre per unit pressure (m^3), both at the positions
    `x_raster`, what the compiled particle pass multiplies by the pressure now (the torque
    growing by (x_raster - x) x the force as the particle leaves its cells' lines); `first`
    (k, n, 3, 3) their first moments (the particle stress's share); `histories` the shared
    HistoryTable."""

    def __init__(self, faces: list[list[Face]], histories, x: np.ndarray, radius: np.ndarray):
        self.faces = faces
        self.histories = history_tables(histories)
        self.radius = np.asarray(radius, float)
        self.cell = CELL * float(np.mean(self.radius))
        self.move = MOVE * float(np.mean(self.radius))
        k, n = len(faces), len(self.radius)
        self.area = np.zeros((k, n, 3))
        self.moment = np.zeros((k, n, 3))
        self.first = np.zeros((k, n, 3, 3))
        self.x_raster = np.zeros((n, 3))  # the positions of the last raster
        self.rasters = 0
        self.rasterise(x)

    def rasterise(self, x: np.ndarray) -> None:
        """The exposure of every loaded face from the particles at x."""
        self.area[:] = 0.0
        self.first[:] = 0.0
        for k, faces in enumerate(self.faces):
            for face in faces:
                force, first = face_loads(x, self.radius, face, self.cell)
                self.area[k] += force
                self.first[k] += first
        self.moment[:] = axial(self.first)  # in place: the compiled step holds these arrays
        self.x_raster[:] = x
        self.rasters += 1

    def update(self, x: np.ndarray) -> None:
        """A new raster once some particle has moved `move` since the last one."""
        moved = float(np.sqrt(np.max(np.sum((x - self.x_raster) ** 2, axis=1))))
        if moved > self.move:
            self.rasterise(x)

    def pressures(self, t: float) -> np.ndarray:
        """Pa, each pressure's value at time t."""
        h = self.histories
        return np.array([np.interp(t, h.times[k, :h.counts[k]], h.values[k, :h.counts[k]])
                         for k in range(len(self.faces))])

    def forces(self, t: float) -> np.ndarray:
        """(n, 3) N, the membrane's force on each particle at time t."""
        return np.einsum("k,kni->ni", self.pressures(t), self.area)

    def face_area(self, k: int) -> float:
        return sum(face.area for face in self.faces[k])

    def confinement(self, direction):
        """The pressure on the sample's sides along `direction` (a platen's travel): a function of
        time, the area-weighted mean of the pressures on the faces parallel to it (Pa); None when
        no loaded face is."""
        weight = np.array([sum(f.area for f in faces if abs(float(f.inward @ direction)) < 1e-9)
                           for faces in self.faces])
        if not weight.any():
            return None
        return SideConfinement(self, weight / weight.sum())


@dataclass(frozen=True, eq=False)
class SideConfinement:
    """Membrane.confinement's function of time (a class: a run's checkpoint pickles it)."""

    membrane: Membrane
    weight: np.ndarray  # per pressure, its share of the sides' area

    def __call__(self, t: float) -> float:
        return float(self.weight @ self.membrane.pressures(t))


def no_membrane(n: int):
    """The compiled step's membrane arguments without pressures: (area, moment (0, n, 3), raster
    positions (0, 3), HistoryTable)."""
    return np.zeros((0, n, 3)), np.zeros((0, n, 3)), np.zeros((0, 3)), history_tables([])

"""Loading: rigid tools (analytic shapes or triangle surfaces), supports, pressure histories.

Method-agnostic descriptions; each method turns them into its own arrays.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.meshes import read_surface, surface_arrays
from .arrays import SHAPE_CODES


@dataclass(frozen=True)
class History:
    """A piecewise-linear function of time, constant beyond its ends."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self):
        if len(self.times) != len(self.values) or len(self.times) == 0:
            raise ValueError("a history needs as many times as values, at least one")
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError("history times must increase strictly")

    @classmethod
    def constant(cls, value: float) -> "History":
        return cls((0.0,), (float(value),))

    @classmethod
    def ramp(cls, value: float, ramp_time: float) -> "History":
        """Linear from 0 at t = 0 to `value` at `ramp_time`, then constant."""
        if ramp_time <= 0:
            return cls.constant(value)
        return cls((0.0, float(ramp_time)), (0.0, float(value)))

    @classmethod
    def rate(cls, rate: float, end_time: float) -> "History":
        """Linear growth at `rate` per second from 0 at t = 0 (extended to `end_time`)."""
        return cls((0.0, float(end_time)), (0.0, float(rate) * float(end_time)))

    @classmethod
    def taylor_wave(cls, peak: float, plateau: float, decay_time: float, samples: int = 256) -> "History":
        """The pressure behind a detonation front (the Taylor wave, after Beltman and Shepherd
        2002): `peak` at t = 0, decaying as plateau x peak + (1 - plateau) x peak x exp(-t /
        decay_time), sampled on `samples` points to 10 decay times (linear between them: within
        2e-4 of the peak; beyond, the value at 10 T, within 5e-5 of the plateau)."""
        t = np.linspace(0.0, 10.0 * decay_time, samples)
        p = peak * (plateau + (1.0 - plateau) * np.exp(-t / decay_time))
        return cls(tuple(float(x) for x in t), tuple(float(x) for x in p))

    def __call__(self, t):
        return np.interp(t, self.times, self.values)

    def integral(self, t: float) -> float:
        """Integral from 0 to t (exact for the piecewise-linear form)."""
        ts = np.asarray(self.times, dtype=float)
        vs = np.asarray(self.values, dtype=float)
        knots = np.concatenate(([0.0], ts[(ts > 0.0) & (ts < t)], [t]))
        vals = np.interp(knots, ts, vs)
        return float(np.sum(0.5 * (vals[1:] + vals[:-1]) * np.diff(knots)))


TOOL_SHAPES = tuple(SHAPE_CODES)


@dataclass(frozen=True)
class Tool:
    """A rigid tool moving by translation along `direction` at speed `speed(t)`; with a `mass`, a free
    rigid body instead (a projectile): launched at speed(0) along `direction`, then slowed or turned
    only by the contact forces of the specimen on it (loading.tools.move_tools).

    Shapes (the tool is the solid region; specimen nodes inside it are pushed out):
      plane:    `point` on the plane, `normal` pointing out of the tool (towards the specimen)
      box:      `center`, `size` (full edge lengths), `axes` (two orthonormal in-plane axes)
      cylinder: `center` on the axis, `axis`, `radius`, `length` (inf for an endless roller)
      sphere:   `center`, `radius`
      support:  no surface: the grip of a support with a speed (loading.build.build_loading), which
                drives the nodes the support holds (solver.integrator) and reads their reaction
      surface:  `vertices` (n, 3) and `triangles` (k, 3), or `surface`, a file meshio reads (STL,
                .obj, .ply, .vtu, .msh ...; see `load_surface` for scale and offset). The
                triangles' normals (right-hand rule on the winding) must point out of the tool,
                towards the specimen; a closed surface is re-oriented outwards by its signed
                volume, an open one (a base plate, a die) is taken as given. A scenario's
                projectile (a nose on a cylinder) arrives here as a surface too
                (geometry.projectile, loading.build.build_tools).
    """

    name: str
    shape: str
    direction: tuple[float, float, float]
    speed: History
    friction: float = 0.0
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    size: tuple[float, float, float] = (1.0, 1.0, 1.0)
    axes: tuple[tuple[float, float, float], tuple[float, float, float]] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    radius: float = 0.0
    length: float = float("inf")
    penalty: float | None = None  # N/m^3 per unit contact area; default from the specimen
    mass: float | None = None  # kg: a free tool, launched at speed(0) and then moved by its contact forces
    glued: bool = False  # points that come within glue_depth stick to it for good (it pulls, never slips)
    seat: bool = False  # points inside it at set-up start unloaded at that depth (loading.tools.seat_points)
    glue_depth: float | None = None  # m; default a millionth of the method's contact depth
    surface: str | None = None  # surface: the file its triangles came from
    vertices: np.ndarray | None = field(default=None, compare=False, repr=False)  # surface: (n, 3), m
    triangles: np.ndarray | None = field(default=None, compare=False, repr=False)  # surface: (k, 3)

    def __post_init__(self):
        if self.shape != "surface":
            return
        if self.vertices is None or self.triangles is None:
            if self.surface is None:
                raise ValueError(f"surface tool {self.name!r} needs `surface` (a file) or `vertices` and `triangles`")
            vertices, triangles = load_surface(self.surface)
        else:
            vertices, triangles = surface_arrays(self.vertices, self.triangles, f"surface tool {self.name!r}")
        # Frozen: set the cleaned, oriented arrays once here.
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "triangles", triangles)

    def geometry_row(self) -> np.ndarray:
        """The 12 numbers the contact kernels read (see loading.tools.tool_gap)."""
        row = np.zeros(12)
        row[0:3] = self.center
        if self.shape == "plane":
            row[3:6] = _unit(self.normal)
        elif self.shape == "sphere":
            row[3] = self.radius
        elif self.shape == "cylinder":
            row[3:6] = _unit(self.axis)
            row[6] = self.radius
            row[7] = 0.5 * self.length
        elif self.shape == "box":
            a1 = _unit(self.axes[0])
            a2 = np.asarray(self.axes[1], dtype=float)
            a2 = _unit(a2 - np.dot(a2, a1) * a1)
            row[3:6] = 0.5 * np.asarray(self.size, dtype=float)
            row[6:9] = a1
            row[9:12] = a2
        elif self.shape in ("surface", "support"):
            pass  # surface: the contact grid's origin, cell and depth, filled in by the model
        else:
            raise ValueError(f"unknown tool shape {self.shape!r}; choose one of {TOOL_SHAPES}")
        return row

    @property
    def moves(self) -> bool:
        """Whether its speed history is ever non-zero (a loading tool, not a support)."""
        return any(v != 0.0 for v in self.speed.values)

    def velocity(self, t: float) -> np.ndarray:
        return float(self.speed(t)) * _unit(self.direction)

    def displacement(self, t: float) -> np.ndarray:
        return self.speed.integral(t) * _unit(self.direction)


@dataclass(frozen=True)
class Selection:
    """Nodes or faces chosen by geometry: on a plane (within tol) or inside an axis-aligned box."""

    plane_point: tuple[float, float, float] | None = None
    plane_normal: tuple[float, float, float] | None = None
    box_min: tuple[float, float, float] | None = None
    box_max: tuple[float, float, float] | None = None
    tol: float | None = None  # default: 1e-6 of the specimen size
    # On a cylinder's side: distance `radius` from the line through axis_point along axis_direction.
    radius: float | None = None
    axis_point: tuple[float, float, float] | None = None
    axis_direction: tuple[float, float, float] | None = None
    # On a named surface of the mesh file: its name, and (set by the method that has the mesh,
    # loading.build.with_named_surfaces) its triangles' corners (k, 3, 3).
    group: str | None = None
    surface: np.ndarray | None = field(default=None, compare=False, repr=False)

    def mask(self, points: np.ndarray, scale: float) -> np.ndarray:
        p = np.asarray(points, dtype=float)
        keep = np.ones(len(p), dtype=bool)
        tol = self.tol if self.tol is not None else 1e-6 * scale
        if self.group is not None:
            keep &= _near(p, self.named_surface().reshape(-1, 3), tol)
        if self.plane_point is not None:
            n = _unit(self.plane_normal)
            keep &= np.abs((p - np.asarray(self.plane_point)) @ n) <= tol
        if self.box_min is not None:
            keep &= np.all(p >= np.asarray(self.box_min) - tol, axis=1)
        if self.box_max is not None:
            keep &= np.all(p <= np.asarray(self.box_max) + tol, axis=1)
        if self.radius is not None:
            a = _unit(self.axis_direction)
            r = p - np.asarray(self.axis_point)
            keep &= np.abs(np.linalg.norm(r - np.outer(r @ a, a), axis=1) - self.radius) <= tol
        return keep

    def face_mask(self, points: np.ndarray, corners: np.ndarray, scale: float) -> np.ndarray:
        """Which faces (rows of `corners`, (m, 3) point indices) the selection takes: those whose
        three corners it holds; on a cylinder's side, not a face of an end whose corners all lie on
        the rim (its normal along the axis)."""
        chosen = np.all(self.mask(points, scale)[corners], axis=1)
        if self.group is not None and chosen.any():
            # A face of the named surface, not one whose corners all lie on it (across a fold).
            tol = self.tol if self.tol is not None else 1e-6 * scale
            centroids = np.asarray(points, dtype=float)[corners[chosen]].mean(axis=1)
            chosen[np.flatnonzero(chosen)] = _near(centroids, self.named_surface().mean(axis=1), tol)
        if self.radius is not None and chosen.any():
            p = np.asarray(points, dtype=float)[corners[chosen]]
            normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
            normal /= np.linalg.norm(normal, axis=1)[:, None]
            # A side face's normal is nearly radial, an end face's along the axis.
            chosen[np.flatnonzero(chosen)[np.abs(normal @ _unit(self.axis_direction)) > 0.5]] = False
        return chosen

    def named_surface(self) -> np.ndarray:
        if self.surface is None:
            raise ValueError(f"where.group = {self.group!r}: named surfaces are those of an FDEM specimen's mesh file")
        return self.surface


def _near(points: np.ndarray, targets: np.ndarray, tol: float) -> np.ndarray:
    """Which points lie within tol of one of the targets (a mask)."""
    return cKDTree(targets).query(points, distance_upper_bound=tol)[0] <= tol


@dataclass(frozen=True)
class Support:
    """fixed: no motion; clamped: no motion (a shell also holds its slope there); roller: no motion
    along `normal` (slides in the plane). With a grip (`tool` >= 0, the index of a Tool of shape
    "support" in the method's tools) the blocked directions move with that tool instead of
    holding still, and the tool's load cell reads the support's reaction."""

    kind: str
    where: Selection
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    tool: int = -1


@dataclass(frozen=True)
class Pressure:
    """A pressure history (Pa, positive pushes into the solid) on a set of faces.

    `faces` is "precrack" (both faces of every pre-crack) or a Selection of boundary faces (a
    face is selected when its three corners are). `wall` ("inner", "outer" or None: both)
    narrows the faces to one wall surface of a shell-like specimen. With a `front_speed` (m/s)
    the history travels: a face whose reference centre X lies at s = (X - front_origin) .
    front_direction feels history(t - s / front_speed), and nothing before (front_direction
    None: the specimen's axis).
    """

    history: History
    faces: str | Selection = "precrack"
    wall: str | None = None
    front_speed: float | None = None
    front_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    front_direction: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Precrack:
    """A planar crack present from the start: internal faces lying on the plane (within tol)
    whose centroids fall in the box [box_min, box_max] start separated (no cohesion)."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    box_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    box_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)
    tol: float | None = None


def load_surface(path: str | os.PathLike, scale: float = 1.0, offset=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3, in m) and triangles (k, 3) of a surface file for a surface tool
    (crackle.geometry.read_surface: any meshio format, points x scale + offset, closed surfaces
    oriented outwards). See `Tool` for the orientation convention."""
    return read_surface(path, scale, offset, hint="export the tool surface as triangles, e.g. STL")


def _unit(v) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    n = np.linalg.norm(a)
    if n == 0:
        raise ValueError("direction vector must be non-zero")
    return a / n


__all__ = ["History", "Precrack", "Pressure", "Selection", "Support", "TOOL_SHAPES", "Tool", "load_surface"]

"""[specimen] of a scenario turned into a tet mesh (and per-tet regions for shells with a suture)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..schema import resolve_path
from .meshes import Hole, TetMesh, gmsh_box, gmsh_cylinder, gmsh_sphere, locality_order, read_mesh, structured_box
from .walnut import shell_from_surface, walnut_shell


def specimen_mesh(spec, base: Path | None, planes: tuple = ()) -> tuple[TetMesh, np.ndarray | None]:
    """The specimen's tet mesh and its per-tet region ids (walnut, shell: 0 face, 1 suture; else
    None). Raises MeshError; relative file names are taken from `base`. Unstructured meshes, a
    file's too, come in a cache-friendly order (locality_order: a file's own order stepped 1.8-2.1x
    slower); a file's tets keep the numbers the file gives them (`TetMesh.labels`: its Abaqus labels,
    else their place in the file from 1), which messages and outputs use. A structured box keeps
    its regular order. `planes`
    ((point, normal) pairs: the material zones' bounding planes) cut a gmsh-meshed box, cylinder,
    disc or sphere so that faces lie on them."""
    if spec.shape == "mesh":
        mesh = read_mesh(resolve_path(spec.file, base))
        if mesh.labels is None:
            mesh = dataclasses.replace(mesh, labels=np.arange(1, mesh.n_tets + 1))
        mesh, _ = locality_order(mesh)
        return (mesh if spec.scale == 1.0 else dataclasses.replace(mesh, points=mesh.points * spec.scale)), None
    if spec.shape in ("box", "beam") and spec.mesh == "structured":
        return structured_box(spec.size, spec.element_size, origin=spec.origin), None
    mesh, region = _generated_mesh(spec, base, planes)
    mesh, order = locality_order(mesh)
    return mesh, (None if region is None else region[order])


# A specimen read from a file larger than this (m), or than FILE_TOOL_RATIO times its largest tool,
# is taken for a file in other units (mm) unless the scenario states specimen.scale.
FILE_EXTENT_LIMIT = 50.0
FILE_TOOL_RATIO = 1000.0
# A body read from a file (a projectile) this many times the specimen's size: a file in mm. A
# projectile is rarely larger than its target; one in mm spans 1000x its size in metres.
BODY_SPECIMEN_RATIO = 20.0


def check_file_units(points: np.ndarray, tools, scale_stated: bool, key: str, what: str = "the specimen",
                     beside: tuple[str, float] | None = None, ratio: float = FILE_TOOL_RATIO) -> None:
    """ValueError when the points of a specimen read from a file span more than FILE_EXTENT_LIMIT
    metres or FILE_TOOL_RATIO times the largest finite tool (a mesh in mm read as metres), unless
    the scenario stated the scale (then the size is meant); the message names `key`, the file's key.
    `what` names the points' body; `beside` (a name, its size in m) stands in for the tools, and
    `ratio` for FILE_TOOL_RATIO (a projectile's mesh beside the specimen: BODY_SPECIMEN_RATIO)."""
    if scale_stated or not len(points):
        return
    extent = float(np.max(np.ptp(points, axis=0)))
    if beside is None:
        sizes = [_tool_size(tool) for tool in tools]
        largest = max((size for size in sizes if size is not None), default=None)
        beside = None if largest is None else ("its largest tool", largest)
    if extent > FILE_EXTENT_LIMIT or (beside is not None and extent > ratio * beside[1]):
        against = f"{FILE_EXTENT_LIMIT:g} m" if beside is None else f"{beside[0]}, {beside[1]:.3g} m across"
        raise ValueError(
            f"{key}: {what} spans {extent:.4g} m, implausibly large against {against}: a file in mm? "
            f"set {key.rsplit('.', 1)[0]}.scale = 1e-3 (or 1 if it is in metres)"
        )


def _tool_size(tool) -> float | None:
    """A tool's largest finite dimension (m); None for a plane or a support grip."""
    if tool.shape in ("sphere", "cylinder"):
        return 2.0 * tool.radius if not math.isfinite(tool.length) or tool.shape == "sphere" else max(2.0 * tool.radius, tool.length)
    if tool.shape == "box":
        return max(tool.size)
    if tool.shape == "surface" and tool.vertices is not None and len(tool.vertices):
        return float(np.max(np.ptp(tool.vertices, axis=0)))
    return None


def planned_tets(spec) -> float | None:
    """About how many tets `spec` asks for, from its sizes and element_size alone (structured
    boxes: 24 per cubic cell; gmsh: a tet of edge h holds ~h^3 / 8.5), before anything is meshed;
    None where only the file tells (mesh, shell)."""
    h = spec.element_size
    if h is None or spec.shape in ("mesh", "shell"):
        return None
    if spec.shape in ("box", "beam"):
        volume = math.prod(spec.size)
        if spec.mesh == "structured":
            return 24.0 * math.prod(max(1.0, L / h) for L in spec.size)
    elif spec.shape == "sphere":
        volume = math.pi / 6.0 * spec.diameter**3
    elif spec.shape in ("disc", "cylinder"):
        volume = math.pi / 4.0 * spec.diameter**2 * spec.thickness
    else:  # walnut: an ellipsoidal wall; its surface by Thomsen's formula
        a, b, c = 0.5 * spec.width, 0.5 * spec.thickness, 0.5 * spec.length
        p = 1.6075
        area = 4.0 * math.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3.0) ** (1.0 / p)
        volume = area * max(spec.wall, spec.suture_wall, spec.layers * h)
    return 8.5 * volume / h**3 + sum(_graded_hole_tets(spec, hole) for hole in getattr(spec, "holes", ()) or ())


def _graded_hole_tets(spec, hole) -> float:
    """The tets a hole's finer element_size adds (about): gmsh grades the size linearly from the
    hole's to the specimen's over `grading` from its wall, so a cylindrical shell of radius r + d
    holds 8.5 dV / h(d)^3, integrated over d (the wall's curvature left out: a lower bound)."""
    h, fine = spec.element_size, hole.element_size
    if fine is None or fine >= h:
        return 0.0
    grading = hole.grading if hole.grading is not None else 3.0 * hole.radius
    axis = np.abs(np.asarray(hole.axis, float)) / np.linalg.norm(hole.axis)
    length = float(axis @ np.asarray(spec.size, float))  # the box's extent along the hole
    slope = (h - fine) / grading
    # 8.5 * integral_0^G 2 pi r L / (fine + slope d)^3 dd
    return 8.5 * math.pi * hole.radius * length / slope * (1.0 / fine**2 - 1.0 / h**2)


def _generated_mesh(spec, base: Path | None, planes: tuple = ()) -> tuple[TetMesh, np.ndarray | None]:
    walls = dict(wall=spec.wall, suture_wall=spec.suture_wall, suture_band=spec.suture_band, layers=spec.layers)
    if spec.shape == "walnut":
        return walnut_shell(spec.length, spec.width, spec.thickness, spec.element_size, center=spec.center, **walls)
    if spec.shape == "shell":
        return shell_from_surface(
            resolve_path(spec.file, base), spec.element_size, suture_normal=spec.suture_normal,
            scale=spec.scale, offset=spec.center, **walls,
        )
    if spec.shape in ("box", "beam"):
        holes = tuple(Hole(h.center, h.axis, h.radius, h.element_size or spec.element_size,
                           h.grading if h.grading is not None else 3.0 * h.radius) for h in spec.holes)
        return gmsh_box(spec.size, spec.element_size, origin=spec.origin, holes=holes, planes=planes), None
    if spec.shape == "sphere":
        return gmsh_sphere(0.5 * spec.diameter, spec.element_size, center=spec.center, planes=planes), None
    return gmsh_cylinder(0.5 * spec.diameter, spec.thickness, spec.element_size, center=spec.center, axis=spec.axis,
                         planes=planes), None

"""[specimen] of a scenario turned into a tet mesh (and per-tet regions for shells with a suture)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .meshes import TetMesh, gmsh_box, gmsh_cylinder, gmsh_sphere, locality_order, read_mesh, structured_box
from .walnut import shell_from_surface, walnut_shell


def specimen_mesh(spec, base: Path | None) -> tuple[TetMesh, np.ndarray | None]:
    """The specimen's tet mesh and its per-tet region ids (walnut, shell: 0 face, 1 suture; else
    None). Raises MeshError; relative file names are taken from `base`. Generated unstructured
    meshes come in a cache-friendly order (locality_order); a structured box keeps its regular
    order, a mesh file its own (so that element numbers in messages are the file's)."""
    from ..scenario import resolve_path

    if spec.shape == "mesh":
        return read_mesh(resolve_path(spec.file, base)), None
    if spec.shape in ("box", "beam") and spec.mesh == "structured":
        return structured_box(spec.size, spec.element_size, origin=spec.origin), None
    mesh, region = _generated_mesh(spec, base)
    mesh, order = locality_order(mesh)
    return mesh, (None if region is None else region[order])


def _generated_mesh(spec, base: Path | None) -> tuple[TetMesh, np.ndarray | None]:
    from ..scenario import resolve_path

    walls = dict(wall=spec.wall, suture_wall=spec.suture_wall, suture_band=spec.suture_band, layers=spec.layers)
    if spec.shape == "walnut":
        return walnut_shell(spec.length, spec.width, spec.thickness, spec.element_size, center=spec.center, **walls)
    if spec.shape == "shell":
        return shell_from_surface(
            resolve_path(spec.file, base), spec.element_size, suture_normal=spec.suture_normal,
            scale=spec.scale, offset=spec.center, **walls,
        )
    if spec.shape in ("box", "beam"):
        return gmsh_box(spec.size, spec.element_size, origin=spec.origin), None
    if spec.shape == "sphere":
        return gmsh_sphere(0.5 * spec.diameter, spec.element_size, center=spec.center), None
    return gmsh_cylinder(0.5 * spec.diameter, spec.thickness, spec.element_size, center=spec.center, axis=spec.axis), None

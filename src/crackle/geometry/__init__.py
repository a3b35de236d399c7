"""Tetrahedral meshes: structured and gmsh generation, import, checks, selections, face topology."""

from .meshes import (
    LOCAL_FACE_VERTICES,
    FaceTopology,
    MeshError,
    TetMesh,
    check_tets,
    disc,
    gmsh_box,
    gmsh_cylinder,
    gmsh_sphere,
    gmsh_from_surface,
    internal_faces,
    nodes_in_box,
    nodes_on_plane,
    read_mesh,
    structured_box,
    tet_volumes,
)

__all__ = [
    "LOCAL_FACE_VERTICES",
    "FaceTopology",
    "MeshError",
    "TetMesh",
    "check_tets",
    "disc",
    "gmsh_box",
    "gmsh_cylinder",
    "gmsh_sphere",
    "gmsh_from_surface",
    "internal_faces",
    "nodes_in_box",
    "nodes_on_plane",
    "read_mesh",
    "structured_box",
    "tet_volumes",
]

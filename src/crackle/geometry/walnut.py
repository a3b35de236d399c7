"""Walnut-like shells (paper 004): a closed ellipsoidal shell with a thicker, weaker suture band.

Paper 004 built its walnut from micro-CT scans. We use an ellipsoid instead, with the nut's
length L (along z), width W (along x, across the suture plane) and thickness T (along y), so
that the paper's equivalent diameter (its eq. 1, Tscheuschner and Mohsenin 1987)

    D_p = [L (W + T)^2 / 4]^(1/3)

is that of the scanned nut (mean over 2000 Wen-185 walnuts: 35.81 mm). A scanned nut can be
used through :func:`shell_from_surface` (its outer surface as STL or any meshio format, walled
inwards like the ellipsoid) or as a ready tet mesh (shape = "mesh").

The suture is the band of the shell within half a band width of the meridional plane x = 0
(the plane through the length axis and the y axis). It is region 1; the rest of the shell (the
face) is region 0. Its wall is thicker (paper: 1.34 mm against 1.11 mm on the face).
"""

from __future__ import annotations

import numpy as np

from .meshes import MeshError, TetMesh, _check_h, _fix_orientation, _gmsh_model, _gmsh_nodes, read_surface, surface_arrays, surface_closure

__all__ = ["equivalent_diameter", "walnut_shell", "shell_from_surface", "ellipsoid_shell_volume", "FACE", "SUTURE"]

FACE, SUTURE = 0, 1


def equivalent_diameter(length: float, width: float, thickness: float) -> float:
    """Paper 004 eq. 1: ``D_p = [L (W + T)^2 / 4]^(1/3)``."""
    return float((length * (width + thickness) ** 2 / 4.0) ** (1.0 / 3.0))


def ellipsoid_shell_volume(semi_axes, wall: float) -> float:
    """Volume between the ellipsoid with ``semi_axes`` and the one with each semi-axis less ``wall``."""
    a, b, c = (float(s) for s in semi_axes)
    return 4.0 / 3.0 * np.pi * (a * b * c - (a - wall) * (b - wall) * (c - wall))


def _unit_sphere_surface(element_size: float) -> tuple[np.ndarray, np.ndarray]:
    """gmsh triangulation of the unit sphere (nodes projected exactly onto it)."""
    with _gmsh_model(element_size) as gmsh:
        gmsh.model.occ.addSphere(0.0, 0.0, 0.0, 1.0)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(2)
        _, tri_nodes = gmsh.model.mesh.getElementsByType(2)
        coords, lookup = _gmsh_nodes(gmsh)
    tris = lookup[np.asarray(tri_nodes, dtype=np.int64).reshape(-1, 3)]
    used = np.unique(tris)
    renum = np.full(coords.shape[0], -1, dtype=np.int64)
    renum[used] = np.arange(used.size)
    pts = coords[used]
    pts /= np.linalg.norm(pts, axis=1)[:, None]
    tris = renum[tris]
    # Closed and manifold: every edge in exactly two triangles.
    e = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(e[:, 0] * pts.shape[0] + e[:, 1], return_counts=True)
    if np.any(counts != 2):
        raise MeshError("gmsh gave an open sphere triangulation; try another element_size")
    return pts, tris


def _prism_tets(tris: np.ndarray, ns: int, layers: int) -> np.ndarray:
    """Tets of a wall extruded from the surface triangles `tris` (ns nodes per layer, layer k's
    nodes numbered k ns .. (k + 1) ns - 1, layer 0 outside): each prism (a, b, c) over
    (a', b', c'), a < b < c by node number, is cut into (a b c a'), (b c a' b'), (c a' b' c').
    Each quad face gets the diagonal from the smaller node's inner copy to the larger node's outer
    copy, a rule both prisms sharing the face agree on, so neighbouring prisms conform."""
    s = np.sort(tris, axis=1)
    a, b, c = s[:, 0], s[:, 1], s[:, 2]
    tets = []
    for k in range(layers):
        lo, hi = k * ns, (k + 1) * ns
        tets += [
            np.column_stack([a + lo, b + lo, c + lo, a + hi]),
            np.column_stack([b + lo, c + lo, a + hi, b + hi]),
            np.column_stack([c + lo, a + hi, b + hi, c + hi]),
        ]
    return np.concatenate(tets)


def _check_shell_args(wall, suture_wall, suture_band, layers) -> tuple[float, int]:
    suture_wall = wall if suture_wall is None else float(suture_wall)
    if not (wall > 0 and suture_wall > 0 and suture_band > 0):
        raise MeshError("a shell needs positive wall, suture_wall and suture_band")
    layers = int(layers)
    if layers < 1:
        raise MeshError(f"layers must be >= 1, got {layers}")
    return suture_wall, layers


def walnut_shell(
    length: float,
    width: float,
    thickness: float,
    element_size: float,
    wall: float = 1.11e-3,
    suture_wall: float | None = 1.34e-3,
    suture_band: float = 4e-3,
    layers: int = 1,
    center=(0.0, 0.0, 0.0),
) -> tuple[TetMesh, np.ndarray]:
    """Tet mesh of a closed ellipsoidal walnut shell and its per-tet region (0 face, 1 suture).

    Semi-axes ``(width, thickness, length) / 2`` along (x, y, z), all in metres. The outer
    surface is a gmsh triangulation of the ellipsoid (edges about ``element_size``, nodes on the
    ellipsoid). Each outer node is mapped to the inner surface, the ellipsoid whose semi-axes are
    each less the local wall thickness (``wall`` on the face, ``suture_wall`` on the suture band
    ``|x| <= suture_band / 2``, ``None`` for the same as the face; the thicker suture grows
    inwards), and the wall is cut into ``layers`` layers of prisms, each split into 3 tets.
    The split follows the nodes' global numbers, so the tets of neighbouring prisms conform.
    Through the wall there are exactly ``layers`` tets along every outer node's line.

    The inner surface is a scaled ellipsoid, so the wall is ``wall`` exactly at the ends of the
    axes and within a few per cent of it elsewhere for nut-like axis ratios; the mesh volume
    approaches :func:`ellipsoid_shell_volume` as the surface triangles shrink.

    A tet is in the suture (region 1) when its centroid is within ``suture_band / 2`` of the
    plane x = 0 (before the shift to ``center``).
    """
    _check_h(element_size)
    semi = 0.5 * np.array([width, thickness, length], dtype=np.float64)
    if not np.all(semi > 0):
        raise MeshError("walnut_shell needs positive length, width and thickness")
    suture_wall, layers = _check_shell_args(wall, suture_wall, suture_band, layers)
    if max(wall, suture_wall) >= 0.5 * semi.min():
        raise MeshError(f"wall {max(wall, suture_wall)} m is too thick for semi-axes {semi.tolist()} m")

    unit, tris = _unit_sphere_surface(element_size / float(np.mean(semi)))
    outer = unit * semi
    ns = outer.shape[0]
    t_node = np.where(np.abs(outer[:, 0]) <= 0.5 * suture_band, suture_wall, wall)
    # Layer k (0 outer, `layers` inner): each semi-axis less k/layers of the local wall.
    pts = np.concatenate(
        [unit * (semi[None, :] - (k / layers) * t_node[:, None]) for k in range(layers + 1)]
    )

    tets = _fix_orientation(pts, _prism_tets(tris, ns, layers))
    centroid_x = pts[tets, 0].mean(axis=1)
    region = np.where(np.abs(centroid_x) <= 0.5 * suture_band, SUTURE, FACE).astype(np.int64)
    pts = pts + np.asarray(center, dtype=np.float64)
    return TetMesh(pts, tets), region


def shell_from_surface(
    path,
    element_size: float | None,
    wall: float = 1.11e-3,
    suture_wall: float | None = 1.34e-3,
    suture_band: float = 4e-3,
    suture_normal=(1.0, 0.0, 0.0),
    layers: int = 1,
    scale: float = 1.0,
    offset=(0.0, 0.0, 0.0),
    allow_open: bool = False,
) -> tuple[TetMesh, np.ndarray]:
    """Tet mesh of a shell whose outer surface is a closed triangulated surface (a scanned nut:
    STL or any meshio format, points x scale + offset, in m) and its per-tet region (0 face,
    1 suture).

    With ``element_size`` gmsh remeshes the surface to that size (patches split at 40 degree
    features); with None its triangles are used as they are. Each outer node moves inwards along
    its area-weighted normal by the local wall (``suture_wall`` within ``suture_band / 2`` of the
    suture plane, through the surface's centroid with normal ``suture_normal``), in ``layers``
    equal steps, and the prisms between are cut into tets as in :func:`walnut_shell`. The wall
    must stay below the surface's smallest radius of curvature, or inner nodes cross: such a
    surface is refused (inverted tets). With ``allow_open`` an open surface is walled too (its
    triangles wound consistently; the wall grows against their right-hand normals).

    The points are numbered layer by layer: the surface's ns nodes first (layer 0, the outer
    surface), node i of layer k is k ns + i.
    """
    suture_wall, layers = _check_shell_args(wall, suture_wall, suture_band, layers)
    try:
        pts, tris = read_surface(path, scale, offset, hint="export the closed outer surface as triangles, e.g. STL")
    except ValueError as err:  # MeshError included
        raise MeshError(str(err)) from None
    closed, consistent = surface_closure(tris)
    if not closed and not allow_open:
        raise MeshError(f"the surface in {path} is not closed (every edge in two triangles): close it first")
    if not consistent:
        raise MeshError(f"the triangles of the surface in {path} are not wound consistently (or an edge has more "
                        "than two): repair it (e.g. fix normals in MeshLab)")
    if element_size is not None:
        _check_h(element_size)
        pts, tris = _remesh_surface(pts, tris, element_size)
    return shell_from_triangles(pts, tris, wall, suture_wall, suture_band, suture_normal, layers,
                                f"the surface in {path}")


def shell_from_triangles(pts, tris, wall: float = 1.11e-3, suture_wall: float | None = 1.34e-3,
                         suture_band: float = 4e-3, suture_normal=(1.0, 0.0, 0.0), layers: int = 1,
                         what: str = "the surface") -> tuple[TetMesh, np.ndarray]:
    """shell_from_surface's walling of triangles already read (points (n, 3) m, triangles (m, 3)
    wound consistently; the wall grows against their right-hand normals); `what` names the
    surface in errors."""
    suture_wall, layers = _check_shell_args(wall, suture_wall, suture_band, layers)
    used = np.unique(tris)
    renum = np.full(len(pts), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    pts, tris = pts[used], renum[tris]
    ns = len(pts)
    # Outward area-weighted vertex normals (read_surface orients a closed surface outwards).
    face_n = np.cross(pts[tris[:, 1]] - pts[tris[:, 0]], pts[tris[:, 2]] - pts[tris[:, 0]])
    normal = np.zeros_like(pts)
    for k in range(3):
        np.add.at(normal, tris[:, k], face_n)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    n_sut = np.asarray(suture_normal, dtype=np.float64)
    n_sut = n_sut / np.linalg.norm(n_sut)
    area = np.linalg.norm(face_n, axis=1)
    middle = (pts[tris].mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()  # surface centroid
    t_node = np.where(np.abs((pts - middle) @ n_sut) <= 0.5 * suture_band, suture_wall, wall)
    layered = np.concatenate([pts - (k / layers) * t_node[:, None] * normal for k in range(layers + 1)])
    tets = _prism_tets(tris, ns, layers)
    vol = np.einsum(
        "ij,ij->i",
        np.cross(layered[tets[:, 1]] - layered[tets[:, 0]], layered[tets[:, 2]] - layered[tets[:, 0]]),
        layered[tets[:, 3]] - layered[tets[:, 0]],
    )
    # With the sorted triangle (a, b, c) wound outwards, each tet of its prisms has negative
    # volume (its fourth node lies inside); a tet of the other sign means inner nodes crossed.
    srt = np.sort(tris, axis=1)
    winding = np.sign(np.einsum("ij,ij->i", np.cross(pts[srt[:, 1]] - pts[srt[:, 0]], pts[srt[:, 2]] - pts[srt[:, 0]]), face_n))
    if np.any(vol * np.tile(winding, 3 * layers) >= 0.0):
        raise MeshError(
            f"the wall ({max(wall, suture_wall)} m) is too thick for the curvature of {what} "
            "(inner nodes cross or prisms invert); use a thinner wall, a smoother surface or a coarser element_size"
        )
    tets = _fix_orientation(layered, tets)
    centroid = layered[tets].mean(axis=1)
    region = np.where(np.abs((centroid - middle) @ n_sut) <= 0.5 * suture_band, SUTURE, FACE).astype(np.int64)
    return TetMesh(layered, tets), region


def _remesh_surface(pts: np.ndarray, tris: np.ndarray, element_size: float) -> tuple[np.ndarray, np.ndarray]:
    """gmsh remeshing of a closed triangulated surface at element_size."""
    with _gmsh_model(element_size) as gmsh:
        tag = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(2, tag, np.arange(1, len(pts) + 1), pts.ravel())
        gmsh.model.mesh.addElementsByType(tag, 2, [], (tris + 1).ravel())
        gmsh.model.mesh.classifySurfaces(np.deg2rad(40.0), True, True, np.pi)
        gmsh.model.mesh.createGeometry()
        gmsh.model.mesh.generate(2)
        _, tri_nodes = gmsh.model.mesh.getElementsByType(2)
        coords, lookup = _gmsh_nodes(gmsh)
    new_tris = lookup[np.asarray(tri_nodes, dtype=np.int64).reshape(-1, 3)]
    return surface_arrays(coords, new_tris, "the remeshed surface")

"""Walnut-like shells (paper 004): a closed ellipsoidal shell with a thicker, weaker suture band.

Paper 004 built its walnut from micro-CT scans. We use an ellipsoid instead, with the nut's
length L (along z), width W (along x, across the suture plane) and thickness T (along y), so
that the paper's equivalent diameter (its eq. 1, Tscheuschner and Mohsenin 1987)

    D_p = [L (W + T)^2 / 4]^(1/3)

is that of the scanned nut (mean over 2000 Wen-185 walnuts: 35.81 mm). A scanned nut can be
used instead as a specimen mesh file (shape = "mesh") or through ``gmsh_from_surface``.

The suture is the band of the shell within half a band width of the meridional plane x = 0
(the plane through the length axis and the y axis). It is region 1; the rest of the shell (the
face) is region 0. Its wall is thicker (paper: 1.34 mm against 1.11 mm on the face).
"""

from __future__ import annotations

import numpy as np

from .meshes import MeshError, TetMesh, _check_h, _fix_orientation, _gmsh_model, _gmsh_nodes

__all__ = ["equivalent_diameter", "walnut_shell", "ellipsoid_shell_volume", "FACE", "SUTURE"]

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
    suture_wall = wall if suture_wall is None else float(suture_wall)
    if not (np.all(semi > 0) and wall > 0 and suture_wall > 0 and suture_band > 0):
        raise MeshError("walnut_shell needs positive length, width, thickness, wall, suture_wall and suture_band")
    if max(wall, suture_wall) >= 0.5 * semi.min():
        raise MeshError(f"wall {max(wall, suture_wall)} m is too thick for semi-axes {semi.tolist()} m")
    layers = int(layers)
    if layers < 1:
        raise MeshError(f"layers must be >= 1, got {layers}")

    unit, tris = _unit_sphere_surface(element_size / float(np.mean(semi)))
    outer = unit * semi
    ns = outer.shape[0]
    t_node = np.where(np.abs(outer[:, 0]) <= 0.5 * suture_band, suture_wall, wall)
    # Layer k (0 outer, `layers` inner): each semi-axis less k/layers of the local wall.
    pts = np.concatenate(
        [unit * (semi[None, :] - (k / layers) * t_node[:, None]) for k in range(layers + 1)]
    )

    # Prism (a, b, c) over (a', b', c'), a < b < c by node number: tets (a b c a'), (b c a' b'),
    # (c a' b' c'). Each quad face gets the diagonal from the smaller node's inner copy to the
    # larger node's outer copy, a rule both prisms sharing the face agree on.
    s = np.sort(tris, axis=1)
    tets = []
    for k in range(layers):
        lo, hi = k * ns, (k + 1) * ns
        a, b, c = s[:, 0], s[:, 1], s[:, 2]
        tets += [
            np.column_stack([a + lo, b + lo, c + lo, a + hi]),
            np.column_stack([b + lo, c + lo, a + hi, b + hi]),
            np.column_stack([c + lo, a + hi, b + hi, c + hi]),
        ]
    tets = np.concatenate(tets)
    tets = _fix_orientation(pts, tets)
    centroid_x = pts[tets, 0].mean(axis=1)
    region = np.where(np.abs(centroid_x) <= 0.5 * suture_band, SUTURE, FACE).astype(np.int64)
    pts = pts + np.asarray(center, dtype=np.float64)
    return TetMesh(pts, tets), region

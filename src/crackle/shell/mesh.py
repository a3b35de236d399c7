"""The shell's triangulated mid-surface: vertices, oriented triangles, the edge table the bending
and the crack paths need, the checks a surface must pass, and pre-cracks cut into it by splitting
vertices along a path of edges (paper 002 section 7.1: "the crack is modeled by splitting the
nodes along the crack path in the reference configuration").

Conventions. Triangle f = (a0, a1, a2) counter-clockwise about its normal; its local edge i is the
edge opposite a_i, from a_{i+1} to a_{i+2}. Edge e joins vertices edge[e] = (e0, e1) in the
direction of its first face (edge_face[e, 0]), whose opposite vertex is edge_opposite[e, 0]; a
second face (edge_face[e, 1], -1 on a boundary) runs the edge the other way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra


class SurfaceError(ValueError):
    """A surface the shell cannot use; the message says what and where."""


@dataclass
class ShellMesh:
    X: np.ndarray  # (n, 3) reference positions of the vertices, m
    tri: np.ndarray  # (m, 3) int64 vertex indices, counter-clockwise
    thickness: np.ndarray  # (m,) m, per triangle
    edge: np.ndarray  # (k, 2) vertices, in the direction of the edge's first face
    edge_face: np.ndarray  # (k, 2) faces on each side, -1 on a boundary
    edge_opposite: np.ndarray  # (k, 2) each face's vertex off the edge, -1 on a boundary
    face_edge: np.ndarray  # (m, 3) edge opposite each corner
    region: np.ndarray  # (m,) int, which of the shell's materials each triangle is (model.ShellMaterial)

    @property
    def boundary(self) -> np.ndarray:
        """Mask of the boundary edges (one face)."""
        return self.edge_face[:, 1] < 0

    def crack_faces(self) -> np.ndarray:
        """(p, 2) edge indices: each pair of boundary edges with the same ends in the reference
        configuration, the two faces of a cut (split_along and the growing cracks copy a vertex
        to its exact position, so the faces coincide bit for bit). A seam the surface left
        unjoined counts too: mechanically it is a crack."""
        edges = np.flatnonzero(self.boundary)
        if len(edges) == 0:
            return np.zeros((0, 2), dtype=np.int64)
        a, b = self.X[self.edge[edges, 0]], self.X[self.edge[edges, 1]]
        diff = b - a  # the faces run an edge in opposite directions: key each by its ends in x, y, z order
        a_first = diff[np.arange(len(diff)), np.argmax(diff != 0.0, axis=1)] > 0.0
        keys = np.where(a_first[:, None], np.hstack([a, b]), np.hstack([b, a]))
        _, group, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        group = group.ravel()
        paired = count[group] == 2
        order = np.argsort(group[paired], kind="stable")
        return edges[paired][order].reshape(-1, 2)

    def element_size(self) -> float:
        """Median edge length (m)."""
        return float(np.median(np.linalg.norm(self.X[self.edge[:, 1]] - self.X[self.edge[:, 0]], axis=1)))


def shell_mesh(X, tri, thickness, region=0) -> ShellMesh:
    """A checked ShellMesh: every edge in one or two triangles, neighbours oriented alike, no
    triangle of zero area, a positive thickness (a number or one per triangle); region: each
    triangle's material (a number or one per triangle; 0, the first, by default)."""
    X = np.ascontiguousarray(X, dtype=float)
    tri = np.ascontiguousarray(tri, dtype=np.int64)
    if X.ndim != 2 or X.shape[1] != 3 or tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise SurfaceError("a shell surface needs vertices (n, 3) and at least one triangle (m, 3)")
    if tri.min() < 0 or tri.max() >= len(X):
        raise SurfaceError("a triangle names a vertex that does not exist")
    thickness = np.broadcast_to(np.asarray(thickness, dtype=float), (len(tri),)).copy()
    if not np.all(np.isfinite(thickness) & (thickness > 0)):
        raise SurfaceError("the shell's thickness must be positive")
    region = np.broadcast_to(np.asarray(region, dtype=np.int64), (len(tri),)).copy()
    a, b, c = (X[tri[:, i]] for i in range(3))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    scale = np.max(np.ptp(X, axis=0))
    degenerate = np.flatnonzero(area2 <= 1e-12 * scale**2)
    if len(degenerate):
        raise SurfaceError(f"{len(degenerate)} triangle(s) of zero area, the first {degenerate[0]} at "
                           f"{np.round(X[tri[degenerate[0]]].mean(axis=0), 6).tolist()}")
    edge, edge_face, edge_opposite, face_edge = _edges(X, tri)
    return ShellMesh(X, tri, thickness, edge, edge_face, edge_opposite, face_edge, region)


def altitudes(X, tri) -> np.ndarray:
    """Each triangle's smallest altitude (m), twice its area over its longest edge: the length
    that sets its stable step."""
    a, b, c = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)],
                     axis=0)
    return twice_area / longest


def _edges(X, tri):
    m = len(tri)
    # Half-edge (f, i): from tri[f, i+1] to tri[f, i+2], opposite corner i.
    start = tri[:, [1, 2, 0]].ravel()
    end = tri[:, [2, 0, 1]].ravel()
    face = np.repeat(np.arange(m), 3)
    corner = np.tile(np.arange(3), m)
    key = np.minimum(start, end) * len(X) + np.maximum(start, end)
    order = np.lexsort((face, key))
    key_sorted = key[order]
    first = np.concatenate([[True], key_sorted[1:] != key_sorted[:-1]])
    edge_id = np.cumsum(first) - 1
    count = np.bincount(edge_id)
    if count.max() > 2:
        bad = order[np.flatnonzero(count[edge_id] > 2)[0]]
        where = 0.5 * (X[start[bad]] + X[end[bad]])
        raise SurfaceError(f"non-manifold surface: an edge shared by {count.max()} triangles at "
                           f"{np.round(where, 6).tolist()}")
    k = len(count)
    edge_face = np.full((k, 2), -1, dtype=np.int64)
    edge_opposite = np.full((k, 2), -1, dtype=np.int64)
    edge = np.zeros((k, 2), dtype=np.int64)
    face_edge = np.zeros((m, 3), dtype=np.int64)
    slot = np.concatenate([[0], (~first[1:]).astype(np.int64)])  # 0 for the first half-edge of an edge, 1 for the second
    he = order
    edge_face[edge_id, slot] = face[he]
    edge_opposite[edge_id, slot] = tri[face[he], corner[he]]
    face_edge[face[he], corner[he]] = edge_id
    firsts = he[first]
    edge[:, 0], edge[:, 1] = start[firsts], end[firsts]
    seconds = he[~first]
    same_way = start[seconds] == edge[edge_id[~first], 0]
    if np.any(same_way):
        bad = seconds[np.flatnonzero(same_way)[0]]
        raise SurfaceError("triangles oriented inconsistently (an inverted triangle, or a non-orientable "
                           f"surface) at {np.round(0.5 * (X[start[bad]] + X[end[bad]]), 6).tolist()}: "
                           "orient every triangle the same way round")
    return edge, edge_face, edge_opposite, face_edge


def rectangle(width: float, height: float, nx: int, ny: int, thickness: float, origin=(0.0, 0.0, 0.0)) -> ShellMesh:
    """A flat rectangle [0, width] x [0, height] (+ origin) in the x-y plane, nx x ny cells, each
    split into two triangles by a diagonal that alternates with the cell (a union-jack-free
    criss-cross: no preferred direction overall)."""
    xs, ys = np.linspace(0.0, width, nx + 1), np.linspace(0.0, height, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1) + np.asarray(origin, float)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b, c, d = (v.ravel() for v in (idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]))
    even = (np.add.outer(np.arange(nx), np.arange(ny)) % 2 == 0).ravel()
    first = np.where(even[:, None], np.stack([a, b, c], axis=1), np.stack([a, b, d], axis=1))
    second = np.where(even[:, None], np.stack([a, c, d], axis=1), np.stack([b, c, d], axis=1))
    return shell_mesh(X, np.stack([first, second], axis=1).reshape(-1, 3), thickness)


def cylinder(radius: float, length: float, around: int, along: int, thickness: float, origin=(0.0, 0.0, 0.0)) -> ShellMesh:
    """An open cylinder about the z axis through origin (the centre of its first end), `around`
    cells round (rounded up to a multiple of 4: the diagonals alternate, and vertices lie on the
    x and y axes' planes) and `along` along z, normals outward."""
    around = -(-around // 4) * 4
    phi = 2.0 * np.pi * np.arange(around) / around
    z = np.linspace(0.0, length, along + 1)
    X = np.stack([np.repeat(radius * np.cos(phi), along + 1), np.repeat(radius * np.sin(phi), along + 1),
                  np.tile(z, around)], axis=1) + np.asarray(origin, float)
    idx = np.arange(around * (along + 1)).reshape(around, along + 1)
    nxt = np.roll(idx, -1, axis=0)
    a, b, c, d = (v.ravel() for v in (idx[:, :-1], nxt[:, :-1], nxt[:, 1:], idx[:, 1:]))
    even = (np.add.outer(np.arange(around), np.arange(along)) % 2 == 0).ravel()
    first = np.where(even[:, None], np.stack([a, b, c], axis=1), np.stack([a, b, d], axis=1))
    second = np.where(even[:, None], np.stack([a, c, d], axis=1), np.stack([b, c, d], axis=1))
    return shell_mesh(X, np.stack([first, second], axis=1).reshape(-1, 3), thickness)


def edge_path(mesh: ShellMesh, polyline) -> np.ndarray:
    """The chain of vertices, joined by edges, that follows a polyline (k >= 2 points on the
    surface) most closely: per segment, the shortest path in the edge graph between the vertices
    nearest its ends, an edge weighted by its length plus four times its midpoint's distance
    from the segment (so a path along the segment wins over a shorter detour)."""
    P = np.asarray(polyline, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2:
        raise SurfaceError("a pre-crack is a polyline of at least two points (x, y, z)")
    h = mesh.element_size()
    path = []
    a, b = mesh.edge[:, 0], mesh.edge[:, 1]
    length = np.linalg.norm(mesh.X[b] - mesh.X[a], axis=1)
    mid = 0.5 * (mesh.X[a] + mesh.X[b])
    for p, q in zip(P[:-1], P[1:]):
        ends = []
        for point in (p, q):
            d = np.linalg.norm(mesh.X - point, axis=1)
            nearest = int(np.argmin(d))
            if d[nearest] > h:
                raise SurfaceError(f"pre-crack point {np.round(point, 6).tolist()} is {d[nearest]:.3g} m off the "
                                   f"surface (more than an element, {h:.3g} m): give points on the mid-surface")
            ends.append(nearest)
        weight = length + 4.0 * _distance_to_segment(mid, p, q)
        graph = coo_matrix((weight, (a, b)), shape=(len(mesh.X),) * 2).tocsr()
        _, previous = dijkstra(graph, directed=False, indices=ends[0], return_predecessors=True)
        chain = [ends[1]]
        while chain[-1] != ends[0]:
            chain.append(int(previous[chain[-1]]))
        chain.reverse()
        path.extend(chain if not path else chain[1:])
    return np.array(path, dtype=np.int64)


def _distance_to_segment(points, p, q):
    d = q - p
    s = np.clip((points - p) @ d / (d @ d), 0.0, 1.0)
    return np.linalg.norm(points - (p + s[:, None] * d), axis=1)


def split_along(mesh: ShellMesh, path: np.ndarray) -> tuple[ShellMesh, np.ndarray]:
    """The mesh cut along a chain of vertices: each vertex of the chain whose triangles fall
    apart once the chain's edges are cut gets a copy per extra piece (the tips inside the
    surface stay whole; an end on the boundary opens). Returns the new mesh and, per new
    vertex, the vertex it copies (parent)."""
    cut = set()
    for u, w in zip(path[:-1], path[1:]):
        cut.add((min(u, w), max(u, w)))
    edge_keys = {(min(int(u), int(w)), max(int(u), int(w))): e for e, (u, w) in enumerate(mesh.edge)}
    missing = [pair for pair in cut if pair not in edge_keys]
    if missing:
        raise SurfaceError(f"the crack path joins vertices {missing[0]} that share no edge")
    tri = mesh.tri.copy()
    X = [mesh.X]
    parent = []
    n = len(mesh.X)
    for v in dict.fromkeys(int(u) for u in path):
        faces = np.flatnonzero(np.any(mesh.tri == v, axis=1))
        # Faces around v joined across an uncut edge at v belong to one piece.
        rows, cols = [], []
        for i, f in enumerate(faces):
            for j, g in enumerate(faces[:i]):
                shared = set(mesh.tri[f]) & set(mesh.tri[g])
                if len(shared) == 2:
                    other = (shared - {v}).pop()
                    if (min(v, other), max(v, other)) not in cut:
                        rows.append(i)
                        cols.append(j)
        graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(faces),) * 2)
        pieces, label = connected_components(graph, directed=False)
        for piece in range(1, pieces):
            for f in faces[label == piece]:
                tri[f][tri[f] == v] = n
            X.append(mesh.X[v][None, :])
            parent.append(v)
            n += 1
    return shell_mesh(np.concatenate(X), tri, mesh.thickness, mesh.region), np.array(parent, dtype=np.int64)

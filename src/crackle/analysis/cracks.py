"""Crack count and main-crack speed of a fractured shell (paper 004, section 3).

Input: the failed interfaces (their centroids in the reference configuration, areas and failure
times, and where the mesh is known their corners' mesh points). Algorithm, at a length scale r
(default: twice the element size):

1. Networks. Failed faces that share a mesh edge belong to one crack network: a crack is a
   connected surface of failed faces, whatever the mesh size (no length in this rule). Without the
   mesh (points alone), failed interfaces closer than r are linked instead (single linkage). A
   network whose extent (largest distance between two of its points) is below 2 r is a damage
   spot (crushing under a plate, an isolated failure), not a crack: counted apart.
2. Topology by rings. For each point of a network, the points at distances r..2r from it, linked
   at r, form k groups: k = 1 near a crack tip, k = 2 along a crack, k >= 3 near a junction
   where k arms meet. Points with k = 1 within r of each other make one tip; points with k >= 3
   make one junction of degree max(k).
3. Count, per network with L tips and junctions of degrees d_j: its arcs are
   E = (L + sum d_j) / 2 and its independent loops C = E - (L + J) + 1 (J junctions). The paper's
   rule (a crack grown both ways from one start is one crack, a branch adds one, a through crack
   counts two) gives cracks = 1 + sum (d_j - 2) + C: a single arc 1, a Y 2, a closed loop round
   the shell (no tips, no junctions) 2, a loop with a tail 3.
4. Main crack: the network that first reaches the top (the point of the specimen farthest along
   `top`), i.e. has a failure within r of that extreme; if none does, the one with the largest
   area. Its length at time t is its failed area up to t over the wall thickness (a crack through
   a wall of thickness w opens w of interface per metre); its speed is the growth of that length
   between 10 % and 90 % of its final value over the time it took, and the per-interval speeds
   Delta l / Delta t are its history (the paper's per-step speeds, averaged).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


@dataclass
class CrackNetwork:
    """One connected set of failed interfaces."""

    members: np.ndarray  # indices into the analysed points
    tips: int
    junction_degrees: list[int]
    loops: int
    cracks: int  # by the paper's rule (0 for a damage spot)
    extent: float  # m
    area: float  # m^2
    first_failure: float  # s
    reaches_top_at: float  # s (inf when it never does)


@dataclass
class CrackAnalysis:
    cracks: int
    networks: list[CrackNetwork]
    damage_spots: int
    main: int | None  # index into networks
    main_reaches_top: bool
    crack_speed: float | None  # m/s, main crack, 10-90 % of its length
    length_history: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (t, length m)
    speed_history: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (t mid, m/s)
    scale: float = 0.0

    def as_summary(self) -> dict:
        main = self.networks[self.main] if self.main is not None else None
        return {
            "cracks": self.cracks,
            "crack_speed": self.crack_speed,
            "crack_networks": [
                {"cracks": n.cracks, "tips": n.tips, "junctions": n.junction_degrees, "loops": n.loops,
                 "extent": n.extent, "failed_interfaces": int(len(n.members))}
                for n in self.networks
            ],
            "damage_spots": self.damage_spots,
            "main_crack": None if main is None else {
                "failed_interfaces": int(len(main.members)),
                "length": float(self.length_history[-1, 1]) if len(self.length_history) else 0.0,
                "reaches_top": self.main_reaches_top,
                "first_failure": main.first_failure,
            },
            "crack_speed_history": self.speed_history.tolist(),
            "crack_scale": self.scale,
        }


def _components(points: np.ndarray, radius: float) -> tuple[int, np.ndarray]:
    """Single-linkage groups of points at distance <= radius."""
    n = len(points)
    if n == 0:
        return 0, np.zeros(0, dtype=np.int64)
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)


def _face_components(faces: np.ndarray) -> tuple[int, np.ndarray]:
    """Groups of faces (k, 3 mesh points) connected through shared edges (two common points)."""
    k = len(faces)
    if k == 0:
        return 0, np.zeros(0, dtype=np.int64)
    ends = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [0, 2]]]), axis=1)
    _, edge = np.unique(ends, axis=0, return_inverse=True)
    edge = edge.ravel()
    owner = np.tile(np.arange(k), 3)
    graph = coo_matrix((np.ones(3 * k), (owner, k + edge)), shape=(k + edge.max() + 1,) * 2)
    _, label = connected_components(graph, directed=False)
    _, label = np.unique(label[:k], return_inverse=True)
    return int(label.max()) + 1, label.ravel()


def _ring_arms(points: np.ndarray, r: float) -> np.ndarray:
    """Per point, the groups of the points at distances r..2r from it, linked at r."""
    near_all = cKDTree(points).query_ball_point(points, 2.0 * r)
    arms = np.zeros(len(points), dtype=np.int64)
    for i, near in enumerate(near_all):
        near = np.asarray(near, dtype=np.int64)
        ring = near[np.linalg.norm(points[near] - points[i], axis=1) > r]
        if len(ring):
            arms[i] = _components(points[ring], r)[0]
    return arms


def analyse_cracks(
    centroids: np.ndarray,
    areas: np.ndarray,
    fail_times: np.ndarray,
    scale: float,
    wall: float,
    top_point: np.ndarray,
    intervals: int = 50,
    faces: np.ndarray | None = None,
) -> CrackAnalysis:
    """Cracks of the failed interfaces at `centroids` (reference positions, m), with their
    `areas` (m^2) and `fail_times` (s); `scale`: the length r (m) of the ring rule and the damage
    spots (and of the linking, without `faces`); `wall`: the shell's thickness (m); `top_point`:
    the specimen's extreme point along the top direction; `faces` (k, 3): each failed face's
    corners as mesh points, whose shared edges make the networks."""
    centroids = np.asarray(centroids, float).reshape(-1, 3)
    areas = np.asarray(areas, float)
    fail_times = np.asarray(fail_times, float)
    if scale <= 0 or wall <= 0:
        raise ValueError("crack analysis needs a positive scale and wall thickness")
    r = float(scale)
    n_groups, label = _components(centroids, r) if faces is None else _face_components(np.asarray(faces).reshape(-1, 3))
    top_point = np.asarray(top_point, float)
    networks: list[CrackNetwork] = []
    spots = 0
    for g in range(n_groups):
        members = np.flatnonzero(label == g)
        pts = centroids[members]
        # Extent: farthest pair, via the farthest point from the farthest point from any point.
        far = pts[np.argmax(np.linalg.norm(pts - pts[0], axis=1))]
        extent = float(np.max(np.linalg.norm(pts - far, axis=1)))
        if extent < 2.0 * r:
            spots += 1
            continue
        arms = _ring_arms(pts, r)
        tips, _ = _components(pts[arms == 1], r)
        junction_pts = np.flatnonzero(arms >= 3)
        n_j, j_label = _components(pts[junction_pts], r)
        degrees = [int(arms[junction_pts[j_label == j]].max()) for j in range(n_j)]
        arcs = (tips + sum(degrees)) / 2.0
        loops = 1 if tips == 0 and n_j == 0 else max(int(round(arcs - (tips + n_j) + 1)), 0)
        cracks = 1 + sum(d - 2 for d in degrees) + loops
        near_top = np.linalg.norm(pts - top_point, axis=1) <= r
        networks.append(CrackNetwork(
            members=members, tips=int(tips), junction_degrees=degrees, loops=loops, cracks=cracks,
            extent=extent, area=float(areas[members].sum()),
            first_failure=float(fail_times[members].min()),
            reaches_top_at=float(fail_times[members][near_top].min()) if near_top.any() else np.inf,
        ))

    total = sum(n.cracks for n in networks)
    if not networks:
        return CrackAnalysis(0, networks, spots, None, False, None, scale=r)
    reach = np.array([n.reaches_top_at for n in networks])
    if np.isfinite(reach).any():
        main, reaches = int(np.argmin(reach)), True
    else:
        main, reaches = int(np.argmax([n.area for n in networks])), False

    members = networks[main].members
    order = np.argsort(fail_times[members], kind="stable")
    t = fail_times[members][order]
    length = np.cumsum(areas[members][order]) / wall
    history = np.column_stack([t, length])
    final = length[-1]
    t10 = t[np.searchsorted(length, 0.1 * final)]
    t90 = t[min(np.searchsorted(length, 0.9 * final), len(t) - 1)]
    l10 = np.interp(t10, t, length)
    l90 = np.interp(t90, t, length)
    speed = float((l90 - l10) / (t90 - t10)) if t90 > t10 else None
    # Per-interval speeds over the growth, as the paper averages per analysis step.
    if t[-1] > t[0]:
        edges = np.linspace(t[0], t[-1], intervals + 1)
        grown = np.interp(edges, t, length)
        speeds = np.diff(grown) / np.diff(edges)
        speed_history = np.column_stack([0.5 * (edges[1:] + edges[:-1]), speeds])
    else:
        speed_history = np.zeros((0, 2))
    return CrackAnalysis(total, networks, spots, main, reaches, speed, history, speed_history, r)


@dataclass(frozen=True)
class CrackSettings:
    """What the crack analysis of a run needs beyond the model."""

    wall: float  # m, shell thickness
    scale: float  # m, linking length r
    top: tuple[float, float, float] = (0.0, 0.0, 1.0)

"""Crack growth on the shell (paper 002 sections 5-6): Griffith's criterion on the J-integral, the
crack speed law, and the topology update that moves a tip along the mesh by splitting vertices.

Every GROWTH_CHECK steps (a fixed grid of step numbers, so the run does not depend on how it is
split into calls), each tip's J (the mean over its rings) is compared with Gc. Where J >= Gc the
tip runs at V = V_max min(1, (J / Gc - 1)^m) (the paper's power law in G / Gc - 1, capped at
V_max), its advance accumulating over the checks; once the advance reaches the next edge ahead
(the tip's edge best aligned with its direction), that edge is cut (mesh.split_along): the tip
vertex splits in two and the edge's far end is the new tip (node release). The new mesh's arrays
are rebuilt and the state carried over: positions and velocities of the old vertices, the
parent's for each new copy (the split conserves mass and momentum), the supports and tool state
of the parent, the work counters on the old vertices (the copies start at zero).

The direction: the kink criterion (maximum tangential stress, Erdogan and Sih, or maximum energy
release rate; K_I and K_II from J and the crack faces' displacements, jintegral.stress_intensity):
straight ahead in mode I, 70.5 (75.2) deg off in pure mode II. So that the path is not locked to the mesh's edge directions, an edge at
the tip is first turned onto that heading (local remeshing by moving vertices, `align_ahead`):
the tip's neighbours move in the reference surface, each at its distance from the tip, as far
as their triangles stay well shaped; their state is interpolated from the old mesh. Then the
edge best aligned with the heading is cut.

Energy: cutting an edge does not move anything, so no energy appears or vanishes at the cut
except the bending energy of the triangles whose edge became free (their free-edge angle is
condensed); moving vertices changes the strain and kinetic energy a little (their triangles'
shapes, their masses, their interpolated state). `energy.damage` books both jumps; the membrane energy near
the tip is then released by the motion (kinetic, then damping). The Griffith energy Gc x
thickness x extension is in the summary, not the audit.

Nucleation (a first version of paper 002's outlook): with a strength (`fracture.strength`), a free
edge of the sheet (its outer boundary or a hole's; not a crack's faces, not a loaded or supported
vertex) starts a crack where its membrane stress along the edge reaches the strength: at a free
edge the stress across it is zero, so that tangential stress is the largest principal one there,
and the crack runs into the sheet normal to it. The edge's vertex opens (the crack's mouth) and
the first edge inward, turned onto the normal first, is cut; its far end is the new tip, which
grows by Griffith and the speed law like any other.

Random fracture properties ([material.random]: `toughness` per edge, `strength` per free-edge
vertex, each material its own, `RandomSites`): the mesh changes as the crack grows (cut_edge
splits vertices and rebuilds the edge table, align_ahead moves the tip's neighbours in the
reference), so values are not stored per edge, which the rebuilds renumber, but kept as a
function of the reference position (`SiteField`) evaluated where they are needed: an edge's Gc
at its mid-point, a vertex's strength at the vertex. A cut copies vertices to their exact
positions, so every edge keeps its mid-point, and its value, through any number of cuts and
rebuilds; an edge that align_ahead turns has a new mid-point and takes the field's value there.
A correlated field (correlation_length) is GSTools' randomisation method, a deterministic
function of position for its seed (materials.random_properties.standard_normal); independent
sites take their standard normal value from a hash of the mid-point's coordinates (their bits)
with the seed, so a value does not depend on the order in which sites are evaluated, on the
thread count or on a resume. Griffith's check reads the Gc of the edge ahead of the tip (along
the heading the kink criterion gives) and, before each further cut, of the edge about to be cut.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..loading.tools import NO_TOOL
from ..materials.random_properties import (RandomProperty, hashed_normal, random_field, statistics, stream_seed,
                                           to_marginal)
from ..solver.integrator import FREE
from .mesh import altitudes, split_along
from .model import Shell, build_shell

GROWTH_CHECK = 20  # steps between checks
ALTITUDE_KEPT = 0.7  # x the starting mesh's smallest altitude: no move makes a triangle thinner (the step)
ALIGNED_ANGLE = np.radians(0.5)  # rad, an edge this close to the heading is not turned


# What [material.random] may draw on a shell: [fracture]'s toughness (Gc, per edge) and strength
# (per free-edge vertex), by their names there.
RANDOM_SITE_PROPERTIES = ("toughness", "strength")

class SiteField:
    """One property of one material as a function of the reference position: the value `spec`'s
    marginal takes (mean `mean`) at a point, from the stream `seed` (stream_seed of the run's seed
    and the names): a GSTools random field with a correlation length, else an independent value
    per point from its hash (hashed_normal). Values already asked for are remembered by point."""

    def __init__(self, spec: RandomProperty, mean: float, seed: int):
        self.spec, self.mean, self.seed = spec, float(mean), int(seed)
        self._known: dict[bytes, float] = {}
        self._field = None  # the GSTools field, built once (its modes take ~0.3 s)

    def __getstate__(self):
        # A checkpoint keeps the definition; values and the field are functions of it, made again.
        return {**self.__dict__, "_known": {}, "_field": None}

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """The values at the points (m, (k, 3))."""
        points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3) + 0.0
        keys = [point.tobytes() for point in points]
        new = [i for i, key in enumerate(keys) if key not in self._known]
        if new:
            fresh = dict(zip((keys[i] for i in new), self._values(points[new])))
            self._known.update(fresh)
        return np.array([self._known[key] for key in keys], dtype=float)

    def _values(self, points: np.ndarray) -> np.ndarray:
        if self.spec.correlation_length is None:
            z = hashed_normal(points, self.seed)
        else:
            if self._field is None:  # kept for the next points
                self._field = random_field(self.spec, self.seed)
            z = np.asarray(self._field(points.T, mesh_type="unstructured"), float)
        return to_marginal(self.spec, self.mean, z)


@dataclass
class RandomSites:
    """The shell's properties drawn per fracture site ([material.random]): per property (a name
    of RANDOM_SITE_PROPERTIES) one SiteField per material (ShellMesh.region indexes them; None
    where that material does not draw it: [fracture]'s value, the mean, everywhere). A site
    between materials (an edge on two regions' triangles, a vertex on several) takes the lowest
    of their values: the weaker side breaks."""

    fields: dict[str, list[SiteField | None]]
    means: dict[str, float]

    @classmethod
    def of(cls, randoms: list[dict], names: list[str], means: dict[str, float], seed: int) -> RandomSites | None:
        """From each material's [material.random] (`randoms`, in region order) and name, [fracture]'s
        values (`means`) and the run's seed; None where no material draws anything."""
        if not any(randoms):
            return None
        fields = {}
        for prop in RANDOM_SITE_PROPERTIES:
            if any(prop in random for random in randoms):
                fields[prop] = [SiteField(random[prop], means[prop], stream_seed(seed, name, prop)) if prop in random
                                else None for random, name in zip(randoms, names)]
        return cls(fields, {prop: float(means[prop]) for prop in fields})

    def values(self, prop: str, points: np.ndarray, regions: np.ndarray) -> np.ndarray:
        """The property at the points (m, (k, 3)) whose materials are `regions` ((k, r), -1 for
        none): the lowest over them."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        regions = np.asarray(regions).reshape(len(points), -1)
        out = np.full(len(points), np.inf)
        for r, site_field in enumerate(self.fields[prop]):
            here = np.flatnonzero(np.any(regions == r, axis=1))
            if len(here):
                value = self.means[prop] if site_field is None else site_field(points[here])
                out[here] = np.minimum(out[here], value)
        return out

    def statistics(self, mesh, names: list[str]) -> dict:
        """summary.json's {material: {property: statistics}} on `mesh` (the set-up's): toughness
        over the edges of each material's triangles (at their mid-points), strength over the
        vertices of its triangles on the boundary (the free edges' nucleation sites), each
        material's own values."""
        out: dict = {}
        boundary_vertex = np.zeros(len(mesh.X), dtype=bool)
        boundary_vertex[mesh.edge[mesh.boundary].ravel()] = True
        for prop, site_fields in self.fields.items():
            for r, site_field in enumerate(site_fields):
                if site_field is None:
                    continue
                if prop == "toughness":
                    edges = np.flatnonzero(np.any((mesh.edge_face >= 0) & (mesh.region[mesh.edge_face] == r), axis=1))
                    points = edge_midpoints(mesh, edges)
                else:
                    vertices = np.unique(mesh.tri[mesh.region == r])
                    points = mesh.X[vertices[boundary_vertex[vertices]]]
                out.setdefault(names[r], {})[prop] = statistics(site_field.spec, points, site_field(points))
        return out


def edge_midpoints(mesh, edges) -> np.ndarray:
    """The edges' mid-points in the reference (m): the same for an edge and its copies after a cut
    (split vertices keep their positions; 0.5 (a + b) is symmetric in its ends)."""
    return 0.5 * (mesh.X[mesh.edge[edges, 0]] + mesh.X[mesh.edge[edges, 1]])


@dataclass
class GrowthLaw:
    toughness: float  # J/m^2, Gc
    max_speed: float  # m/s, V_max
    exponent: float = 1.0  # m
    criterion: str = "j"  # "j": the domain J; "g": G by virtual crack extension
    kink: str = "mts"  # the turn's criterion: a key of jintegral.KINK_CRITERIA
    strength: float = float("inf")  # Pa, a free edge's tangential membrane stress that starts a crack (inf: none)
    # Gc and the strength drawn per site ([material.random]); None: the values above everywhere.
    sites: RandomSites | None = None

    @property
    def random_toughness(self) -> bool:
        """Gc differs from edge to edge: Griffith reads each edge's (edge_toughness)."""
        return self.sites is not None and "toughness" in self.sites.fields

    def speed(self, j: float, toughness: float | None = None) -> float:
        """V (m/s) at J (J/m^2): 0 below Gc (`toughness`, an edge's; default the law's)."""
        gc = self.toughness if toughness is None else toughness
        if not j >= gc:
            return 0.0
        return self.max_speed * min(1.0, (j / gc - 1.0) ** self.exponent)

    def edge_toughness(self, mesh, edges) -> np.ndarray:
        """Gc (J/m^2) of the mesh's `edges`: drawn at their reference mid-points, the lowest of
        their triangles' materials' (RandomSites), or the law's value."""
        edges = np.atleast_1d(np.asarray(edges, dtype=np.int64))
        if not self.random_toughness:
            return np.full(len(edges), self.toughness)
        faces = mesh.edge_face[edges]
        regions = np.where(faces >= 0, mesh.region[faces], -1)
        return self.sites.values("toughness", edge_midpoints(mesh, edges), regions)

    def vertex_strength(self, mesh, vertices) -> np.ndarray:
        """The nucleation strength (Pa) at the mesh's `vertices`: drawn at their reference
        positions, the lowest of their triangles' materials', or the law's value."""
        vertices = np.atleast_1d(np.asarray(vertices, dtype=np.int64))
        if self.sites is None or "strength" not in self.sites.fields:
            return np.full(len(vertices), self.strength)
        materials = len(self.sites.fields["strength"])
        regions = np.full((len(mesh.X), materials), -1, dtype=np.int64)  # column r: r where a triangle of r has the vertex
        for r in range(materials):
            regions[np.unique(mesh.tri[mesh.region == r]), r] = r
        return self.sites.values("strength", mesh.X[vertices], regions[vertices])


@dataclass
class Advance:
    time: float
    position: np.ndarray  # reference, the new tip
    tip: int
    mode: int  # solver.failures code of the tip's mixity


def edge_stresses(shell: Shell, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The free-edge vertices that may start a crack (two boundary edges, not on a crack's faces,
    not loaded, clamped, touching a tool or held in the sheet's plane by a support: a roller
    across the sheet leaves it free), their membrane stress along the edge (Pa: the mean
    membrane force of their triangles over the thickness, t N t with t the edge's tangent) and
    the unit vector into the sheet normal to the edge, in its tangent plane."""
    mesh, nodes = shell.mesh, shell.nodes
    X = mesh.X
    bounding = mesh.edge[mesh.boundary]
    on_crack = np.zeros(len(X), dtype=bool)
    on_crack[mesh.edge[mesh.crack_faces().ravel()]] = True
    count = np.bincount(bounding.ravel(), minlength=len(X))
    held = np.any(nodes.load != 0.0, axis=1) | (nodes.tool != NO_TOOL)
    if shell.clamped is not None:
        held |= shell.clamped
    candidates = np.flatnonzero((count == 2) & ~on_crack & ~held)
    _, force = shell.membrane_state(x)
    stress = force / mesh.thickness[:, None]
    tensor = np.stack([stress[:, [0, 3, 5]], stress[:, [3, 1, 4]], stress[:, [5, 4, 2]]], axis=1)  # (m, 3, 3)
    free, tangential, inward = [], [], []
    for v in candidates:
        ends = bounding[np.any(bounding == v, axis=1)].ravel()
        ends = ends[ends != v]
        tangent = X[ends[1]] - X[ends[0]]
        tangent /= np.linalg.norm(tangent)
        faces = np.flatnonzero(np.any(mesh.tri == v, axis=1))
        normal = _normals(X, mesh.tri[faces]).sum(axis=0)
        into = np.cross(normal, tangent)
        into /= np.linalg.norm(into)
        if into @ (X[mesh.tri[faces]].mean(axis=(0, 1)) - X[v]) < 0.0:
            into = -into
        if nodes.constraint[v] != FREE:
            projection = nodes.projection[nodes.constraint[v]]
            if not np.allclose(projection @ np.stack([tangent, into], axis=1), np.stack([tangent, into], axis=1),
                               rtol=0.0, atol=1e-9):
                continue
        free.append(v)
        tangential.append(tangent @ tensor[faces].mean(axis=0) @ tangent)
        inward.append(into)
    return np.array(free, dtype=np.int64), np.array(tangential), np.array(inward).reshape(-1, 3)


def step_ahead(shell: Shell, vertex: int, direction: np.ndarray) -> tuple[int, float] | None:
    """The neighbour of `vertex` along the edge best aligned with `direction` (within 60 deg),
    and that edge's length; None if there is none (the crack reached a boundary)."""
    mesh = shell.mesh
    edges = np.flatnonzero(np.any(mesh.edge == vertex, axis=1) & ~mesh.boundary)
    best, best_cos, best_length = None, 0.5, 0.0
    for e in edges:
        other = int(mesh.edge[e, 0] if mesh.edge[e, 1] == vertex else mesh.edge[e, 1])
        d = mesh.X[other] - mesh.X[vertex]
        length = float(np.linalg.norm(d))
        cos = float(np.dot(d, direction)) / length
        if cos > best_cos + 1e-12:
            best, best_cos, best_length = other, cos, length
    return None if best is None else (best, best_length)


def edge_between(mesh, a: int, b: int) -> int:
    """The index of the mesh's edge joining vertices a and b (the first where a cut left two)."""
    ends = mesh.edge
    return int(np.flatnonzero(((ends[:, 0] == a) & (ends[:, 1] == b)) | ((ends[:, 0] == b) & (ends[:, 1] == a)))[0])


def cut_edge(shell: Shell, a: int, b: int) -> tuple[Shell, np.ndarray]:
    """The shell with the edge (a, b) cut and its state carried over (module docstring), and the
    vertices the cut opened (a always; b too when it is on a boundary: the crack went through)."""
    mesh, parent = split_along(shell.mesh, np.array([a, b]))
    return _continued(shell, mesh, np.concatenate([np.arange(len(shell.mesh.X)), parent])), parent


def align_ahead(shell: Shell, tip: int, heading: np.ndarray, thinnest: float) -> Shell | None:
    """The shell with an edge at the crack tip turned onto the tip's heading (a unit tangent
    vector) by moving the tip's neighbours in the reference surface, or None where no turn is
    needed (an edge within ALIGNED_ANGLE) or none keeps the mesh good enough. The edges tried
    are the two nearest the heading, one on each side. Turning the edge to a neighbour b: every
    neighbour keeps its distance from the tip, and their angles about it are stretched on one
    side of b and squeezed on the other, up to the nearest neighbours that cannot move (the
    crack's flanks, a boundary, the edge of a support's or a tool's region, a load: _movable), so
    no one triangle takes the whole turn. The whole turn, else 3/4 or 1/2 of it (the least
    missed first), is taken if every triangle changed keeps its orientation and an altitude of
    at least ALTITUDE_KEPT x `thinnest` (the starting mesh's smallest: the stable step). A moved
    vertex's position and velocity are interpolated in the triangle of the old mesh its new
    reference point lands in (a linear field stays exact); the topology does not change."""
    mesh = shell.mesh
    X = mesh.X
    ring = np.unique(mesh.edge[np.any(mesh.edge == tip, axis=1)])
    ring = ring[ring != tip]
    movable = np.array([_movable(shell, u) for u in ring])
    normal = _normals(X, mesh.tri[np.any(mesh.tri == tip, axis=1)]).sum(axis=0)
    normal /= np.linalg.norm(normal)
    e1 = heading - (heading @ normal) * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    arms = X[ring] - X[tip]
    theta = np.arctan2(arms @ e2, arms @ e1)  # the heading at 0
    if np.min(np.abs(theta)) < ALIGNED_ANGLE:
        return None
    sides = [np.flatnonzero(theta > 0.0), np.flatnonzero(theta < 0.0)]
    candidates = sorted((abs(theta[side[np.argmin(np.abs(theta[side]))]]), int(side[np.argmin(np.abs(theta[side]))]))
                        for side in sides if len(side))
    for share in (1.0, 0.75, 0.5):
        for _, b in candidates:
            if movable[b]:
                new = _turned(shell, tip, ring, movable, theta, b, share, (e1, e2), thinnest)
                if new is not None:
                    return new
    return None


def _turned(shell: Shell, tip: int, ring, movable, theta, b: int, share: float, frame, thinnest: float) -> Shell | None:
    """align_ahead's move of the tip's neighbours ring (angles theta from the heading) that turns
    the edge to ring[b] by `share` of its angle; None if the mesh would not stay good enough."""
    mesh, nodes = shell.mesh, shell.nodes
    X = mesh.X
    phi = np.angle(np.exp(1j * (theta - theta[b])))  # about ring[b], in (-pi, pi]
    anchors = phi[~movable]
    if not len(anchors):
        return None
    hi = np.min(anchors[anchors > 0.0]) if np.any(anchors > 0.0) else np.min(anchors) + 2.0 * np.pi
    lo = np.max(anchors[anchors < 0.0]) if np.any(anchors < 0.0) else np.max(anchors) - 2.0 * np.pi
    t = share * np.angle(np.exp(-1j * theta[b]))  # towards the heading, about ring[b]
    if not lo < t < hi:
        return None
    inside = movable & (phi > lo) & (phi < hi)
    turned = np.where(phi <= 0.0, lo + (phi - lo) * (t - lo) / (0.0 - lo), t + phi * (hi - t) / hi) + theta[b]
    patch = mesh.tri[np.any(np.isin(mesh.tri, ring[inside]), axis=1)]
    moved = X.copy()
    located = []
    for k in np.flatnonzero(inside):
        aim = X[tip] + np.linalg.norm(X[ring[k]] - X[tip]) * (np.cos(turned[k]) * frame[0] + np.sin(turned[k]) * frame[1])
        face, weights, moved[ring[k]] = _closest_on(X, patch, aim)
        located.append((ring[k], patch[face], weights))
    if (np.min(altitudes(moved, patch)) < ALTITUDE_KEPT * thinnest
            or np.any(np.einsum("kd,kd->k", _normals(moved, patch), _normals(X, patch)) <= 0.0)):
        return None
    new = _continued(shell, replace(mesh, X=moved), np.arange(len(X)))
    for u, corners, weights in located:
        new.nodes.x[u] = weights @ nodes.x[corners]
        new.nodes.v[u] = weights @ nodes.v[corners]
    return new


def _movable(shell: Shell, vertex: int) -> bool:
    """Whether `vertex` may move in the reference: off every boundary and crack face, not loaded
    or clamped, and inside any support's or tool's region (those are placed by region: its whole
    star is held alike, a roller on the whole sheet, say)."""
    mesh, nodes = shell.mesh, shell.nodes
    if np.any(mesh.edge[mesh.boundary] == vertex) or np.any(nodes.load[vertex] != 0.0):
        return False
    if shell.clamped is not None and shell.clamped[vertex]:
        return False
    star = np.unique(mesh.tri[np.any(mesh.tri == vertex, axis=1)])
    return bool(np.all(nodes.constraint[star] == nodes.constraint[vertex]) and np.all(nodes.tool[star] == nodes.tool[vertex]))


def _normals(X, tri) -> np.ndarray:
    return np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]])


def _closest_on(X, tri, point) -> tuple[int, np.ndarray, np.ndarray]:
    """The triangle (index into tri), the barycentric weights and the point of the triangles tri
    nearest to `point`."""
    best = (np.inf, 0, None, None)
    for f, corners in enumerate(tri):
        weights = _closest_barycentric(X[corners], point)
        q = weights @ X[corners]
        distance = float(np.linalg.norm(q - point))
        if distance < best[0] - 1e-15:
            best = (distance, f, weights, q)
    return best[1], best[2], best[3]


def _closest_barycentric(corners, point) -> np.ndarray:
    """Barycentric weights of the point of a triangle nearest to `point`: the projection onto its
    plane if inside, else the nearest point of its edges."""
    a, b, c = corners
    e1, e2 = b - a, c - a
    gram = np.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
    s, t = np.linalg.solve(gram, [e1 @ (point - a), e2 @ (point - a)])
    if s >= 0.0 and t >= 0.0 and s + t <= 1.0:
        return np.array([1.0 - s - t, s, t])
    best, weights = np.inf, None
    for i, j in ((0, 1), (1, 2), (2, 0)):
        p, q = corners[i], corners[j]
        u = float(np.clip((point - p) @ (q - p) / ((q - p) @ (q - p)), 0.0, 1.0))
        distance = np.linalg.norm(p + u * (q - p) - point)
        if distance < best:
            best, weights = distance, np.zeros(3)
            weights[i], weights[j] = 1.0 - u, u
    return weights


def _continued(shell: Shell, mesh, source: np.ndarray) -> Shell:
    """A shell on `mesh` whose vertex i continues the old vertex source[i] (the vertices past the
    old count are new copies): positions, velocities, supports and tool state carried, the
    copies' edge loads and work counters zero (the parent keeps them), the faces' pressures (a
    cut or a move keeps the triangles' order) and the edges' state (_carry_edge_state)."""
    old, n_old = shell.nodes, len(shell.mesh.X)
    new = build_shell(mesh, shell.material, None if shell.clamped is None else shell.clamped[source])
    carried = {}
    for name in ("x", "v", "constraint", "tool", "tool_offset", "friction", "load"):
        carried[name] = getattr(old, name)[source].copy()
    for name in ("w_external", "w_damping", "d_friction"):
        counter = np.zeros(len(source))
        counter[:n_old] = getattr(old, name)
        carried[name] = counter
    carried["load"][n_old:] = 0.0
    new.nodes = new.nodes._replace(projection=old.projection, support_tool=old.support_tool, **carried)
    for name in ("pressure", "pressure_sign", "pressure_delay"):
        getattr(new.faces, name)[:] = getattr(shell.faces, name)
    _carry_edge_state(shell, new, source)
    return new


def _carry_edge_state(old: Shell, new: Shell, source: np.ndarray) -> None:
    """The mid-edge rotations, their rates and damping work from each old edge to the new edge
    between the same vertices (a copy counts as its parent); the cut edge's two sides are
    boundary edges, without xi: only its damping work moves, to the first of them."""
    n = len(source)

    def keys(ends):
        a, b = np.sort(ends, axis=1).astype(np.int64).T
        return a * n + b

    old_keys = keys(old.edges.ends)
    new_keys = keys(source[new.edges.ends])
    order = np.argsort(old_keys)
    at = np.searchsorted(old_keys[order], new_keys)
    match = order[np.minimum(at, len(order) - 1)]
    found = old_keys[match] == new_keys
    first = np.zeros(len(new_keys), dtype=bool)
    first[np.unique(new_keys, return_index=True)[1]] = True
    take = found & first
    interior = new.edges.xi_inertia > 0.0
    for name in ("xi", "xi_rate"):
        getattr(new.edges, name)[take & interior] = getattr(old.edges, name)[match[take & interior]]
    new.edges.xi_damping[take] = old.edges.xi_damping[match[take]]

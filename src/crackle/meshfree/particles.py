"""Particles through the wall of a thin structure and their integration cells.

Plate: a box whose thinnest side is the wall thickness, filled with a grid of particles,
`layers` of them through the thickness (on both faces and evenly between) and a spacing as close
as fits to the asked one along the two in-plane sides (on the edges and evenly between). Each
particle owns the cuboid of the grid around it (half a cell on a face or edge).

Tube: a circular tube (inner radius, wall thickness, length along an axis from the centre of
its first end), particles on a structured grid circumferential x axial x `layers` radial: the
circumferential count is the one whose arc step at the mean radius is closest to the spacing
(closed around), the axial step as close as fits (both ends included), the layers on both walls
and evenly between. Each particle owns the hexahedron between the mid-points to its neighbours
(clipped at the walls and ends), with straight edges and planar quadrilateral faces.

Tet mesh (tet_node_particles): a particle at each node of any tet mesh, owning its median-dual
cell (median_dual_cells: a quarter of each tet, bounded by two planar triangles per tet edge and
a quadrilateral per boundary triangle and node; ~80 faces a cell); a solid, no wall. Shell
(shell_particles): the same on the wall FDEM's shell_from_surface builds inwards from a closed
or open triangle surface, `layers` particles on each surface node's line through the wall.

Every cell is a closed list of planar faces, given as the quadrature over them that stabilised
conforming nodal integration (shape.smoothed_gradients) needs (`Cells`: points and weight
vectors): a grid cell's face centroids with their area vectors (outward normal x area), a
median-dual cell's triangle vertices. A face between two cells is computed once and used by
both with opposite signs, so the weights of neighbours cancel (the integration constraint).
The cell volume is the particle's nodal volume (the quadrature weight, and mass = density x
volume); the contact area against tools is the cell's extent along the wall (volume / extent
through the wall). The faces on the wall's two surfaces (`WallFaces`) are where pressures act."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

# Wall surfaces: the inner one (a tube's inside, a plate's face at its origin side along the
# thickness) and the outer one.
INNER, OUTER = 0, 1
WALL_SIDES = {"inner": INNER, "outer": OUTER}


@dataclass
class Cells:
    """Each particle's integration cell as a quadrature over its closed polyhedral boundary: the
    rows start[I]:start[I + 1] of particle I, each a point (`point`, an index into `points`) and
    its weight vector, so that the integral of f n dA over the cell's boundary is sum weight
    f(point), exact for linear f. A plate's or tube's row is a face: its centroid and area vector
    (outward normal x area). A median-dual cell's is one of its faces' vertices, shared by the
    cells that meet there: the sum of A / 3 over the cell's triangles at the vertex (vertex
    quadrature; median_dual_cells)."""

    start: np.ndarray  # (n + 1,) int64
    point: np.ndarray  # (k,) int64, each row's quadrature point
    weight: np.ndarray  # (k, 3) m^2
    points: np.ndarray  # (p, 3) m


@dataclass
class WallFaces:
    """The cell faces on the wall's two surfaces, in the reference configuration."""

    particle: np.ndarray  # (k,) int64, the cell's particle
    centre: np.ndarray  # (k, 3) m
    area: np.ndarray  # (k, 3) m^2, A0 N: outward (out of the solid) normal x area
    side: np.ndarray  # (k,) int8, INNER or OUTER


@dataclass
class WallParticles:
    shape: str  # "plate", "tube", "mesh" (tet_node_particles) or "shell" (shell_particles)
    X: np.ndarray  # (n, 3) m, material (reference) positions
    volume: np.ndarray  # (n,) m^3, the cells' volumes
    area: np.ndarray  # (n,) m^2, the cell's extent along the wall (contact area against tools)
    # (3,) m, the grid steps (plate: along x, y, z; tube: arc at the outer wall, axial, radial; mesh and shell:
    # the 90th-percentile, median and shortest tet edge): the support radius is dilation x the first, h the last
    spacing: np.ndarray
    layers: int  # particles through the wall (mesh: 0, a solid)
    cells: Cells
    # (n, 3, 3): rows two unit tangents of the wall and its unit normal (outward); None for a solid mesh (no
    # wall: fracture keeps the principal direction as the crack normal)
    wall_frame: np.ndarray | None
    surface: WallFaces
    thickness_axis: int | None = None  # plate (and a graded plate, a shell): 0, 1 or 2, its thinnest side; tube: None
    axis: np.ndarray | None = None  # tube: the unit vector along it; plate: None
    # (n, 2) m, mesh and shell: the 90th percentile and the median of the tet edges around each particle (its
    # own and its edge neighbours'; local_edge_spacing): a graded set's local spacing; None on a grid
    local_spacing: np.ndarray | None = None


def plate_particles(origin, size, spacing: float, layers: int) -> WallParticles:
    """The particle grid of the box [origin, origin + size]; raises ValueError naming what is
    too coarse."""
    size = np.asarray(size, dtype=float)
    origin = np.asarray(origin, dtype=float)
    axis = int(np.argmin(size))
    counts = []
    for k in range(3):
        counts.append(layers if k == axis else int(round(size[k] / spacing)) + 1)
    if min(c for k, c in enumerate(counts) if k != axis) < 3:
        raise ValueError("spacing: fewer than 3 particles along an in-plane side; make it smaller")
    steps = size / (np.array(counts) - 1)
    grids = [origin[k] + steps[k] * np.arange(counts[k]) for k in range(3)]
    # A particle's share of its side: half a step at both ends.
    shares = []
    for k in range(3):
        share = np.full(counts[k], steps[k])
        share[0] = share[-1] = 0.5 * steps[k]
        shares.append(share)
    gx, gy, gz = np.meshgrid(*grids, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    sx, sy, sz = np.meshgrid(*shares, indexing="ij")
    cell = np.stack([sx.ravel(), sy.ravel(), sz.ravel()], axis=1)
    volume = np.prod(cell, axis=1)
    area = volume / cell[:, axis]
    cell_lo = np.maximum(X - 0.5 * steps, origin)
    cell_hi = np.minimum(X + 0.5 * steps, origin + size)
    cells = _cuboid_cells(cell_lo, cell_hi)
    n = len(X)
    in_plane = [a for a in range(3) if a != axis]
    frame = np.zeros((n, 3, 3))
    frame[:, 0, in_plane[0]] = frame[:, 1, in_plane[1]] = frame[:, 2, axis] = 1.0
    # The wall's surfaces: the -axis face of the first layer, the +axis face of the last.
    layer = np.rint((X[:, axis] - origin[axis]) / steps[axis]).astype(np.int64)
    faces = []
    for side, at, face in ((INNER, 0, 2 * axis), (OUTER, layers - 1, 2 * axis + 1)):
        ids = np.flatnonzero(layer == at)
        rows = cells.start[ids] + face
        faces.append((ids, cells.points[cells.point[rows]], cells.weight[rows], np.full(len(ids), side, dtype=np.int8)))
    surface = WallFaces(*(np.concatenate(parts) for parts in zip(*faces)))
    return WallParticles("plate", X, volume, area, steps, layers, cells, frame, surface, axis)


def _cuboid_cells(lo: np.ndarray, hi: np.ndarray) -> Cells:
    """The 6 faces of each box [lo, hi], in the order -x, +x, -y, +y, -z, +z."""
    n = len(lo)
    centre = 0.5 * (lo + hi)
    face_centre = np.empty((n, 6, 3))
    face_area = np.zeros((n, 6, 3))
    for axis in range(3):
        area = np.prod(np.delete(hi - lo, axis, axis=1), axis=1)
        for k, (side, bound) in enumerate(((-1.0, lo), (1.0, hi))):
            face = centre.copy()
            face[:, axis] = bound[:, axis]
            face_centre[:, 2 * axis + k] = face
            face_area[:, 2 * axis + k, axis] = side * area
    return _face_cells(face_centre.reshape(-1, 3), face_area.reshape(-1, 3))


def _face_cells(centre: np.ndarray, area: np.ndarray) -> Cells:
    """The Cells of 6 faces a particle, in order: each face its own quadrature point."""
    return Cells(np.arange(0, len(area) + 1, 6, dtype=np.int64), np.arange(len(area), dtype=np.int64), area, centre)


def tube_frame(axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (e1, e2, e3) of a tube along `axis`: e3 the axis, e1 the coordinate axis least
    aligned with it (the first such; x for a tube along z) made normal to it, e2 = e3 x e1.
    The angle around the tube counts from e1 towards e2."""
    e3 = np.asarray(axis, dtype=float)
    e3 = e3 / np.linalg.norm(e3)
    e1 = np.eye(3)[int(np.argmin(np.abs(e3)))]
    e1 = e1 - (e1 @ e3) * e3
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(e3, e1), e3


def tube_particles(origin, axis, inner_radius: float, thickness: float, length: float, spacing: float,
                   layers: int) -> WallParticles:
    """The particle grid of the tube (see the module docstring); raises ValueError naming the key
    that is too coarse."""
    if layers < 3:
        raise ValueError(f"layers = {layers}: a tube needs 3 or more particles through the wall (on two "
                         "cylinders the quadratic basis is nearly singular)")
    origin = np.asarray(origin, dtype=float)
    e1, e2, e3 = tube_frame(axis)
    r_mean = inner_radius + 0.5 * thickness
    n_theta = int(round(2.0 * np.pi * r_mean / spacing))
    n_axial = int(round(length / spacing)) + 1
    if n_theta < 12:
        raise ValueError(f"spacing: {n_theta} particles around the tube; 12 or more are needed, make it smaller")
    if n_axial < 3:
        raise ValueError("spacing: fewer than 3 particles along the tube; make it smaller")
    d_theta = 2.0 * np.pi / n_theta
    radii = inner_radius + thickness * np.arange(layers) / (layers - 1)
    axial = length * np.arange(n_axial) / (n_axial - 1)
    r_bound = np.concatenate(([inner_radius], 0.5 * (radii[1:] + radii[:-1]), [inner_radius + thickness]))
    z_bound = np.concatenate(([0.0], 0.5 * (axial[1:] + axial[:-1]), [length]))
    theta = d_theta * np.arange(n_theta)
    theta_bound = theta - 0.5 * d_theta  # bound j lies before particle j; bound n_theta is bound 0 again

    def points(r, angle, z):  # (len(r), len(angle), len(z), 3)
        radial = np.cos(angle)[:, None] * e1 + np.sin(angle)[:, None] * e2
        return (origin + r[:, None, None, None] * radial[None, :, None, :]
                + z[None, None, :, None] * e3[None, None, None, :])

    corner = points(r_bound, theta_bound, z_bound)  # (layers + 1, n_theta, n_axial + 1, 3)
    X_grid = points(radii, theta, axial)  # (layers, n_theta, n_axial, 3)
    nr, nt, nz = layers, n_theta, n_axial
    k, j, i = np.meshgrid(np.arange(nr), np.arange(nt), np.arange(nz), indexing="ij")
    jn = (j + 1) % nt
    # Each face once, as 4 corners in the order that makes its area vector point towards +r,
    # +theta or +axis; index arrays of the same shape as the particle grid.
    radial_faces = _quads(corner, (k, j, i), (k, jn, i), (k, jn, i + 1), (k, j, i + 1))
    radial_outer = _quads(corner, (k + 1, j, i), (k + 1, jn, i), (k + 1, jn, i + 1), (k + 1, j, i + 1))
    angular_faces = _quads(corner, (k, j, i), (k, j, i + 1), (k + 1, j, i + 1), (k + 1, j, i))
    axial_faces = _quads(corner, (k, j, i), (k + 1, j, i), (k + 1, jn, i), (k, jn, i))
    axial_last = _quads(corner, (k, j, i + 1), (k + 1, j, i + 1), (k + 1, jn, i + 1), (k, jn, i + 1))
    # The +r face of layer k is the -r face of layer k + 1 (computed once: bit-identical).
    outer_c = np.concatenate([radial_faces[0][1:], radial_outer[0][-1:]], axis=0)
    outer_a = np.concatenate([radial_faces[1][1:], radial_outer[1][-1:]], axis=0)
    up_c = np.concatenate([axial_faces[0][:, :, 1:], axial_last[0][:, :, -1:]], axis=2)
    up_a = np.concatenate([axial_faces[1][:, :, 1:], axial_last[1][:, :, -1:]], axis=2)
    next_c = np.roll(angular_faces[0], -1, axis=1)
    next_a = np.roll(angular_faces[1], -1, axis=1)
    # Particle order: layers fastest, then around, then along the tube (neighbours close in memory).
    def by_particle(a):  # (nr, nt, nz, ...) -> (nz * nt * nr, ...)
        return np.transpose(a, (2, 1, 0) + tuple(range(3, a.ndim))).reshape((nr * nt * nz,) + a.shape[3:])

    centres = np.stack([by_particle(c) for c in (radial_faces[0], outer_c, angular_faces[0], next_c, axial_faces[0],
                                                  up_c)], axis=1)
    areas = np.stack([by_particle(a) for a in (-radial_faces[1], outer_a, -angular_faces[1], next_a,
                                               -axial_faces[1], up_a)], axis=1)
    X = by_particle(X_grid)
    n = len(X)
    # The volume of a polyhedron with planar faces, by the divergence theorem (relative to the
    # particle: no cancellation of large coordinates).
    volume = np.einsum("nfa,nfa->n", areas, centres - X[:, None, :]) / 3.0
    extent = by_particle(np.broadcast_to((r_bound[1:] - r_bound[:-1])[:, None, None], (nr, nt, nz)))
    radial_dir = (X - origin) - ((X - origin) @ e3)[:, None] * e3
    radial_dir /= np.linalg.norm(radial_dir, axis=1)[:, None]
    frame = np.stack([np.cross(e3, radial_dir), np.broadcast_to(e3, (n, 3)), radial_dir], axis=1)
    cells = _face_cells(centres.reshape(-1, 3), areas.reshape(-1, 3))
    layer = by_particle(k)
    faces = []
    for side, at, face in ((INNER, 0, 0), (OUTER, nr - 1, 1)):
        ids = np.flatnonzero(layer == at)
        faces.append((ids, centres[ids, face], areas[ids, face], np.full(len(ids), side, dtype=np.int8)))
    surface = WallFaces(*(np.concatenate(parts) for parts in zip(*faces)))
    steps = np.array([(inner_radius + thickness) * d_theta, axial[1] - axial[0], radii[1] - radii[0]])
    return WallParticles("tube", X, volume, volume / extent, steps, layers, cells, frame, surface, None, e3)


def _quads(corner, c0, c1, c2, c3):
    """Centroids and area vectors of the planar quadrilaterals with corners corner[c0], ...,
    corner[c3] (each an index triple, wrapping around in the second index is the caller's):
    area vector (c2 - c0) x (c3 - c1) / 2, centroid the area-weighted mean of the two triangles'
    (the mean of the corners is not the centroid of a trapezoid, and linear fields are exact only
    with the centroid)."""
    p0, p1, p2, p3 = (corner[c] for c in (c0, c1, c2, c3))
    area = 0.5 * np.cross(p2 - p0, p3 - p1)
    unit = area / np.linalg.norm(area, axis=-1)[..., None]
    a1 = 0.5 * np.einsum("...a,...a->...", np.cross(p1 - p0, p2 - p0), unit)
    a2 = 0.5 * np.einsum("...a,...a->...", np.cross(p2 - p0, p3 - p0), unit)
    centre = (a1[..., None] * (p0 + p1 + p2) + a2[..., None] * (p0 + p2 + p3)) / (3.0 * (a1 + a2)[..., None])
    return centre, area


# The 6 edges of a tet as local vertices (a, b, c, d): (a, b) the edge and (a, b, c, d) an even
# permutation of (0, 1, 2, 3), so that det(b - a, c - a, d - a) = 6 V > 0 in a positive tet and
# the dual triangles below have area vectors along b - a (from a's cell into b's).
_EDGE_VERTICES = np.array([[0, 1, 2, 3], [0, 2, 3, 1], [0, 3, 1, 2], [1, 2, 0, 3], [1, 3, 2, 0], [2, 3, 0, 1]])
# The row of _EDGE_VERTICES of the edge between two local vertices (either order).
_LOCAL_EDGE = np.full((4, 4), -1, dtype=np.int64)
_LOCAL_EDGE[_EDGE_VERTICES[:, 0], _EDGE_VERTICES[:, 1]] = range(6)
_LOCAL_EDGE[_EDGE_VERTICES[:, 1], _EDGE_VERTICES[:, 0]] = range(6)


# The percentile of a tet mesh's edge lengths that the support radius is dilation x (mesh_spacing).
SUPPORT_EDGE_PERCENTILE = 90.0


def tet_node_particles(points, tets) -> WallParticles:
    """Particles at the nodes of a tet mesh (a solid: shape "mesh"), each owning its median-dual
    cell (median_dual_cells). No wall: wall_frame None (a crack keeps its principal normal),
    layers 0, the full quadratic basis; the contact area against tools is volume^(2/3) and every
    boundary face is on the OUTER surface. spacing: the 90th percentile, the median and the
    shortest tet edge (mesh_spacing). Raises ValueError naming what is wrong with the mesh."""
    particles, _ = _tet_node_particles(points, tets)
    return particles


def _tet_node_particles(points, tets) -> tuple[WallParticles, tuple]:
    """tet_node_particles and the boundary faces of median_dual_cells (with their triangles)."""
    X, tets = _checked_tets(points, tets)
    cells, volume, boundary = median_dual_cells(X, tets)
    owner, centre, area, _ = boundary
    surface = WallFaces(owner, centre, area, np.full(len(owner), OUTER, dtype=np.int8))
    particles = WallParticles("mesh", X, volume, volume ** (2.0 / 3.0), mesh_spacing(X, tets), 0, cells, None,
                              surface, local_spacing=local_edge_spacing(X, tets))
    return particles, boundary


def node_groups(X, tets, groups: dict) -> dict[str, np.ndarray]:
    """A tet mesh's groups of tets ({name: tet ids}) as groups of the particles at its nodes X
    (masks): each particle in the group that holds the most of its median-dual cell (a quarter of
    each tet around it, median_dual_cells), in every group that ties for it (within 1e-9 of the
    cell: a node on a plane between two groups, half in each, is in both whatever the rounding of
    the sums); a particle in no group's tet in none. What [materials.NAME] group reads on a mesh's
    particles."""
    from ..geometry.meshes import tet_volumes

    tets = np.asarray(tets, dtype=np.int64)
    quarter = np.repeat(0.25 * np.abs(tet_volumes(np.asarray(X, dtype=float), tets)), 4)
    cell = np.bincount(tets.ravel(), weights=quarter, minlength=len(X))
    share = {name: np.bincount(tets[ids].ravel(), weights=quarter.reshape(-1, 4)[ids].ravel(), minlength=len(X))
             for name, ids in groups.items()}
    if not share:
        return {}
    most = np.max(np.stack(list(share.values())), axis=0)
    return {name: (held > 0.0) & (held >= most - 1e-9 * cell) for name, held in share.items()}


def shell_particles(path, wall: float, layers: int, scale: float = 1.0, offset=(0.0, 0.0, 0.0),
                    element_size: float | None = None) -> WallParticles:
    """Particles through the wall of a shell walled inwards from a closed or open triangle
    surface (geometry.walnut.shell_from_surface: the file's points x scale + offset, remeshed to
    element_size when given; `layers` particles on each surface node's line through the wall,
    layers - 1 tets), each owning its median-dual cell (median_dual_cells). wall_frame: the
    surface's outward vertex normal (the same on the node's whole line) and two tangents; the
    contact area against tools is volume / the node's extent through the wall (wall / (layers -
    1), half on the two surfaces); the boundary faces on the file's surface are OUTER, those on
    the offset one INNER (an open surface's rim is neither). Particle order: the layers of one
    line fastest. Raises ValueError (geometry.MeshError) naming what is wrong."""
    from ..geometry.walnut import shell_from_surface

    _check_shell_layers(layers)
    mesh, _ = shell_from_surface(path, element_size, wall=wall, suture_wall=None, layers=layers - 1, scale=scale,
                                 offset=offset, allow_open=True)
    return _walled_particles(mesh, wall, layers)


def graded_plate_particles(origin, size, spacing: float, layers: int, fine_spacing: float, fine_center,
                           fine_radius: float, transition: float) -> WallParticles:
    """Particles through a plate (the box [origin, origin + size], its thinnest side the wall)
    graded in its plane: a gmsh triangulation of its face (geometry.meshes.gmsh_graded_rectangle:
    fine_spacing within fine_radius of fine_center's projection, growing to `spacing` over
    `transition`) walled through the thickness as a shell (shell_particles: `layers` particles
    on each node's line), with thickness_axis set as for a plate."""
    from ..geometry.meshes import gmsh_graded_rectangle
    from ..geometry.walnut import shell_from_triangles

    _check_shell_layers(layers)
    origin, size = np.asarray(origin, dtype=float), np.asarray(size, dtype=float)
    axis = int(np.argmin(size))
    a, b = [k for k in range(3) if k != axis]
    uv, tris = gmsh_graded_rectangle(origin[[a, b]], size[[a, b]], spacing, fine_spacing,
                                     np.asarray(fine_center, dtype=float)[[a, b]], fine_radius, transition)
    # Counter-clockwise in (a, b): the triangles' normal is e_a x e_b, +-e_axis; the surface is
    # the face it points out of, the wall grows from there into the plate.
    outward = np.cross(np.eye(3)[a], np.eye(3)[b])[axis]
    points = np.empty((len(uv), 3))
    points[:, a], points[:, b] = uv[:, 0], uv[:, 1]
    points[:, axis] = origin[axis] + (size[axis] if outward > 0 else 0.0)
    mesh, _ = shell_from_triangles(points, tris, wall=size[axis], suture_wall=None, layers=layers - 1,
                                   what="the graded plate")
    particles = _walled_particles(mesh, size[axis], layers)
    particles.thickness_axis = axis
    return particles


def _check_shell_layers(layers: int) -> None:
    if layers < 3:
        raise ValueError(f"layers = {layers}: a shell needs 3 or more particles through the wall (on two "
                         "surfaces the quadratic basis is nearly singular)")


def _walled_particles(mesh, wall: float, layers: int) -> WallParticles:
    """shell_particles' particles of a walled surface mesh (geometry.walnut.shell_from_triangles)."""
    ns = mesh.n_points // layers
    # Node i of layer k (k ns + i in the walled mesh) becomes particle i layers + k.
    k, i = np.divmod(np.arange(mesh.n_points), ns)
    new = i * layers + k
    X = np.empty_like(mesh.points)
    X[new] = mesh.points
    particles, boundary = _tet_node_particles(X, new[mesh.tets])
    layer = np.arange(len(X)) % layers
    outward = X[layer == 0] - X[layer == 1]  # along the vertex normal the walling used
    normal = np.repeat(outward / np.linalg.norm(outward, axis=1)[:, None], layers, axis=0)
    extent = np.where((layer == 0) | (layer == layers - 1), 0.5, 1.0) * wall / (layers - 1)
    # A boundary face is on a surface when its triangle's three nodes are (an open surface's
    # rim triangles span the layers).
    owner, centre, area, triangle = boundary
    outer = np.all(layer[triangle] == 0, axis=1)
    inner = np.all(layer[triangle] == layers - 1, axis=1)
    keep = outer | inner
    faces = WallFaces(owner[keep], centre[keep], area[keep], np.where(outer[keep], OUTER, INNER).astype(np.int8))
    return WallParticles("shell", X, particles.volume, particles.volume / extent, particles.spacing, layers,
                         particles.cells, _frame_of_normals(normal), faces, local_spacing=particles.local_spacing)


def wall_columns(wall: WallParticles) -> np.ndarray | None:
    """(m, layers): the particles of each line through the wall, from the inner surface to the
    outer (a plate: from its origin side along the thickness); None for a solid (no wall). A
    plate's particles are grouped by their in-plane grid position; a tube's and a shell's lines
    are consecutive (their layers are the fastest index)."""
    if wall.layers < 2 or wall.shape == "mesh":
        return None
    n = len(wall.X)
    if wall.shape != "plate":
        return np.arange(n, dtype=np.int64).reshape(-1, wall.layers)
    grid = np.rint((wall.X - wall.X.min(axis=0)) / wall.spacing).astype(np.int64)
    in_plane = [a for a in range(3) if a != wall.thickness_axis]
    order = np.lexsort((grid[:, wall.thickness_axis], grid[:, in_plane[1]], grid[:, in_plane[0]]))
    return order.reshape(-1, wall.layers)


def _frame_of_normals(normal: np.ndarray) -> np.ndarray:
    """(n, 3, 3): rows two unit tangents and the unit normal; the first tangent from the
    coordinate axis least aligned with the normal (as tube_frame)."""
    axis = np.eye(3)[np.argmin(np.abs(normal), axis=1)]
    t1 = axis - np.einsum("na,na->n", axis, normal)[:, None] * normal
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return np.stack([t1, np.cross(normal, t1), normal], axis=1)


def _checked_tets(points, tets) -> tuple[np.ndarray, np.ndarray]:
    """Float and int64 copies, every tet positively oriented; ValueError for a point in no tet or
    a flat tet."""
    from ..geometry.meshes import tet_volumes

    X = np.ascontiguousarray(points, dtype=float)
    tets = np.array(tets, dtype=np.int64)
    if X.ndim != 2 or X.shape[1] != 3 or tets.ndim != 2 or tets.shape[1] != 4 or len(tets) == 0:
        raise ValueError("a tet mesh needs (n, 3) points and (m, 4) tets")
    if tets.min() < 0 or tets.max() >= len(X):
        raise ValueError("tets refer to missing points")
    if np.any(np.bincount(tets.ravel(), minlength=len(X)) == 0):
        raise ValueError("some points are in no tet (a particle needs a cell): remove them")
    volume = tet_volumes(X, tets)
    if np.any(volume == 0.0):
        raise ValueError("some tets are flat (zero volume)")
    flip = volume < 0.0
    tets[flip] = tets[flip][:, [1, 0, 2, 3]]
    return X, tets


def mesh_spacing(X: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(3,) m: the 90th percentile, the median and the shortest of the tet edges. The support
    radius is dilation x the first (build.py; global): long enough for the quadratic basis where
    the mesh is coarse (the crack discs of neighbours then overlap, fracture.py), but not set by
    the few longest edges (a gmsh surface's longest edge is ~1.7 x its median; a support that
    long smears a shell's wall through its thickness: a pressurised sphere's hoop stress went
    from the outer to the inner layer as 12.7, 9.1, 6.0 MPa for Lame's 9.0, 9.3, 9.5). A
    support that leaves a face centre too few neighbours stops the set-up naming
    particles.dilation. The shortest edge is the stiffest pair, what the tool penalty E / h and
    the step's probe take."""
    from ..geometry.meshes import TetMesh

    edges = TetMesh(X, tets).edges()
    length = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
    return np.array([np.percentile(length, SUPPORT_EDGE_PERCENTILE), np.median(length), length.min()])


def local_edge_spacing(X: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(n, 2) m: per node the 90th percentile and the median of the lengths of the tet edges
    around it, its own and its edge neighbours' (~100 edges inside a mesh): mesh_spacing's
    measures taken locally, so that a graded mesh's supports follow its spacing (dilation x the
    first: build.py with support "local") and on a uniform mesh come close to the global ones."""
    from ..geometry.meshes import TetMesh

    edges = TetMesh(X, tets).edges()
    length = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    order = np.argsort(ends, kind="stable")
    start = np.zeros(len(X) + 1, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=len(X)), out=start[1:])
    edge_of = order % len(edges)  # node a's edges, in CSR order
    other = np.concatenate([edges[:, 1], edges[:, 0]])[order]  # the node at the edge's far end
    return _around(start, edge_of, other, length)


@njit(parallel=True, cache=True)
def _around(start, edge_of, other, length):
    """For each node, the 90th percentile and median (numpy's linear interpolation) of the
    distinct edges at it and at its neighbours (CSR start / edge_of / other)."""
    n = start.shape[0] - 1
    out = np.empty((n, 2))
    for a in prange(n):
        count = start[a + 1] - start[a]
        for r in range(start[a], start[a + 1]):
            b = other[r]
            count += start[b + 1] - start[b]
        ids = np.empty(count, dtype=np.int64)
        c = 0
        for r in range(start[a], start[a + 1]):
            ids[c] = edge_of[r]
            c += 1
            b = other[r]
            for t in range(start[b], start[b + 1]):
                ids[c] = edge_of[t]
                c += 1
        ids = np.unique(ids)
        lengths = np.sort(length[ids])
        out[a, 0] = np.percentile(lengths, 90.0)
        out[a, 1] = np.median(lengths)
    return out


def median_dual_cells(X: np.ndarray, tets: np.ndarray):
    """The median-dual cells of the nodes of a tet mesh (tets positively oriented): each tet is
    split among its 4 nodes. Inside a tet the face between the cells of an edge's two nodes is
    the two planar triangles (edge midpoint, centroid of one of the two tet faces on the edge,
    tet centroid), added to both cells with opposite signs. A boundary triangle gives each of
    its nodes the planar quadrilateral (node, the two edge midpoints, the triangle's centroid),
    the two triangles (node, midpoint, centroid) of a sixth of its area each.
    The cells' quadrature (Cells) is at the triangles' vertices: the mean of a field at a planar
    triangle's 3 vertices integrates it over the triangle exactly when linear, so a cell needs the
    MLS only at its distinct vertices (~35 for ~80 triangles), each shared by the cells meeting
    there (an edge midpoint by 2, a tet-face centroid by 3, a tet centroid by 4) and computed once:
    the weights of the cells at a vertex cancel (to rounding; the integration constraint). Returns
    (Cells, volume = the sum of a quarter of each tet's volume (the divergence theorem's volume of
    the cell), the boundary faces: the quadrilaterals as (particle, centroid (2 node + both
    midpoints + 2 triangle centroid) / 6, a third of the triangle's area vector, the nodes (k, 3)
    of the triangle), in the cells' order)."""
    from ..geometry.meshes import LOCAL_FACE_VERTICES, internal_faces, tet_volumes

    n, m = len(X), len(tets)
    # The quadrature points, each computed once: the nodes (a boundary quadrilateral's corner),
    # the edge midpoints, the tet-face centroids and the tet centroids, in this order.
    edge_nodes, edge_id = _distinct(tets[:, _EDGE_VERTICES[:, :2]], n)  # (m, 6): the edges (a, b)
    face_nodes, face_id = _distinct(tets[:, LOCAL_FACE_VERTICES], n)  # (m, 4): the face opposite vertex f
    points = np.concatenate([X, 0.5 * (X[edge_nodes[:, 0]] + X[edge_nodes[:, 1]]), X[face_nodes].mean(axis=1),
                             X[tets].mean(axis=1)])
    at_edge, at_face, at_tet = n, n + len(edge_nodes), n + len(edge_nodes) + len(face_nodes)
    # Rows (owner, point, weight) before summing per (owner, point): per tet and edge (a, b) the
    # triangles T1 = (mid, f1, g) and T2 = (mid, g, f2) with area vectors A1, A2 along b - a give
    # a the weights (A1 + A2) / 3 at mid and g, A1 / 3 at f1, A2 / 3 at f2, and b their negatives.
    g = at_tet + np.arange(m)
    owner, point, weight = [], [], []
    for e, (a, b, c, d) in enumerate(_EDGE_VERTICES):
        mid, f1, f2 = at_edge + edge_id[:, e], at_face + face_id[:, d], at_face + face_id[:, c]
        A1 = 0.5 * np.cross(points[f1] - points[mid], points[g] - points[mid]) / 3.0
        A2 = 0.5 * np.cross(points[g] - points[mid], points[f2] - points[mid]) / 3.0
        for w, q in ((A1 + A2, mid), (A1, f1), (A2, f2), (A1 + A2, g)):
            # a's and b's rows side by side: both cells meet a midpoint's rows in one order, so
            # their sums there are exactly opposite.
            owner.append(tets[:, [a, b]].ravel())
            point.append(np.repeat(q, 2))
            weight.append(np.stack([w, -w], axis=1).reshape(-1, 3))
    # A boundary triangle (p, q, r) outward, area vector A: p's two triangles (p, m_pq, centroid),
    # (p, centroid, m_pr) give p and the centroid A / 9 each, the midpoints A / 18.
    boundary = internal_faces(tets).boundary_faces
    tri = tets[boundary[:, 0][:, None], LOCAL_FACE_VERTICES[boundary[:, 1]]]  # (b, 3), outward
    P = X[tri]  # (b, 3, 3)
    tri_area = 0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    tri_centre = P.mean(axis=1)
    tri_point = at_face + face_id[boundary[:, 0], boundary[:, 1]]
    b_owner, b_centre = np.empty((len(tri), 3), dtype=np.int64), np.empty((len(tri), 3, 3))
    local = LOCAL_FACE_VERTICES[boundary[:, 1]]  # the triangle's nodes as the tet's local vertices
    for k in range(3):
        p, q, r = P[:, k], P[:, (k + 1) % 3], P[:, (k + 2) % 3]
        b_owner[:, k] = tri[:, k]
        b_centre[:, k] = (2.0 * p + 0.5 * (p + q) + 0.5 * (p + r) + 2.0 * tri_centre) / 6.0
        m_pq, m_pr = (at_edge + edge_id[boundary[:, 0], _LOCAL_EDGE[local[:, k], local[:, j]]]
                      for j in ((k + 1) % 3, (k + 2) % 3))
        for w, at in ((tri_area / 9.0, tri[:, k]), (tri_area / 18.0, m_pq), (tri_area / 18.0, m_pr),
                      (tri_area / 9.0, tri_point)):
            owner.append(tri[:, k])
            point.append(at)
            weight.append(w)
    owner, point, weight = np.concatenate(owner), np.concatenate(point), np.concatenate(weight)
    # Summed per (owner, point) in a fixed order; the points used, renumbered in order.
    order = np.lexsort((point, owner))
    owner, point, weight = owner[order], point[order], weight[order]
    first = np.flatnonzero(np.r_[True, (owner[1:] != owner[:-1]) | (point[1:] != point[:-1])])
    weight = np.add.reduceat(weight, first, axis=0)
    owner, point = owner[first], point[first]
    used, point = np.unique(point, return_inverse=True)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(owner, minlength=n), out=start[1:])
    volume = np.bincount(tets.ravel(), weights=np.repeat(tet_volumes(X, tets) / 4.0, 4), minlength=n)
    b_order = np.argsort(b_owner.ravel(), kind="stable")  # the boundary faces in the cells' order
    faces = (b_owner.ravel()[b_order], b_centre.reshape(-1, 3)[b_order], np.repeat(tri_area / 3.0, 3, axis=0)[b_order],
             tri[b_order // 3])
    return Cells(start, point.ravel(), weight, points[used]), volume, faces


def _distinct(nodes: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct node tuples among `nodes` (..., k) of a mesh of n nodes (each tuple as a set:
    sorted) and the index of each tuple among them (shape nodes.shape[:-1])."""
    rows = np.sort(nodes, axis=-1).reshape(-1, nodes.shape[-1])
    if n ** rows.shape[1] < 2**63:  # one int64 key a tuple: far faster than np.unique(axis=0)
        key = rows[:, 0].astype(np.int64)
        for k in range(1, rows.shape[1]):
            key = key * np.int64(n) + rows[:, k]
        _, first, ids = np.unique(key, return_index=True, return_inverse=True)
    else:
        _, first, ids = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    return rows[first], ids.reshape(nodes.shape[:-1])

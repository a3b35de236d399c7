"""A shell's compiled arrays from its mesh and material: each triangle's reference frame, membrane
constants and bending form H (shell.kernels), the edge table with the reference dihedral angles,
lumped masses and the node-to-slot tables of the gathers; nodal loads of edge tractions."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..solver import stability
from ..solver.body import body_arrays
from .kernels import CLAMPED, Edges, Faces, Nodes, element_forces, face_edge_moments, internal_forces, strain_energies
from .mesh import ShellMesh, altitudes


XI_FREQUENCY_STEP = 0.5  # the mid-edge rotations' own frequency x the membrane's step
INDEX = np.int32  # the kernels' index tables (a shell of up to ~500 M triangles)


@dataclass(frozen=True)
class ShellMaterial:
    """The shell's elastic materials: numbers (one material) or one entry per region
    (ShellMesh.region indexes them); `of_triangles` gives each triangle its own."""

    density: float | np.ndarray  # kg/m^3
    youngs_modulus: float | np.ndarray  # Pa
    poissons_ratio: float | np.ndarray

    def of_triangles(self, region: np.ndarray) -> ShellMaterial:
        """The material of each triangle (arrays (m,)), from its region."""
        return ShellMaterial(*(np.atleast_1d(np.asarray(value, dtype=float))[region]
                               for value in (self.density, self.youngs_modulus, self.poissons_ratio)))

    def lame_plane_stress(self) -> tuple[float, float]:
        E, nu = self.youngs_modulus, self.poissons_ratio
        return E * nu / (1.0 - nu * nu), E / (2.0 * (1.0 + nu))

    def bending_stiffness(self, thickness):
        """D = E t^3 / (12 (1 - nu^2)) (N m)."""
        return self.youngs_modulus * np.asarray(thickness) ** 3 / (12.0 * (1.0 - self.poissons_ratio**2))


def face_frames(mesh: ShellMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per triangle: its reference tangent frame (m, 3, 2) (the first column along the edge from
    corner 0 to corner 1), the corners' coordinates in it (m, 3, 2) (corner 0 at the origin) and
    the unit normal (m, 3)."""
    X0, X1, X2 = (mesh.X[mesh.tri[:, i]] for i in range(3))
    t1 = X1 - X0
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    normal = np.cross(X1 - X0, X2 - X0)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    t2 = np.cross(normal, t1)
    frame = np.stack([t1, t2], axis=2)
    local = np.zeros((len(mesh.tri), 3, 2))
    for c, Xc in ((1, X1), (2, X2)):
        local[:, c] = np.einsum("mdk,md->mk", frame, Xc - X0)
    return frame, local, normal


def bending_forms(mesh: ShellMesh, local: np.ndarray, bending_stiffness: np.ndarray, nu: float,
                  clamped_edge: np.ndarray) -> np.ndarray:
    """Per triangle the 3 x 3 form H of its bending energy 1/2 d^T H d in its three edges' turns d
    (kernels): H = A D [nu c c^T + (1 - nu) G], c_i = |e_i| / (2 A), G_ij = c_i c_j (m_i . m_j)^2,
    m_i the outward normal of edge i in the triangle's plane. A free boundary edge's turn is held
    by nothing: it is condensed out, which sets the moment across a free edge to zero (a clamped
    edge keeps its turn against the held normal)."""
    edge_vec = np.stack([local[:, (i + 2) % 3] - local[:, (i + 1) % 3] for i in range(3)], axis=1)  # (m, 3, 2)
    length = np.linalg.norm(edge_vec, axis=2)
    outward = np.stack([edge_vec[..., 1], -edge_vec[..., 0]], axis=2) / length[..., None]
    area = 0.5 * np.abs(local[:, 1, 0] * local[:, 2, 1] - local[:, 1, 1] * local[:, 2, 0])
    c = length / (2.0 * area[:, None])
    cos2 = np.einsum("mik,mjk->mij", outward, outward) ** 2
    nu = np.broadcast_to(nu, area.shape)[:, None, None]  # one material or one per triangle
    H = (area * bending_stiffness)[:, None, None] * (nu * c[:, :, None] * c[:, None, :]
                                                      + (1.0 - nu) * c[:, :, None] * c[:, None, :] * cos2)
    free = (mesh.boundary & ~clamped_edge)[mesh.face_edge]  # (m, 3)
    # The Schur complement onto the held turns, one free edge eliminated at a time (Gauss
    # pivots in turn give the block elimination); all three free leaves nothing.
    for c in range(3):
        f = np.flatnonzero(free[:, c])
        pivot = H[f, c, c]
        live = pivot > 0.0
        f, pivot = f[live], pivot[live]
        H[f] -= H[f, :, c, None] * H[f, None, c, :] / pivot[:, None, None]
        H[np.flatnonzero(free[:, c]), c, :] = 0.0
        H[np.flatnonzero(free[:, c]), :, c] = 0.0
    return H


def clamped_edges(mesh: ShellMesh, clamped: np.ndarray | None) -> np.ndarray:
    """Mask of the boundary edges whose two ends are clamped vertices (clamped: (n,) bool or None)."""
    if clamped is None:
        return np.zeros(len(mesh.edge), dtype=bool)
    return mesh.boundary & clamped[mesh.edge[:, 0]] & clamped[mesh.edge[:, 1]]


def build_arrays(mesh: ShellMesh, material: ShellMaterial, clamped: np.ndarray | None = None):
    """(Faces, Edges, mass, area, radius, face CSR, edge CSR) of the shell: what Nodes and the
    kernels need besides the loads. `clamped` (n,) marks the vertices whose boundary edges hold
    their slope (a clamped support)."""
    material = material.of_triangles(mesh.region)
    frame, local, _ = face_frames(mesh)
    m = len(mesh.tri)
    Dm = np.stack([local[:, 1], local[:, 2]], axis=2)  # (m, 2, 2): columns are corners 1 and 2
    dm_inv = np.linalg.inv(Dm).reshape(m, 4)
    area = 0.5 * np.abs(np.linalg.det(Dm))
    lam, mu = material.lame_plane_stress()
    held = clamped_edges(mesh, clamped)
    H = bending_forms(mesh, local, material.bending_stiffness(mesh.thickness), material.poissons_ratio, held)
    upper = np.stack([H[:, 0, 0], H[:, 0, 1], H[:, 0, 2], H[:, 1, 1], H[:, 1, 2], H[:, 2, 2]], axis=1)
    # The step streams these tables every step: 32-bit indices halve their share of the traffic.
    faces = Faces(tri=mesh.tri.astype(INDEX), dm_inv=np.ascontiguousarray(dm_inv), area=area, lam_t=lam * mesh.thickness,
                  mu_t=mu * mesh.thickness, bend=np.ascontiguousarray(upper), face_edge=mesh.face_edge.astype(INDEX),
                  force=np.zeros((m, 3, 3)), moment=np.zeros((m, 3)), pressure=np.full(m, -1, dtype=INDEX),
                  pressure_sign=np.ones(m), pressure_delay=np.zeros(m), pressure_force=np.zeros((m, 3)))
    k = len(mesh.edge)
    local_index = np.zeros((k, 2), dtype=INDEX)
    for s in range(2):
        has = mesh.edge_face[:, s] >= 0
        f = mesh.edge_face[has, s]
        local_index[has, s] = np.argmax(mesh.face_edge[f] == np.flatnonzero(has)[:, None], axis=1)
    opposite = mesh.edge_opposite.copy()
    opposite[held, 1] = CLAMPED
    edges = Edges(ends=mesh.edge.astype(INDEX), opposite=opposite.astype(INDEX), face=mesh.edge_face.astype(INDEX), local=local_index,
                  theta=np.zeros(k), theta0=np.zeros(k), force=np.zeros((k, 4, 3)), ghost=_ghosts(mesh, held),
                  xi=np.zeros(k), xi_rate=np.zeros(k), xi_inertia=_xi_inertia(mesh, material, H, local_index),
                  xi_force=np.zeros(k), xi_damping=np.zeros(k))
    element_forces(mesh.X, faces, edges)  # the reference dihedral angles, into edges.theta
    edges.theta0[:] = edges.theta
    n = len(mesh.X)
    mass = np.zeros(n)
    node_area = np.zeros(n)
    radius = np.zeros(n)
    for c in range(3):
        np.add.at(mass, mesh.tri[:, c], material.density * mesh.thickness * area / 3.0)
        np.add.at(node_area, mesh.tri[:, c], area / 3.0)
        np.maximum.at(radius, mesh.tri[:, c], 0.5 * mesh.thickness)
    face_start, face_slot = _csr(mesh.tri.ravel(), n)
    edge_nodes = np.concatenate([mesh.edge, mesh.edge_opposite], axis=1)  # slots e0, e1, oa, ob
    edge_start, edge_slot = _csr(edge_nodes.ravel(), n)
    return faces, edges, mass, node_area, radius, (face_start, face_slot), (edge_start, edge_slot)


def _xi_inertia(mesh: ShellMesh, material: ShellMaterial, H: np.ndarray, local_index: np.ndarray) -> np.ndarray:
    """(k,) kg m^2, the rotary inertia of each interior edge's xi (0 on a boundary edge). A
    Kirchhoff-Love shell has none, so it is chosen for the step: xi's own frequency
    sqrt(k_xi / J), k_xi = d^2E/dxi^2 = 4 (H_ii of both faces), is XI_FREQUENCY_STEP / dt_m with
    dt_m = the smallest triangle altitude / the plate wave speed (the membrane's step, an upper
    bound of the shell's): xi then follows the faces within a few steps and never limits them."""
    interior = mesh.edge_face[:, 1] >= 0
    k_xi = np.zeros(len(mesh.edge))
    for s in range(2):
        f, i = mesh.edge_face[interior, s], local_index[interior, s]
        k_xi[interior] += 4.0 * H[f, i, i]
    E, nu, rho = material.youngs_modulus, material.poissons_ratio, material.density  # per triangle
    dt_m = float(np.min(altitudes(mesh.X, mesh.tri))) / float(np.max(np.sqrt(E / (rho * (1.0 - nu * nu)))))
    return k_xi * (dt_m / XI_FREQUENCY_STEP) ** 2


def _ghosts(mesh: ShellMesh, held: np.ndarray) -> np.ndarray:
    """(k, 3) m: on each held edge its wing's tip mirrored across the edge line (a flat hinge in
    the reference state); zeros elsewhere."""
    ghost = np.zeros((len(mesh.edge), 3))
    e0, e1, tip = (mesh.X[mesh.edge[held, 0]], mesh.X[mesh.edge[held, 1]], mesh.X[mesh.edge_opposite[held, 0]])
    along = (e1 - e0) / np.linalg.norm(e1 - e0, axis=1)[:, None]
    foot = e0 + np.einsum("kd,kd->k", tip - e0, along)[:, None] * along
    ghost[held] = 2.0 * foot - tip
    return ghost


def _csr(owner: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per node, the flat slots whose owner it is, in slot order (negative owners skipped)."""
    slots = np.flatnonzero(owner >= 0)
    nodes = owner[slots]
    order = np.argsort(nodes, kind="stable")
    start = np.zeros(n + 1, dtype=INDEX)
    np.cumsum(np.bincount(nodes, minlength=n), out=start[1:])
    return start, slots[order].astype(INDEX)


def edge_loads(mesh: ShellMesh, edges: np.ndarray, traction) -> np.ndarray:
    """Nodal forces (n, 3) of a traction (Pa, a 3-vector, per area of the shell's cross-section)
    on the given boundary edges: traction x thickness x length, half to each end."""
    load = np.zeros((len(mesh.X), 3))
    a, b = mesh.edge[edges, 0], mesh.edge[edges, 1]
    length = np.linalg.norm(mesh.X[b] - mesh.X[a], axis=1)
    t = mesh.thickness[mesh.edge_face[edges, 0]]
    share = 0.5 * (length * t)[:, None] * np.asarray(traction, float)[None, :]
    np.add.at(load, a, share)
    np.add.at(load, b, share)
    return load


@dataclass
class Shell:
    """A shell ready to step or solve: its mesh, material and compiled arrays."""

    mesh: ShellMesh
    material: ShellMaterial
    faces: Faces
    edges: Edges
    nodes: Nodes
    clamped: np.ndarray | None = None  # (n,) the vertices of clamped supports (build_arrays)

    @cached_property
    def triangle_material(self) -> ShellMaterial:
        """Each triangle's material (arrays (m,))."""
        return self.material.of_triangles(self.mesh.region)

    @cached_property
    def frames(self) -> np.ndarray:
        """(m, 3, 2) each triangle's reference tangent frame (face_frames)."""
        return face_frames(self.mesh)[0]

    def forces(self, x: np.ndarray, out: np.ndarray) -> None:
        """Internal forces (N) at positions x into out (n, 3)."""
        internal_forces(x, self.nodes, self.faces, self.edges, out)

    def strain_energies(self, x: np.ndarray, xi: np.ndarray | None = None) -> tuple[float, float]:
        """(membrane, bending) strain energy (J) at positions x and mid-edge rotations xi (default
        the edges' own)."""
        return strain_energies(x, self.faces, self.edges if xi is None else self.edges._replace(xi=xi))

    def membrane_kinematics(self, x: np.ndarray, which=None):
        """(F (k, 3, 2), E (k, 2, 2), N (k, 2, 2)) of the triangles `which` (default all) at positions
        x, in each triangle's reference frame: the deformation gradient, the Green-Lagrange strain
        the membrane law uses and the membrane force N = lam_t tr(E) I + 2 mu_t E (N/m)."""
        faces = self.faces
        which = np.arange(len(self.mesh.tri)) if which is None else which
        tri = self.mesh.tri[which]
        Ds = np.stack([x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]], axis=2)
        F = Ds @ faces.dm_inv[which].reshape(-1, 2, 2)
        E = 0.5 * (np.einsum("kia,kib->kab", F, F) - np.eye(2))
        trace = E[:, 0, 0] + E[:, 1, 1]
        lam_t, mu_t = faces.lam_t[which], faces.mu_t[which]
        N = lam_t[:, None, None] * trace[:, None, None] * np.eye(2) + 2.0 * mu_t[:, None, None] * E
        return F, E, N

    def membrane_state(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per triangle at positions x: the membrane strain and force (membrane_kinematics), each a
        symmetric tensor in the global axes through the triangle's reference frame, (m, 6) in the
        order xx yy zz xy yz xz (io.fields.STRESS_COMPONENTS)."""
        _, strain, force = self.membrane_kinematics(x)
        return _global_components(self.frames, strain), _global_components(self.frames, force)

    def bending_moment_state(self, x: np.ndarray) -> np.ndarray:
        """Per triangle at positions x (and the edges' mid-edge rotations) the bending moment
        tensor M (N m/m), (m, 6) in the global order xx yy zz xy yz xz through the triangle's
        reference frame. The bending form H = A D [nu c c^T + (1 - nu) G] is the energy of
        M = D [nu tr(kappa) I + (1 - nu) kappa], kappa = sum_i c_i d_i m_i m_i^T, whose moment
        conjugate to edge i's turn is (H d)_i = A c_i m_i^T M m_i (m_i the edge's outward normal,
        c_i = |e_i| / 2A): three edges' normal moments give M (a free edge's is zero: condensed)."""
        edge_moments = np.zeros((len(self.mesh.tri), 3))
        face_edge_moments(x, self.faces, self.edges, edge_moments)
        frame, local, _ = face_frames(self.mesh)
        edge_vec = np.stack([local[:, (i + 2) % 3] - local[:, (i + 1) % 3] for i in range(3)], axis=1)
        length = np.linalg.norm(edge_vec, axis=2)
        nx, ny = edge_vec[..., 1] / length, -edge_vec[..., 0] / length
        normal_moment = edge_moments / (0.5 * length)  # m_i^T M m_i
        system = np.stack([nx * nx, 2.0 * nx * ny, ny * ny], axis=2)  # rows: edges; columns: M11, M12, M22
        m11, m12, m22 = np.moveaxis(np.linalg.solve(system, normal_moment[..., None])[..., 0], 1, 0)
        M = np.stack([np.stack([m11, m12], axis=1), np.stack([m12, m22], axis=1)], axis=1)
        return _global_components(frame, M)

    def stable_dt(self, tool_k=0.0) -> float:
        """The largest stable step times stability.STEP_MARGIN, by Lanczos on the shell's forces
        (membrane and bending; tool penalties tool_k N/m per node)."""
        return stability.stable_step(self.mesh.X, self.nodes.mass, self.forces, self.mesh.element_size(), tool_k)


def _global_components(frame: np.ndarray, tensor: np.ndarray) -> np.ndarray:
    """Symmetric 2 x 2 tensors in each triangle's frame (m, 3, 2) as global (m, 6): xx yy zz xy yz xz."""
    g = np.einsum("kia,kab,kjb->kij", frame, tensor, frame)
    return np.stack([g[:, 0, 0], g[:, 1, 1], g[:, 2, 2], g[:, 0, 1], g[:, 1, 2], g[:, 0, 2]], axis=1)


def build_shell(mesh: ShellMesh, material: ShellMaterial, clamped: np.ndarray | None = None) -> Shell:
    """A Shell at rest in its reference state, with no loads, supports or tools; the boundary
    edges between `clamped` vertices hold their slope (their nodes still need a support)."""
    faces, edges, mass, area, radius, (face_start, face_slot), (edge_start, edge_slot) = build_arrays(mesh, material,
                                                                                                      clamped)
    n = len(mesh.X)
    nodes = Nodes(**body_arrays(mesh.X, mass, area, radius), load=np.zeros((n, 3)), face_start=face_start,
                  face_slot=face_slot, edge_start=edge_start, edge_slot=edge_slot)
    return Shell(mesh, material, faces, edges, nodes, clamped)

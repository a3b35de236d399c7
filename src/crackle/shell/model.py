"""A shell's compiled arrays from its mesh and material: each triangle's reference frame, membrane
constants and bending form H (shell.kernels), the edge table with the reference dihedral angles,
lumped masses and the node-to-slot tables of the gathers; nodal loads of edge tractions."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..solver import stability
from ..solver.integrator import FREE
from .kernels import Edges, Faces, Nodes, element_forces, internal_forces, strain_energies
from .mesh import ShellMesh


@dataclass(frozen=True)
class ShellMaterial:
    density: float  # kg/m^3
    youngs_modulus: float  # Pa
    poissons_ratio: float

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


def bending_forms(mesh: ShellMesh, local: np.ndarray, bending_stiffness: np.ndarray, nu: float) -> np.ndarray:
    """Per triangle the 3 x 3 form H of its bending energy 1/2 dtheta^T H dtheta (kernels):
    H = A D [nu c c^T + (1 - nu) G], c_i = |e_i| / (2 A), G_ij = c_i c_j (m_i . m_j)^2, m_i the
    outward normal of edge i in the triangle's plane. A boundary edge's angle is free (no
    neighbour holds it): it is condensed out, which sets the moment across a free edge to zero."""
    edge_vec = np.stack([local[:, (i + 2) % 3] - local[:, (i + 1) % 3] for i in range(3)], axis=1)  # (m, 3, 2)
    length = np.linalg.norm(edge_vec, axis=2)
    outward = np.stack([edge_vec[..., 1], -edge_vec[..., 0]], axis=2) / length[..., None]
    area = 0.5 * np.abs(local[:, 1, 0] * local[:, 2, 1] - local[:, 1, 1] * local[:, 2, 0])
    c = length / (2.0 * area[:, None])
    cos2 = np.einsum("mik,mjk->mij", outward, outward) ** 2
    H = (area * bending_stiffness)[:, None, None] * (nu * c[:, :, None] * c[:, None, :]
                                                      + (1.0 - nu) * c[:, :, None] * c[:, None, :] * cos2)
    free = mesh.boundary[mesh.face_edge]  # (m, 3)
    for f in np.flatnonzero(free.any(axis=1)):
        b, i = free[f], ~free[f]
        Hc = np.zeros((3, 3))
        if i.any():
            Hbb = H[f][np.ix_(b, b)]
            Hib = H[f][np.ix_(i, b)]
            Hc[np.ix_(i, i)] = H[f][np.ix_(i, i)] - Hib @ np.linalg.solve(Hbb, Hib.T)
        H[f] = Hc
    return H


def build_arrays(mesh: ShellMesh, material: ShellMaterial):
    """(Faces, Edges, mass, area, radius, face CSR, edge CSR) of the shell: what Nodes and the
    kernels need besides the loads."""
    frame, local, _ = face_frames(mesh)
    m = len(mesh.tri)
    Dm = np.stack([local[:, 1], local[:, 2]], axis=2)  # (m, 2, 2): columns are corners 1 and 2
    dm_inv = np.linalg.inv(Dm).reshape(m, 4)
    area = 0.5 * np.abs(np.linalg.det(Dm))
    lam, mu = material.lame_plane_stress()
    H = bending_forms(mesh, local, material.bending_stiffness(mesh.thickness), material.poissons_ratio)
    upper = np.stack([H[:, 0, 0], H[:, 0, 1], H[:, 0, 2], H[:, 1, 1], H[:, 1, 2], H[:, 2, 2]], axis=1)
    faces = Faces(tri=mesh.tri.copy(), dm_inv=np.ascontiguousarray(dm_inv), area=area, lam_t=lam * mesh.thickness,
                  mu_t=mu * mesh.thickness, bend=np.ascontiguousarray(upper), face_edge=mesh.face_edge.copy(),
                  force=np.zeros((m, 3, 3)), moment=np.zeros((m, 3)), pressure=np.full(m, -1, dtype=np.int64),
                  pressure_sign=np.ones(m), pressure_delay=np.zeros(m), pressure_force=np.zeros((m, 3)))
    k = len(mesh.edge)
    local_index = np.zeros((k, 2), dtype=np.int64)
    for s in range(2):
        has = mesh.edge_face[:, s] >= 0
        f = mesh.edge_face[has, s]
        local_index[has, s] = np.argmax(mesh.face_edge[f] == np.flatnonzero(has)[:, None], axis=1)
    edges = Edges(ends=mesh.edge.copy(), opposite=mesh.edge_opposite.copy(), face=mesh.edge_face.copy(),
                  local=local_index, theta=np.zeros(k), theta0=np.zeros(k), force=np.zeros((k, 4, 3)))
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


def _csr(owner: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per node, the flat slots whose owner it is, in slot order (negative owners skipped)."""
    slots = np.flatnonzero(owner >= 0)
    nodes = owner[slots]
    order = np.argsort(nodes, kind="stable")
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(nodes, minlength=n), out=start[1:])
    return start, slots[order].astype(np.int64)


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

    @cached_property
    def frames(self) -> np.ndarray:
        """(m, 3, 2) each triangle's reference tangent frame (face_frames)."""
        return face_frames(self.mesh)[0]

    def forces(self, x: np.ndarray, out: np.ndarray) -> None:
        """Internal forces (N) at positions x into out (n, 3)."""
        internal_forces(x, self.nodes, self.faces, self.edges, out)

    def strain_energies(self, x: np.ndarray) -> tuple[float, float]:
        """(membrane, bending) strain energy (J) at positions x."""
        return strain_energies(x, self.faces, self.edges)

    def stable_dt(self, tool_k=0.0) -> float:
        """The largest stable step times stability.STEP_MARGIN, by Lanczos on the shell's forces
        (membrane and bending; tool penalties tool_k N/m per node)."""
        return stability.stable_step(self.mesh.X, self.nodes.mass, self.forces, self.mesh.element_size(), tool_k)


def build_shell(mesh: ShellMesh, material: ShellMaterial) -> Shell:
    """A Shell at rest in its reference state, with no loads, supports or tools."""
    faces, edges, mass, area, radius, (face_start, face_slot), (edge_start, edge_slot) = build_arrays(mesh, material)
    n = len(mesh.X)
    nodes = Nodes(x=mesh.X.copy(), v=np.zeros((n, 3)), mass=mass, area=area, radius=radius,
                  constraint=np.full(n, FREE, dtype=np.int16), projection=np.zeros((1, 3, 3)),
                  tool=np.full(n, -1, dtype=np.int8), tool_offset=np.zeros(n), friction=np.zeros((n, 3)),
                  d_friction=np.zeros(n), w_external=np.zeros(n), w_damping=np.zeros(n), load=np.zeros((n, 3)),
                  face_start=face_start, face_slot=face_slot, edge_start=edge_start, edge_slot=edge_slot)
    return Shell(mesh, material, faces, edges, nodes)

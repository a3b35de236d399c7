"""Initial stress of a bonded-particle model ([initial_stress] with the DEM): bonds preloaded so
that the packing carries the stress at t = 0 without moving.

A packing does not carry a stress the way a continuum does: the bond forces of an affine strain
leave each particle of a random packing unbalanced (the non-affine part a real packing relaxes
by). So the preload is the packing's own elastic answer to the stress's loads, found once by a
sparse linear solve on the bond network at its set-up positions:

  K u = F,   K = sum over bonds of G^T k G,   F = the surface tractions sigma . n_out of the
  stress on the specimen's box faces (on the membrane's cells, dem.membrane: the same particles,
  areas and moments as a [[pressures]] entry on that face) + the particles' weight (with
  run.gravity; the stress growing with depth is in equilibrium with it),

with u the particles' translations and spins, G the map from them to the relative displacement of
a bond's contact point (kernels._contact_velocity), k = kn n n + kt (I - n n) its springs (n the
line of centres; a smooth joint's flaw normal). Each bond then gets the force G u gives it, at the
particles' set-up places: its rest distance d0 shifted by fn / kn, its shear spring preloaded (a
joint's incremental un). The particles do not move; the bonds' forces on each of them sum to -F,
so with the matching loads applied (pressures = -sigma_nn on every face, the same gravity) nothing
moves, and on a free face the particles relax as a continuum's surface would. The stress the
packing carries is the stress on average (its mean over the box, the tractions' moments taken at
the faces, is the stress: the virial of forces in equilibrium), with the packing's own
fluctuations about it (force chains).
Chosen over preloading each bond with sigma's traction on an area: that leaves the particles
unbalanced by the packing's disorder, and the model moves from t = 0.

Limits:
- The specimen is a box (the tractions are taken on its faces, as the DEM's pressures are).
- Contacts between unbonded particles start unloaded (only bonds and joints carry the stress),
  and a tool (platen) touching the sample starts without force: a face under a platen needs the
  initial stress's traction as a pressure, or a support, or it relaxes against the platen.
- A joint cannot carry tension: where the solve asks one to, it opens at t = 0.
- Rigid-body parts of F (a gravity the stress's gradient does not balance) and the few
  mechanisms of a random packing (a particle held by one bond spins freely about it) are left
  unbalanced: they move, as they would in the run.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import cg

from .kernels import BONDED, JOINT, Interactions, Particles
from .membrane import CELL, Face, face_cells
from ..scenario import stress_matrices

# Tikhonov term of the solve, relative to each row's diagonal: it makes the mechanisms (and the
# rigid-body modes) of the network solvable at an imbalance ~1e-10 of the forces.
REGULARISATION = 1e-12
# The solve: conjugate gradients with the diagonal as preconditioner, to a residual 1e-12 of the
# load (measured: 333 iterations, 0.4 s at 1,650 particles; 795, 11 s and 1.1 GB at 20,700; a
# direct solve took 1.5 s and 320 s).
SOLVE_TOLERANCE = 1e-12
MAX_ITERATIONS = 100_000


def face_tractions(x: np.ndarray, radius: np.ndarray, faces: list[Face], stress_at):
    """Per box face, its membrane cells (dem.membrane.face_cells): each cell's particle (c,),
    its centre on the face (c, 3) and the force there of the traction sigma . n_out of the stress
    field `stress_at` (points (c, 3) -> (c, 6) in STRESS_ORDER), (c, 3). A cell's force acts at its
    centre on the face: a shear traction's moment is then the stress's (on the sphere, where a
    pressure's line of action meets it, the cells' depths below the face would turn the packing)."""
    cell = CELL * float(np.mean(radius))
    for face in faces:
        owner, offset, area = face_cells(x, radius, face, cell)
        point = x[owner] + offset
        point[:, face.axis] = face.level
        yield owner, point, area * np.einsum("kij,j->ki", stress_matrices(stress_at(point)), -face.inward)


def surface_loads(x: np.ndarray, radius: np.ndarray, faces: list[Face], stress_at) -> tuple[np.ndarray, np.ndarray]:
    """Per particle, the force (n, 3) and the torque about its centre (n, 3) of the traction of
    the stress field `stress_at` on the box `faces` (face_tractions)."""
    n = len(radius)
    force = np.zeros((n, 3))
    torque = np.zeros((n, 3))
    for owner, point, f in face_tractions(x, radius, faces, stress_at):
        moment = np.cross(point - x[owner], f)
        for d in range(3):
            force[:, d] += np.bincount(owner, weights=f[:, d], minlength=n)
            torque[:, d] += np.bincount(owner, weights=moment[:, d], minlength=n)
    return force, torque


def _skew(e: np.ndarray) -> np.ndarray:
    """[e]x, the matrices with [e]x w = e x w, (k, 3, 3)."""
    z = np.zeros(len(e))
    return np.stack([np.stack([z, -e[:, 2], e[:, 1]], -1), np.stack([e[:, 2], z, -e[:, 0]], -1),
                     np.stack([-e[:, 1], e[:, 0], z], -1)], 1)


def _carrying(inter: Interactions) -> np.ndarray:
    """The interactions that carry the initial stress: bonds and joints."""
    return np.flatnonzero((inter.state == BONDED) | (inter.state == JOINT))


def _geometry(particles: Particles, inter: Interactions, ids: np.ndarray):
    """Per interaction: its G (k, 3, 12) over (u_a, w_a, u_b, w_b) and its springs' matrix k (k, 3, 3)."""
    x, radius = particles.x, particles.radius
    a, b = inter.a[ids], inter.b[ids]
    d = x[b] - x[a]
    dist = np.linalg.norm(d, axis=1)
    e = d / dist[:, None]
    la = dist * radius[a] / (radius[a] + radius[b])
    lb = dist - la
    # Relative displacement of the contact point, b's against a's: u_b - u_a - (lb w_b + la w_a) x e.
    skew = _skew(e)
    eye = np.broadcast_to(np.eye(3), (len(ids), 3, 3))
    g = np.concatenate([-eye, la[:, None, None] * skew, eye, lb[:, None, None] * skew], axis=2)
    n = e.copy()
    joint = inter.joint[ids]
    at_joint = joint >= 0
    n[at_joint] = inter.joint_normal[joint[at_joint]]
    nn = np.einsum("ki,kj->kij", n, n)
    k = inter.kn[ids, None, None] * nn + inter.kt[ids, None, None] * (np.eye(3) - nn)
    return g, k, e, n


def _without_rigid_part(x: np.ndarray, load: np.ndarray) -> np.ndarray:
    """The load (6n: per particle force and torque) less its rigid-body part (its net force and
    moment, which no bond can carry): projected off the six rigid motions (translations; turns
    moving each centre by w x x and spinning it by w)."""
    n = len(x)
    centred = x - x.mean(axis=0)
    modes = np.zeros((6 * n, 6))
    for d in range(3):
        translation = np.zeros((n, 6))
        translation[:, d] = 1.0
        modes[:, d] = translation.ravel()
        axis = np.eye(3)[d]
        turn = np.zeros((n, 6))
        turn[:, :3] = np.cross(axis, centred)
        turn[:, 3 + d] = 1.0
        modes[:, 3 + d] = turn.ravel()
    basis, _ = np.linalg.qr(modes)
    return load - basis @ (basis.T @ load)


def preload(particles: Particles, inter: Interactions, force: np.ndarray, torque: np.ndarray) -> dict:
    """Preload the bonds and joints of `inter` (in place: d0, shear, joint_un) so that at the
    particles' present places their forces on each particle sum to -force and their torques to
    -torque (n, 3 each): the static solve of the module's docstring. Returns each carrying
    interaction's force on b ("force", (k, 3)), its ids ("ids") and how far along its strength it
    is ("utilisation": >= 1 where it would fail at t = 0)."""
    n = len(particles.radius)
    ids = _carrying(inter)
    g, k, e, normal = _geometry(particles, inter, ids)
    dofs = np.concatenate([6 * inter.a[ids, None] + np.arange(6), 6 * inter.b[ids, None] + np.arange(6)], axis=1)
    block = np.einsum("kpi,kpq,kqj->kij", g, k, g)
    rows = np.repeat(dofs, 12, axis=1).ravel()
    cols = np.tile(dofs, (1, 12)).ravel()
    stiffness = sp.csr_matrix((block.ravel(), (rows, cols)), shape=(6 * n, 6 * n))
    diagonal = stiffness.diagonal()
    diagonal = np.where(diagonal > 0.0, diagonal, max(float(diagonal.max()), 1.0) if len(diagonal) else 1.0)
    load = _without_rigid_part(particles.x, np.concatenate([force, torque], axis=1).ravel())
    matrix = stiffness + sp.diags(REGULARISATION * diagonal, format="csr")
    u, info = cg(matrix, load, rtol=SOLVE_TOLERANCE, maxiter=MAX_ITERATIONS, M=sp.diags(1.0 / diagonal))
    if info != 0:
        raise ValueError(f"initial_stress: the bond network's static solve did not converge in {MAX_ITERATIONS:,} "
                         "iterations (a packing with parts the bonds do not hold together?)")
    u = np.asarray(u).reshape(n, 6)
    delta = np.einsum("kij,kj->ki", g, np.concatenate([u[inter.a[ids]], u[inter.b[ids]]], axis=1))
    on_b = -np.einsum("kij,kj->ki", k, delta)  # the interaction's force on b at the solved state
    fn = np.einsum("ki,ki->k", on_b, normal)
    shear = on_b - fn[:, None] * normal
    bonded = inter.state[ids] == BONDED
    inter.d0[ids[bonded]] += fn[bonded] / inter.kn[ids[bonded]]
    inter.shear[ids] = shear
    joint = inter.joint[ids[~bonded]]
    inter.joint_un[joint] = fn[~bonded] / inter.kn[ids[~bonded]]
    return {"ids": ids, "force": on_b, "utilisation": _utilisation(inter, ids, fn, shear, bonded)}


def _utilisation(inter: Interactions, ids, fn, shear, bonded) -> np.ndarray:
    """How far each preloaded bond is along its strength (kernels._interaction_block's criteria:
    tension fn < -fn_max, shear |Fs| > cohesion + fn tan phi); 0 for joints (they slide or open,
    they do not fail)."""
    size = np.linalg.norm(shear, axis=1)
    strength = inter.cohesion[ids] + fn * inter.tan_phi[ids]
    with np.errstate(divide="ignore", invalid="ignore"):
        in_shear = np.where(strength > 0.0, size / strength, np.inf)
        in_tension = np.where(fn < 0.0, -fn / inter.fn_max[ids], 0.0)
    return np.where(bonded, np.maximum(in_shear, in_tension), 0.0)

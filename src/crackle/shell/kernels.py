"""The compiled step of the Kirchhoff-Love shell on triangles.

Membrane: constant-strain triangles, Green-Lagrange strain from the deformed edge vectors and the
reference ones (F = Ds Dm^-1, 3 x 2), St. Venant-Kirchhoff in plane stress; membrane force
N = t S per unit length.

Bending: the shape operator of each triangle from the rotations of its three mid-edge normals
(paper 002 section 7.2.2, the variation of the normals; Morley's triangle in rotation-free form):
K = sum_i d_i |e_i| / (2 A) m_i m_i^T, m_i the reference in-plane normal of edge i and d_i twice
the turn of the triangle's normal against edge i's mid-edge normal. That normal is the bisector of
the two faces turned by a rotation xi_e of its own (one degree of freedom per interior edge):
d_i = (theta_e - theta_e^0) + 2 s xi_e, theta_e the dihedral angle, s = +1 on the edge's first
face and -1 on its second. With xi = 0 (the bisector) the operator stores 2 / (1 - nu) times the
energy of a twist on a regular mesh and a simply supported plate deflects 0.62-0.65 of its closed form; with
xi free (the moments of the two faces across an edge then agree at equilibrium) it converges to
the plate's closed forms. Objective: dihedral angles and xi do not change under rigid motion. The
plate energy A D / 2 [nu (tr K)^2 + (1 - nu) K : K] is a quadratic form 1/2 d^T H d: H per
triangle is computed once (shell.model), a free boundary edge's d condensed out (no moment across
a free edge). On a clamped edge the mid-edge normal is the reference one, held: d_i is twice the
dihedral angle against a fixed ghost wing. xi carries a rotary inertia chosen so that its own
frequency stays well inside the step (Kirchhoff-Love shells have no rotary inertia; shell.model).

Five passes per step, each a gather (no races, deterministic for any thread count): edges
(dihedral angles), faces (membrane forces on the three corners, bending moments dE/dd), edges
(the moment of both faces times the angle's gradient on the edge's four vertices, and the moment
on xi), nodes (gather, external loads, tools, the shared integrator) and edges (xi's step)."""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..loading.arrays import HistoryTable
from ..loading.tools import interp_history, load_cell_step, move_tools, tool_velocities, tool_velocity_rows
from ..solver.body import BODY_FIELDS
from ..solver.integrator import block_kernel, step_point

BLOCK = 256  # faces, edges or nodes per parallel task

# The shared per-node arrays (solver.body; radius: half the thickness), with the method's own:
Nodes = namedtuple("Nodes", BODY_FIELDS + " load face_start face_slot edge_start edge_slot")
# load: (n, 3) N, the nodal external force at load factor 1 (edge tractions, lumped);
# face_slot / edge_slot: CSR (by node, in face then corner order) into Faces.force (face * 3 +
# corner) and Edges.force (edge * 4 + slot).
Faces = namedtuple("Faces", "tri dm_inv area lam_t mu_t bend face_edge force moment pressure pressure_sign "
                             "pressure_delay pressure_force")
# dm_inv: (m, 4) the inverse of the reference edge matrix in the face's own frame, row-major;
# lam_t, mu_t: plane-stress Lame constants times thickness (N/m); bend: (m, 6) H's upper
# triangle (00 01 02 11 12 22); force (m, 3, 3) per corner; moment (m, 3) dE/dtheta per local edge;
# pressure (m,) the row of the face's pressure history in the shell's pressures (a HistoryTable; -1: none), pressure_sign +1
# where it pushes along the face's normal, -1 against; pressure_delay (m,) s, a travelling
# front's arrival (nothing before it); pressure_force (m, 3) the force on each corner (external).
Edges = namedtuple("Edges", "ends opposite face local theta theta0 force ghost xi xi_rate xi_inertia xi_force "
                             "xi_damping")
# ends (k, 2), opposite (k, 2) (on a boundary opposite[:, 1] is FREE_EDGE, or CLAMPED where the
# edge holds its slope), face (k, 2) (-1 on a boundary), local (k, 2) the edge's index in each
# face; theta (k,) the current dihedral angle, theta0 the reference one; force (k, 4, 3) on
# ends[0], ends[1], opposite[0], opposite[1]; ghost (k, 3) m, on a clamped edge the fixed tip of
# its second wing (the first wing's tip mirrored across the edge in the reference state, so the
# face keeps its reference slope there), unused elsewhere; xi (k,) rad, the mid-edge normal's own
# rotation, xi_rate its rate, xi_inertia (k,) kg m^2 (0 on a boundary edge: no xi there),
# xi_force (k,) N m, -dE/dxi, xi_damping (k,) J, the mass-proportional damping's work on xi.
FREE_EDGE = -1
CLAMPED = -2
LoadFactor = namedtuple("LoadFactor", "times values n")  # the history that scales Nodes.load


@njit(cache=True, inline="always")
def _wing_normal(px, py, pz, x, b, c):
    """(b - p) x (c - p) for the point p = (px, py, pz)."""
    ux, uy, uz = x[b, 0] - px, x[b, 1] - py, x[b, 2] - pz
    wx, wy, wz = x[c, 0] - px, x[c, 1] - py, x[c, 2] - pz
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


@njit(cache=True, inline="always")
def _normal(x, a, b, c):
    """(b - a) x (c - a)."""
    return _wing_normal(x[a, 0], x[a, 1], x[a, 2], x, b, c)


@njit(cache=True, inline="always")
def _second_wing(x, e, opposite, ghost):
    """The position of edge e's second wing tip: its opposite vertex, or on a clamped edge the
    fixed ghost point (Edges.ghost)."""
    ob = opposite[e, 1]
    if ob == CLAMPED:
        return ghost[e, 0], ghost[e, 1], ghost[e, 2]
    return x[ob, 0], x[ob, 1], x[ob, 2]


@njit(cache=True, inline="always")
def dihedral_angle(x, e0, e1, oa, qx, qy, qz):
    """Signed angle (rad) between the normals of faces (oa, e0, e1) and (q, e1, e0), q = (qx, qy,
    qz) the second wing's tip, measured about the edge e0 -> e1: 0 when flat; its sign says on
    which side of the normals it folds and does not depend on which face is called first."""
    ax, ay, az = _normal(x, oa, e0, e1)
    bx, by, bz = _wing_normal(qx, qy, qz, x, e1, e0)
    ex, ey, ez = x[e1, 0] - x[e0, 0], x[e1, 1] - x[e0, 1], x[e1, 2] - x[e0, 2]
    length = math.sqrt(ex * ex + ey * ey + ez * ez)
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return math.atan2((cx * ex + cy * ey + cz * ez) / length, ax * bx + ay * by + az * bz)


@njit(cache=True, inline="always")
def _dihedral_gradient(x, e0, e1, oa, qx, qy, qz, out, k, scale):
    """out[k, slot] = scale x d(theta)/d(vertex) for the slots e0, e1, oa and the second wing's
    tip q (the hinge's gradient: Bridson, Marino and Fedkiw 2003)."""
    ax, ay, az = _normal(x, oa, e0, e1)
    bx, by, bz = _wing_normal(qx, qy, qz, x, e1, e0)
    ex, ey, ez = x[e1, 0] - x[e0, 0], x[e1, 1] - x[e0, 1], x[e1, 2] - x[e0, 2]
    length = math.sqrt(ex * ex + ey * ey + ez * ez)
    na2 = ax * ax + ay * ay + az * az
    nb2 = bx * bx + by * by + bz * bz
    # Projections of the wing tips on the edge, from e0 and from e1.
    pa0 = ((x[oa, 0] - x[e0, 0]) * ex + (x[oa, 1] - x[e0, 1]) * ey + (x[oa, 2] - x[e0, 2]) * ez) / length
    pb0 = ((qx - x[e0, 0]) * ex + (qy - x[e0, 1]) * ey + (qz - x[e0, 2]) * ez) / length
    pa1 = pa0 - length
    pb1 = pb0 - length
    sa = -scale / na2
    sb = -scale / nb2
    for d, na, nb in ((0, ax, bx), (1, ay, by), (2, az, bz)):
        out[k, 2, d] = sa * length * na
        out[k, 3, d] = sb * length * nb
        out[k, 0, d] = sa * pa1 * na + sb * pb1 * nb
        out[k, 1, d] = -(sa * pa0 * na + sb * pb0 * nb)


@njit(cache=True, inline="always")
def membrane(x, a0, a1, a2, dm, area, lam_t, mu_t):
    """Deformation gradient columns (F0, F1: 3-vectors), membrane force N (n00, n01, n11, N/m)
    and energy (J) of one triangle."""
    d1x, d1y, d1z = x[a1, 0] - x[a0, 0], x[a1, 1] - x[a0, 1], x[a1, 2] - x[a0, 2]
    d2x, d2y, d2z = x[a2, 0] - x[a0, 0], x[a2, 1] - x[a0, 1], x[a2, 2] - x[a0, 2]
    f0x = d1x * dm[0] + d2x * dm[2]
    f0y = d1y * dm[0] + d2y * dm[2]
    f0z = d1z * dm[0] + d2z * dm[2]
    f1x = d1x * dm[1] + d2x * dm[3]
    f1y = d1y * dm[1] + d2y * dm[3]
    f1z = d1z * dm[1] + d2z * dm[3]
    e00 = 0.5 * (f0x * f0x + f0y * f0y + f0z * f0z - 1.0)
    e11 = 0.5 * (f1x * f1x + f1y * f1y + f1z * f1z - 1.0)
    e01 = 0.5 * (f0x * f1x + f0y * f1y + f0z * f1z)
    trace = e00 + e11
    n00 = lam_t * trace + 2.0 * mu_t * e00
    n11 = lam_t * trace + 2.0 * mu_t * e11
    n01 = 2.0 * mu_t * e01
    energy = area * (mu_t * (e00 * e00 + e11 * e11 + 2.0 * e01 * e01) + 0.5 * lam_t * trace * trace)
    return f0x, f0y, f0z, f1x, f1y, f1z, n00, n01, n11, energy


@njit(cache=True, inline="always")
def bending_moments(bend, f, d0, d1, d2):
    """H dtheta for face f (bend: the upper triangle of H)."""
    h = bend[f]
    return (h[0] * d0 + h[1] * d1 + h[2] * d2, h[1] * d0 + h[3] * d1 + h[4] * d2,
            h[2] * d0 + h[4] * d1 + h[5] * d2)


@njit(cache=True, inline="always")
def _turn(edges, e, f):
    """2 s xi_e: what edge e's own rotation adds to face f's angle change (s = +1 on the edge's
    first face, -1 on its second; xi is 0 on a boundary edge)."""
    xi = edges.xi[e]
    return 2.0 * xi if edges.face[e, 0] == f else -2.0 * xi


@njit(cache=True, inline="always")
def _step_xi(e, dt, edges, alpha):
    """Central-difference step of edge e's mid-edge rotation xi from its moment xi_force (the
    node's scheme, with the mass-proportional damping's work into xi_damping)."""
    j = edges.xi_inertia[e]
    if j == 0.0:
        return
    rate = edges.xi_rate[e]
    damping = -alpha * j * rate
    new = rate + dt * (edges.xi_force[e] + damping) / j
    if alpha != 0.0:
        edges.xi_damping[e] -= damping * 0.5 * (rate + new) * dt
    edges.xi_rate[e] = new
    edges.xi[e] += dt * new


@block_kernel
def _angle_block(lo, hi, x, edges):
    ends, opposite, theta = edges.ends, edges.opposite, edges.theta
    for e in range(lo, hi):
        if opposite[e, 1] == FREE_EDGE:
            theta[e] = 0.0
        else:
            qx, qy, qz = _second_wing(x, e, opposite, edges.ghost)
            theta[e] = dihedral_angle(x, ends[e, 0], ends[e, 1], opposite[e, 0], qx, qy, qz)
            if opposite[e, 1] == CLAMPED:  # the held mid-edge normal is the ghost's side: twice the turn
                theta[e] *= 2.0


@block_kernel
def _face_block(lo, hi, t, x, faces, edges, pressures):
    tri, dm_inv, area, force, moment = faces.tri, faces.dm_inv, faces.area, faces.force, faces.moment
    face_edge, theta, theta0 = faces.face_edge, edges.theta, edges.theta0
    for f in range(lo, hi):
        a0, a1, a2 = tri[f, 0], tri[f, 1], tri[f, 2]
        dm = dm_inv[f]
        f0x, f0y, f0z, f1x, f1y, f1z, n00, n01, n11, _ = membrane(x, a0, a1, a2, dm, area[f], faces.lam_t[f],
                                                                  faces.mu_t[f])
        # P = F N (3 x 2); corner forces -A P Dm^-T on corners 1 and 2, corner 0 balances them.
        px0 = f0x * n00 + f1x * n01
        py0 = f0y * n00 + f1y * n01
        pz0 = f0z * n00 + f1z * n01
        px1 = f0x * n01 + f1x * n11
        py1 = f0y * n01 + f1y * n11
        pz1 = f0z * n01 + f1z * n11
        s = -area[f]
        for c, r in ((1, 0), (2, 1)):
            g0 = dm[2 * r]
            g1 = dm[2 * r + 1]
            force[f, c, 0] = s * (px0 * g0 + px1 * g1)
            force[f, c, 1] = s * (py0 * g0 + py1 * g1)
            force[f, c, 2] = s * (pz0 * g0 + pz1 * g1)
        for d in range(3):
            force[f, 0, d] = -(force[f, 1, d] + force[f, 2, d])
        k = faces.pressure[f]
        if k >= 0:
            # A follower pressure: p / 6 x the current area vector (twice the area along the
            # normal) on each corner.
            delay = faces.pressure_delay[f]
            p = 0.0
            if t >= delay:
                p = faces.pressure_sign[f] * interp_history(t - delay, pressures.times[k], pressures.values[k],
                                                            pressures.counts[k]) / 6.0
            nx, ny, nz = _normal(x, a0, a1, a2)
            faces.pressure_force[f, 0] = p * nx
            faces.pressure_force[f, 1] = p * ny
            faces.pressure_force[f, 2] = p * nz
        e0, e1, e2 = face_edge[f, 0], face_edge[f, 1], face_edge[f, 2]
        m0, m1, m2 = bending_moments(faces.bend, f, theta[e0] - theta0[e0] + _turn(edges, e0, f),
                                     theta[e1] - theta0[e1] + _turn(edges, e1, f),
                                     theta[e2] - theta0[e2] + _turn(edges, e2, f))
        moment[f, 0] = m0
        moment[f, 1] = m1
        moment[f, 2] = m2


@block_kernel
def _hinge_block(lo, hi, x, faces, edges, dt, alpha):
    """The hinges' bending forces from the faces' moments; with dt > 0 also the step of the
    interior edges' xi (their moment is complete here, and nothing later in the step reads xi)."""
    ends, opposite, face, local, force, moment = (edges.ends, edges.opposite, edges.face, edges.local, edges.force,
                                                  faces.moment)
    for e in range(lo, hi):
        if opposite[e, 1] == FREE_EDGE:
            for s in range(4):
                force[e, s, 0] = 0.0
                force[e, s, 1] = 0.0
                force[e, s, 2] = 0.0
            continue
        total = moment[face[e, 0], local[e, 0]]
        if face[e, 1] >= 0:
            second = moment[face[e, 1], local[e, 1]]
            total += second
            edges.xi_force[e] = -2.0 * (moment[face[e, 0], local[e, 0]] - second)
            if dt > 0.0:
                _step_xi(e, dt, edges, alpha)
        else:  # a clamped edge: one face, twice the angle
            total *= 2.0
        qx, qy, qz = _second_wing(x, e, opposite, edges.ghost)
        _dihedral_gradient(x, ends[e, 0], ends[e, 1], opposite[e, 0], qx, qy, qz, force, e, -total)


@njit(cache=True, inline="always")
def _gathered(g, nodes, faces, edges):
    """Node g's internal force (fx, fy, fz: its corners' membrane forces and its hinges' bending
    forces) and pressure force (px, py, pz), from the element passes' slots in a fixed order."""
    face_force, edge_force, pressure, pressure_force = faces.force, edges.force, faces.pressure, faces.pressure_force
    fx = 0.0
    fy = 0.0
    fz = 0.0
    px = 0.0
    py = 0.0
    pz = 0.0
    for r in range(nodes.face_start[g], nodes.face_start[g + 1]):
        k = nodes.face_slot[r]
        f = k // 3
        c = k - 3 * f
        fx += face_force[f, c, 0]
        fy += face_force[f, c, 1]
        fz += face_force[f, c, 2]
        if pressure[f] >= 0:
            px += pressure_force[f, 0]
            py += pressure_force[f, 1]
            pz += pressure_force[f, 2]
    for r in range(nodes.edge_start[g], nodes.edge_start[g + 1]):
        k = nodes.edge_slot[r]
        e = k // 4
        s = k - 4 * e
        fx += edge_force[e, s, 0]
        fy += edge_force[e, s, 1]
        fz += edge_force[e, s, 2]
    return fx, fy, fz, px, py, pz


@block_kernel
def _node_block(lo, hi, slot, t, dt, nodes, faces, edges, tools, tool_v_prev, tool_v_next, load_factor, gravity,
                alpha):
    mass, load = nodes.mass, nodes.load
    scale = interp_history(t, load_factor.times, load_factor.values, load_factor.n)
    for g in range(lo, hi):
        fx, fy, fz, px, py, pz = _gathered(g, nodes, faces, edges)
        m = mass[g]
        external = (m * gravity[0] + scale * load[g, 0] + px, m * gravity[1] + scale * load[g, 1] + py,
                    m * gravity[2] + scale * load[g, 2] + pz)
        step_point(g, nodes, (fx, fy, fz), external, m, alpha, dt, dt, slot, tools, tool_v_prev, tool_v_next)


@njit(parallel=True, cache=True)
def element_passes(t, x, faces, edges, pressures, dt=0.0, alpha=0.0):
    """The three element passes at time t and positions x: edge angles, faces (membrane forces,
    bending moments, pressure forces), hinges; Faces.force, Edges.force and the pressure forces
    in place; with dt > 0 the mid-edge rotations take their step (damping alpha) in the hinge
    pass."""
    n_face = faces.tri.shape[0]
    n_edge = edges.ends.shape[0]
    for blk in prange((n_edge + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        _angle_block(lo, min(lo + BLOCK, n_edge), x, edges)
    for blk in prange((n_face + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        _face_block(lo, min(lo + BLOCK, n_face), t, x, faces, edges, pressures)
    for blk in prange((n_edge + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        _hinge_block(lo, min(lo + BLOCK, n_edge), x, faces, edges, dt, alpha)


# Pressures before the time begins (t = -inf): none acts (the statics' and Lanczos' forces).
NO_PRESSURE = HistoryTable(np.zeros((1, 1)), np.zeros((1, 1)), np.ones(1, dtype=np.int64))


def element_forces(x, faces, edges):
    """The element passes' internal forces at positions x, pressures left out (external loads)."""
    element_passes(-np.inf, x, faces, edges, NO_PRESSURE, 0.0, 0.0)  # dt, alpha given: one compiled signature


@njit(parallel=True, cache=True)
def gather_forces(nodes, faces, edges, out):
    """The internal force on each node (N) from the element passes' slots, into out (n, 3)."""
    for g in prange(out.shape[0]):
        fx, fy, fz, _, _, _ = _gathered(g, nodes, faces, edges)
        out[g, 0] = fx
        out[g, 1] = fy
        out[g, 2] = fz


def internal_forces(x, nodes, faces, edges, out):
    """Internal forces (N) at positions x into out (n, 3): the static solver's residual and the
    stable step's K v."""
    element_forces(x, faces, edges)
    gather_forces(nodes, faces, edges, out)


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, nodes, faces, edges, tools, load_factor, pressures, gravity, alpha):
    """n_steps central-difference steps from step number first_step (time first_step x dt);
    arrays updated in place."""
    n_node = nodes.x.shape[0]
    tool_v_prev, tool_v_next = tool_velocity_rows(tools)
    x = nodes.x
    for step in range(n_steps):
        t = (first_step + step) * dt
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        element_passes(t, x, faces, edges, pressures, dt, alpha)
        for blk in prange((n_node + BLOCK - 1) // BLOCK):
            lo = blk * BLOCK
            _node_block(lo, min(lo + BLOCK, n_node), np.int64(blk), t, dt, nodes, faces, edges, tools, tool_v_prev,
                        tool_v_next, load_factor, gravity, alpha)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)


@njit(cache=True)
def face_energies(x, faces, edges, which, membrane_out, bending_out):
    """The membrane and bending strain energy (J) at positions x (and the edges' xi) of the
    triangles `which`, into membrane_out[k] and bending_out[k] for which[k]."""
    tri, area = faces.tri, faces.area
    for k in range(which.shape[0]):
        f = which[k]
        membrane_out[k] = membrane(x, tri[f, 0], tri[f, 1], tri[f, 2], faces.dm_inv[f], area[f], faces.lam_t[f],
                                   faces.mu_t[f])[9]
        d0, d1, d2 = _face_turns(x, faces, edges, f)
        m0, m1, m2 = bending_moments(faces.bend, f, d0, d1, d2)
        bending_out[k] = 0.5 * (m0 * d0 + m1 * d1 + m2 * d2)


@njit(cache=True, inline="always")
def _face_turns(x, faces, edges, f):
    """The turns d of face f's three edges at positions x (the dihedral angle's change plus the
    mid-edge rotation's share; 0 across a free edge), as the bending energy 1/2 d^T H d uses them."""
    ends, opposite, theta0 = edges.ends, edges.opposite, edges.theta0
    d = np.zeros(3)
    for i in range(3):
        e = faces.face_edge[f, i]
        if opposite[e, 1] != FREE_EDGE:
            qx, qy, qz = _second_wing(x, e, opposite, edges.ghost)
            angle = dihedral_angle(x, ends[e, 0], ends[e, 1], opposite[e, 0], qx, qy, qz)
            if opposite[e, 1] == CLAMPED:
                angle *= 2.0
            d[i] = angle - theta0[e] + _turn(edges, e, f)
    return d[0], d[1], d[2]


@njit(cache=True)
def face_edge_moments(x, faces, edges, out):
    """Per face, H d: the bending moment conjugate to each edge's turn (N m), into out (m, 3)."""
    for f in range(faces.tri.shape[0]):
        d0, d1, d2 = _face_turns(x, faces, edges, f)
        out[f, 0], out[f, 1], out[f, 2] = bending_moments(faces.bend, f, d0, d1, d2)


def strain_energies(x, faces, edges) -> tuple[float, float]:
    """(membrane, bending) strain energy (J) at positions x."""
    m = faces.tri.shape[0]
    membrane_energy, bending_energy = np.zeros(m), np.zeros(m)
    face_energies(x, faces, edges, np.arange(m), membrane_energy, bending_energy)
    return float(membrane_energy.sum()), float(bending_energy.sum())

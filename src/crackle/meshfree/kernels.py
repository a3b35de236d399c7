"""The compiled step of the meshfree (EFG) method: a pass over the particles that computes each
one's deformation gradient from its links, its stress (material.stress_update) and its
stabilisation, then a pass over the particles that gathers their forces from the links of their
neighbours, adds the follower pressure on their wall faces (Nanson's formula with their own F,
behind a travelling front where one is given) and calls the shared tool contact (loading.tools)
and node update (solver.integrator).
No races: the first pass writes only the particle's own rows and the rows of its own links, the
second reads them in the fixed CSR order.

Nodal integration (the particles are the quadrature points, weight = nodal volume V), with the
gradients smoothed over each particle's cell (stabilised conforming nodal integration, see
shape.smoothed_gradients: it meets the integration constraint, so a uniform stress leaves
every particle away from the boundary in equilibrium):
  F_I = I + sum_J u_J (x) grad N_J(I)                        (u = x - X, the nodal displacements)
  f_L = - sum_{I ~ L} V_I P_I grad N_L(I)                    (P = F S, first Piola-Kirchhoff)
One point per particle still leaves zero-energy modes (a field oscillating from particle to
particle that no particle's gradient sees). The stabilisation penalises each particle's
displacement against the MLS approximation of the displacement field at it:
  eps_I = u_I - sum_K N_K(X_I) u_K,   energy (1/2) sum_I k_I |eps_I|^2,
k_I = alpha E V_I sum_K w_IK / sum_K w_IK |X_K - X_I|^2 (alpha = particles.stabilisation, w the
kernel weights over I's links: a strain energy density alpha E |eps / dX|^2 / 2 with dX the
weighted mean link length). The MLS reproduces its basis, so eps is zero for every quadratic
displacement field: no linear field (the patch test is untouched), no rigid motion, no bending of
a thin wall (a penalty on the links' departure from the particle's own F, tried first, resisted
curvature: +35 % on the bending frequency of a strip at twice the thickness, x 2.6 on a 0.8 mm
wall at 5 mm spacing). An oscillation from particle to particle is far from its own smooth
approximation, so eps stiffens the modes nodal integration leaves free. It is a true
potential (its forces are its exact derivative, so the energy audit holds it:
`energy.stabilisation`); objective, as eps = x_I - sum_K N_K(X_I) x_K turns with the body. Its
force on L:
  f_L += -k_L eps_L + sum_{J ~ L} N_L(X_J) k_J eps_J,
so the first pass stores each particle's k eps and the gather reads it with the values N_L(X_J).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..loading.tools import contact_with_tools, interp_history, load_cell_step, move_tools, tool_velocities
from ..solver.integrator import block_kernel, move, update_velocity
from .material import elastic_energy, stress_update
from .shape import quartic_spline_array

Particles = namedtuple(
    "Particles",
    "x v X mass volume area constraint projection support_tool tool tool_offset friction d_friction w_external w_damping "
    "plastic eq_plastic w_plastic stress deformation internal stab_k stab_force thermal",
)
# thermal: per particle the temperature (K) and the stored energy per reference volume the
# temperature changes released (J/m^3, energy.thermal); the thermo law's state (material.py).
# stab_k: k_I of the stabilisation (N/m); stab_force: k_I eps_I (N), written by the stress pass.
# start, neighbour: the CSR of each particle's links (I, J) (itself included); grad: grad N_J at
# I (smoothed over I's cell); value: N_J(X_I) (the MLS at the particle itself, 0 on a link the
# crack removed); back_start, back_row: the transpose, for particle L every link (I, L) and its I,
# in order of I; to_back: each link's position in it. back_grad = grad and back_value = value in
# the transposed order (kept equal by build and fracture), so that the gather reads them in
# sequence (an indirect read per link made the gather 5 x slower).
Links = namedtuple("Links", "start neighbour grad value back_start to_back back_row back_grad back_value")
# Pressures on the wall faces of the surface particles: the faces of particle g are rows
# start[g]:start[g + 1]; area: A0 N (reference area vector, out of the solid); load: the row of
# the history tables (times, values, n: loading.arrays.history_tables); delay: s / front speed
# (0 without a front), the time the front reaches the face.
Pressures = namedtuple("Pressures", "start area load delay times values n")

BLOCK = 128  # particles per parallel task


@block_kernel
def _stress_block(lo, hi, dt, p, links, law):
    x, X, start, neighbour, grad, value = p.x, p.X, links.start, links.neighbour, links.grad, links.value
    for i in range(lo, hi):
        f00 = 1.0
        f01 = 0.0
        f02 = 0.0
        f10 = 0.0
        f11 = 1.0
        f12 = 0.0
        f20 = 0.0
        f21 = 0.0
        f22 = 1.0
        ax = 0.0  # the MLS approximation of u at X_i
        ay = 0.0
        az = 0.0
        for r in range(start[i], start[i + 1]):
            j = neighbour[r]
            ux = x[j, 0] - X[j, 0]
            uy = x[j, 1] - X[j, 1]
            uz = x[j, 2] - X[j, 2]
            nv = value[r]
            ax += nv * ux
            ay += nv * uy
            az += nv * uz
            g0 = grad[r, 0]
            g1 = grad[r, 1]
            g2 = grad[r, 2]
            f00 += ux * g0
            f01 += ux * g1
            f02 += ux * g2
            f10 += uy * g0
            f11 += uy * g1
            f12 += uy * g2
            f20 += uz * g0
            f21 += uz * g1
            f22 += uz * g2
        # Green-Lagrange strain E = (F^T F - I) / 2.
        e0 = 0.5 * (f00 * f00 + f10 * f10 + f20 * f20 - 1.0)
        e1 = 0.5 * (f01 * f01 + f11 * f11 + f21 * f21 - 1.0)
        e2 = 0.5 * (f02 * f02 + f12 * f12 + f22 * f22 - 1.0)
        e3 = 0.5 * (f00 * f01 + f10 * f11 + f20 * f21)
        e4 = 0.5 * (f01 * f02 + f11 * f12 + f21 * f22)
        e5 = 0.5 * (f00 * f02 + f10 * f12 + f20 * f22)
        s0, s1, s2, s3, s4, s5, work = stress_update(i, e0, e1, e2, e3, e4, e5, p.plastic, p.eq_plastic, p.thermal,
                                                     dt, law)
        vol = p.volume[i]
        if work != 0.0:
            p.w_plastic[i] += vol * work
        st = p.stress
        st[i, 0] = s0
        st[i, 1] = s1
        st[i, 2] = s2
        st[i, 3] = s3
        st[i, 4] = s4
        st[i, 5] = s5
        d = p.deformation
        d[i, 0] = f00
        d[i, 1] = f01
        d[i, 2] = f02
        d[i, 3] = f10
        d[i, 4] = f11
        d[i, 5] = f12
        d[i, 6] = f20
        d[i, 7] = f21
        d[i, 8] = f22
        k = p.stab_k[i]
        p.stab_force[i, 0] = k * (x[i, 0] - X[i, 0] - ax)
        p.stab_force[i, 1] = k * (x[i, 1] - X[i, 1] - ay)
        p.stab_force[i, 2] = k * (x[i, 2] - X[i, 2] - az)
        # T = V P with P = F S (S symmetric: s0 s3 s5 / s3 s1 s4 / s5 s4 s2).
        t = p.internal
        t[i, 0] = vol * (f00 * s0 + f01 * s3 + f02 * s5)
        t[i, 1] = vol * (f00 * s3 + f01 * s1 + f02 * s4)
        t[i, 2] = vol * (f00 * s5 + f01 * s4 + f02 * s2)
        t[i, 3] = vol * (f10 * s0 + f11 * s3 + f12 * s5)
        t[i, 4] = vol * (f10 * s3 + f11 * s1 + f12 * s4)
        t[i, 5] = vol * (f10 * s5 + f11 * s4 + f12 * s2)
        t[i, 6] = vol * (f20 * s0 + f21 * s3 + f22 * s5)
        t[i, 7] = vol * (f20 * s3 + f21 * s1 + f22 * s4)
        t[i, 8] = vol * (f20 * s5 + f21 * s4 + f22 * s2)


@njit(cache=True, inline="always")
def _link_force(g, p, links):
    """The internal force on particle g gathered from the links (i, g) towards it (after _stress_block)."""
    back_start, back_row, grad, value, t, q = (links.back_start, links.back_row, links.back_grad, links.back_value,
                                               p.internal, p.stab_force)
    fx = -q[g, 0]
    fy = -q[g, 1]
    fz = -q[g, 2]
    for r in range(back_start[g], back_start[g + 1]):
        i = back_row[r]  # the link (i, g): grad N_g and N_g at i
        g0 = grad[r, 0]
        g1 = grad[r, 1]
        g2 = grad[r, 2]
        nv = value[r]
        fx -= t[i, 0] * g0 + t[i, 1] * g1 + t[i, 2] * g2 - nv * q[i, 0]
        fy -= t[i, 3] * g0 + t[i, 4] * g1 + t[i, 5] * g2 - nv * q[i, 1]
        fz -= t[i, 6] * g0 + t[i, 7] * g1 + t[i, 8] * g2 - nv * q[i, 2]
    return fx, fy, fz


@block_kernel
def _particle_block(lo, hi, slot, t_now, dt, p, links, tools, pressures, tool_v_prev, tool_v_next, radius, gravity,
                    alpha):
    x, v, mass = p.x, p.v, p.mass
    force_slots = tools.force_slots
    n_tool = tools.kind.shape[0]
    for g in range(lo, hi):
        fx, fy, fz = _link_force(g, p, links)
        m = mass[g]
        ex = m * gravity[0]
        ey = m * gravity[1]
        ez = m * gravity[2]
        if pressures.start[g + 1] > pressures.start[g]:
            px, py, pz = _pressure_force(g, t_now, p.deformation, pressures)
            ex += px
            ey += py
            ez += pz
        cx, cy, cz, tool_work = contact_with_tools(
            g, x[g, 0], x[g, 1], x[g, 2], v[g, 0], v[g, 1], v[g, 2], radius, p.area[g], dt, slot, tools, n_tool,
            force_slots, tool_v_prev, tool_v_next, p.tool, p.tool_offset, p.friction, p.d_friction,
        )
        update_velocity(g, v, fx, fy, fz, ex, ey, ez, cx, cy, cz, tool_work,
                        m, alpha, dt, p.constraint, p.projection, p.support_tool, tool_v_next, force_slots, slot,
                        p.w_external, p.w_damping)
        move(g, x, v, dt)


@njit(cache=True, inline="always")
def _pressure_force(g, t, deformation, pressures):
    """The follower pressure force on particle g at time t: -p(t - delay) J F^-T A0 N summed over
    its wall faces (Nanson's formula with the particle's F of this step: the face's current area
    vector), nothing on a face the front has not reached."""
    d = deformation
    f00, f01, f02 = d[g, 0], d[g, 1], d[g, 2]
    f10, f11, f12 = d[g, 3], d[g, 4], d[g, 5]
    f20, f21, f22 = d[g, 6], d[g, 7], d[g, 8]
    # cof(F) = J F^-T
    c00 = f11 * f22 - f12 * f21
    c01 = f12 * f20 - f10 * f22
    c02 = f10 * f21 - f11 * f20
    c10 = f02 * f21 - f01 * f22
    c11 = f00 * f22 - f02 * f20
    c12 = f01 * f20 - f00 * f21
    c20 = f01 * f12 - f02 * f11
    c21 = f02 * f10 - f00 * f12
    c22 = f00 * f11 - f01 * f10
    fx = 0.0
    fy = 0.0
    fz = 0.0
    area = pressures.area
    for r in range(pressures.start[g], pressures.start[g + 1]):
        tau = t - pressures.delay[r]
        if tau < 0.0:
            continue
        q = pressures.load[r]
        pr = interp_history(tau, pressures.times[q], pressures.values[q], pressures.n[q])
        a0, a1, a2 = area[r, 0], area[r, 1], area[r, 2]
        fx -= pr * (c00 * a0 + c01 * a1 + c02 * a2)
        fy -= pr * (c10 * a0 + c11 * a1 + c12 * a2)
        fz -= pr * (c20 * a0 + c21 * a1 + c22 * a2)
    return fx, fy, fz


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, particles, links, law, tools, pressures, radius, gravity, alpha):
    """n_steps central-difference steps from step number first_step (time first_step x dt, the
    same however a run is split into calls); arrays updated in place."""
    n_tool = tools.kind.shape[0]
    n = particles.x.shape[0]
    n_block = (n + BLOCK - 1) // BLOCK
    tool_v_prev = np.zeros((max(n_tool, 1), 3))
    tool_v_next = np.zeros((max(n_tool, 1), 3))
    for step in range(n_steps):
        t = (first_step + step) * dt
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        for blk in prange(n_block):
            lo = blk * BLOCK
            _stress_block(lo, min(lo + BLOCK, n), dt, particles, links, law)
        for blk in prange(n_block):
            lo = blk * BLOCK
            _particle_block(lo, min(lo + BLOCK, n), blk, t, dt, particles, links, tools, pressures, tool_v_prev,
                            tool_v_next, radius, gravity, alpha)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)


@njit(parallel=True, cache=True)
def internal_forces(dt, particles, links, law, force):
    """The internal forces (n, 3) at particles.x into `force`, by the step's own two passes (its
    stress pass updates the particles' stress state: call it on a copy); for the stable step."""
    n = particles.x.shape[0]
    n_block = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_block):
        lo = blk * BLOCK
        _stress_block(lo, min(lo + BLOCK, n), dt, particles, links, law)
    for g in prange(n):
        fx, fy, fz = _link_force(g, particles, links)
        force[g, 0] = fx
        force[g, 1] = fy
        force[g, 2] = fz


@njit(parallel=True, cache=True)
def strain_energies(rows, x, X, volume, plastic, thermal, stab_k, start, neighbour, grad, value, law, elastic,
                    stabilisation):
    """Per particle of `rows`, at positions x: the elastic energy V (E - Ep) : C : (E - Ep) / 2
    with its current plastic strain (and temperature), and its stabilisation energy k |eps|^2 / 2
    (J), into elastic[i] and stabilisation[i]."""
    for k in prange(rows.shape[0]):
        i = rows[k]
        F = np.eye(3)
        a = np.zeros(3)
        for r in range(start[i], start[i + 1]):
            j = neighbour[r]
            for c in range(3):
                u = x[j, c] - X[j, c]
                a[c] += value[r] * u
                for b in range(3):
                    F[c, b] += u * grad[r, b]
        C = F.T @ F
        e0 = 0.5 * (C[0, 0] - 1.0) - plastic[i, 0]
        e1 = 0.5 * (C[1, 1] - 1.0) - plastic[i, 1]
        e2 = 0.5 * (C[2, 2] - 1.0) - plastic[i, 2]
        e3 = 0.5 * C[0, 1] - plastic[i, 3]
        e4 = 0.5 * C[1, 2] - plastic[i, 4]
        e5 = 0.5 * C[0, 2] - plastic[i, 5]
        elastic[i] = volume[i] * elastic_energy(i, e0, e1, e2, e3, e4, e5, thermal, law)
        acc = 0.0
        for c in range(3):
            d = x[i, c] - X[i, c] - a[c]
            acc += d * d
        stabilisation[i] = 0.5 * stab_k[i] * acc


def stabilisation_stiffness(X, volume, row, neighbour, kept, radius: float, scale: float) -> np.ndarray:
    """k_I = scale V_I sum_K w_IK / sum_K w_IK |X_K - X_I|^2 over the `kept` links (I, K) (row,
    neighbour: the two particles of each link given, every link of the particles wanted), scale =
    alpha E (module docstring). Returns k for all particles (n,), 0 where none of the given links
    but the particle's own is kept."""
    n = len(X)
    dX = X[neighbour] - X[row]
    dist2 = np.einsum("ij,ij->i", dX, dX)
    weight = np.where(kept, quartic_spline_array(np.sqrt(dist2) / radius), 0.0)
    spread = np.bincount(row, weights=weight * dist2, minlength=n)
    total = np.bincount(row, weights=weight, minlength=n)
    return np.where(spread > 0.0, scale * volume * total / np.where(spread > 0.0, spread, 1.0), 0.0)

"""The compiled step of the meshfree (EFG) method: a pass over the particles that computes each
one's deformation gradient from its links and its stabilisation, a pass for the stress at its two
Gauss points through the wall (material.stress_update; thickness.py) and one that adds what its
F moves at its neighbours' on its line through the wall, then a pass over the particles that
gathers their forces from the links of their neighbours, adds the follower pressure on their wall faces (Nanson's formula with their own F,
behind a travelling front where one is given) and calls the shared tool contact (loading.tools)
and node update (solver.integrator).
No races: each pass writes only the particle's own rows, the later ones read the earlier ones' in
the fixed CSR orders.

Nodal integration (the particles are the quadrature points, weight = nodal volume V), with the
gradients smoothed over each particle's cell (stabilised conforming nodal integration, see
shape.smoothed_gradients: it meets the integration constraint, so a uniform stress leaves
every particle away from the boundary in equilibrium):
  F_I = I + sum_J u_J (x) grad N_J(I)                        (u = x - X, the nodal displacements)
      = R_I + sum_J (x_J - x_I) (x) grad N_J(I),  R_I = I - sum_J (X_J - X_I) (x) grad N_J(I)
(sum_J grad N_J = 0: the MLS holds the constants). The step uses the second form: it reads only
the neighbours' x, and R_I (zero up to the stored gradients' rounding, links.rest_F) makes a body
at rest exactly unstrained and a translation exactly strain-free whatever that rounding.
  f_L = - sum_{I ~ L} T_I grad N_L(I)                        (T_I = V_I P_I, P = F S, first Piola-Kirchhoff,
                                                               at two points through the wall: thickness.py)
the derivative of the second form: at L's own link grad N_L(L) - sum_J grad N_J(L), so that the
forces sum to zero exactly however the gradients are rounded (links.link_sums).
One point per particle still leaves zero-energy modes (a field oscillating from particle to
particle that no particle's gradient sees). The stabilisation penalises each particle's
displacement against the MLS approximation of the displacement field at it:
  eps_I = u_I - sum_K N_K(X_I) u_K,   energy (1/2) sum_I k_I |eps_I|^2,
(in the step eps_I = e_I - sum_K N_K(X_I) (x_K - x_I), e_I = sum_K N_K(X_I) (X_K - X_I): the same
where sum_K N_K = 1, links.rest_eps),
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

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange, uint64

from ..materials.elasticity import green_lagrange
from ..loading.tools import interp_history, load_cell_step, move_tools, tool_velocities, tool_velocity_rows
from ..solver.body import BODY_FIELDS
from ..solver.integrator import FUSED_MATH, block_kernel, fused_block_kernel, slp_vectorised, step_point
from .material import elastic_energy, stress_update
from .shape import quartic_spline_array

# The shared per-node arrays (solver.body; radius 0: the surface particles meet the tools at
# their centres), with the method's own: X the reference positions, and
Particles = namedtuple("Particles", BODY_FIELDS + " X volume plastic eq_plastic w_plastic stress deformation internal "
                                                  "bending stab_k stab_force thermal material")
# plastic, eq_plastic, thermal: the law's state at each particle's two Gauss points through the
# wall (rows 2 I and 2 I + 1, thickness.py); thermal: the temperature (K) and the stored energy
# per reference volume the temperature changes released (J/m^3, energy.thermal), the thermo law's
# (material.py). material: the particle's row of the law table (one row per body: a projectile is
# another material than its target). stress: the mean of the two points' second Piola-Kirchhoff stress; internal:
# T_I = V P of the gather; bending: a V (P+ - P-) / 2 (thickness.py).
# stab_k: k_I of the stabilisation (N/m); stab_force: k_I eps_I (N), written by the gradient pass.
# start, neighbour: the CSR of each particle's links (I, J) (itself included); grad_value (links,
# 4): per link grad N_J at I (smoothed over I's cell) and N_J(X_I) (the MLS at the particle itself,
# 0 on a link the crack removed), side by side, so that the step's sums over a link are one
# four-wide multiply-add per row of F (_relative_sums: the SLP vectoriser); back_start,
# back_row: the transpose, for particle L every link (I, L) and its I, in order of I; to_back: each
# link's position in it. back_grad_value: grad_value in the transposed order (kept equal by build
# and fracture), so that the gather reads it in sequence (an indirect read per link made the
# gather 5 x slower). rest_F (n, 9), rest_eps (n, 3): each particle's R_I and e_I (module
# docstring); link_sums (n, 4): sum_J grad N_J(X_I) and sum_K N_K(X_I) over its links (zero and
# one but for the stored values' rounding; the gather's self terms), all from the stored values in
# double: rest_terms keeps them in step with every change of a particle's links. grad, value,
# back_grad, back_value: views of the two columns, for the numpy code (set-up, fracture, bounds).
_LinkArrays = namedtuple("_LinkArrays", "start neighbour grad_value back_start to_back back_row back_grad_value rest_F "
                                        "rest_eps link_sums")


class Links(_LinkArrays):
    __slots__ = ()

    @property
    def grad(self):
        return self.grad_value[:, :3]

    @property
    def value(self):
        return self.grad_value[:, 3]

    @property
    def back_grad(self):
        return self.back_grad_value[:, :3]

    @property
    def back_value(self):
        return self.back_grad_value[:, 3]


# The links' grad and value (and their transposed copies) are stored in single precision: the step
# streams them twice, at the memory's bandwidth (docs/validation.md, issue 68: with the relative
# form, 1.2-1.3 x the particle-steps per second at 100k). Their rounding (6e-8 relative) is part of
# the discretisation, the same for forces and energies (both read the stored values): a linear
# field is reproduced to 6e-8 of its gradient, a rotation is strained by 3e-8 of its angle (rad). Every
# sum is in double, and rest_F, rest_eps and link_sums keep exact what must not rest on the
# rounding: a body at rest, a translation, the momentum.
LINK_FLOAT = np.float32
# The wall faces of the surface particles that pressures load: the faces of particle g are rows
# start[g]:start[g + 1]; area: A0 N (reference area vector, out of the solid); load: the face's
# row in the pressures' histories (a loading.arrays.HistoryTable, as FDEM's and the shell's);
# delay: s / front speed (0 without a front), the time the front reaches the face.
PressedFaces = namedtuple("PressedFaces", "start area load delay")
# The penalty contact between particles no link joins (contact.py): the pairs of particle g are
# rows start[g]:start[g + 1] (each pair in both particles' rows, with the same numbers), the other
# particle, the pair's spring (N/m) and its reach (m: the distance under which it pushes);
# force: (n, 3), the contact force on each particle, written by the contact pass.
PairContact = namedtuple("PairContact", "start other stiffness reach force")

BLOCK = 128  # particles per parallel task


@slp_vectorised
@fused_block_kernel
def _relative_sums(i, x, start, neighbour, grad_value):
    """Over particle i's links at positions x: sum_J (x_J - x_i) (x) grad N_J(X_i) and
    sum_K N_K(X_i) (x_K - x_i), returned row by row: each row of the first followed by that
    component of the second. A row and its component take one displacement component times the
    link's four stored numbers: one four-wide multiply-add (the SLP vectoriser: the gradient pass
    1.25 x faster at 100k), each lane the scalar arithmetic; returned in that order, the
    vectoriser packs them so (in another order it shuffled lanes, slower than the scalar code).
    One compiled function for the step and for rest_terms at x = X, so that a body at rest sums to
    exactly what rest_terms subtracts (module docstring): inlined into each (numba's
    inline="always"), the vectoriser packed rest_terms' lanes otherwise than the step's, with
    some products rounded before their sum."""
    x0 = x[i, 0]
    x1 = x[i, 1]
    x2 = x[i, 2]
    f00 = 0.0
    f01 = 0.0
    f02 = 0.0
    ax = 0.0
    f10 = 0.0
    f11 = 0.0
    f12 = 0.0
    ay = 0.0
    f20 = 0.0
    f21 = 0.0
    f22 = 0.0
    az = 0.0
    for r in range(uint64(start[i]), uint64(start[i + 1])):  # unsigned: no wraparound (integrator.py)
        j = uint64(neighbour[r])
        ux = x[j, 0] - x0
        uy = x[j, 1] - x1
        uz = x[j, 2] - x2
        g0 = np.float64(grad_value[r, 0])
        g1 = np.float64(grad_value[r, 1])
        g2 = np.float64(grad_value[r, 2])
        nv = np.float64(grad_value[r, 3])
        f00 += ux * g0
        f01 += ux * g1
        f02 += ux * g2
        ax += ux * nv
        f10 += uy * g0
        f11 += uy * g1
        f12 += uy * g2
        ay += uy * nv
        f20 += uz * g0
        f21 += uz * g1
        f22 += uz * g2
        az += uz * nv
    return f00, f01, f02, ax, f10, f11, f12, ay, f20, f21, f22, az


@fused_block_kernel
def _gradient_block(lo, hi, p, links):
    """Each particle's smoothed F (into p.deformation) and its stabilisation force k eps."""
    x, start, neighbour, grad_value = p.x, links.start, links.neighbour, links.grad_value
    rest_F, rest_eps = links.rest_F, links.rest_eps
    d = p.deformation
    for i in range(lo, hi):
        f00, f01, f02, ax, f10, f11, f12, ay, f20, f21, f22, az = _relative_sums(i, x, start, neighbour, grad_value)
        d[i, 0] = rest_F[i, 0] + f00
        d[i, 1] = rest_F[i, 1] + f01
        d[i, 2] = rest_F[i, 2] + f02
        d[i, 3] = rest_F[i, 3] + f10
        d[i, 4] = rest_F[i, 4] + f11
        d[i, 5] = rest_F[i, 5] + f12
        d[i, 6] = rest_F[i, 6] + f20
        d[i, 7] = rest_F[i, 7] + f21
        d[i, 8] = rest_F[i, 8] + f22
        k = p.stab_k[i]
        p.stab_force[i, 0] = k * (rest_eps[i, 0] - ax)
        p.stab_force[i, 1] = k * (rest_eps[i, 1] - ay)
        p.stab_force[i, 2] = k * (rest_eps[i, 2] - az)


@njit(cache=True, inline="always")
def _gauss_point(g, f00, f01, f02, f10, f11, f12, f20, f21, f22, dt, p, law):
    """The stress at one Gauss point (state row g) of deformation gradient F: its second
    Piola-Kirchhoff stress S (6), P = F S (9) and the plastic work density of the update."""
    e0, e1, e2, e3, e4, e5 = green_lagrange(f00, f01, f02, f10, f11, f12, f20, f21, f22)
    s0, s1, s2, s3, s4, s5, work = stress_update(g, e0, e1, e2, e3, e4, e5, p.plastic, p.eq_plastic, p.thermal,
                                                 dt, law)
    # P = F S (S symmetric: s0 s3 s5 / s3 s1 s4 / s5 s4 s2).
    return (s0, s1, s2, s3, s4, s5,
            f00 * s0 + f01 * s3 + f02 * s5, f00 * s3 + f01 * s1 + f02 * s4, f00 * s5 + f01 * s4 + f02 * s2,
            f10 * s0 + f11 * s3 + f12 * s5, f10 * s3 + f11 * s1 + f12 * s4, f10 * s5 + f11 * s4 + f12 * s2,
            f20 * s0 + f21 * s3 + f22 * s5, f20 * s3 + f21 * s1 + f22 * s4, f20 * s5 + f21 * s4 + f22 * s2,
            work)


@fused_block_kernel
def _stress_block(lo, hi, dt, p, columns, law):
    """At each particle's two Gauss points through the wall (thickness.py), F = F_I -+ a_I dF/dzeta,
    the stress (material.stress_update, state rows 2 I and 2 I + 1); stores the mean second
    Piola-Kirchhoff stress, V (P- + P+) / 2 into p.internal and a V (P+ - P-) / 2 into p.bending."""
    d, cstart, member, coef = p.deformation, columns.start, columns.member, columns.coef
    st, t, b = p.stress, p.internal, p.bending
    one_law = law.shape[0] == 1  # one body: no per-particle lookup of its law's row
    law0 = law[0]
    for i in range(lo, hi):
        z0 = 0.0
        z1 = 0.0
        z2 = 0.0
        z3 = 0.0
        z4 = 0.0
        z5 = 0.0
        z6 = 0.0
        z7 = 0.0
        z8 = 0.0
        for r in range(uint64(cstart[i]), uint64(cstart[i + 1])):
            j = uint64(member[r])
            c = coef[r]
            z0 += c * d[j, 0]
            z1 += c * d[j, 1]
            z2 += c * d[j, 2]
            z3 += c * d[j, 3]
            z4 += c * d[j, 4]
            z5 += c * d[j, 5]
            z6 += c * d[j, 6]
            z7 += c * d[j, 7]
            z8 += c * d[j, 8]
        a = columns.offset[i]
        lw = law0 if one_law else law[p.material[i]]
        f0, f1, f2, f3, f4, f5, f6, f7, f8 = d[i, 0], d[i, 1], d[i, 2], d[i, 3], d[i, 4], d[i, 5], d[i, 6], d[i, 7], d[i, 8]
        (m0, m1, m2, m3, m4, m5, p0, p1, p2, p3, p4, p5, p6, p7, p8, w_minus) = _gauss_point(
            2 * i, f0 - a * z0, f1 - a * z1, f2 - a * z2, f3 - a * z3, f4 - a * z4, f5 - a * z5, f6 - a * z6,
            f7 - a * z7, f8 - a * z8, dt, p, lw)
        (n0, n1, n2, n3, n4, n5, q0, q1, q2, q3, q4, q5, q6, q7, q8, w_plus) = _gauss_point(
            2 * i + 1, f0 + a * z0, f1 + a * z1, f2 + a * z2, f3 + a * z3, f4 + a * z4, f5 + a * z5, f6 + a * z6,
            f7 + a * z7, f8 + a * z8, dt, p, lw)
        half = 0.5 * p.volume[i]
        if w_minus + w_plus != 0.0:
            p.w_plastic[i] += half * (w_minus + w_plus)
        st[i, 0] = 0.5 * (m0 + n0)
        st[i, 1] = 0.5 * (m1 + n1)
        st[i, 2] = 0.5 * (m2 + n2)
        st[i, 3] = 0.5 * (m3 + n3)
        st[i, 4] = 0.5 * (m4 + n4)
        st[i, 5] = 0.5 * (m5 + n5)
        t[i, 0] = half * (p0 + q0)
        t[i, 1] = half * (p1 + q1)
        t[i, 2] = half * (p2 + q2)
        t[i, 3] = half * (p3 + q3)
        t[i, 4] = half * (p4 + q4)
        t[i, 5] = half * (p5 + q5)
        t[i, 6] = half * (p6 + q6)
        t[i, 7] = half * (p7 + q7)
        t[i, 8] = half * (p8 + q8)
        ha = half * a
        b[i, 0] = ha * (q0 - p0)
        b[i, 1] = ha * (q1 - p1)
        b[i, 2] = ha * (q2 - p2)
        b[i, 3] = ha * (q3 - p3)
        b[i, 4] = ha * (q4 - p4)
        b[i, 5] = ha * (q5 - p5)
        b[i, 6] = ha * (q6 - p6)
        b[i, 7] = ha * (q7 - p7)
        b[i, 8] = ha * (q8 - p8)


@fused_block_kernel
def _through_wall_block(lo, hi, p, columns):
    """T_J += sum_I c_IJ a_I V_I (P_I+ - P_I-) / 2 over the particles I whose dF/dzeta holds J
    (thickness.py): what J's F moves through its neighbours' Gauss points."""
    t, b, start, member, coef = p.internal, p.bending, columns.back_start, columns.back_member, columns.back_coef
    for j in range(lo, hi):
        for r in range(uint64(start[j]), uint64(start[j + 1])):
            i = uint64(member[r])
            c = coef[r]
            for k in range(9):
                t[j, k] += c * b[i, k]


@njit(cache=True, inline="always")
def _link_force(g, p, links):
    """The internal force on particle g gathered from the links (i, g) towards it (after _stress_block)."""
    back_start, back_row, grad_value = links.back_start, links.back_row, links.back_grad_value
    t, q = p.internal, p.stab_force
    # The exact derivative of the relative forms (module docstring) at g's own link: the loop's
    # self terms less T_g sum_J grad N_J(g) and q_g sum_K N_K(X_g) (links.link_sums), so that
    # the forces sum to zero (momentum) whatever the stored values' rounding.
    s0, s1, s2, s3 = links.link_sums[g, 0], links.link_sums[g, 1], links.link_sums[g, 2], links.link_sums[g, 3]
    # One accumulator per product: no product waits for the one before it (a single running sum
    # per component made the gather 1.25x slower).
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    a4 = 0.0
    a5 = 0.0
    a6 = 0.0
    a7 = 0.0
    a8 = 0.0
    bx = 0.0
    by = 0.0
    bz = 0.0
    for r in range(uint64(back_start[g]), uint64(back_start[g + 1])):  # unsigned: no wraparound (integrator.py)
        i = uint64(back_row[r])  # the link (i, g): grad N_g and N_g at i
        g0 = grad_value[r, 0]
        g1 = grad_value[r, 1]
        g2 = grad_value[r, 2]
        nv = grad_value[r, 3]
        a0 += t[i, 0] * g0
        a1 += t[i, 1] * g1
        a2 += t[i, 2] * g2
        a3 += t[i, 3] * g0
        a4 += t[i, 4] * g1
        a5 += t[i, 5] * g2
        a6 += t[i, 6] * g0
        a7 += t[i, 7] * g1
        a8 += t[i, 8] * g2
        bx += nv * q[i, 0]
        by += nv * q[i, 1]
        bz += nv * q[i, 2]
    fx = t[g, 0] * s0 + t[g, 1] * s1 + t[g, 2] * s2 - s3 * q[g, 0] + bx - (a0 + a1 + a2)
    fy = t[g, 3] * s0 + t[g, 4] * s1 + t[g, 5] * s2 - s3 * q[g, 1] + by - (a3 + a4 + a5)
    fz = t[g, 6] * s0 + t[g, 7] * s1 + t[g, 8] * s2 - s3 * q[g, 2] + bz - (a6 + a7 + a8)
    return fx, fy, fz


@block_kernel
def _contact_block(lo, hi, x, contact):
    """The contact force on each particle from its pairs: k (reach - d) along the line from the
    other particle, d < reach (the pair's two rows give equal and opposite forces, bit for bit).
    A pass of its own: it reads the positions before the particle pass moves them."""
    start, other, stiffness, reach, force = contact.start, contact.other, contact.stiffness, contact.reach, contact.force
    for g in range(lo, hi):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for r in range(uint64(start[g]), uint64(start[g + 1])):
            j = uint64(other[r])
            dx = x[g, 0] - x[j, 0]
            dy = x[g, 1] - x[j, 1]
            dz = x[g, 2] - x[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            s = reach[r]
            if d2 < s * s and d2 > 0.0:
                d = math.sqrt(d2)
                f = stiffness[r] * (s - d) / d
                fx += f * dx
                fy += f * dy
                fz += f * dz
        force[g, 0] = fx
        force[g, 1] = fy
        force[g, 2] = fz


@fused_block_kernel
def _particle_block(lo, hi, slot, t_now, dt, kick, p, links, tools, pressed, pressures, contact, tool_v_prev,
                    tool_v_next, gravity, alpha):
    mass = p.mass
    pairs = contact.other.shape[0] > 0
    for g in range(lo, hi):
        fx, fy, fz = _link_force(g, p, links)
        if pairs and contact.start[g + 1] > contact.start[g]:
            fx += contact.force[g, 0]
            fy += contact.force[g, 1]
            fz += contact.force[g, 2]
        m = mass[g]
        ex = m * gravity[0]
        ey = m * gravity[1]
        ez = m * gravity[2]
        if pressed.start[g + 1] > pressed.start[g]:
            px, py, pz = _pressure_force(g, t_now, p.deformation, pressed, pressures)
            ex += px
            ey += py
            ez += pz
        step_point(g, p, (fx, fy, fz), (ex, ey, ez), m, alpha, dt, kick, slot, tools, tool_v_prev, tool_v_next)


@njit(cache=True, inline="always")
def _pressure_force(g, t, deformation, pressed, pressures):
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
    area = pressed.area
    for r in range(pressed.start[g], pressed.start[g + 1]):
        tau = t - pressed.delay[r]
        if tau < 0.0:
            continue
        q = pressed.load[r]
        pr = interp_history(tau, pressures.times[q], pressures.values[q], pressures.counts[q])
        a0, a1, a2 = area[r, 0], area[r, 1], area[r, 2]
        fx -= pr * (c00 * a0 + c01 * a1 + c02 * a2)
        fy -= pr * (c10 * a0 + c11 * a1 + c12 * a2)
        fz -= pr * (c20 * a0 + c21 * a1 + c22 * a2)
    return fx, fy, fz


@njit(parallel=True, cache=True)
def _stress_passes(dt, particles, links, columns, law):
    """The step's three passes up to the internal forces: the deformation gradients, the stress at
    both Gauss points through the wall, and the through-wall (bending) terms."""
    n = particles.x.shape[0]
    n_block = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_block):
        lo = blk * BLOCK
        _gradient_block(lo, min(lo + BLOCK, n), particles, links)
    for blk in prange(n_block):
        lo = blk * BLOCK
        _stress_block(lo, min(lo + BLOCK, n), dt, particles, columns, law)
    for blk in prange(n_block):
        lo = blk * BLOCK
        _through_wall_block(lo, min(lo + BLOCK, n), particles, columns)


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, particles, links, columns, law, tools, pressed, pressures, contact, gravity, alpha,
            first_kick=-1.0):
    """n_steps central-difference steps from step number first_step (time first_step x dt, the
    same however a run is split into calls); arrays updated in place. contact: the pairs of the
    particle contact (PairContact; none: no pass). first_kick (s, if positive): the first step's
    velocity update spans that time instead of dt, the central difference where the step changes
    (v(t + dt_new / 2) = v(t - dt_old / 2) + a(t) (dt_old + dt_new) / 2)."""
    n = particles.x.shape[0]
    n_block = (n + BLOCK - 1) // BLOCK
    tool_v_prev, tool_v_next = tool_velocity_rows(tools)
    for step in range(n_steps):
        t = (first_step + step) * dt
        kick = first_kick if step == 0 and first_kick > 0.0 else dt
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        _stress_passes(dt, particles, links, columns, law)
        if contact.other.shape[0] > 0:
            for blk in prange(n_block):
                lo = blk * BLOCK
                _contact_block(lo, min(lo + BLOCK, n), particles.x, contact)
        for blk in prange(n_block):
            lo = blk * BLOCK
            _particle_block(lo, min(lo + BLOCK, n), np.int64(blk), t, dt, kick, particles, links, tools, pressed,
                            pressures, contact, tool_v_prev, tool_v_next, gravity, alpha)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)


@njit(parallel=True, cache=True)
def internal_forces(dt, particles, links, columns, law, force):
    """The internal forces (n, 3) at particles.x into `force`, by the step's own passes (its
    stress pass updates the particles' stress state: call it on a copy); for the stable step."""
    n = particles.x.shape[0]
    _stress_passes(dt, particles, links, columns, law)
    for g in prange(n):
        fx, fy, fz = _link_force(g, particles, links)
        force[g, 0] = fx
        force[g, 1] = fy
        force[g, 2] = fz


@njit(parallel=True, cache=True, fastmath=FUSED_MATH)
def rest_terms(rows, X, links):
    """R_I, e_I (module docstring) and the link sums of the particles `rows` from their stored
    links, into links.rest_F, rest_eps and link_sums: at set-up and after every change of their
    grad or value. The step's own sums at x = X (same code, same fused arithmetic), so that at
    rest R_I + sum is I and e_I - sum is 0 exactly (1 - s + s = 1 exactly for s near 1)."""
    # The outputs bound to names before the prange: numba 0.61 dropped the writes made through
    # links.rest_F[...] inside it (every row stayed 0).
    start, neighbour, grad_value = links.start, links.neighbour, links.grad_value
    rest_F, rest_eps, sums = links.rest_F, links.rest_eps, links.link_sums
    for k in prange(rows.shape[0]):
        i = rows[k]
        f00, f01, f02, ax, f10, f11, f12, ay, f20, f21, f22, az = _relative_sums(i, X, start, neighbour, grad_value)
        rest_F[i, 0] = 1.0 - f00
        rest_F[i, 1] = -f01
        rest_F[i, 2] = -f02
        rest_F[i, 3] = -f10
        rest_F[i, 4] = 1.0 - f11
        rest_F[i, 5] = -f12
        rest_F[i, 6] = -f20
        rest_F[i, 7] = -f21
        rest_F[i, 8] = 1.0 - f22
        rest_eps[i, 0] = ax
        rest_eps[i, 1] = ay
        rest_eps[i, 2] = az
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        for r in range(start[i], start[i + 1]):
            s0 += grad_value[r, 0]
            s1 += grad_value[r, 1]
            s2 += grad_value[r, 2]
            s3 += grad_value[r, 3]
        sums[i, 0] = s0
        sums[i, 1] = s1
        sums[i, 2] = s2
        sums[i, 3] = s3


@njit(cache=True)
def _smoothed_deformation(i, x, links, F):
    """F_i = R_i + sum_J (x_J - x_i) (x) grad N_J(X_i) at positions x, into F (3, 3) (as the step)."""
    sums = _relative_sums(i, x, links.start, links.neighbour, links.grad_value)
    for c in range(3):
        for b in range(3):
            F[c, b] = links.rest_F[i, 3 * c + b] + sums[4 * c + b]


@njit(cache=True)
def _gauss_deformations(i, x, links, columns, out):
    """The deformation gradients at particle i's two Gauss points through the wall
    (thickness.py) at positions x, into out (2, 3, 3)."""
    F = np.empty((3, 3))
    slope = np.zeros((3, 3))
    for r in range(columns.start[i], columns.start[i + 1]):
        _smoothed_deformation(columns.member[r], x, links, F)
        slope += columns.coef[r] * F
    _smoothed_deformation(i, x, links, F)
    a = columns.offset[i]
    out[0] = F - a * slope
    out[1] = F + a * slope


@njit(parallel=True, cache=True)
def gauss_strains(rows, x, links, columns, strain):
    """Per particle of `rows`, the Green-Lagrange strains (xx yy zz xy yz xz) at its two Gauss
    points at positions x, into strain (len(rows), 2, 6)."""
    for k in prange(rows.shape[0]):
        F = np.empty((2, 3, 3))
        _gauss_deformations(rows[k], x, links, columns, F)
        for side in range(2):
            C = F[side].T @ F[side]
            strain[k, side, 0] = 0.5 * (C[0, 0] - 1.0)
            strain[k, side, 1] = 0.5 * (C[1, 1] - 1.0)
            strain[k, side, 2] = 0.5 * (C[2, 2] - 1.0)
            strain[k, side, 3] = 0.5 * C[0, 1]
            strain[k, side, 4] = 0.5 * C[1, 2]
            strain[k, side, 5] = 0.5 * C[0, 2]


@njit(parallel=True, cache=True)
def strain_energies(rows, x, volume, plastic, thermal, stab_k, links, columns, law, material, elastic, stabilisation):
    """Per particle of `rows`, at positions x: the elastic energy sum over its two Gauss points of
    V / 2 (E - Ep) : C : (E - Ep) / 2 with their current plastic strain (and temperature), and its
    stabilisation energy k |eps|^2 / 2 (J, eps as the step's), into elastic[i] and stabilisation[i]."""
    for k in prange(rows.shape[0]):
        i = rows[k]
        F = np.empty((2, 3, 3))
        _gauss_deformations(i, x, links, columns, F)
        energy = 0.0
        for side in range(2):
            C = F[side].T @ F[side]
            g = 2 * i + side
            e0 = 0.5 * (C[0, 0] - 1.0) - plastic[g, 0]
            e1 = 0.5 * (C[1, 1] - 1.0) - plastic[g, 1]
            e2 = 0.5 * (C[2, 2] - 1.0) - plastic[g, 2]
            e3 = 0.5 * C[0, 1] - plastic[g, 3]
            e4 = 0.5 * C[1, 2] - plastic[g, 4]
            e5 = 0.5 * C[0, 2] - plastic[g, 5]
            energy += 0.5 * volume[i] * elastic_energy(g, e0, e1, e2, e3, e4, e5, thermal, law[material[i]])
        elastic[i] = energy
        sums = _relative_sums(i, x, links.start, links.neighbour, links.grad_value)
        acc = 0.0
        for c in range(3):
            d = links.rest_eps[i, c] - sums[4 * c + 3]
            acc += d * d
        stabilisation[i] = 0.5 * stab_k[i] * acc


def stabilisation_stiffness(X, volume, row, neighbour, kept, radius, scale: float) -> np.ndarray:
    """k_I = scale V_I sum_K w_IK / sum_K w_IK |X_K - X_I|^2 over the `kept` links (I, K) (row,
    neighbour: the two particles of each link given, every link of the particles wanted), w_IK
    the weight of K's support (radius: one for all or per particle) at X_I, scale = alpha E
    (module docstring). Returns k for all particles (n,), 0 where none of the given links but the
    particle's own is kept."""
    n = len(X)
    dX = X[neighbour] - X[row]
    dist2 = np.einsum("ij,ij->i", dX, dX)
    radius = np.asarray(radius, dtype=float)
    weight = np.where(kept, quartic_spline_array(np.sqrt(dist2) / (radius if radius.ndim == 0 else radius[neighbour])),
                      0.0)
    spread = np.bincount(row, weights=weight * dist2, minlength=n)
    total = np.bincount(row, weights=weight, minlength=n)
    return np.where(spread > 0.0, scale * volume * total / np.where(spread > 0.0, spread, 1.0), 0.0)

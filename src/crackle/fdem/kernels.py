"""Compiled FDEM step: interfaces, tetrahedra, tools, time integration.

State is flat arrays grouped in named tuples (see ``model.py``). The exploded mesh gives each tet
its own 4 nodes (node 4e+k is corner k of tet e), so one step is two parallel passes with no
races and no atomics:

1. over interfaces: kinematics, the interface law of each (fdem.laws) or (once failed) penalty
   contact with Coulomb friction; the traction force on each of the 3 B-side
   nodes goes to ``ifs.force`` (the A side gets its negative), and on a failed face the part that
   acts on both nodes of a pair alike (its normal's turn, ``interface.turning_forces``) to
   ``ifs.force_mid`` (failed and damaged faces, flagged in ``ifs.turning``);
2. over tets: St Venant-Kirchhoff forces, gather of the interface forces of the tet's 4 faces,
   pressures, tool contact, damping, gravity, central-difference update of the tet's 4 nodes.

Every energy term is accumulated per node or per interface (never into a shared scalar), and
summed in a fixed order between chunks: results do not depend on the thread count.
"""

from __future__ import annotations


import numpy as np
from numba import njit, prange

from ..loading.friction import coulomb_update
from ..loading.tools import (contact_with_tools, interp_history, load_cell_step, move_tools, tool_velocities,
                             tool_velocity_rows)
from ..materials.elasticity import green_lagrange, svk_stress
from ..solver.integrator import block_kernel, move, update_velocity
from .contact import gathered_contact_force, node_contact, reaction_lists
from .extrinsic import (LOAD_EXTERNAL, LOAD_FORCE, LOAD_MASS, LOAD_TOOL_WORK, TIED, VERTEX_BLOCK, cluster_block,
                        copies_block, regroup_released, released_vertices, state_row, try_insert)
from .interface import MID_FACE_MIN, mid_face, opening, opening_earlier, turning_forces
from .laws import LAW_MU, intact_energy, intact_step
from .topology import INTACT, face_corners, twice_area_vector


# A failed pair deeper than this fraction of its longest edge has passed through (its faces slid
# apart beyond reach, crossed, and came back): penalty contact there would fire the stored
# p_n dn^2 / 2 at once (seen in crushed walnut shells: 300 N in one step), so it stays off. Honest
# penalty penetrations are orders of magnitude smaller (stress / p_n).
PASSED_THROUGH = 0.1


# Interfaces.pair_entry of a point pair out of paired contact (an entry opening is never positive).
OUT_OF_CONTACT = 1.0


@njit(cache=True, inline="always")
def _pair_touching(dn, sx, sy, sz, reach2, depth):
    """Whether point pair (dn, s) of a failed interface is in paired contact: closed, slid less
    than reach (reach2 = reach^2), and not passed through (dn > -depth)."""
    return -depth < dn < 0.0 and sx * sx + sy * sy + sz * sz <= reach2


@njit(cache=True, inline="always")
def _pair_entry(entry, dn, dt, v, a, b, nx, ny, nz):
    """The opening from which a touching point pair (nodes a, b; opening dn) is pressed: its
    entry, 0 for a pair that closed from open. A pair out of contact the step before that is
    already below the face (it slid back within reach, or came up from past the passed-through
    depth) enters unloaded at its depth, as a node woken inside a tool: p_n dn^2 A / 6 at once is
    energy from nowhere (a pair 27 um deep, 0.39 J into one tet, blew up the intrinsic Brazilian
    disc at the paper's mesh). The entry follows a pair that rises (no force while it does), so
    the spring is loaded from the highest point it reached."""
    if entry == OUT_OF_CONTACT:
        return 0.0 if opening_earlier(dn, dt, v, a, b, nx, ny, nz) >= 0.0 else dn
    return max(entry, dn)


@njit(cache=True, inline="always")
def _pair_traction(i, p, sigma, cap, nx, ny, nz, dt, ps, a3, na, nb, v, traction_t, force):
    """Paired contact of point pair p of failed interface i: normal stress sigma and a Coulomb
    stick spring ps capped at `cap`, driven by the slip rate; the forces on the B node into
    `force` (A gets their negatives); returns the energy the cap dissipated (J)."""
    a = na[i, p]
    b = nb[i, p]
    # The traction resists B sliding over A: A's velocity relative to B drives the spring.
    tx, ty, tz, lost = coulomb_update(
        traction_t[i, p, 0], traction_t[i, p, 1], traction_t[i, p, 2], nx, ny, nz,
        v[a, 0] - v[b, 0], v[a, 1] - v[b, 1], v[a, 2] - v[b, 2], dt, ps, cap,
    )
    traction_t[i, p, 0] = tx
    traction_t[i, p, 1] = ty
    traction_t[i, p, 2] = tz
    force[i, p, 0] = -(sigma * nx + tx) * a3
    force[i, p, 1] = -(sigma * ny + ty) * a3
    force[i, p, 2] = -(sigma * nz + tz) * a3
    return lost * a3


@njit(cache=True, inline="always")
def _law_turning_forces(x, na, nb, i, nx, ny, nz, force, force_mid):
    """The turning forces (interface.turning_forces) of intact interface i's law, from the forces
    it wrote: for a law with a potential E(dn_p, s_p) per point, dE/dn = sum_p A/3 (sigma_p s_p -
    dn_p t_p), zero where the law is isotropic in the gap (an undamaged face, k_n = k_s, in
    opening) and not where it is not: a softening face of a walnut sliding 0.3 mm with two
    corners pressed, (1 - D) k_s in shear and k_n in compression."""
    qx = 0.0
    qy = 0.0
    qz = 0.0
    for p in range(3):
        dn, sx, sy, sz = opening(x, na, nb, i, p, nx, ny, nz)
        # The law's force on B is -(sigma n + t) A/3.
        fx = force[i, p, 0]
        fy = force[i, p, 1]
        fz = force[i, p, 2]
        fn = fx * nx + fy * ny + fz * nz
        qx += dn * (fx - fn * nx) - fn * sx
        qy += dn * (fy - fn * ny) - fn * sy
        qz += dn * (fz - fn * nz) - fn * sz
    turning_forces(x, na, nb, i, nx, ny, nz, qx, qy, qz, force_mid)


@block_kernel
def _interface_block(lo, hi, blk, t, dt, x, v, ifs, ties, released_blocks):
    """Interfaces lo..hi-1 (block blk): kinematics, the insertion check of tied (extrinsic) faces,
    Guo-Munjiza or bilinear law or (once failed) paired penalty contact with Coulomb friction; the
    force on each B-side node into ifs.force (A gets its negative). A block that inserted a face
    flags itself in released_blocks. Positions and velocities are read at the points' state rows
    (ties.na_at, nb_at: a tied cluster's leader)."""
    # Unpacked once per block: attribute access per element costs reference counting.
    na, nb, area, pn_all, ps_all = ties.na_at, ties.nb_at, ifs.area, ifs.pn, ifs.ps
    na_copy, nb_copy = ifs.na, ifs.nb
    state, damage, force, traction_t = ifs.state, ifs.damage, ifs.force, ifs.traction_t
    force_mid, turning = ifs.force_mid, ifs.turning
    slip_plastic, dn_shift, reading_offset, pair_entry = ifs.slip_plastic, ifs.dn_shift, ifs.reading_offset, ifs.pair_entry
    tied, tet_stress = ties.tied, ties.tet_stress
    prestressed = ifs.prestressed.shape[0] > 0
    released = False
    law_table, law_of = ifs.law_table, ifs.law
    e_damage, e_friction, reach = ifs.e_damage, ifs.e_friction, ifs.reach
    fail_time, fail_mode = ifs.fail_time, ifs.fail_mode
    for i in range(lo, hi):
        law = law_table[law_of[i]]
        pn = pn_all[i]
        ps = ps_all[i]
        a3 = area[i] / 3.0
        nx, ny, nz, mid_area = mid_face(x, na, nb, i)

        if tied[i] == TIED:
            # A tied face carries no force; once its tets' traction reaches the strength it is
            # inserted and carries its law from this step on.
            if not try_insert(i, na_copy[i, 0] // 4, nb_copy[i, 0] // 4, x, na, nb, area[i], damage, slip_plastic,
                              dn_shift, e_damage, ifs.e_inserted, tied, tet_stress, law, pn, ps, nx, ny, nz,
                              prestressed):
                continue
            released = True
        if state[i] == INTACT and intact_step(
            i, t, dt, x, v, na, nb, area[i], damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
            law, pn, ps, nx, ny, nz, dn_shift[i], reading_offset,
        ):
            if damage[i] > 0.0:
                _law_turning_forces(x, na, nb, i, nx, ny, nz, force, force_mid)
                turning[i] = 1
            continue

        # Failed (or pre-cracked) faces: penalty contact with Coulomb friction between the pair,
        # while the two faces still face each other (interface.MID_FACE_MIN).
        facing = mid_area >= MID_FACE_MIN * area[i]
        mu = law[LAW_MU]
        reach2 = reach[i] * reach[i]
        depth = PASSED_THROUGH * reach[i]
        # Under an initial stress a face keeps the compressive shift it carried its initial
        # compression with (fdem.prestress) as its contact's reference: it goes on pressing.
        shift = min(dn_shift[i], 0.0) if prestressed else 0.0
        # dE/dn of the pressed pairs' energy p_n (dn - entry)^2 A / 6: their slips turn it.
        qx = 0.0
        qy = 0.0
        qz = 0.0
        for p in range(3):
            dn, sx, sy, sz = opening(x, na, nb, i, p, nx, ny, nz)
            if prestressed:
                dn += shift
            if not (facing and _pair_touching(dn, sx, sy, sz, reach2, depth)):
                pair_entry[i, p] = OUT_OF_CONTACT
                traction_t[i, p, 0] = 0.0
                traction_t[i, p, 1] = 0.0
                traction_t[i, p, 2] = 0.0
                force[i, p, 0] = 0.0
                force[i, p, 1] = 0.0
                force[i, p, 2] = 0.0
                continue
            entry = _pair_entry(pair_entry[i, p], dn, dt, v, na[i, p], nb[i, p], nx, ny, nz)
            pair_entry[i, p] = entry
            sigma = pn * (dn - entry)
            e_friction[i] += _pair_traction(i, p, sigma, -mu * sigma, nx, ny, nz, dt, ps, a3, na, nb, v, traction_t, force)
            qx += sigma * a3 * sx
            qy += sigma * a3 * sy
            qz += sigma * a3 * sz
        turning_forces(x, na, nb, i, nx, ny, nz, qx, qy, qz, force_mid)
        turning[i] = 1
    if released:
        released_blocks[blk] = 1


@njit(cache=True, inline="always")
def _tet_forces(e, x, rows, dm_inv, vol, lam, mu, s0, prestressed, f, tet_stress, keep_stress):
    """St Venant-Kirchhoff nodal forces of tet e into f (its own 4 nodes), its corners' positions
    read at x[rows[k]]; with keep_stress its Kirchhoff stress P F^T (xx, yy, zz, xy, yz, xz) into
    tet_stress[e], for the insertion check. prestressed: the tet's initial stress s0[e] (Tets.s0,
    STRESS_ORDER) is added to its second Piola-Kirchhoff stress, S = C:E + S0 (see Tets)."""
    n0 = 4 * e
    r0, r1, r2, r3 = rows
    x0, y0, z0 = x[r0, 0], x[r0, 1], x[r0, 2]
    a11 = x[r1, 0] - x0
    a21 = x[r1, 1] - y0
    a31 = x[r1, 2] - z0
    a12 = x[r2, 0] - x0
    a22 = x[r2, 1] - y0
    a32 = x[r2, 2] - z0
    a13 = x[r3, 0] - x0
    a23 = x[r3, 1] - y0
    a33 = x[r3, 2] - z0
    m00, m01, m02 = dm_inv[e, 0, 0], dm_inv[e, 0, 1], dm_inv[e, 0, 2]
    m10, m11, m12 = dm_inv[e, 1, 0], dm_inv[e, 1, 1], dm_inv[e, 1, 2]
    m20, m21, m22 = dm_inv[e, 2, 0], dm_inv[e, 2, 1], dm_inv[e, 2, 2]
    # F = Ds Dm^-1
    f11 = a11 * m00 + a12 * m10 + a13 * m20
    f12 = a11 * m01 + a12 * m11 + a13 * m21
    f13 = a11 * m02 + a12 * m12 + a13 * m22
    f21 = a21 * m00 + a22 * m10 + a23 * m20
    f22 = a21 * m01 + a22 * m11 + a23 * m21
    f23 = a21 * m02 + a22 * m12 + a23 * m22
    f31 = a31 * m00 + a32 * m10 + a33 * m20
    f32 = a31 * m01 + a32 * m11 + a33 * m21
    f33 = a31 * m02 + a32 * m12 + a33 * m22
    e11, e22, e33, e12, e23, e13 = green_lagrange(f11, f12, f13, f21, f22, f23, f31, f32, f33)
    s11, s22, s33, s12, s23, s13 = svk_stress(lam[e], mu[e], e11, e22, e33, e12, e23, e13)
    if prestressed:
        s11 += s0[e, 0]
        s22 += s0[e, 1]
        s33 += s0[e, 2]
        s12 += s0[e, 3]
        s23 += s0[e, 4]
        s13 += s0[e, 5]
    # P = F S
    p11 = f11 * s11 + f12 * s12 + f13 * s13
    p12 = f11 * s12 + f12 * s22 + f13 * s23
    p13 = f11 * s13 + f12 * s23 + f13 * s33
    p21 = f21 * s11 + f22 * s12 + f23 * s13
    p22 = f21 * s12 + f22 * s22 + f23 * s23
    p23 = f21 * s13 + f22 * s23 + f23 * s33
    p31 = f31 * s11 + f32 * s12 + f33 * s13
    p32 = f31 * s12 + f32 * s22 + f33 * s23
    p33 = f31 * s13 + f32 * s23 + f33 * s33
    if keep_stress:
        tet_stress[e, 0] = p11 * f11 + p12 * f12 + p13 * f13
        tet_stress[e, 1] = p21 * f21 + p22 * f22 + p23 * f23
        tet_stress[e, 2] = p31 * f31 + p32 * f32 + p33 * f33
        tet_stress[e, 3] = p11 * f21 + p12 * f22 + p13 * f23
        tet_stress[e, 4] = p21 * f31 + p22 * f32 + p23 * f33
        tet_stress[e, 5] = p11 * f31 + p12 * f32 + p13 * f33
    # H = -V P Dm^-T: column k is the force on corner k+1
    scale = -vol[e]
    for k, mk0, mk1, mk2 in ((1, m00, m01, m02), (2, m10, m11, m12), (3, m20, m21, m22)):
        f[n0 + k, 0] = scale * (p11 * mk0 + p12 * mk1 + p13 * mk2)
        f[n0 + k, 1] = scale * (p21 * mk0 + p22 * mk1 + p23 * mk2)
        f[n0 + k, 2] = scale * (p31 * mk0 + p32 * mk1 + p33 * mk2)
    f[n0, 0] = -(f[n0 + 1, 0] + f[n0 + 2, 0] + f[n0 + 3, 0])
    f[n0, 1] = -(f[n0 + 1, 1] + f[n0 + 2, 1] + f[n0 + 3, 1])
    f[n0, 2] = -(f[n0 + 1, 2] + f[n0 + 2, 2] + f[n0 + 3, 2])


# The parallel loops run over fixed blocks of elements, each block one call of a serial function
# (block_kernel: no reference counting) that unpacks the named tuples once. A function call per
# element from the prange body costs reference counting and struct copies that dominated the
# step; inlining the element code into the prange body itself is not an option (numba 0.68 drops
# writes through named-tuple attributes there).
INTERFACE_BLOCK = 1024
TET_BLOCK = 512


@block_kernel
def _tet_block(lo, hi, slot, dt, kick, nodes, tets, ifs, contact, tools, pressure_now, tool_v_prev, tool_v_next,
               ctrl, ties):
    """Tets lo..hi-1: bulk forces, gathered interface forces, pressures, tool contact (forces
    on the tools into their `slot`), damping, gravity and the central-difference update of each
    tet's own 4 nodes (velocity by `kick`, position by dt: advance). With tied faces (clusters,
    ties.load not empty) the update is the node pass's (extrinsic.cluster_block): the forces and
    the mass go to its ties.load rows instead."""
    x, v, mass = nodes.x, nodes.v, nodes.mass
    dm_inv, vol, lam, mu, s0 = tets.dm_inv, tets.vol, tets.lam, tets.mu, tets.s0
    prestressed = s0.shape[0] > 0
    face_iface, face_side, face_pressure = tets.face_iface, tets.face_side, tets.face_pressure
    na, nb, if_force, force_mid, turning, if_state = ifs.na, ifs.nb, ifs.force, ifs.force_mid, ifs.turning, ifs.state
    node_slot = contact.node_slot
    any_contact = contact.counts[1] > 0
    gx, gy, gz = ctrl.gravity[0], ctrl.gravity[1], ctrl.gravity[2]
    alpha = ctrl.damping[0]
    clustered = ties.load.shape[0] > 0
    tet_stress, load, leader = ties.tet_stress, ties.load, ties.leader
    # With clusters the forces (internal, interfaces', contact, tools') go straight into the node
    # pass's rows (their first 3 columns).
    f = load if clustered else nodes.force
    for e in range(lo, hi):
        n0 = 4 * e
        # Where each corner's motion is held: its cluster leader's row (extrinsic.state_row).
        rows = (state_row(n0, leader), state_row(n0 + 1, leader), state_row(n0 + 2, leader),
                state_row(n0 + 3, leader))
        _tet_forces(e, x, rows, dm_inv, vol, lam, mu, s0, prestressed, f, tet_stress, clustered)
        # Faces without an intact interface, as bits: where pressures act and tools can touch.
        free_faces = 0
        for face in range(4):
            iface = face_iface[e, face]
            if iface >= 0:
                # The face's 3 nodes are this tet's own: gather the interface's forces on them.
                if face_side[e, face] == 1:
                    for p in range(3):
                        g = nb[iface, p]
                        f[g, 0] += if_force[iface, p, 0]
                        f[g, 1] += if_force[iface, p, 1]
                        f[g, 2] += if_force[iface, p, 2]
                else:
                    for p in range(3):
                        g = na[iface, p]
                        f[g, 0] -= if_force[iface, p, 0]
                        f[g, 1] -= if_force[iface, p, 1]
                        f[g, 2] -= if_force[iface, p, 2]
                if turning[iface]:
                    # The force on both nodes of each pair alike (the face normal's turn).
                    side = nb if face_side[e, face] == 1 else na
                    for p in range(3):
                        g = side[iface, p]
                        f[g, 0] += force_mid[iface, p, 0]
                        f[g, 1] += force_mid[iface, p, 1]
                        f[g, 2] += force_mid[iface, p, 2]
                if if_state[iface] == INTACT:
                    continue
            free_faces |= 1 << face

        for k in range(4):
            g = n0 + k
            m = mass[g]
            # External forces that work on the node's own motion: pressure and gravity.
            ex = 0.0
            ey = 0.0
            ez = 0.0
            for face in range(4):
                pid = face_pressure[e, face]
                if face == k or pid < 0 or not (free_faces >> face) & 1:
                    continue
                # Follower pressure on the current face, pushing into the tet; a third per corner.
                c0, c1, c2 = face_corners(face)
                ax, ay, az = twice_area_vector(x, rows[c0], rows[c1], rows[c2])
                scale = -pressure_now[pid] / 6.0  # area vector / 2, shared by 3 corners
                ex += scale * ax
                ey += scale * ay
                ez += scale * az
            ex += m * gx
            ey += m * gy
            ez += m * gz
            cx = 0.0
            cy = 0.0
            cz = 0.0
            work = 0.0
            # A node on a free face (any but face k) may touch a tool, with its fixed contact area.
            if free_faces & ~(1 << k):
                cx, cy, cz, work = contact_with_tools(g, nodes, dt, slot, tools, tool_v_prev, tool_v_next, rows[k])
            # Node-to-surface contact between free surfaces: internal to the specimen.
            if any_contact and node_slot[g] >= 0:
                sx, sy, sz = gathered_contact_force(g, contact)
                f[g, 0] += sx
                f[g, 1] += sy
                f[g, 2] += sz
            if clustered:
                load[g, LOAD_EXTERNAL] = ex
                load[g, LOAD_EXTERNAL + 1] = ey
                load[g, LOAD_EXTERNAL + 2] = ez
                load[g, LOAD_FORCE] += cx
                load[g, LOAD_FORCE + 1] += cy
                load[g, LOAD_FORCE + 2] += cz
                load[g, LOAD_TOOL_WORK] = work
                load[g, LOAD_MASS] = m
                continue
            update_velocity(g, nodes, (f[g, 0], f[g, 1], f[g, 2]), (ex, ey, ez), (cx, cy, cz), work, m, alpha, kick,
                            tools, tool_v_next, slot)
        if clustered:
            continue
        # Positions last: the pressure on a face above used the corners' positions at time t.
        for g in range(n0, n0 + 4):
            move(g, x, v, dt)


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, nodes, tets, ifs, contact, tools, pressures, ctrl, ties, first_kick=-1.0,
            stop_on_insertion=False):
    """Run n_steps central-difference steps from step number first_step (time first_step x dt:
    the same times however a run is split into calls); arrays are updated in place. Returns the
    steps taken and whether the last one inserted an extrinsic face: with stop_on_insertion, the
    call stops after the first step that did. first_kick (s, if positive): the first step's
    velocity update spans that time instead of dt: (old + new) / 2 where the step changes
    (v(t + dt_new / 2) = v(t - dt_old / 2) + a(t) (dt_old + dt_new) / 2, the central difference
    with unequal steps). With tied faces a cluster's motion is held on its leader's row within the
    call (extrinsic.state_row) and every copy gets it when the call returns."""
    n_if = ifs.na.shape[0]
    clustered = ties.load.shape[0] > 0
    n_vertex_blocks = (ties.vertex_ptr.shape[0] - 1 + VERTEX_BLOCK - 1) // VERTEX_BLOCK
    n_tet = tets.vol.shape[0]
    n_press = pressures.counts.shape[0]
    n_slot = contact.counts[1]
    n_if_blocks = (n_if + INTERFACE_BLOCK - 1) // INTERFACE_BLOCK
    n_tet_blocks = (n_tet + TET_BLOCK - 1) // TET_BLOCK
    pressure_now = np.zeros(max(n_press, 1))
    tool_v_prev, tool_v_next = tool_velocity_rows(tools)
    released_blocks = np.zeros(n_if_blocks, dtype=np.uint8)
    # The mesh points of the faces a step inserts (extrinsic.released_vertices).
    touched = np.empty(ties.vertex_ptr.shape[0] - 1, dtype=np.int64)
    seen = np.zeros(ties.vertex_ptr.shape[0] - 1, dtype=np.uint8)
    taken = n_steps
    stopped = False
    for step in range(n_steps):
        t = (first_step + step) * dt
        kick = first_kick if step == 0 and first_kick > 0.0 else dt
        for q in range(n_press):
            pressure_now[q] = interp_history(t, pressures.times[q], pressures.values[q], pressures.counts[q])
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        for blk in prange(n_if_blocks):
            lo = blk * INTERFACE_BLOCK
            _interface_block(lo, min(lo + INTERFACE_BLOCK, n_if), np.int64(blk), t, dt, nodes.x, nodes.v, ifs, ties,
                             released_blocks)
        inserted = False
        if clustered:
            # The regrouping of the inserted faces' mesh points, each once and in parallel: done
            # serially per face it took 1 ms of each step of the Akantu bar's inserting phase
            # (about 60 faces a step; docs/validation.md).
            n_touched = released_vertices(ties, ifs.na, released_blocks, INTERFACE_BLOCK, touched, seen)
            if n_touched > 0:
                inserted = True
                for k in prange(n_touched):
                    regroup_released(touched[k], ties, ifs.na, ifs.nb, nodes.x, nodes.v)
        if n_slot > 0:
            for s in prange(n_slot):
                node_contact(np.int64(s), dt, nodes.x, nodes.v, tets, ifs, contact, ties.leader)
            reaction_lists(contact)
        for blk in prange(n_tet_blocks):
            lo = blk * TET_BLOCK
            _tet_block(lo, min(lo + TET_BLOCK, n_tet), np.int64(blk), dt, kick, nodes, tets, ifs, contact, tools,
                       pressure_now, tool_v_prev, tool_v_next, ctrl, ties)
        if clustered:
            n_vertex = ties.vertex_ptr.shape[0] - 1
            for blk in prange(n_vertex_blocks):
                lo = blk * VERTEX_BLOCK
                cluster_block(lo, min(lo + VERTEX_BLOCK, n_vertex), np.int64(blk), dt, kick, nodes, ties, ctrl, tools,
                              tool_v_next)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)
        if inserted and stop_on_insertion:
            taken = step + 1
            stopped = True
            break
    if clustered:
        # The step moved the leaders' rows only: every copy gets its cluster's state back.
        n_vertex = ties.vertex_ptr.shape[0] - 1
        for blk in prange(n_vertex_blocks):
            lo = blk * VERTEX_BLOCK
            copies_block(lo, min(lo + VERTEX_BLOCK, n_vertex), ties, nodes.x, nodes.v)
    return taken, stopped


@njit(parallel=True, cache=True)
def interface_forces(t, dt, x, v, ifs, ties):
    """The interface pass alone (law and contact forces at positions x): for unit tests of the law
    under prescribed openings, as in a one-element test."""
    n_if = ifs.na.shape[0]
    n_blocks = (n_if + INTERFACE_BLOCK - 1) // INTERFACE_BLOCK
    released_blocks = np.zeros(n_blocks, dtype=np.uint8)
    for blk in prange(n_blocks):
        lo = blk * INTERFACE_BLOCK
        _interface_block(lo, min(lo + INTERFACE_BLOCK, n_if), np.int64(blk), t, dt, x, v, ifs, ties, released_blocks)


# ---------------------------------------------------------------------------------------------
# Diagnostics evaluated between chunks (not in the step loop).


@njit(parallel=True, cache=True)
def tet_energy_and_stress(x, tets, energy, stress):
    """Per-tet St Venant-Kirchhoff energy V0 W(E) and Cauchy stress (xx, yy, zz, xy, yz, xz).
    The 3 x 3 work arrays are allocated once per block of TET_BLOCK tets, not once per tet.

    With an initial stress S0 (Tets.s0) the stress is S = C:E + S0, the gradient of
    W(E) = (E + E0):C:(E + E0) / 2 with E0 = C^-1:S0, the strain that would have built S0 from a
    stress-free state: W = C:E:E / 2 + S0:E + S0:C^-1:S0 / 2. The last term, the energy the tet
    holds at t = 0, is a constant: with it the stored energy at t = 0 is the initial state's, which
    the simulation counts as work put in (FdemSimulation._initial_energy), so the audit closes
    whatever the constant; S0:E is the work of the initial stress on the strain since."""
    n_tet = tets.vol.shape[0]
    s0 = tets.s0
    prestressed = s0.shape[0] > 0
    for blk in prange((n_tet + TET_BLOCK - 1) // TET_BLOCK):
        f = np.empty(9)  # F = [x1 - x0, x2 - x0, x3 - x0] Dm^-1, row-major
        g = np.empty(9)  # Green-Lagrange E = (F^T F - I) / 2, then S = lam tr(E) I + 2 mu E
        fs = np.empty(9)  # F S
        for e in range(blk * TET_BLOCK, min(n_tet, (blk + 1) * TET_BLOCK)):
            n0 = 4 * e
            m = tets.dm_inv[e]
            for r in range(3):
                a1 = x[n0 + 1, r] - x[n0, r]
                a2 = x[n0 + 2, r] - x[n0, r]
                a3 = x[n0 + 3, r] - x[n0, r]
                for c in range(3):
                    f[3 * r + c] = a1 * m[0, c] + a2 * m[1, c] + a3 * m[2, c]
            lam = tets.lam[e]
            mu = tets.mu[e]
            for i in range(3):
                for j in range(3):
                    g[3 * i + j] = 0.5 * (f[i] * f[j] + f[3 + i] * f[3 + j] + f[6 + i] * f[6 + j])
                g[4 * i] -= 0.5
            tr = g[0] + g[4] + g[8]
            ee = 0.0
            for k in range(9):
                ee += g[k] * g[k]
            energy[e] = tets.vol[e] * (0.5 * lam * tr * tr + mu * ee)
            if prestressed:
                # g holds E: + S0:E and S0:C^-1:S0 / 2, C^-1:S = (S - lam / (3 lam + 2 mu) tr(S) I) / (2 mu).
                a0, a1, a2, a3, a4, a5 = s0[e, 0], s0[e, 1], s0[e, 2], s0[e, 3], s0[e, 4], s0[e, 5]
                work = a0 * g[0] + a1 * g[4] + a2 * g[8] + 2.0 * (a3 * g[1] + a4 * g[5] + a5 * g[2])
                tr0 = a0 + a1 + a2
                s0s0 = a0 * a0 + a1 * a1 + a2 * a2 + 2.0 * (a3 * a3 + a4 * a4 + a5 * a5)
                held = (s0s0 - lam / (3.0 * lam + 2.0 * mu) * tr0 * tr0) / (4.0 * mu)
                energy[e] += tets.vol[e] * (work + held)
            for k in range(9):
                g[k] *= 2.0 * mu
            for i in range(3):
                g[4 * i] += lam * tr
            if prestressed:
                g[0] += s0[e, 0]
                g[4] += s0[e, 1]
                g[8] += s0[e, 2]
                g[1] += s0[e, 3]
                g[3] += s0[e, 3]
                g[5] += s0[e, 4]
                g[7] += s0[e, 4]
                g[2] += s0[e, 5]
                g[6] += s0[e, 5]
            # sigma = F S F^T / J.
            J = (f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6])
                 + f[2] * (f[3] * f[7] - f[4] * f[6]))
            for i in range(3):
                for j in range(3):
                    fs[3 * i + j] = f[3 * i] * g[j] + f[3 * i + 1] * g[3 + j] + f[3 * i + 2] * g[6 + j]
            for k, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))):
                stress[e, k] = (fs[3 * i] * f[3 * j] + fs[3 * i + 1] * f[3 * j + 1] + fs[3 * i + 2] * f[3 * j + 2]) / J


@njit(parallel=True, cache=True)
def interface_energy(x, ifs, cohesive, contact):
    """Stored energy per interface: cohesive (intact) or contact penalty (failed / pre-crack)."""
    for i in prange(ifs.na.shape[0]):
        law = ifs.law_table[ifs.law[i]]
        nx, ny, nz, mid_area = mid_face(x, ifs.na, ifs.nb, i)
        pn = ifs.pn[i]
        a3 = ifs.area[i] / 3.0
        cohesive[i] = 0.0
        contact[i] = 0.0
        if ifs.state[i] == INTACT:
            cohesive[i] = intact_energy(i, x, ifs.na, ifs.nb, ifs.area[i], ifs.damage, ifs.slip_plastic, law, pn,
                                        ifs.ps[i], nx, ny, nz, ifs.dn_shift[i])
        else:
            reach2 = ifs.reach[i] * ifs.reach[i]
            depth = PASSED_THROUGH * ifs.reach[i]
            facing = mid_area >= MID_FACE_MIN * ifs.area[i]
            for p in range(3):
                dn, sx, sy, sz = opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
                if ifs.prestressed.shape[0] > 0:
                    dn += min(ifs.dn_shift[i], 0.0)
                entry = ifs.pair_entry[i, p]
                if facing and entry != OUT_OF_CONTACT and _pair_touching(dn, sx, sy, sz, reach2, depth):
                    pressed = min(dn - entry, 0.0)
                    t2 = ifs.traction_t[i, p, 0] ** 2 + ifs.traction_t[i, p, 1] ** 2 + ifs.traction_t[i, p, 2] ** 2
                    contact[i] += (0.5 * pn * pressed * pressed + 0.5 * t2 / ifs.ps[i]) * a3

"""The compiled step of the bonded-particle DEM (paper 003, the JCFpm model): a pass over the
interactions (bonds and contacts), then a pass over the particles that gathers their forces and
torques and calls the shared tool contact (loading.tools) and node update (solver.integrator).
No races: each interaction writes its own rows, each particle reads the rows of its
interactions in a fixed order (the `start` / `entry` / `sign` CSR of Interactions).

An interaction joins particles a and b, n the unit vector from a to b, D their distance:
  normal:  un = d0 - D (positive when closer than d0), Fn = kn un, on b along +n;
  shear:   an incremental spring, Fs += -kt (relative tangential motion of the contact point);
  states:  BONDED   cohesive: breaks in tension when Fn < -fn_max, in shear when
                    |Fs| > cohesion + Fn tan_phi; a shear failure in compression leaves it BROKEN;
           BROKEN   a former bond, purely frictional (|Fs| <= Fn tan_phi) while un >= 0; GONE once
                    it opens;
           CONTACT  a geometric contact (d0 = Ra + Rb): frictional with tan_phi, no force apart;
           GONE     nothing (a later touch is a new CONTACT);
           JOINT    a smooth joint (paper 003 section 3, a closed flaw): normal and shear taken
                    on the flaw's plane, not the line of centres: un grows by the contact point's
                    relative approach along the flaw normal n_j (incremental, like the shear, so
                    that the torques of a force off the line of centres do work that the springs
                    store); frictional (tan_phi) with dilatancy (Fn = kn (un + tan_psi x plastic
                    slip)); no force while open, never gone.
The contact point lies on the line of centres e at la = D Ra / (Ra + Rb) from a (lb = D - la
from b), so the pair's moments cancel: torque on a = la (F x e), on b = lb (F x e), F the force
on b (only its shear part counts, except at a joint).

Energy: elastic = kn un^2 / 2 + |Fs|^2 / (2 kt) of live interactions; a break books what its
spring held into `e_damage`, a slip the friction force times the slip into `e_friction`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange, uint64

from ..loading.tools import (contact_with_tools, interp_history, load_cell_step, move_tools, tool_velocities,
                             tool_velocity_rows)
from ..solver.body import BODY_FIELDS
from ..solver.failures import MODE_SHEAR, MODE_TENSION
from ..solver.integrator import (FUSED_MATH, block_kernel, fused_block_kernel, local_damping_force, move,
                                 update_velocity_local_damping)

BONDED, BROKEN, CONTACT, GONE, JOINT = 0, 1, 2, 3, 4

# The shared per-node arrays (solver.body; radius: each sphere's, its contact radius too), with
# the spins and rotational inertias.
Particles = namedtuple("Particles", BODY_FIELDS + " spin inertia")
Interactions = namedtuple(
    "Interactions",
    "a b state d0 kn kt fn_max cohesion tan_phi shear transfer fail_time fail_mode e_damage e_friction "
    "start entry sign joint joint_normal joint_un joint_tan_psi joint_slip",
)

# Columns of inter.transfer, what an interaction hands its two particles, one 64-byte row each:
# the force on b, its moment about the line of centres per unit lever (F x e), and the levers of
# a and b. The particle pass reads the rows of a particle's interactions scattered: one row
# costs a cache line where three arrays cost three (measured: the gather 4.4 -> 2.8 ms at 100k,
# with `sign` in int8).
TRANSFER_FORCE, TRANSFER_MOMENT, TRANSFER_LEVER_A, TRANSFER_LEVER_B = 0, 3, 6, 7
TRANSFER_COLUMNS = 8

BLOCK = 256  # interactions or particles per parallel task


@njit(cache=True, inline="always")
def _shear_energy(sx, sy, sz, kt):
    return 0.5 * (sx * sx + sy * sy + sz * sz) / kt


@njit(cache=True, inline="always")
def _contact_velocity(v, w, radius, a, b, dist, ex, ey, ez):
    """The contact point's lever arms (la from a, lb from b, on the line of centres e) and its
    velocity on b relative to a, spins included."""
    la = dist * radius[a] / (radius[a] + radius[b])
    lb = dist - la
    ox = lb * w[b, 0] + la * w[a, 0]
    oy = lb * w[b, 1] + la * w[a, 1]
    oz = lb * w[b, 2] + la * w[a, 2]
    rx = v[b, 0] - v[a, 0] - (oy * ez - oz * ey)
    ry = v[b, 1] - v[a, 1] - (oz * ex - ox * ez)
    rz = v[b, 2] - v[a, 2] - (ox * ey - oy * ex)
    return la, lb, rx, ry, rz


@njit(cache=True, inline="always")
def _distance(x, a, b):
    """|x_b - x_a| and its components. The one formula for a pair's distance, in the step and in
    the rest distances d0 (pair_distances), so that a pair set up at rest starts with exactly no
    force however its multiply-adds are fused."""
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    dist2 = dx * dx + dy * dy + dz * dz
    return math.sqrt(dist2), dist2, dx, dy, dz


@njit(cache=True, fastmath=FUSED_MATH)  # as the interaction pass (fused_block_kernel)
def pair_distances(x, a, b):
    """|x[b] - x[a]| per pair, as the interaction pass measures it."""
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = _distance(x, a[i], b[i])[0]
    return out


@fused_block_kernel
def _interaction_block(lo, hi, t, dt, particles, inter):
    x, v, w, radius = particles.x, particles.v, particles.spin, particles.radius
    a_of, b_of, state, d0, kn, kt = inter.a, inter.b, inter.state, inter.d0, inter.kn, inter.kt
    shear, transfer = inter.shear, inter.transfer
    for i in range(uint64(lo), uint64(hi)):  # unsigned indices: no wraparound (solver/integrator.py)
        for d in range(TRANSFER_LEVER_A):  # no force, no moment unless stored below
            transfer[i, d] = 0.0
        st = state[i]
        if st == GONE:
            continue
        a = uint64(a_of[i])
        b = uint64(b_of[i])
        dist, dist2, dx, dy, dz = _distance(x, a, b)
        inv_dist = 1.0 / dist
        nx = dx * inv_dist
        ny = dy * inv_dist
        nz = dz * inv_dist
        un = d0[i] - dist
        k_t = kt[i]
        if st == JOINT:
            _joint(i, dt, x, v, w, radius, a, b, dx, dy, dz, dist, k_t, inter)
            continue
        fn = kn[i] * un
        # The old shear force s, turned into the new tangent plane (its magnitude kept):
        # (s - (s.n) n) x keep, keep^2 = |s|^2 / |s - (s.n) n|^2 = |s|^2 |d|^2 / (|s|^2 |d|^2 - (s.d)^2).
        # keep from the unnormalised d, so that its division and root run beside those of n,
        # not after them: the step's longest chain of dependent operations, halved.
        sx, sy, sz = shear[i, 0], shear[i, 1], shear[i, 2]
        old2 = sx * sx + sy * sy + sz * sz
        sd = sx * dx + sy * dy + sz * dz
        turned = old2 * dist2 - sd * sd
        keep = math.sqrt(old2 * dist2 / turned) if turned > 0.0 else 1.0
        sn = sx * nx + sy * ny + sz * nz
        sx = (sx - sn * nx) * keep
        sy = (sy - sn * ny) * keep
        sz = (sz - sn * nz) * keep
        # Relative motion of the contact point over the last step, tangential part.
        la, lb, rx, ry, rz = _contact_velocity(v, w, radius, a, b, dist, nx, ny, nz)
        rn = rx * nx + ry * ny + rz * nz
        ux = (rx - rn * nx) * dt
        uy = (ry - rn * ny) * dt
        uz = (rz - rn * nz) * dt
        if st == BONDED and fn < -inter.fn_max[i]:
            # Tension failure: the bond and what its springs held (at the mid-step) are gone.
            un_mid = un + 0.5 * rn * dt
            inter.e_damage[i] += 0.5 * kn[i] * un_mid * un_mid + _shear_energy(
                sx - 0.5 * k_t * ux, sy - 0.5 * k_t * uy, sz - 0.5 * k_t * uz, k_t)
            _release(i, t, MODE_TENSION, state, shear, inter)
            continue
        if st != BONDED and un < 0.0:
            # Apart: no force; a former bond is gone.
            _slide_empty(i, sx, sy, sz, k_t, inter)
            if st == BROKEN:
                state[i] = GONE
            continue
        tx = sx - k_t * ux
        ty = sy - k_t * uy
        tz = sz - k_t * uz
        # Compared squared: the root only where the spring fails or slides (most hold).
        trial2 = tx * tx + ty * ty + tz * tz
        cap = fn * inter.tan_phi[i]
        if st == BONDED:
            strength = inter.cohesion[i] + cap
            if strength < 0.0 or trial2 > strength * strength:
                trial = math.sqrt(trial2)
                # Shear failure: in compression the pair goes on rubbing (BROKEN), else it is gone.
                if fn < 0.0:
                    inter.e_damage[i] += 0.5 * kn[i] * un * un + _shear_energy(tx, ty, tz, k_t)
                    _release(i, t, MODE_SHEAR, state, shear, inter)
                    continue
                state[i] = BROKEN
                inter.fail_time[i] = t
                inter.fail_mode[i] = MODE_SHEAR
                inter.e_damage[i] += 0.5 * (trial2 - cap * cap) / k_t
                tx, ty, tz = _scaled(tx, ty, tz, cap / trial)
        elif trial2 > cap * cap:  # cap >= 0 here: a pair apart returned above
            trial = math.sqrt(trial2)
            # Sliding: the cap times the slip (trial - cap) / kt. (The drop of the spring's
            # energy, (trial^2 - cap^2) / (2 kt), would book an extra kt slip^2 / 2 each step:
            # an error of first order in dt over a sliding distance.)
            inter.e_friction[i] += cap * (trial - cap) / k_t
            tx, ty, tz = _scaled(tx, ty, tz, cap / trial)
        _store(i, fn, nx, ny, nz, tx, ty, tz, nx, ny, nz, la, lb, inter)


@njit(cache=True, inline="always")
def _joint(i, dt, x, v, w, radius, a, b, dx, dy, dz, dist, k_t, inter):
    """A smooth-joint interaction (state JOINT): see the module's docstring."""
    j = inter.joint[i]
    nx, ny, nz = inter.joint_normal[j, 0], inter.joint_normal[j, 1], inter.joint_normal[j, 2]
    ex = dx / dist
    ey = dy / dist
    ez = dz / dist
    la, lb, rx, ry, rz = _contact_velocity(v, w, radius, a, b, dist, ex, ey, ez)
    rn = rx * nx + ry * ny + rz * nz
    un = inter.joint_un[j] - rn * dt
    inter.joint_un[j] = un
    un += inter.joint_tan_psi[j] * inter.joint_slip[j]
    shear = inter.shear
    sx, sy, sz = shear[i, 0], shear[i, 1], shear[i, 2]
    if un <= 0.0:
        _slide_empty(i, sx, sy, sz, k_t, inter)  # open: no force
        return
    tx = sx - k_t * (rx - rn * nx) * dt
    ty = sy - k_t * (ry - rn * ny) * dt
    tz = sz - k_t * (rz - rn * nz) * dt
    fn = inter.kn[i] * un
    cap = fn * inter.tan_phi[i]
    trial = math.sqrt(tx * tx + ty * ty + tz * tz)
    if trial > cap:
        slip = (trial - cap) / k_t
        inter.joint_slip[j] += slip
        inter.e_friction[i] += cap * slip
        tx, ty, tz = _scaled(tx, ty, tz, cap / trial)
    _store(i, fn, nx, ny, nz, tx, ty, tz, ex, ey, ez, la, lb, inter)


@njit(cache=True, inline="always")
def _scaled(x, y, z, factor):
    return x * factor, y * factor, z * factor


@njit(cache=True, inline="always")
def _store(i, fn, nx, ny, nz, tx, ty, tz, ex, ey, ez, la, lb, inter):
    """The interaction's shear force t, its force on b (fn along n plus t) and the moment of that
    force about the line of centres e (F x e: the torque on a per unit of la, on b per unit of
    lb; along e the normal part drops out exactly)."""
    shear, row = inter.shear, inter.transfer
    shear[i, 0] = tx
    shear[i, 1] = ty
    shear[i, 2] = tz
    row[i, TRANSFER_FORCE] = fn * nx + tx
    row[i, TRANSFER_FORCE + 1] = fn * ny + ty
    row[i, TRANSFER_FORCE + 2] = fn * nz + tz
    row[i, TRANSFER_MOMENT] = (ty * ez - tz * ey) + fn * (ny * ez - nz * ey)
    row[i, TRANSFER_MOMENT + 1] = (tz * ex - tx * ez) + fn * (nz * ex - nx * ez)
    row[i, TRANSFER_MOMENT + 2] = (tx * ey - ty * ex) + fn * (nx * ey - ny * ex)
    row[i, TRANSFER_LEVER_A] = la
    row[i, TRANSFER_LEVER_B] = lb


@njit(cache=True, inline="always")
def _slide_empty(i, sx, sy, sz, k_t, inter):
    """No force: the shear spring slides to nothing, its energy booked as friction."""
    inter.e_friction[i] += _shear_energy(sx, sy, sz, k_t)
    inter.shear[i, 0] = 0.0
    inter.shear[i, 1] = 0.0
    inter.shear[i, 2] = 0.0


@njit(cache=True, inline="always")
def _release(i, t, mode, state, shear, inter):
    state[i] = GONE
    shear[i, 0] = 0.0
    shear[i, 1] = 0.0
    shear[i, 2] = 0.0
    inter.fail_time[i] = t
    inter.fail_mode[i] = mode


@block_kernel
def _particle_block(lo, hi, slot, dt, particles, inter, tools, tool_v_prev, tool_v_next, gravity, alpha,
                    membrane_area, membrane_moment, membrane_x, pressure_now):
    x, v, w, mass, inertia = particles.x, particles.v, particles.spin, particles.mass, particles.inertia
    n_pressure = membrane_area.shape[0]
    transfer, start, entry, sign = inter.transfer, inter.start, inter.entry, inter.sign
    w_damping = particles.w_damping
    for g in range(lo, hi):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        mx = 0.0
        my = 0.0
        mz = 0.0
        for r in range(uint64(start[g]), uint64(start[g + 1])):
            i = uint64(entry[r])
            s = sign[r]  # +1: g is the interaction's b, -1: its a
            fx += s * transfer[i, TRANSFER_FORCE]
            fy += s * transfer[i, TRANSFER_FORCE + 1]
            fz += s * transfer[i, TRANSFER_FORCE + 2]
            arm = transfer[i, TRANSFER_LEVER_B] if s > 0 else transfer[i, TRANSFER_LEVER_A]
            mx += arm * transfer[i, TRANSFER_MOMENT]
            my += arm * transfer[i, TRANSFER_MOMENT + 1]
            mz += arm * transfer[i, TRANSFER_MOMENT + 2]
        m = mass[g]
        cx, cy, cz, tool_work = contact_with_tools(g, particles, dt, slot, tools, tool_v_prev, tool_v_next)
        ex = m * gravity[0]
        ey = m * gravity[1]
        ez = m * gravity[2]
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(n_pressure):
            # The membrane (dem.membrane): pressure x exposed area, inward, on the cells' lines of
            # action, fixed in space: the moment about the centre at the raster, plus (x_raster -
            # x) x the force as the particle moves.
            p = pressure_now[k]
            ax = membrane_area[k, g, 0]
            ay = membrane_area[k, g, 1]
            az = membrane_area[k, g, 2]
            rx = membrane_x[g, 0] - x[g, 0]
            ry = membrane_x[g, 1] - x[g, 1]
            rz = membrane_x[g, 2] - x[g, 2]
            ex += p * ax
            ey += p * ay
            ez += p * az
            tx += p * (membrane_moment[k, g, 0] + ry * az - rz * ay)
            ty += p * (membrane_moment[k, g, 1] + rz * ax - rx * az)
            tz += p * (membrane_moment[k, g, 2] + rx * ay - ry * ax)
        if n_pressure > 0:
            mx += tx
            my += ty
            mz += tz
        update_velocity_local_damping(g, particles, (fx, fy, fz), (ex, ey, ez),
                                      (cx, cy, cz), tool_work, m, alpha, dt, tools, tool_v_next, slot)
        move(g, x, v, dt)
        # Spin: the same central difference and local damping on the torque (no supports on it).
        j = inertia[g]
        dx = local_damping_force(mx, w[g, 0], j, alpha, dt)
        dy = local_damping_force(my, w[g, 1], j, alpha, dt)
        dz = local_damping_force(mz, w[g, 2], j, alpha, dt)
        wx = w[g, 0] + (mx + dx) * dt / j
        wy = w[g, 1] + (my + dy) * dt / j
        wz = w[g, 2] + (mz + dz) * dt / j
        if alpha != 0.0:
            w_damping[g] -= 0.5 * dt * (dx * (w[g, 0] + wx) + dy * (w[g, 1] + wy) + dz * (w[g, 2] + wz))
        if n_pressure > 0:  # the membrane's torque works on the spin
            particles.w_external[g] += 0.5 * dt * (tx * (w[g, 0] + wx) + ty * (w[g, 1] + wy) + tz * (w[g, 2] + wz))
        w[g, 0] = wx
        w[g, 1] = wy
        w[g, 2] = wz


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, particles, inter, tools, gravity, alpha, membrane_area, membrane_moment,
            membrane_x, pressures):
    """n_steps central-difference steps from step number first_step (time first_step x dt, the
    same however a run is split into calls); arrays updated in place. `alpha`: the local
    non-viscous damping (0 to 1). `membrane_area`, `membrane_moment` (k, n, 3): each particle's
    exposed area vector and its cells' moment about its centre per unit pressure, `membrane_x`
    the positions they were taken at (dem.membrane), `pressures` their HistoryTable (k rows;
    k = 0: none)."""
    n_inter = inter.a.shape[0]
    n = particles.x.shape[0]
    tool_v_prev, tool_v_next = tool_velocity_rows(tools)
    n_pressure = membrane_area.shape[0]
    pressure_now = np.zeros(max(n_pressure, 1))
    for step in range(n_steps):
        t = (first_step + step) * dt
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        for k in range(n_pressure):
            pressure_now[k] = interp_history(t, pressures.times[k], pressures.values[k], pressures.counts[k])
        for blk in prange((n_inter + BLOCK - 1) // BLOCK):
            lo = blk * BLOCK
            _interaction_block(lo, min(lo + BLOCK, n_inter), t, dt, particles, inter)
        for blk in prange((n + BLOCK - 1) // BLOCK):
            lo = blk * BLOCK
            _particle_block(lo, min(lo + BLOCK, n), np.int64(blk), dt, particles, inter, tools, tool_v_prev, tool_v_next,
                            gravity, alpha, membrane_area, membrane_moment, membrane_x, pressure_now)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)

"""Compiled FDEM step: interfaces, tetrahedra, tools, time integration.

State is flat arrays grouped in named tuples (see ``model.py``). The exploded mesh gives each tet
its own 4 nodes (node 4e+k is corner k of tet e), so one step is two parallel passes with no
races and no atomics:

1. over interfaces: kinematics, Guo-Munjiza or bilinear cohesive law (per law row) or (once
   failed) penalty contact with Coulomb friction; the traction force on each of the 3 B-side
   nodes goes to ``ifs.force`` (the A side gets its negative);
2. over tets: St Venant-Kirchhoff forces, gather of the interface forces of the tet's 4 faces,
   pressures, tool contact, damping, gravity, central-difference update of the tet's 4 nodes.

Every energy term is accumulated per node or per interface (never into a shared scalar), and
summed in a fixed order between chunks: results do not depend on the thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .contact import BARY_TOL, gathered_contact_force, node_contact, reaction_lists
from .friction import coulomb_update
from .topology import FAILED, INTACT, face_corners, twice_area_vector
from .law import (
    LAW_GF1,
    LAW_GF2,
    LAW_A,
    LAW_B,
    LAW_CS,
    LAW_FT,
    LAW_IZ,
    LAW_KIND,
    LAW_MU,
    KIND_BILINEAR,
    PRE_PEAK_NORMAL,
    PRE_PEAK_SHEAR,
    bilinear_damage,
    critical_opening,
    normal_stress,
    peak_curve_energy,
    shear_strength,
    softening,
)

# Failure modes recorded in events.csv.
MODE_NAMES = ("none", "tension", "shear", "mixed")
# Tool shapes.
TOOL_PLANE, TOOL_BOX, TOOL_CYLINDER, TOOL_SPHERE, TOOL_SURFACE = 0, 1, 2, 3, 4
# Columns of a surface tool's triangle rows (Tools.surf_tri), in the tool's own frame: corner 0,
# edges e1 = p1 - p0 and e2 = p2 - p0, unit outward normal, and the barycentric Gram terms
# e1.e1, e1.e2, e2.e2 and 1 / (e1.e1 e2.e2 - (e1.e2)^2).
SURF_TRI_COLUMNS = 16
# Node constraints: -1 free, else the index of the node's velocity projector (0: fixed).
FREE, FIXED = -1, 0
# nodes.tool: index of the tool a node touches, NO_TOOL, or HIDDEN while the node is on no free
# face (inside the body: no tool contact).
NO_TOOL, HIDDEN = -1, -2


@njit(cache=True, inline="always")
def interp_history(t, times, values, n):
    """Piecewise-linear history; constant beyond its ends."""
    if t <= times[0]:
        return values[0]
    if t >= times[n - 1]:
        return values[n - 1]
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if times[mid] <= t:
            lo = mid
        else:
            hi = mid
    w = (t - times[lo]) / (times[hi] - times[lo])
    return values[lo] + w * (values[hi] - values[lo])


@njit(cache=True, inline="always")
def _mid_normal(x, na, nb, i):
    """Unit normal of the mid-surface of interface i, pointing from side A to side B."""
    a0, a1, a2 = na[i, 0], na[i, 1], na[i, 2]
    b0, b1, b2 = nb[i, 0], nb[i, 1], nb[i, 2]
    p0x = 0.5 * (x[a0, 0] + x[b0, 0])
    p0y = 0.5 * (x[a0, 1] + x[b0, 1])
    p0z = 0.5 * (x[a0, 2] + x[b0, 2])
    ux = 0.5 * (x[a1, 0] + x[b1, 0]) - p0x
    uy = 0.5 * (x[a1, 1] + x[b1, 1]) - p0y
    uz = 0.5 * (x[a1, 2] + x[b1, 2]) - p0z
    wx = 0.5 * (x[a2, 0] + x[b2, 0]) - p0x
    wy = 0.5 * (x[a2, 1] + x[b2, 1]) - p0y
    wz = 0.5 * (x[a2, 2] + x[b2, 2]) - p0z
    nx = uy * wz - uz * wy
    ny = uz * wx - ux * wz
    nz = ux * wy - uy * wx
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * inv, ny * inv, nz * inv


@njit(cache=True, inline="always")
def _opening(x, na, nb, i, p, nx, ny, nz):
    """Normal opening and tangential slip vector of point pair p of interface i."""
    a = na[i, p]
    b = nb[i, p]
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    dn = dx * nx + dy * ny + dz * nz
    return dn, dx - dn * nx, dy - dn * ny, dz - dn * nz


@njit(cache=True, inline="always")
def _opening_energy(dn, ft, dnp):
    """Phi_n(dn): the undamaged normal free energy per unit area at opening dn (none in
    compression, which is the separate penalty)."""
    return peak_curve_energy(dn, ft, dnp) if dn > 0.0 else 0.0


@njit(cache=True, inline="always")
def _normal_potential(x, ifs, i, nx, ny, nz):
    """Sum over the 3 points of A/3 * Phi_n(dn), the undamaged normal free energy in opening;
    the cohesive energy in opening is z(D) times it."""
    law = ifs.law_table[ifs.law[i]]
    ft = law[LAW_FT]
    dnp = 2.0 * ft / ifs.pn[i]
    total = 0.0
    for p in range(3):
        dn, sx, sy, sz = _opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
        total += _opening_energy(dn, ft, dnp)
    return total * ifs.area[i] / 3.0


@njit(cache=True, inline="always")
def _bilinear_potential(x, ifs, i, kn, ks, nx, ny, nz):
    """Sum over the 3 points of A/3 * (kn <dn>^2 + ks |s|^2) / 2: the undamaged bilinear energy in
    opening and shear; the cohesive energy there is (1 - D) times it."""
    total = 0.0
    for p in range(3):
        dn, sx, sy, sz = _opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
        if dn > 0.0:
            total += kn * dn * dn
        total += ks * (sx * sx + sy * sy + sz * sz)
    return 0.5 * total * ifs.area[i] / 3.0


@njit(cache=True, inline="always")
def _bilinear_potential_mid(x, v, dt, ifs, i, kn, ks, nx, ny, nz):
    """_bilinear_potential at the half step x - v dt / 2 (v: the velocities of the step that led
    to x): the energy a damage step releases, booked there so that the audit of the explicit
    scheme closes to second order in dt (at x itself it drifts by dD x half a step's work)."""
    total = 0.0
    h = 0.5 * dt
    for p in range(3):
        a = ifs.na[i, p]
        b = ifs.nb[i, p]
        dx = x[b, 0] - x[a, 0] - h * (v[b, 0] - v[a, 0])
        dy = x[b, 1] - x[a, 1] - h * (v[b, 1] - v[a, 1])
        dz = x[b, 2] - x[a, 2] - h * (v[b, 2] - v[a, 2])
        dn = dx * nx + dy * ny + dz * nz
        sx = dx - dn * nx
        sy = dy - dn * ny
        sz = dz - dn * nz
        if dn > 0.0:
            total += kn * dn * dn
        total += ks * (sx * sx + sy * sy + sz * sz)
    return 0.5 * total * ifs.area[i] / 3.0


@njit(cache=True, inline="always")
def _centroid_opening(x, na, nb, i, nx, ny, nz):
    """Normal opening and slip magnitude of interface i at its centroid (the mean of its 3 pairs):
    what its damage is computed from."""
    dn_c = 0.0
    sx_c = 0.0
    sy_c = 0.0
    sz_c = 0.0
    for p in range(3):
        dn, sx, sy, sz = _opening(x, na, nb, i, p, nx, ny, nz)
        dn_c += dn / 3.0
        sx_c += sx / 3.0
        sy_c += sy / 3.0
        sz_c += sz / 3.0
    return dn_c, math.sqrt(sx_c * sx_c + sy_c * sy_c + sz_c * sz_c)


@njit(cache=True, inline="always")
def _bilinear_intact(i, t, dt, x, v, ifs, law, kn, ks, a3, nx, ny, nz):
    """Bilinear cohesive law on intact interface i: damage from the centroid's effective opening
    (irreversible), then the point tractions (1 - D) kn dn (kn dn in compression) and
    (1 - D) ks s into ifs.force. Returns False once the interface has failed (D = 1): the caller
    then treats it as a failed pair."""
    na, nb = ifs.na, ifs.nb
    dn_c, ds_c = _centroid_opening(x, na, nb, i, nx, ny, nz)
    d_old = ifs.damage[i]
    d_new, mix = bilinear_damage(dn_c, ds_c, kn, ks, law)
    d = d_old
    if d_new > d_old:
        d = d_new
        ifs.damage[i] = d
        # The stored energy the damage step releases (at the half step: see the function).
        ifs.e_damage[i] += (d - d_old) * _bilinear_potential_mid(x, v, dt, ifs, i, kn, ks, nx, ny, nz)
        if d >= 1.0:
            ifs.state[i] = FAILED
            ifs.fail_time[i] = t
            # Mode from the energy ratio G_II / G_T: tension below sin^2(15 deg), shear above
            # sin^2(75 deg) (the Guo-Munjiza angles, in energy-scaled openings).
            if mix < math.sin(math.radians(15.0)) ** 2:
                ifs.fail_mode[i] = 1
            elif mix > math.sin(math.radians(75.0)) ** 2:
                ifs.fail_mode[i] = 2
            else:
                ifs.fail_mode[i] = 3
            return False  # its friction traction starts at zero: intact pairs never write it
    s = 1.0 - d
    for p in range(3):
        dn, sx, sy, sz = _opening(x, na, nb, i, p, nx, ny, nz)
        sigma = kn * dn if dn < 0.0 else s * kn * dn
        tx = s * ks * sx
        ty = s * ks * sy
        tz = s * ks * sz
        ifs.force[i, p, 0] = -(sigma * nx + tx) * a3
        ifs.force[i, p, 1] = -(sigma * ny + ty) * a3
        ifs.force[i, p, 2] = -(sigma * nz + tz) * a3
    return True


# A failed pair deeper than this fraction of its longest edge has passed through (its faces slid
# apart beyond reach, crossed, and came back): penalty contact there would fire the stored
# p_n dn^2 / 2 at once (seen in crushed walnut shells: 300 N in one step), so it stays off. Honest
# penalty penetrations are orders of magnitude smaller (stress / p_n).
PASSED_THROUGH = 0.1


@njit(cache=True, inline="always")
def _pair_touching(dn, sx, sy, sz, reach2, depth):
    """Whether point pair (dn, s) of a failed interface is in paired contact: closed, slid less
    than reach (reach2 = reach^2), and not passed through (dn > -depth)."""
    return -depth < dn < 0.0 and sx * sx + sy * sy + sz * sz <= reach2


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
def _cohesive_shear_trial(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps):
    """Elastic shear traction ps (s - s_p) of point p of intact interface i: slip s beyond its
    plastic slip s_p, which is kept in the global frame and projected on the current tangent plane
    (it only grows on a damaging interface, whose rotation before failure is small)."""
    px = slip_plastic[i, p, 0]
    py = slip_plastic[i, p, 1]
    pz = slip_plastic[i, p, 2]
    pdn = px * nx + py * ny + pz * nz
    return ps * (sx - px + pdn * nx), ps * (sy - py + pdn * ny), ps * (sz - pz + pdn * nz)


@njit(cache=True, inline="always")
def _cohesive_shear(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps, cap, cap_before):
    """Shear traction of point p of intact interface i from its total slip s: the spring ps on
    s - s_p, returned onto the cap z(D) f_s(sigma_n) (the excess becomes plastic slip), and the
    energy the return dissipates per unit area. Written from the total slip, it needs no
    velocities and no stored traction: while the interface sticks, the shear costs one read of s_p.

    The dissipation splits the excess of the trial traction t over the cap like an incremental
    update would: the part below cap_before (the cap before this step's damage) is stored energy
    the falling cap releases, (t_c^2 - cap^2) / 2 ps; the rest is slip at the cap,
    cap (t - max(t_c, cap)) / ps. Exact for a pure cap drop and for pure sliding."""
    tx, ty, tz = _cohesive_shear_trial(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps)
    t2 = tx * tx + ty * ty + tz * tz
    cap2 = cap * cap
    if t2 <= cap2:
        return tx, ty, tz, 0.0
    t_trial = math.sqrt(t2)
    t_carried = min(t_trial, cap_before)
    lost = 0.0
    if t_carried > cap:
        lost = (t_carried * t_carried - cap2) / (2.0 * ps)
    lost += cap * (t_trial - max(t_carried, cap)) / ps
    scale = cap / t_trial
    tx *= scale
    ty *= scale
    tz *= scale
    slip_plastic[i, p, 0] = sx - tx / ps
    slip_plastic[i, p, 1] = sy - ty / ps
    slip_plastic[i, p, 2] = sz - tz / ps
    return tx, ty, tz, lost


@njit(cache=True)
def _interface_block(lo, hi, t, dt, x, v, ifs):
    """Interfaces lo..hi-1: kinematics, Guo-Munjiza or bilinear law or (once failed) paired penalty
    contact with Coulomb friction; the force on each B-side node into ifs.force (A gets its
    negative)."""
    # Unpacked once per block: attribute access per element costs reference counting.
    na, nb, area, pn_all, ps_all = ifs.na, ifs.nb, ifs.area, ifs.pn, ifs.ps
    state, damage, force, traction_t = ifs.state, ifs.damage, ifs.force, ifs.traction_t
    slip_plastic = ifs.slip_plastic
    law_table, law_of = ifs.law_table, ifs.law
    e_damage, e_friction, reach = ifs.e_damage, ifs.e_friction, ifs.reach
    fail_time, fail_mode = ifs.fail_time, ifs.fail_mode
    for i in range(lo, hi):
        law = law_table[law_of[i]]
        pn = pn_all[i]
        ps = ps_all[i]
        a3 = area[i] / 3.0
        nx, ny, nz = _mid_normal(x, na, nb, i)

        if state[i] == INTACT and law[LAW_KIND] == KIND_BILINEAR:
            # Bilinear cohesive law: pn, ps are its stiffnesses kn, ks.
            if _bilinear_intact(i, t, dt, x, v, ifs, law, pn, ps, a3, nx, ny, nz):
                continue
        elif state[i] == INTACT:
            # The three point openings, read once (the stores below may alias x for the compiler,
            # so it would reload them).
            dn0, s0x, s0y, s0z = _opening(x, na, nb, i, 0, nx, ny, nz)
            dn1, s1x, s1y, s1z = _opening(x, na, nb, i, 1, nx, ny, nz)
            dn2, s2x, s2y, s2z = _opening(x, na, nb, i, 2, nx, ny, nz)
            # Damage from the centroid opening and slip (eq. 8), irreversible.
            dn_c = (dn0 + dn1 + dn2) / 3.0
            sx_c = (s0x + s1x + s2x) / 3.0
            sy_c = (s0y + s1y + s2y) / 3.0
            sz_c = (s0z + s1z + s2z) / 3.0
            ds_c = math.sqrt(sx_c * sx_c + sy_c * sy_c + sz_c * sz_c)
            a, b, c = law[LAW_A], law[LAW_B], law[LAW_CS]
            d_old = damage[i]
            z_old = softening(d_old, a, b, c)
            ft = law[LAW_FT]
            dnp = 2.0 * ft / pn
            dnc = critical_opening(ft, dnp, law[LAW_GF1], law[LAW_IZ], PRE_PEAK_NORMAL)
            fs_c = shear_strength(normal_stress(dn_c, pn, z_old, law), law)
            dsp = 2.0 * fs_c / ps
            dsc = critical_opening(fs_c, dsp, law[LAW_GF2], law[LAW_IZ], PRE_PEAK_SHEAR)
            d_n = (dn_c - dnp) / (dnc - dnp) if dn_c > dnp else 0.0
            d_s = (ds_c - dsp) / (dsc - dsp) if ds_c > dsp else 0.0
            d_new = math.sqrt(d_n * d_n + d_s * d_s)
            if d_new > 1.0:
                d_new = 1.0
            z = z_old
            if d_new > d_old:
                z = softening(d_new, a, b, c)
                damage[i] = d_new
                # Energy released by the damage step at the current opening
                # (the shear spring releases its part through the cap, below).
                e_damage[i] += (z_old - z) * a3 * (
                    _opening_energy(dn0, ft, dnp) + _opening_energy(dn1, ft, dnp) + _opening_energy(dn2, ft, dnp)
                )
                if d_new >= 1.0:
                    state[i] = FAILED
                    fail_time[i] = t
                    angle = math.atan2(d_s, d_n)
                    if angle < math.radians(15.0):
                        fail_mode[i] = 1
                    elif angle > math.radians(75.0):
                        fail_mode[i] = 2
                    else:
                        fail_mode[i] = 3
            # Shear: an elastic spring ps capped at z(D) f_s(sigma_n); the cap dissipates (at
            # failure z = 0 releases what the spring still holds). (The paper's f_s (2x - x^2)
            # curve of the total slip has no potential when sigma_n varies and pumps energy into
            # a crushed zone.)
            lost = 0.0
            for p, dn, sx, sy, sz in ((0, dn0, s0x, s0y, s0z), (1, dn1, s1x, s1y, s1z), (2, dn2, s2x, s2y, s2z)):
                sigma = normal_stress(dn, pn, z, law)
                fs = shear_strength(sigma, law)
                tx, ty, tz, released = _cohesive_shear(
                    slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps, z * fs, z_old * fs
                )
                lost += released
                force[i, p, 0] = -(sigma * nx + tx) * a3
                force[i, p, 1] = -(sigma * ny + ty) * a3
                force[i, p, 2] = -(sigma * nz + tz) * a3
            e_damage[i] += lost * a3
            continue

        # Failed (or pre-cracked) faces: penalty contact with Coulomb friction between the pair.
        mu = law[LAW_MU]
        reach2 = reach[i] * reach[i]
        depth = PASSED_THROUGH * reach[i]
        for p in range(3):
            dn, sx, sy, sz = _opening(x, na, nb, i, p, nx, ny, nz)
            if not _pair_touching(dn, sx, sy, sz, reach2, depth):
                traction_t[i, p, 0] = 0.0
                traction_t[i, p, 1] = 0.0
                traction_t[i, p, 2] = 0.0
                force[i, p, 0] = 0.0
                force[i, p, 1] = 0.0
                force[i, p, 2] = 0.0
                continue
            sigma = pn * dn
            e_friction[i] += _pair_traction(i, p, sigma, -mu * sigma, nx, ny, nz, dt, ps, a3, na, nb, v, traction_t, force)


@njit(cache=True, inline="always")
def _surface_gap(j, px, py, pz, tools):
    """Signed distance of a point to surface tool j and the outward normal, from the triangle
    nearest to it along its normal among those whose projection holds the point and that lie
    less than the contact depth away: negative (in contact) when the point is behind that
    triangle; (inf, 0, 0, 0) when there is none or when the point is in front of it. For a point
    inside the tool this is the least deep penetration; a nearer triangle in front shows that a
    point behind another one's plane is outside the tool (beside it, or over a part of the tool
    thinner than the contact depth).

    The tool only translates, so the point is moved into the tool's frame and looked up in the
    static grid built with the model (geom row: grid origin, 1 / cell size, contact depth;
    surf_grid row: cells along x, y, z and the tool's first entry in surf_cell_start)."""
    g = tools.geom[j]
    qx = px - tools.disp[j, 0]
    qy = py - tools.disp[j, 1]
    qz = pz - tools.disp[j, 2]
    inv_h = g[3]
    grid = tools.surf_grid[j]
    ci = (qx - g[0]) * inv_h
    cj = (qy - g[1]) * inv_h
    ck = (qz - g[2]) * inv_h
    # Written so that a NaN position is "no contact" too.
    if not (ci >= 0.0 and ci < grid[0] and cj >= 0.0 and cj < grid[1] and ck >= 0.0 and ck < grid[2]):
        return math.inf, 0.0, 0.0, 0.0
    cell = grid[3] + (int(ci) * grid[1] + int(cj)) * grid[2] + int(ck)
    start, cell_tris, tri = tools.surf_cell_start, tools.surf_cell_tris, tools.surf_tri
    nearest = g[4]  # the contact depth
    best_gap = math.inf
    bnx = 0.0
    bny = 0.0
    bnz = 0.0
    for s in range(start[cell], start[cell + 1]):
        t = cell_tris[s]
        rx = qx - tri[t, 0]
        ry = qy - tri[t, 1]
        rz = qz - tri[t, 2]
        nx, ny, nz = tri[t, 9], tri[t, 10], tri[t, 11]
        gap = rx * nx + ry * ny + rz * nz
        # Ties keep the first candidate: the order is fixed, the result deterministic.
        if abs(gap) >= nearest:
            continue
        d20 = rx * tri[t, 3] + ry * tri[t, 4] + rz * tri[t, 5]
        d21 = rx * tri[t, 6] + ry * tri[t, 7] + rz * tri[t, 8]
        d00, d01, d11, inv_den = tri[t, 12], tri[t, 13], tri[t, 14], tri[t, 15]
        l1 = (d11 * d20 - d01 * d21) * inv_den
        l2 = (d00 * d21 - d01 * d20) * inv_den
        l0 = 1.0 - l1 - l2
        # The tolerance keeps a point over a shared edge or corner in contact with one of them.
        if l0 < -BARY_TOL or l1 < -BARY_TOL or l2 < -BARY_TOL:
            continue
        nearest = abs(gap)
        best_gap = gap
        bnx, bny, bnz = nx, ny, nz
    if best_gap >= 0.0:
        return math.inf, 0.0, 0.0, 0.0
    return best_gap, bnx, bny, bnz


@njit(cache=True, inline="always")
def tool_gap(j, px, py, pz, tools):
    """Signed distance of a point to tool j's surface (negative inside) and the outward normal."""
    kind = tools.kind[j]
    if kind == TOOL_SURFACE:
        return _surface_gap(j, px, py, pz, tools)
    g = tools.geom[j]
    cx = g[0] + tools.disp[j, 0]
    cy = g[1] + tools.disp[j, 1]
    cz = g[2] + tools.disp[j, 2]
    qx = px - cx
    qy = py - cy
    qz = pz - cz
    if kind == TOOL_PLANE:
        return qx * g[3] + qy * g[4] + qz * g[5], g[3], g[4], g[5]
    if kind == TOOL_SPHERE:
        d = math.sqrt(qx * qx + qy * qy + qz * qz)
        if d == 0.0:
            return -g[3], 0.0, 0.0, 1.0
        return d - g[3], qx / d, qy / d, qz / d
    if kind == TOOL_CYLINDER:
        s = qx * g[3] + qy * g[4] + qz * g[5]
        rx = qx - s * g[3]
        ry = qy - s * g[4]
        rz = qz - s * g[5]
        rho = math.sqrt(rx * rx + ry * ry + rz * rz)
        radial = rho - g[6]
        axial = abs(s) - g[7]
        if radial >= 0.0 or axial >= 0.0:
            # Outside: positive distance (exact enough for a contact test).
            return max(radial, axial), 0.0, 0.0, 0.0
        if -radial <= -axial:
            if rho == 0.0:
                return radial, 1.0, 0.0, 0.0
            return radial, rx / rho, ry / rho, rz / rho
        sg = 1.0 if s >= 0.0 else -1.0
        return axial, sg * g[3], sg * g[4], sg * g[5]
    # Box: centre, half extents g[3:6], axes g[6:9], g[9:12], third axis = first x second.
    e1x, e1y, e1z = g[6], g[7], g[8]
    e2x, e2y, e2z = g[9], g[10], g[11]
    e3x = e1y * e2z - e1z * e2y
    e3y = e1z * e2x - e1x * e2z
    e3z = e1x * e2y - e1y * e2x
    q1 = qx * e1x + qy * e1y + qz * e1z
    q2 = qx * e2x + qy * e2y + qz * e2z
    q3 = qx * e3x + qy * e3y + qz * e3z
    o1 = abs(q1) - g[3]
    o2 = abs(q2) - g[4]
    o3 = abs(q3) - g[5]
    if o1 >= 0.0 or o2 >= 0.0 or o3 >= 0.0:
        return max(o1, max(o2, o3)), 0.0, 0.0, 0.0
    # Inside: leave through the nearest face.
    if o1 >= o2 and o1 >= o3:
        sg = 1.0 if q1 >= 0.0 else -1.0
        return o1, sg * e1x, sg * e1y, sg * e1z
    if o2 >= o3:
        sg = 1.0 if q2 >= 0.0 else -1.0
        return o2, sg * e2x, sg * e2y, sg * e2z
    sg = 1.0 if q3 >= 0.0 else -1.0
    return o3, sg * e3x, sg * e3y, sg * e3z


@njit(cache=True, inline="always")
def _tet_forces(e, x, dm_inv, vol, lam, mu, f):
    """St Venant-Kirchhoff nodal forces of tet e into f (its own 4 nodes)."""
    n0 = 4 * e
    x0, y0, z0 = x[n0, 0], x[n0, 1], x[n0, 2]
    a11 = x[n0 + 1, 0] - x0
    a21 = x[n0 + 1, 1] - y0
    a31 = x[n0 + 1, 2] - z0
    a12 = x[n0 + 2, 0] - x0
    a22 = x[n0 + 2, 1] - y0
    a32 = x[n0 + 2, 2] - z0
    a13 = x[n0 + 3, 0] - x0
    a23 = x[n0 + 3, 1] - y0
    a33 = x[n0 + 3, 2] - z0
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
    # Green-Lagrange strain E = (F^T F - I) / 2
    e11 = 0.5 * (f11 * f11 + f21 * f21 + f31 * f31 - 1.0)
    e22 = 0.5 * (f12 * f12 + f22 * f22 + f32 * f32 - 1.0)
    e33 = 0.5 * (f13 * f13 + f23 * f23 + f33 * f33 - 1.0)
    e12 = 0.5 * (f11 * f12 + f21 * f22 + f31 * f32)
    e13 = 0.5 * (f11 * f13 + f21 * f23 + f31 * f33)
    e23 = 0.5 * (f12 * f13 + f22 * f23 + f32 * f33)
    lam_e = lam[e]
    mu2 = 2.0 * mu[e]
    tr = lam_e * (e11 + e22 + e33)
    s11 = tr + mu2 * e11
    s22 = tr + mu2 * e22
    s33 = tr + mu2 * e33
    s12 = mu2 * e12
    s13 = mu2 * e13
    s23 = mu2 * e23
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
# that unpacks the named tuples once. A function call per element from the prange body costs
# reference counting and struct copies that dominated the step; inlining the element code into
# the prange body itself is not an option (numba 0.68 drops writes through named-tuple attributes
# there).
INTERFACE_BLOCK = 1024
TET_BLOCK = 512


@njit(cache=True)
def _tet_block(lo, hi, dt, nodes, tets, ifs, contact, tools, pressure_now, tool_v_prev, tool_v_next, ctrl):
    """Tets lo..hi-1: bulk forces, gathered interface forces, pressures, tool contact, damping,
    gravity and the central-difference update of each tet's own 4 nodes."""
    x, v, f, mass, contact_area = nodes.x, nodes.v, nodes.force, nodes.mass, nodes.contact_area
    dm_inv, vol, lam, mu = tets.dm_inv, tets.vol, tets.lam, tets.mu
    face_iface, face_side, face_pressure = tets.face_iface, tets.face_side, tets.face_pressure
    na, nb, if_force, if_state = ifs.na, ifs.nb, ifs.force, ifs.state
    tool_of, tool_offset, friction, d_friction = nodes.tool, nodes.tool_offset, nodes.friction, nodes.d_friction
    w_external, w_damping = nodes.w_external, nodes.w_damping
    constraint, constraint_projection = nodes.constraint, nodes.constraint_projection
    node_slot = contact.node_slot
    any_contact = contact.counts[1] > 0
    impulse = tools.impulse
    n_tool = tools.kind.shape[0]
    gx, gy, gz = ctrl.gravity[0], ctrl.gravity[1], ctrl.gravity[2]
    alpha = ctrl.damping[0]
    for e in range(lo, hi):
        _tet_forces(e, x, dm_inv, vol, lam, mu, f)
        n0 = 4 * e
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
                if if_state[iface] == INTACT:
                    continue
            free_faces |= 1 << face

        for k in range(4):
            g = n0 + k
            m = mass[g]
            vx0, vy0, vz0 = v[g, 0], v[g, 1], v[g, 2]
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
                ax, ay, az = twice_area_vector(x, n0 + c0, n0 + c1, n0 + c2)
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
            tool_work = 0.0
            # A node on a free face (any but face k) may touch a tool, with its fixed contact area.
            if free_faces & ~(1 << k):
                tributary = contact_area[g]
                prev = tool_of[g]
                offset = tool_offset[g]
                touching = -1
                for j in range(n_tool):
                    gap, nx, ny, nz = tool_gap(j, x[g, 0], x[g, 1], x[g, 2], tools)
                    if j == prev and offset < 0.0 and gap < 0.0:
                        gap -= offset
                        if gap >= 0.0 and touching < 0:
                            # Woken inside (below), risen above its wake depth but not out yet:
                            # no force, and the offset holds until the node is out.
                            touching = j
                            friction[g, 0] = 0.0
                            friction[g, 1] = 0.0
                            friction[g, 2] = 0.0
                            continue
                    elif prev == HIDDEN and gap < 0.0 and touching < 0:
                        # Exposed by a crack while already inside the tool: its spring starts
                        # unloaded at this depth, so that no energy comes from nowhere.
                        touching = j
                        offset = gap
                        continue
                    if gap >= 0.0:
                        continue
                    kn = tools.penalty[j] * tributary
                    fn = -kn * gap
                    fx = fn * nx
                    fy = fn * ny
                    fz = fn * nz
                    tvx = 0.5 * (tool_v_prev[j, 0] + tool_v_next[j, 0])
                    tvy = 0.5 * (tool_v_prev[j, 1] + tool_v_next[j, 1])
                    tvz = 0.5 * (tool_v_prev[j, 2] + tool_v_next[j, 2])
                    if touching < 0:
                        touching = j
                        # Coulomb friction with a stick spring of the normal stiffness.
                        tx, ty, tz, lost = coulomb_update(
                            friction[g, 0], friction[g, 1], friction[g, 2], nx, ny, nz,
                            vx0 - tvx, vy0 - tvy, vz0 - tvz, dt, kn, tools.mu[j] * fn,
                        )
                        d_friction[g] += lost
                        friction[g, 0] = tx
                        friction[g, 1] = ty
                        friction[g, 2] = tz
                        fx += tx
                        fy += ty
                        fz += tz
                    cx += fx
                    cy += fy
                    cz += fz
                    # Per-tet impulse: the sampled tool force is its mean over the output interval.
                    impulse[j, e, 0] += fx * dt
                    impulse[j, e, 1] += fy * dt
                    impulse[j, e, 2] += fz * dt
                    tool_work += (fx * tvx + fy * tvy + fz * tvz) * dt
                if touching < 0:
                    offset = 0.0
                    friction[g, 0] = 0.0
                    friction[g, 1] = 0.0
                    friction[g, 2] = 0.0
                tool_of[g] = touching
                tool_offset[g] = offset
            # Node-to-surface contact between free surfaces: internal to the specimen.
            if any_contact and node_slot[g] >= 0:
                sx, sy, sz = gathered_contact_force(g, contact)
                f[g, 0] += sx
                f[g, 1] += sy
                f[g, 2] += sz
            # Mass-proportional damping on the previous half-step velocity.
            dx = -alpha * m * vx0
            dy = -alpha * m * vy0
            dz = -alpha * m * vz0
            inv_m = dt / m
            vx = vx0 + (f[g, 0] + ex + cx + dx) * inv_m
            vy = vy0 + (f[g, 1] + ey + cy + dy) * inv_m
            vz = vz0 + (f[g, 2] + ez + cz + dz) * inv_m
            con = constraint[g]
            if con >= 0:
                pr = constraint_projection[con]
                px = pr[0, 0] * vx + pr[0, 1] * vy + pr[0, 2] * vz
                py = pr[1, 0] * vx + pr[1, 1] * vy + pr[1, 2] * vz
                pz = pr[2, 0] * vx + pr[2, 1] * vy + pr[2, 2] * vz
                vx, vy, vz = px, py, pz
            # Work over the step with the mean of the two half-step velocities: the exact discrete
            # counterpart of the kinetic-energy change of the central-difference scheme.
            mx = 0.5 * (vx0 + vx) * dt
            my = 0.5 * (vy0 + vy) * dt
            mz = 0.5 * (vz0 + vz) * dt
            # Only where a force works: the accumulators are a read-write of memory per node.
            if ex != 0.0 or ey != 0.0 or ez != 0.0 or tool_work != 0.0:
                w_external[g] += ex * mx + ey * my + ez * mz + tool_work
            if alpha != 0.0:
                w_damping[g] -= dx * mx + dy * my + dz * mz
            v[g, 0] = vx
            v[g, 1] = vy
            v[g, 2] = vz
        # Positions last: the pressure on a face above used the corners' positions at time t.
        for g in range(n0, n0 + 4):
            x[g, 0] += v[g, 0] * dt
            x[g, 1] += v[g, 1] * dt
            x[g, 2] += v[g, 2] * dt


@njit(parallel=True, cache=True)
def advance(n_steps, t0, dt, nodes, tets, ifs, contact, tools, pressures, ctrl):
    """Run n_steps central-difference steps from time t0; arrays are updated in place."""
    n_if = ifs.na.shape[0]
    n_tet = tets.vol.shape[0]
    n_tool = tools.kind.shape[0]
    n_press = pressures.n.shape[0]
    n_slot = contact.counts[1]
    n_if_blocks = (n_if + INTERFACE_BLOCK - 1) // INTERFACE_BLOCK
    n_tet_blocks = (n_tet + TET_BLOCK - 1) // TET_BLOCK
    pressure_now = np.zeros(max(n_press, 1))
    tool_v_prev = np.zeros((max(n_tool, 1), 3))
    tool_v_next = np.zeros((max(n_tool, 1), 3))
    for step in range(n_steps):
        t = t0 + step * dt
        for q in range(n_press):
            pressure_now[q] = interp_history(t, pressures.times[q], pressures.values[q], pressures.n[q])
        for j in range(n_tool):
            sp = interp_history(t - 0.5 * dt, tools.times[j], tools.speeds[j], tools.n[j])
            sn = interp_history(t + 0.5 * dt, tools.times[j], tools.speeds[j], tools.n[j])
            for d in range(3):
                tool_v_prev[j, d] = sp * tools.direction[j, d]
                tool_v_next[j, d] = sn * tools.direction[j, d]
        for blk in prange(n_if_blocks):
            lo = blk * INTERFACE_BLOCK
            _interface_block(lo, min(lo + INTERFACE_BLOCK, n_if), t, dt, nodes.x, nodes.v, ifs)
        if n_slot > 0:
            for s in prange(n_slot):
                node_contact(s, dt, nodes.x, nodes.v, tets, ifs, contact)
            reaction_lists(contact)
        for blk in prange(n_tet_blocks):
            lo = blk * TET_BLOCK
            _tet_block(lo, min(lo + TET_BLOCK, n_tet), dt, nodes, tets, ifs, contact, tools, pressure_now,
                       tool_v_prev, tool_v_next, ctrl)
        for j in range(n_tool):
            for d in range(3):
                tools.disp[j, d] += tool_v_next[j, d] * dt


@njit(parallel=True, cache=True)
def interface_forces(t, dt, x, v, ifs):
    """The interface pass alone (law and contact forces at positions x): for unit tests of the law
    under prescribed openings, as in a one-element test."""
    n_if = ifs.na.shape[0]
    for blk in prange((n_if + INTERFACE_BLOCK - 1) // INTERFACE_BLOCK):
        lo = blk * INTERFACE_BLOCK
        _interface_block(lo, min(lo + INTERFACE_BLOCK, n_if), t, dt, x, v, ifs)


# ---------------------------------------------------------------------------------------------
# Diagnostics evaluated between chunks (not in the step loop).


@njit(parallel=True, cache=True)
def tet_energy_and_stress(x, tets, energy, stress):
    """Per-tet St Venant-Kirchhoff energy V0 W(E) and Cauchy stress (xx, yy, zz, xy, yz, xz)."""
    for e in prange(tets.vol.shape[0]):
        n0 = 4 * e
        m = tets.dm_inv[e]
        F = np.empty((3, 3))
        for r in range(3):
            a1 = x[n0 + 1, r] - x[n0, r]
            a2 = x[n0 + 2, r] - x[n0, r]
            a3 = x[n0 + 3, r] - x[n0, r]
            for col in range(3):
                F[r, col] = a1 * m[0, col] + a2 * m[1, col] + a3 * m[2, col]
        E = 0.5 * (F.T @ F - np.eye(3))
        lam = tets.lam[e]
        mu = tets.mu[e]
        tr = E[0, 0] + E[1, 1] + E[2, 2]
        energy[e] = tets.vol[e] * (0.5 * lam * tr * tr + mu * np.sum(E * E))
        S = 2.0 * mu * E
        for r in range(3):
            S[r, r] += lam * tr
        J = np.linalg.det(F)
        sig = F @ S @ F.T / J
        stress[e, 0] = sig[0, 0]
        stress[e, 1] = sig[1, 1]
        stress[e, 2] = sig[2, 2]
        stress[e, 3] = sig[0, 1]
        stress[e, 4] = sig[1, 2]
        stress[e, 5] = sig[0, 2]


@njit(parallel=True, cache=True)
def interface_energy(x, ifs, cohesive, contact):
    """Stored energy per interface: cohesive (intact) or contact penalty (failed / pre-crack)."""
    for i in prange(ifs.na.shape[0]):
        law = ifs.law_table[ifs.law[i]]
        nx, ny, nz = _mid_normal(x, ifs.na, ifs.nb, i)
        pn = ifs.pn[i]
        a3 = ifs.area[i] / 3.0
        cohesive[i] = 0.0
        contact[i] = 0.0
        if ifs.state[i] == INTACT and law[LAW_KIND] == KIND_BILINEAR:
            comp = 0.0
            for p in range(3):
                dn, sx, sy, sz = _opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
                if dn < 0.0:
                    comp += 0.5 * pn * dn * dn * a3
            cohesive[i] = comp + (1.0 - ifs.damage[i]) * _bilinear_potential(x, ifs, i, pn, ifs.ps[i], nx, ny, nz)
        elif ifs.state[i] == INTACT:
            z = softening(ifs.damage[i], law[LAW_A], law[LAW_B], law[LAW_CS])
            springs = 0.0
            for p in range(3):
                dn, sx, sy, sz = _opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
                if dn < 0.0:
                    springs += 0.5 * pn * dn * dn * a3
                tx, ty, tz = _cohesive_shear_trial(ifs.slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ifs.ps[i])
                springs += 0.5 * (tx * tx + ty * ty + tz * tz) / ifs.ps[i] * a3
            cohesive[i] = springs + z * _normal_potential(x, ifs, i, nx, ny, nz)
        else:
            reach2 = ifs.reach[i] * ifs.reach[i]
            depth = PASSED_THROUGH * ifs.reach[i]
            for p in range(3):
                dn, sx, sy, sz = _opening(x, ifs.na, ifs.nb, i, p, nx, ny, nz)
                if _pair_touching(dn, sx, sy, sz, reach2, depth):
                    t2 = ifs.traction_t[i, p, 0] ** 2 + ifs.traction_t[i, p, 1] ** 2 + ifs.traction_t[i, p, 2] ** 2
                    contact[i] += (0.5 * pn * dn * dn + 0.5 * t2 / ifs.ps[i]) * a3


@njit(cache=True)
def tool_contact_state(nodes, tets, ifs, tools, forces, energy):
    """Per-tool contact force on the specimen (N) and stored contact energy, at the current state.

    Serial on purpose: a fixed summation order keeps the history bit-identical for any thread
    count, and it runs only at output times.
    """
    forces[:] = 0.0
    energy[:] = 0.0
    n_tool = tools.kind.shape[0]
    if n_tool == 0:
        return
    for e in range(tets.vol.shape[0]):
        n0 = 4 * e
        for k in range(4):
            g = n0 + k
            if nodes.tool[g] == HIDDEN:
                continue
            tributary = nodes.contact_area[g]
            for j in range(n_tool):
                gap, nx, ny, nz = tool_gap(j, nodes.x[g, 0], nodes.x[g, 1], nodes.x[g, 2], tools)
                if j == nodes.tool[g] and gap < 0.0:
                    gap -= nodes.tool_offset[g]
                if gap >= 0.0:
                    continue
                kn = tools.penalty[j] * tributary
                fn = -kn * gap
                forces[j, 0] += fn * nx
                forces[j, 1] += fn * ny
                forces[j, 2] += fn * nz
                energy[j] += 0.5 * kn * gap * gap
                if nodes.tool[g] == j:
                    for d in range(3):
                        forces[j, d] += nodes.friction[g, d]
                    t2 = nodes.friction[g, 0] ** 2 + nodes.friction[g, 1] ** 2 + nodes.friction[g, 2] ** 2
                    energy[j] += 0.5 * t2 / kn

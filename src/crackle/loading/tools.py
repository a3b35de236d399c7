"""Compiled tool pieces every method's step calls: history interpolation, the signed distance of a
point to a rigid tool, and the penalty + Coulomb contact of one node (or particle, or shell node)
against all tools, with its work and its share of the tool's load-cell force; the load cell's
per-step update.

All are numba ``inline="always"`` functions over the arrays of ``loading.arrays.Tools``: a
method's fused step loop calls them directly (a Python callback into a numba kernel would defeat
``cache=True``). The same functions serve the diagnostics between chunks
(`tool_contact_diagnostics`), so the force a history reports is the force the step applied.

A point meets a tool at a contact radius r: 0 for a tet node, the radius of a sphere, half the
thickness of a shell node; its gap is the distance of its centre to the tool surface minus r.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .friction import coulomb_update

# Tool shapes (Tools.kind); TOOL_SUPPORT: a moving support's grip, which touches nothing (the
# integrator drives the support's nodes and puts their reaction in its force slots).
TOOL_PLANE, TOOL_BOX, TOOL_CYLINDER, TOOL_SPHERE, TOOL_SURFACE, TOOL_SUPPORT = 0, 1, 2, 3, 4, 5
# Columns of a surface tool's triangle rows (Tools.surf_tri), in the tool's own frame: corner 0,
# edges e1 = p1 - p0 and e2 = p2 - p0, unit outward normal, the barycentric Gram terms
# e1.e1, e1.e2, e2.e2 and 1 / (e1.e1 e2.e2 - (e1.e2)^2), and the tolerances of the three
# barycentric coordinates (SURF_TRI_TOL: see BARY_TOL).
SURF_TRI_TOL = 16
SURF_TRI_COLUMNS = 19
# Tolerance of a point-over-triangle test: a point over a shared edge or corner stays in contact
# with one of the triangles despite round-off. For FDEM's faces, a fraction of each barycentric
# coordinate; for a surface tool's triangle, a fraction of its shortest altitude h_min, the same
# distance past every edge and every corner (coordinate i's tolerance BARY_TOL x |edge i| / the
# longest edge, on both sides: below 0 and above 1). A relative tolerance on a long sliver, as
# CAD exports a cylinder's side, reaches tenths of a millimetre past its sharp corners, where a
# point in front of the next face (a projectile's nose) took the sliver's plane, behind which it
# lies, for the tool's surface and was thrown out.
BARY_TOL = 0.01
# Per-point tool state (the `node_tool` array): the index of the tool the point touches, NO_TOOL,
# or HIDDEN while the point is inside the body (no tool contact until a crack exposes it).
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
def tool_velocity_rows(tools):
    """The rows tool_velocities fills, one per tool (one at least): each method's step allocates
    them once per call."""
    n = max(tools.kind.shape[0], 1)
    return np.zeros((n, 3)), np.zeros((n, 3))


@njit(cache=True, inline="always")
def tool_velocities(t, dt, tools, v_prev, v_next):
    """Each tool's velocity over the half steps before and after time t (rows of v_prev, v_next).
    A free tool's is its velocity now in both: move_tools sets the one after the step once the
    step's contact force is known."""
    for j in range(tools.kind.shape[0]):
        if tools.mass[j] > 0.0:
            for d in range(3):
                v_prev[j, d] = tools.velocity[j, d]
                v_next[j, d] = tools.velocity[j, d]
            continue
        sp = interp_history(t - 0.5 * dt, tools.times[j], tools.speeds[j], tools.n[j])
        sn = interp_history(t + 0.5 * dt, tools.times[j], tools.speeds[j], tools.n[j])
        for d in range(3):
            v_prev[j, d] = sp * tools.direction[j, d]
            v_next[j, d] = sn * tools.direction[j, d]


@njit(cache=True, inline="always")
def move_tools(dt, tools, v_next):
    """Advance each tool's displacement by one step at its velocity after the step; after
    load_cell_step. A free tool first takes the step's contact force: the specimen pushed on it
    with -step_force, so m (v_after - v_before) = -step_force dt (central difference)."""
    for j in range(tools.kind.shape[0]):
        if tools.mass[j] > 0.0:
            for d in range(3):
                tools.velocity[j, d] -= tools.step_force[j, d] * dt / tools.mass[j]
                v_next[j, d] = tools.velocity[j, d]
        for d in range(3):
            tools.disp[j, d] += v_next[j, d] * dt


@njit(cache=True, inline="always")
def _surface_gap(j, px, py, pz, radius, tools):
    """Gap of a ball (centre p, radius r) to surface tool j and the outward normal, from the
    triangle nearest to it along its normal among those whose projection holds the point and
    that lie less than the contact depth away: negative (in contact) when the centre is less than
    r in front of that triangle or behind it; (inf, 0, 0, 0) when there is none or when the ball
    is clear of it. For a point
    inside the tool this is the least deep penetration; a nearer triangle in front shows that a
    point behind another one's plane is outside the tool (beside it, or over a part of the tool
    thinner than the contact depth).

    The tool only translates, so the point is moved into the tool's frame and looked up in the
    static grid built with the tool arrays (geom row: grid origin, 1 / cell size, contact depth;
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
        # Within the band of every edge's line and of the line through each corner parallel to
        # the opposite edge (beyond a sliver's sharp corner the edges' bands alone reach far).
        t0, t1, t2 = tri[t, SURF_TRI_TOL], tri[t, SURF_TRI_TOL + 1], tri[t, SURF_TRI_TOL + 2]
        if l0 < -t0 or l1 < -t1 or l2 < -t2 or l0 > 1.0 + t0 or l1 > 1.0 + t1 or l2 > 1.0 + t2:
            continue
        nearest = abs(gap)
        best_gap = gap
        bnx, bny, bnz = nx, ny, nz
    if best_gap >= radius:
        return math.inf, 0.0, 0.0, 0.0
    return best_gap - radius, bnx, bny, bnz


@njit(cache=True, inline="always")
def tool_gap(j, px, py, pz, radius, tools):
    """Gap between a ball (centre p, radius r: 0 for a point) and tool j: the signed distance of
    the centre to the tool's surface (negative inside) minus r, and the tool's outward normal
    there (exact on both sides for a radius > 0; a point away from a surface tool gets inf)."""
    kind = tools.kind[j]
    if kind == TOOL_SURFACE:
        return _surface_gap(j, px, py, pz, radius, tools)
    if kind == TOOL_SUPPORT:
        return math.inf, 0.0, 0.0, 0.0
    g = tools.geom[j]
    cx = g[0] + tools.disp[j, 0]
    cy = g[1] + tools.disp[j, 1]
    cz = g[2] + tools.disp[j, 2]
    qx = px - cx
    qy = py - cy
    qz = pz - cz
    if kind == TOOL_PLANE:
        return qx * g[3] + qy * g[4] + qz * g[5] - radius, g[3], g[4], g[5]
    if kind == TOOL_SPHERE:
        d = math.sqrt(qx * qx + qy * qy + qz * qz)
        if d == 0.0:
            return -g[3] - radius, 0.0, 0.0, 1.0
        return d - g[3] - radius, qx / d, qy / d, qz / d
    if kind == TOOL_CYLINDER:
        s = qx * g[3] + qy * g[4] + qz * g[5]
        rx = qx - s * g[3]
        ry = qy - s * g[4]
        rz = qz - s * g[5]
        rho = math.sqrt(rx * rx + ry * ry + rz * rz)
        radial = rho - g[6]
        axial = abs(s) - g[7]
        if max(radial, axial) >= radius:
            # Clear of the ball: a lower bound of the gap is enough.
            return max(radial, axial) - radius, 0.0, 0.0, 0.0
        sg = 1.0 if s >= 0.0 else -1.0
        if rho > 0.0:
            rx /= rho
            ry /= rho
            rz /= rho
        else:
            rx, ry, rz = 1.0, 0.0, 0.0
        if radial > 0.0 and axial > 0.0:
            # Outside, nearest to the rim.
            d = math.sqrt(radial * radial + axial * axial)
            return (d - radius, (radial * rx + axial * sg * g[3]) / d, (radial * ry + axial * sg * g[4]) / d,
                    (radial * rz + axial * sg * g[5]) / d)
        # Inside (leave through the nearer of the mantle and the end), or outside beside one of them.
        if radial >= axial:
            return radial - radius, rx, ry, rz
        return axial - radius, sg * g[3], sg * g[4], sg * g[5]
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
    o_max = max(o1, max(o2, o3))
    if o_max >= radius:
        # Clear of the ball whatever the nearest point: a lower bound of the gap is enough.
        return o_max - radius, 0.0, 0.0, 0.0
    s1 = 1.0 if q1 >= 0.0 else -1.0
    s2 = 1.0 if q2 >= 0.0 else -1.0
    s3 = 1.0 if q3 >= 0.0 else -1.0
    w1 = max(o1, 0.0)
    w2 = max(o2, 0.0)
    w3 = max(o3, 0.0)
    d = math.sqrt(w1 * w1 + w2 * w2 + w3 * w3)
    if d > 0.0:
        # Outside: towards the nearest point of the box (a face, an edge or a corner).
        nx = (w1 * s1 * e1x + w2 * s2 * e2x + w3 * s3 * e3x) / d
        ny = (w1 * s1 * e1y + w2 * s2 * e2y + w3 * s3 * e3y) / d
        nz = (w1 * s1 * e1z + w2 * s2 * e2z + w3 * s3 * e3z) / d
        return d - radius, nx, ny, nz
    # Inside or on the surface: leave through the nearest face.
    if o1 >= o2 and o1 >= o3:
        return o1 - radius, s1 * e1x, s1 * e1y, s1 * e1z
    if o2 >= o3:
        return o2 - radius, s2 * e2x, s2 * e2y, s2 * e2z
    return o3 - radius, s3 * e3x, s3 * e3y, s3 * e3z


@njit(cache=True, inline="always")
def _glued_tie(g, vx, vy, vz, area, dt, slot, tools, force_slots, tool_v_prev, tool_v_next, j, tie):
    """Point g glued to tool j: a 3D spring of the tool's penalty (per its contact area) on the
    point's displacement relative to the tool since it attached, carried incrementally in tie[g]
    (the friction slot: a glued point has no Coulomb friction). It pulls as well as pushes and
    never slips. v is the point's velocity over the half step before t, over which the tool moved
    at tool_v_prev: the tie follows the relative displacement exactly. Returns the force on the
    point and the tool's work on it over the step, as contact_with_tools."""
    kn = tools.penalty[j] * area
    tx = tie[g, 0] - kn * (vx - tool_v_prev[j, 0]) * dt
    ty = tie[g, 1] - kn * (vy - tool_v_prev[j, 1]) * dt
    tz = tie[g, 2] - kn * (vz - tool_v_prev[j, 2]) * dt
    tie[g, 0] = tx
    tie[g, 1] = ty
    tie[g, 2] = tz
    force_slots[j, slot, 0] += tx
    force_slots[j, slot, 1] += ty
    force_slots[j, slot, 2] += tz
    work = 0.0
    if tools.mass[j] == 0.0:
        tvx = 0.5 * (tool_v_prev[j, 0] + tool_v_next[j, 0])
        tvy = 0.5 * (tool_v_prev[j, 1] + tool_v_next[j, 1])
        tvz = 0.5 * (tool_v_prev[j, 2] + tool_v_next[j, 2])
        work = (tx * tvx + ty * tvy + tz * tvz) * dt
    return tx, ty, tz, work


@njit(cache=True, inline="always")
def contact_radius(body, g):
    """Point g's contact radius: body.radius holds one per point, or one for all."""
    return body.radius[g] if body.radius.shape[0] > 1 else body.radius[0]


@njit(cache=True)
def seat_points(tools, seated, body):
    """Seat the points of `body` (solver.body.Body's fields) that lie inside a seated tool (index
    in `seated`) at set-up: each starts in that tool's contact state woken at its present depth
    (body.tool_offset = its gap < 0), so that it carries no force until the tool pushes it deeper
    (contact_with_tools), as a platen seated on a packing that overlaps it. Points already in a
    tool's contact, or HIDDEN inside a body, are left as they are."""
    x, node_tool, node_offset = body.x, body.tool, body.tool_offset
    for g in range(x.shape[0]):
        if node_tool[g] != NO_TOOL:
            continue
        r = contact_radius(body, g)
        for j in seated:
            gap, _, _, _ = tool_gap(j, x[g, 0], x[g, 1], x[g, 2], r, tools)
            if gap < 0.0:
                node_tool[g] = j
                node_offset[g] = gap
                break


@njit(cache=True, inline="always")
def contact_with_tools(g, body, dt, slot, tools, tool_v_prev, tool_v_next, row=-1):
    """Penalty contact of point g of `body` (solver.body.Body's fields: position at time t,
    velocity over the half step before t, contact radius and area) against every tool; returns
    the total force on the point and the work the driven tools did on it over the step (free
    tools: free_tool_work). The point's position and velocity are read at `row` when it is given
    (an FDEM node copy in a tied cluster: its leader's row, fdem.extrinsic.state_row), at g
    otherwise.

    The penalty per point is the tool's penalty (N/m^3) times `area`. Only the first tool touched
    carries Coulomb friction, with a stick spring of the normal stiffness; its tangential force
    lives in friction[g] and the dissipation goes to d_friction[g]. Each tool's force adds to
    force_slots[tool, slot] (tools.force_slots; one slot per parallel block, so that blocks never
    write the same entry), which `load_cell_step` sums and clears after every step.

    body.tool[g] and body.tool_offset[g] carry the point's contact state between steps (see NO_TOOL,
    HIDDEN): a point exposed (HIDDEN before) while already inside a tool starts its spring
    unloaded at that depth (node_offset < 0), so that no energy comes from nowhere, and gets no
    force until it is pushed deeper or has left the tool.

    A glued tool (tools.glue[j] > 0, the attach distance) takes a point that comes within that
    distance of it (touching no other tool) and holds it from then on by `_glued_tie`: a gripped
    end that pulls as well as pushes (direct tension)."""
    node_tool, node_offset, friction = body.tool, body.tool_offset, body.friction
    force_slots = tools.force_slots
    at = g if row < 0 else row
    vx, vy, vz = body.v[at, 0], body.v[at, 1], body.v[at, 2]
    area = body.area[g]
    prev = node_tool[g]
    if prev >= 0 and tools.glue[prev] > 0.0:
        return _glued_tie(g, vx, vy, vz, area, dt, slot, tools, force_slots, tool_v_prev, tool_v_next, prev, friction)
    px, py, pz = body.x[at, 0], body.x[at, 1], body.x[at, 2]
    radius = contact_radius(body, g)
    cx = 0.0
    cy = 0.0
    cz = 0.0
    work = 0.0
    offset = node_offset[g]
    touching = -1
    for j in range(tools.kind.shape[0]):
        gap, nx, ny, nz = tool_gap(j, px, py, pz, radius, tools)
        if tools.glue[j] > 0.0 and gap <= tools.glue[j] and touching < 0 and prev != HIDDEN:
            # Attached to a glued tool from now on, its tie unloaded at the current position.
            touching = j
            friction[g, :] = 0.0
            break
        if j == prev and offset < 0.0 and gap < 0.0:
            gap -= offset
            if gap >= 0.0 and touching < 0:
                # Woken inside (below), risen above its wake depth but not out yet: no force,
                # and the offset holds until the point is out.
                touching = j
                friction[g, :] = 0.0
                continue
        elif prev == HIDDEN and gap < 0.0 and touching < 0:
            touching = j
            offset = gap
            continue
        if gap >= 0.0:
            continue
        kn = tools.penalty[j] * area
        fn = -kn * gap
        fx = fn * nx
        fy = fn * ny
        fz = fn * nz
        tvx = 0.5 * (tool_v_prev[j, 0] + tool_v_next[j, 0])
        tvy = 0.5 * (tool_v_prev[j, 1] + tool_v_next[j, 1])
        tvz = 0.5 * (tool_v_prev[j, 2] + tool_v_next[j, 2])
        if touching < 0:
            touching = j
            tx, ty, tz, lost = coulomb_update(
                friction[g, 0], friction[g, 1], friction[g, 2], nx, ny, nz,
                vx - tvx, vy - tvy, vz - tvz, dt, kn, tools.mu[j] * fn,
            )
            body.d_friction[g] += lost
            friction[g, 0] = tx
            friction[g, 1] = ty
            friction[g, 2] = tz
            fx += tx
            fy += ty
            fz += tz
        cx += fx
        cy += fy
        cz += fz
        force_slots[j, slot, 0] += fx
        force_slots[j, slot, 1] += fy
        force_slots[j, slot, 2] += fz
        if tools.mass[j] == 0.0:
            # A free tool's work is its loss of kinetic energy (loading.arrays.free_tool_work):
            # its velocity after this step is not known yet.
            work += (fx * tvx + fy * tvy + fz * tvz) * dt
    if touching < 0 or tools.glue[touching] > 0.0:
        offset = 0.0
    if touching < 0:
        friction[g, 0] = 0.0
        friction[g, 1] = 0.0
        friction[g, 2] = 0.0
    node_tool[g] = touching
    node_offset[g] = offset
    return cx, cy, cz, work


@njit(cache=True)
def load_cell_step(time, tools):
    """The load cell, after every step ending at `time`: the step's force of each tool (its
    force_slots summed in slot order, then cleared) enters a ring of the recent steps; the cell
    reads the mean over the last `window` steps (tools.cell_count = [steps seen, window]) and
    keeps the largest magnitude of that mean and its time (tools.cell_state[j] = moving sum x, y,
    z, peak, peak time); the step's force also goes to tools.step_force (move_tools). Serial, in
    a fixed order: the same with any thread count."""
    slots, ring, state = tools.force_slots, tools.cell_ring, tools.cell_state
    count, window = tools.cell_count[0], tools.cell_count[1]
    pos = count % window
    n_mean = min(count + 1, window)
    for j in range(slots.shape[0]):
        for a in range(3):
            f = 0.0
            for b in range(slots.shape[1]):
                f += slots[j, b, a]
                slots[j, b, a] = 0.0
            tools.step_force[j, a] = f
            # The running sum drops the force that leaves the window (0 while the ring fills);
            # re-summed exactly once per turn of the ring so that rounding cannot build up.
            state[j, a] += f - ring[j, pos, a]
            ring[j, pos, a] = f
            if pos == window - 1:
                total = 0.0
                for i in range(window):
                    total += ring[j, i, a]
                state[j, a] = total
        mean = math.sqrt(state[j, 0] ** 2 + state[j, 1] ** 2 + state[j, 2] ** 2) / n_mean
        if mean > state[j, 3]:
            state[j, 3] = mean
            state[j, 4] = time
    tools.cell_count[0] = count + 1


@njit(cache=True, inline="always")
def tool_contact_diagnostics(g, body, tools, forces, energy):
    """Add point g's contact force on each tool (forces[j], N) and the energy stored in its
    springs (energy[j], J) at its current position and contact state: the springs of
    `contact_with_tools` after its last step. Sum points in a fixed order (histories then do not
    depend on the thread count)."""
    node_tool, node_offset, friction = body.tool, body.tool_offset, body.friction
    if node_tool[g] == HIDDEN:
        return
    area = body.area[g]
    j = node_tool[g]
    if j >= 0 and tools.glue[j] > 0.0:
        kn = tools.penalty[j] * area
        for d in range(3):
            forces[j, d] += friction[g, d]
        energy[j] += 0.5 * (friction[g, 0] ** 2 + friction[g, 1] ** 2 + friction[g, 2] ** 2) / kn
        return
    radius = contact_radius(body, g)
    for j in range(tools.kind.shape[0]):
        gap, nx, ny, nz = tool_gap(j, body.x[g, 0], body.x[g, 1], body.x[g, 2], radius, tools)
        if j == node_tool[g] and gap < 0.0:
            gap -= node_offset[g]
        if gap >= 0.0:
            continue
        kn = tools.penalty[j] * area
        fn = -kn * gap
        forces[j, 0] += fn * nx
        forces[j, 1] += fn * ny
        forces[j, 2] += fn * nz
        energy[j] += 0.5 * kn * gap * gap
        if node_tool[g] == j:
            for d in range(3):
                forces[j, d] += friction[g, d]
            t2 = friction[g, 0] ** 2 + friction[g, 1] ** 2 + friction[g, 2] ** 2
            energy[j] += 0.5 * t2 / kn


# Points per block of tool_contact_totals: the blocks are fixed, whatever the thread count, and
# their partial sums are added in block order, so the totals do not depend on the threads.
TOTALS_BLOCK = 2048


@njit(parallel=True, cache=True)
def tool_contact_totals(body, tools, forces, energy):
    """Per-tool contact force on the specimen (forces, N) and stored contact energy (energy, J)
    at the current state of `body` (solver.body.Body's fields), over all its points. Runs at
    output times only."""
    forces[:] = 0.0
    energy[:] = 0.0
    n_tools = tools.kind.shape[0]
    if n_tools == 0:
        return
    n = body.x.shape[0]
    n_blocks = (n + TOTALS_BLOCK - 1) // TOTALS_BLOCK
    part_forces = np.zeros((n_blocks, n_tools, 3))
    part_energy = np.zeros((n_blocks, n_tools))
    for blk in prange(n_blocks):
        block_forces = part_forces[blk]
        block_energy = part_energy[blk]
        for g in range(blk * TOTALS_BLOCK, min(n, (blk + 1) * TOTALS_BLOCK)):
            tool_contact_diagnostics(g, body, tools, block_forces, block_energy)
    for blk in range(n_blocks):
        for j in range(n_tools):
            energy[j] += part_energy[blk, j]
            for d in range(3):
                forces[j, d] += part_forces[blk, j, d]

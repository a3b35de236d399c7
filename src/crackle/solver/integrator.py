"""The central-difference update of one node (or particle, or shell node) that every method's
fused step calls: damping, supports and the work accounting, as numba ``inline="always"``
functions, plus the support table they read (built once from loading.Support selections).

Scheme: v(t + dt/2) = v(t - dt/2) + dt F(t) / m, x(t + dt) = x(t) + dt v(t + dt/2). Work over the
step is counted with the mean of the two half-step velocities, the exact discrete counterpart of
the change of kinetic energy of this scheme; potentials evaluated at x - v dt/2 (the mid-step
positions) then close the energy audit to second order in dt.
"""

from __future__ import annotations

import numpy as np
from numba import config, njit

from ..loading.tools import contact_with_tools

# The serial block functions that a method's parallel loop calls once per block of elements
# (particles, nodes), and that call the inline pieces below, are compiled without numba's
# reference counting (NRT). With it, every array handed to an inline function gets an atomic
# reference count per call wherever the array is used only inside a branch (numba's pruning
# misses that case), and with 2 or more threads those atomics fight over the arrays' shared
# counters: measured a quarter of the FDEM step at 2 threads. Such a block cannot allocate
# arrays (numba refuses to compile one that tries); allocate in the caller.
block_kernel = njit(cache=True, _nrt=False)
# The same, with a * b + c allowed to be one fused multiply-add (one rounding instead of two;
# the machine's FMA unit where it has one): for a block whose time is its arithmetic's chain of
# dependent operations (measured at 100k: the DEM's interaction pass 9.4 -> 8.2 ms, the meshfree
# step 60 -> 48 ms). Still the same operations in the same order for every element, so results
# stay thread-count independent.
FUSED_MATH = {"contract"}  # numba fastmath flags: fusion only, nothing reassociated
fused_block_kernel = njit(cache=True, _nrt=False, fastmath=FUSED_MATH)


def slp_vectorised(dispatcher):
    """A numba function compiled with LLVM's SLP vectoriser, which packs independent, identical
    scalar operations into one vector operation (four multiply-adds into one): each lane does the
    same arithmetic as alone, so the results are the scalar code's. numba leaves it off (LLVM
    11-14 miscompiled some code with it, numba PR 8852); the kernel that is written for it turns it
    on for its own compilation only: the meshfree gradient pass, 1.25 x faster at 100k particles
    with it (docs/validation.md, issue 68), where the DEM's step was 6 % slower. numba reads the
    setting while it optimises a function, and compiles both on a first call and as a callee
    through `compile`."""
    compile_scalar = dispatcher.compile

    def compile_vectorised(sig):
        before = config.SLP_VECTORIZE
        config.SLP_VECTORIZE = 1
        try:
            return compile_scalar(sig)
        finally:
            config.SLP_VECTORIZE = before

    dispatcher.compile = compile_vectorised
    return dispatcher

# In the kernels' inner loops over CSR rows and neighbour lists, the row counter and the neighbour
# index are cast to uint64 (`for r in range(uint64(start[i]), uint64(start[i + 1]))`,
# `j = uint64(neighbour[r])`): numba gives a signed index Python's negative-index wraparound, a
# compare-and-select per array access that also costs registers (spills in the meshfree gather);
# unsigned, it drops them. Same loads, same arithmetic, bit-identical results. Measured at 100k
# (alternated): the meshfree gather 22.4 -> 18.8 ms, its step +11 %, the DEM step +7 %; the FDEM
# passes (node numbers cast in interface.py and the tet's corners) got 5-10 % slower, so they keep
# signed ones. Only for indices that are never negative (not -1 sentinels).

# constraint[node]: FREE, or the node's row of the support table (row FIXED = 0: no motion).
# Per row: projection[row], the velocity projector P (3, 3) of the supports that hold the node
# (they block the directions I - P), and support_tool[row], the index in the Tools arrays of the
# grip that drives the blocked directions (a support with a speed: loading.build.build_loading
# makes it a tool of shape "support", so that the load cell reads its reaction like a tool's
# force), or -1 where they hold still.
FREE, FIXED = -1, 0


@njit(cache=True, inline="always")
def update_velocity(g, body, f, e, c, tool_work, m, alpha, dt, tools, tool_v_next, slot):
    """New half-step velocity of node g into body.v[g] and the node's work accounting (body:
    solver.body.Body's fields).

    f: the method's internal forces (elements, bonds, cohesive and self-contact); e: external
    forces that work on the node's own motion (pressure, gravity); c: tool contact forces, whose
    work `tool_work` the tool contact counted itself (at the tool's velocity); each a tuple
    (x, y, z). m: the mass moved (the node's, or a tied cluster's on its leader); alpha: the
    mass-proportional damping coefficient (force -alpha m v on the previous half-step velocity).
    The supports project the new velocity (body.constraint[g], see support_constraints); a support
    with a speed sets the blocked components to its grip's velocity tool_v_next[j] and adds its
    reaction to tools.force_slots[j, slot] (the grip's load cell, see contact_with_tools). Work of
    e, of the tools and of a moving support goes to body.w_external[g], the damping's loss to
    body.w_damping[g]; the accumulators are only touched where a force works (each touch is a
    read-write of memory)."""
    v = body.v
    damping = (-alpha * m * v[g, 0], -alpha * m * v[g, 1], -alpha * m * v[g, 2])
    _step_velocity(g, body, f, e, c, damping, alpha != 0.0, tool_work, m, dt, tools, tool_v_next, slot)


@njit(cache=True, inline="always")
def step_point(g, body, f, e, m, alpha, dt, kick, slot, tools, tool_v_prev, tool_v_next):
    """One point's step after its forces: the tool contact (loading.tools.contact_with_tools),
    the new velocity from the internal forces f and external ones e (update_velocity, over
    `kick`: dt, or the meshfree's first half kick) and the move over dt."""
    cx, cy, cz, tool_work = contact_with_tools(g, body, dt, slot, tools, tool_v_prev, tool_v_next)
    update_velocity(g, body, f, e, (cx, cy, cz), tool_work, m, alpha, kick, tools, tool_v_next, slot)
    move(g, body.x, body.v, dt)


@njit(cache=True, inline="always")
def local_damping_force(f, v, m, alpha, dt):
    """One component of the local non-viscous damping force (Cundall's; paper 003 eq. 5): alpha
    times the unbalanced force f, against the motion v + f dt / (2 m) the force is causing."""
    power = f * (v + 0.5 * dt * f / m)
    return -alpha * f if power > 0.0 else (alpha * f if power < 0.0 else 0.0)


@njit(cache=True, inline="always")
def update_velocity_local_damping(g, body, f, e, c, tool_work, m, alpha, dt, tools, tool_v_next, slot):
    """update_velocity with local non-viscous damping instead of the mass-proportional one:
    `alpha` (0 to 1) scales the unbalanced force of each component (local_damping_force)."""
    v = body.v
    damping = (local_damping_force(f[0] + e[0] + c[0], v[g, 0], m, alpha, dt),
               local_damping_force(f[1] + e[1] + c[1], v[g, 1], m, alpha, dt),
               local_damping_force(f[2] + e[2] + c[2], v[g, 2], m, alpha, dt))
    _step_velocity(g, body, f, e, c, damping, alpha != 0.0, tool_work, m, dt, tools, tool_v_next, slot)


@njit(cache=True, inline="always")
def _step_velocity(g, body, f, e, c, d, damped, tool_work, m, dt, tools, tool_v_next, slot):
    """v[g] += dt (f + e + c + d) / m, projected by the supports (the blocked part set to a moving
    support's velocity), with the work of e, the tools and a moving support into w_external[g] and
    that of the damping force d into w_damping[g] (at the mean of the two half-step velocities)."""
    v = body.v
    fx, fy, fz = f
    ex, ey, ez = e
    cx, cy, cz = c
    dx, dy, dz = d
    vx0, vy0, vz0 = v[g, 0], v[g, 1], v[g, 2]
    inv_m = dt / m
    vx = vx0 + (fx + ex + cx + dx) * inv_m
    vy = vy0 + (fy + ey + cy + dy) * inv_m
    vz = vz0 + (fz + ez + cz + dz) * inv_m
    con = body.constraint[g]
    rx = 0.0
    ry = 0.0
    rz = 0.0
    driven = False
    if con >= 0:
        pr = body.projection[con]
        px = pr[0, 0] * vx + pr[0, 1] * vy + pr[0, 2] * vz
        py = pr[1, 0] * vx + pr[1, 1] * vy + pr[1, 2] * vz
        pz = pr[2, 0] * vx + pr[2, 1] * vy + pr[2, 2] * vz
        j = body.support_tool[con]
        if j >= 0:
            # The blocked part follows the grip: v = P v* + (I - P) u; the support's reaction
            # m (v - v*) / dt is the grip's force on the specimen.
            driven = True
            ux, uy, uz = tool_v_next[j, 0], tool_v_next[j, 1], tool_v_next[j, 2]
            px += ux - (pr[0, 0] * ux + pr[0, 1] * uy + pr[0, 2] * uz)
            py += uy - (pr[1, 0] * ux + pr[1, 1] * uy + pr[1, 2] * uz)
            pz += uz - (pr[2, 0] * ux + pr[2, 1] * uy + pr[2, 2] * uz)
            rx = (px - vx) * m / dt
            ry = (py - vy) * m / dt
            rz = (pz - vz) * m / dt
            force_slots = tools.force_slots
            force_slots[j, slot, 0] += rx
            force_slots[j, slot, 1] += ry
            force_slots[j, slot, 2] += rz
        vx, vy, vz = px, py, pz
    mx = 0.5 * (vx0 + vx) * dt
    my = 0.5 * (vy0 + vy) * dt
    mz = 0.5 * (vz0 + vz) * dt
    if ex != 0.0 or ey != 0.0 or ez != 0.0 or tool_work != 0.0 or driven:
        body.w_external[g] += ex * mx + ey * my + ez * mz + tool_work + rx * mx + ry * my + rz * mz
    if damped:
        body.w_damping[g] -= dx * mx + dy * my + dz * mz
    v[g, 0] = vx
    v[g, 1] = vy
    v[g, 2] = vz


@njit(cache=True, inline="always")
def move(g, x, v, dt):
    """x(t + dt) = x(t) + dt v(t + dt/2) for node g."""
    x[g, 0] += v[g, 0] * dt
    x[g, 1] += v[g, 1] * dt
    x[g, 2] += v[g, 2] * dt


def support_constraints(supports, points: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point, the velocity projection of all the supports that hold it and the grip that
    drives it, if one does: (constraint (n,) int16, projection (k, 3, 3), support_tool (k,)
    int64), what update_velocity applies.
    `scale` (the specimen size) sets the default selection tolerance. A point held by two moving
    supports is an error (which one would it follow?)."""
    normals_of = {}
    grip_of = {}
    for k, sup in enumerate(supports):
        sel = sup.where.mask(points, scale)
        if not sel.any():
            raise ValueError(f"supports.{k}: the {sup.kind} support selects no node: check its plane or box")
        if sup.kind in ("fixed", "clamped"):  # a shell also holds a clamped edge's rotation (shell.model)
            blocked = np.eye(3)
        elif sup.kind == "roller":
            blocked = np.asarray(sup.normal, float)[None, :]
        else:
            raise ValueError(f"support kind must be 'fixed', 'clamped' or 'roller', not {sup.kind!r}")
        for node in np.flatnonzero(sel):
            normals_of.setdefault(int(node), []).append(blocked)
            if sup.tool >= 0:
                if grip_of.setdefault(int(node), sup.tool) != sup.tool:
                    raise ValueError(f"two moving supports select the node at {points[node].tolist()}: "
                                     "make their selections apart")
    constraint = np.full(len(points), FREE, dtype=np.int16)
    projections = [np.zeros((3, 3))]  # FIXED
    tools = [-1]
    known = {(projections[0].round(12).tobytes(), -1): FIXED}
    for node, blocks in normals_of.items():
        proj = _velocity_projection(np.concatenate(blocks))
        key = (proj.round(12).tobytes(), grip_of.get(node, -1))
        if key not in known:
            known[key] = len(projections)
            projections.append(proj)
            tools.append(key[1])
        constraint[node] = known[key]
    return constraint, np.array(projections), np.array(tools, dtype=np.int64)


def _velocity_projection(blocked: np.ndarray) -> np.ndarray:
    """Projector removing the velocity components along the blocked directions (rows)."""
    basis = []
    for n in blocked:
        w = n / np.linalg.norm(n)
        for b in basis:
            w = w - np.dot(w, b) * b
        if np.linalg.norm(w) > 1e-9:
            basis.append(w / np.linalg.norm(w))
    proj = np.eye(3)
    for b in basis:
        proj -= np.outer(b, b)
    return proj

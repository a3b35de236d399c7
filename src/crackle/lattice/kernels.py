"""The compiled step of the lattice: a pass over springs, then a pass over nodes that gathers
their forces and calls the shared tool contact (loading.tools) and node update
(solver.integrator). No races: each spring writes its own force row, each node reads the rows of
its springs in a fixed order (node_spring CSR)."""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..loading.tools import load_cell_step, move_tools, tool_velocities, tool_velocity_rows
from ..solver.failures import MODE_TENSION
from ..solver.body import Body
from ..solver.integrator import block_kernel, step_point

Nodes = Body  # the lattice's nodes need nothing beyond the shared per-node arrays
Springs = namedtuple("Springs", "a b rest k intact fail_time fail_mode e_damage force node_start node_spring node_sign")


@njit(cache=True, inline="always")
def _spring_length(x, a, b):
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    return dx, dy, dz, math.sqrt(dx * dx + dy * dy + dz * dz)


BLOCK = 256  # springs or nodes per parallel task


@block_kernel
def _spring_block(lo, hi, t, dt, x, v, springs, break_strain):
    """Spring forces on their b node (a gets the negative); a spring stretched beyond
    break_strain breaks and releases its energy at the mid-step positions x - v dt/2 (the
    audit's positions)."""
    a_of, b_of, rest, k, intact, force = springs.a, springs.b, springs.rest, springs.k, springs.intact, springs.force
    for s in range(lo, hi):
        force[s, 0] = 0.0
        force[s, 1] = 0.0
        force[s, 2] = 0.0
        if not intact[s]:
            continue
        a = a_of[s]
        b = b_of[s]
        dx, dy, dz, length = _spring_length(x, a, b)
        stretch = length - rest[s]
        if stretch > break_strain * rest[s]:
            intact[s] = False
            springs.fail_time[s] = t
            springs.fail_mode[s] = MODE_TENSION
            mx = dx - 0.5 * dt * (v[b, 0] - v[a, 0])
            my = dy - 0.5 * dt * (v[b, 1] - v[a, 1])
            mz = dz - 0.5 * dt * (v[b, 2] - v[a, 2])
            mid = math.sqrt(mx * mx + my * my + mz * mz) - rest[s]
            springs.e_damage[s] += 0.5 * k[s] * mid * mid
            continue
        scale = -k[s] * stretch / length
        force[s, 0] = scale * dx
        force[s, 1] = scale * dy
        force[s, 2] = scale * dz


@block_kernel
def _node_block(lo, hi, slot, dt, nodes, springs, tools, tool_v_prev, tool_v_next, gravity, alpha):
    mass = nodes.mass
    start, node_spring, node_sign, force = springs.node_start, springs.node_spring, springs.node_sign, springs.force
    for g in range(lo, hi):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for r in range(start[g], start[g + 1]):
            s = node_spring[r]
            sign = node_sign[r]
            fx += sign * force[s, 0]
            fy += sign * force[s, 1]
            fz += sign * force[s, 2]
        m = mass[g]
        step_point(g, nodes, (fx, fy, fz), (m * gravity[0], m * gravity[1], m * gravity[2]), m, alpha, dt, dt, slot,
                   tools, tool_v_prev, tool_v_next)


@njit(parallel=True, cache=True)
def advance(n_steps, first_step, dt, nodes, springs, tools, break_strain, gravity, alpha):
    """n_steps central-difference steps from step number first_step (time first_step x dt, the
    same however a run is split into calls); arrays updated in place."""
    n_spring = springs.a.shape[0]
    n_node = nodes.x.shape[0]
    tool_v_prev, tool_v_next = tool_velocity_rows(tools)
    for step in range(n_steps):
        t = (first_step + step) * dt
        tool_velocities(t, dt, tools, tool_v_prev, tool_v_next)
        for blk in prange((n_spring + BLOCK - 1) // BLOCK):
            lo = blk * BLOCK
            _spring_block(lo, min(lo + BLOCK, n_spring), t, dt, nodes.x, nodes.v, springs, break_strain)
        for blk in prange((n_node + BLOCK - 1) // BLOCK):
            lo = blk * BLOCK
            _node_block(lo, min(lo + BLOCK, n_node), np.int64(blk), dt, nodes, springs, tools, tool_v_prev, tool_v_next,
                        gravity, alpha)
        load_cell_step((first_step + step + 1) * dt, tools)
        move_tools(dt, tools, tool_v_next)

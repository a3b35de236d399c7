"""The loading descriptions (tools, histories) turned into the flat arrays that the compiled step
of any method reads (see loading.tools)."""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..schema import ScenarioError
from .tools import (BARY_TOL, SURF_TRI_COLUMNS, SURF_TRI_TOL, TOOL_BOX, TOOL_CYLINDER, TOOL_PLANE, TOOL_SPHERE,
                    TOOL_SUPPORT, TOOL_SURFACE, seat_points)

# Piecewise-linear histories padded into tables, one row each (history_tables): the one layout of
# every method's pressure histories (FDEM's and the shell's pressures, the last three fields of
# the meshfree wall pressures).
HistoryTable = namedtuple("HistoryTable", "times values counts")
Tools = namedtuple(
    "Tools",
    "kind geom disp direction times speeds n mu penalty force_slots cell_ring cell_state cell_count "
    "surf_grid surf_cell_start surf_cell_tris surf_tri mass velocity step_force glue",
)
# kind, geom (12 numbers, see Tool.geometry_row), disp (current displacement), direction (unit),
# times / speeds / n (the speed history table), mu (Coulomb), penalty (N/m^3 per unit contact
# area), force_slots (tool, slot, 3): the step's contact force on the tool, one slot per block of
# points that a parallel pass owns; the load cell (see loading.tools.load_cell_step and
# loading.loadcell): cell_ring (tool, LOAD_CELL_RING, 3) the forces of the recent steps,
# cell_state (tool, 5) the moving sum over the window, the peak of its mean and the peak's time,
# cell_count [steps seen, window in steps].
# Surface tools (shape "surface"), all of them concatenated: surf_tri (k, SURF_TRI_COLUMNS)
# triangle rows in each tool's own frame; per tool a uniform grid over the triangles' boxes
# inflated by the contact depth, in CSR form: surf_grid[j] = (cells along x, y, z, first entry
# of tool j in surf_cell_start); surf_cell_start[first + c] .. [first + c + 1] delimits cell c's
# triangles (rows of surf_tri) in surf_cell_tris. Built once: the tools only translate.
# Free tools (a projectile): mass (tool,) in kg, 0 for a driven tool; velocity (tool, 3) a free
# tool's velocity over the last half step (its launch velocity before the first); step_force
# (tool, 3) the last step's contact force on the specimen, which load_cell_step writes and
# move_tools turns into the free tool's change of velocity.
# glue (tool,): 0, or the distance within which a glued tool attaches a point for good.

# Default tool penalty per unit contact area: TOOL_PENALTY_FACTOR x E / h, h the method's length
# scale (FDEM: the median tet altitude; lattice: the spacing), the usual explicit-contact order.
TOOL_PENALTY_FACTOR = 10.0


def default_tool_penalty(youngs_modulus: float, length: float) -> float:
    """Pa/m, a tool's penalty per unit contact area when the scenario gives none: TOOL_PENALTY_FACTOR
    x E / h, h the method's length scale (FDEM: the median tet altitude; meshfree and shell: the
    smallest particle step or element size; lattice: the spacing)."""
    return TOOL_PENALTY_FACTOR * youngs_modulus / length

# The longest load-cell window, in steps (the ring holds that many steps per tool).
LOAD_CELL_RING = 4096

SHAPE_CODES = {
    "plane": TOOL_PLANE,
    "box": TOOL_BOX,
    "cylinder": TOOL_CYLINDER,
    "sphere": TOOL_SPHERE,
    "surface": TOOL_SURFACE,
    "support": TOOL_SUPPORT,
}


def tool_arrays(tools, default_penalty: float, contact_depth: float, force_slots: int) -> Tools:
    """Arrays of `tools` (a list of loading.Tool). A tool without its own penalty gets
    `default_penalty`; a point further than `contact_depth` behind (or, with a contact radius, in
    front of) a surface tool's triangle is not its contact (keeps the far side of a thin tool
    apart; make it at least the largest contact radius); `force_slots` is the number of parallel
    blocks that write tool forces (one slot each). The load cell starts with a one-step window
    (loading.loadcell.LoadCell.set_window sets it)."""
    kind = np.array([SHAPE_CODES[t.shape] for t in tools], dtype=np.int64)
    geom = np.array([t.geometry_row() for t in tools]).reshape(len(tools), 12)
    direction = np.array([np.asarray(t.direction, float) / np.linalg.norm(t.direction) for t in tools]).reshape(-1, 3)
    times, speeds, counts = history_tables([t.speed for t in tools])
    mu = np.array([t.friction for t in tools], dtype=float)
    # A support's grip touches nothing: no penalty (none for the stable step to heed).
    penalty = np.array([0.0 if t.shape == "support" else t.penalty if t.penalty is not None else default_penalty
                        for t in tools], dtype=float)
    surf = _surface_tool_grids(tools, geom, contact_depth)
    mass = np.array([t.mass or 0.0 for t in tools], dtype=float)
    # A glued tool attaches the points within this distance (default: a millionth of the contact
    # depth, an element's size: the points a touching tool rests on, within round-off).
    glue = np.array([(t.glue_depth or 1e-6 * contact_depth) if t.glued else 0.0 for t in tools], dtype=float)
    launch = (speeds[:, 0:1] * direction) * (mass[:, None] > 0.0)
    return Tools(
        kind, geom, np.zeros((len(tools), 3)), direction, times, speeds, counts, mu, penalty,
        force_slots=np.zeros((len(tools), force_slots, 3)), cell_ring=np.zeros((len(tools), LOAD_CELL_RING, 3)),
        cell_state=np.zeros((len(tools), 5)), cell_count=np.array([0, 1], dtype=np.int64), **surf,
        mass=mass, velocity=launch.reshape(-1, 3), step_force=np.zeros((len(tools), 3)), glue=glue,
    )


# The words of the set-up note for points inside a tool that does not seat them (the driver's
# advice when energy appears from nowhere looks for them).
STARTS_INSIDE = "start inside it"
# A tool (not seated) that starts deeper in the specimen than this fraction of the specimen's
# extent is a set-up mistake, not a contact: its penalty would throw the points out at once.
DEEP_START = 0.05


def seat_on_tools(tools, table: Tools, body, what: str = "points") -> list[str]:
    """Seat the points of `body` (solver.body.Body's fields) inside the tools that ask `seat`
    (loading.tools.seat_points); returns the set-up notes: how many were seated, and for a tool
    that does not ask it, how many points it pushes from step 0."""
    x, node_tool, node_offset = body.x, body.tool, body.tool_offset
    notes = []
    # Overlaps within round-off of the positions (a touching tool) are not worth a note.
    tolerance = 1e-9 * float(np.max(np.ptp(x, axis=0))) if len(x) else 0.0
    for j, tool in enumerate(tools):
        if tool.shape == "support":
            continue
        trial_tool, trial_offset = node_tool.copy(), node_offset.copy()
        seat_points(table, np.array([j], dtype=np.int64), body._replace(tool=trial_tool, tool_offset=trial_offset))
        inside = int(np.count_nonzero((trial_tool != node_tool) & (trial_offset < -tolerance)))
        if not inside:
            continue
        if tool.seat:
            node_tool[:], node_offset[:] = trial_tool, trial_offset
            notes.append(f"tool {tool.name}: {inside} {what} inside it at set-up start unloaded there (seat = true)")
        else:
            deepest = float(-np.min(trial_offset[trial_tool != node_tool]))
            extent = float(np.max(np.ptp(x, axis=0)))
            if deepest > DEEP_START * extent:
                raise ScenarioError(
                    f"tools: tool {tool.name} starts {deepest:.3g} m deep in the specimen ({deepest / extent:.0%} of its "
                    f"{extent:.3g} m; {inside} {what} inside it): a specimen in other units than the tools (a mesh "
                    "file in mm: specimen.scale = 1e-3) or a tool off its place; place it on the surface (touch = true)"
                )
            notes.append(f"tool {tool.name}: {inside} {what} {STARTS_INSIDE} (up to {deepest:.3g} m deep) and are "
                         "pushed out from the first step; set seat = true on it to start them unloaded")
    return notes


def free_tool_work(tools: Tools) -> float:
    """The work (J) the free tools have done on the specimen so far: the kinetic energy they lost.
    Exact for the central-difference update of move_tools (each step m dv = -F dt, so the loss
    is F . (v_before + v_after) / 2 dt, the work the contact force took from the tool)."""
    launch = tools.speeds[:, 0:1] * tools.direction
    lost = 0.5 * tools.mass * (np.einsum("ij,ij->i", launch, launch) - np.einsum("ij,ij->i", tools.velocity, tools.velocity))
    return float(np.sum(lost))


def _surface_tool_grids(tools, geom: np.ndarray, depth: float) -> dict:
    """Triangle rows and static contact grids of the surface tools (see `Tools`); fills each
    surface tool's geom row with its grid origin, 1 / cell size, contact depth and the surface's
    area centroid (geom[5:8]: on a projectile's axis, the impact axis of a perforation)."""
    grids = np.zeros((len(tools), 4), dtype=np.int64)
    starts = [np.zeros(1, dtype=np.int64)]
    cell_tris = []
    rows = []
    n_tri = 0
    n_entries = 0
    for j, tool in enumerate(tools):
        if tool.shape != "surface":
            continue
        v, t = tool.vertices, tool.triangles
        p0, p1, p2 = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        e1, e2 = p1 - p0, p2 - p0
        normal = np.cross(e1, e2)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        d00 = np.einsum("ij,ij->i", e1, e1)
        d01 = np.einsum("ij,ij->i", e1, e2)
        d11 = np.einsum("ij,ij->i", e2, e2)
        row = np.empty((len(t), SURF_TRI_COLUMNS))
        row[:, 0:3], row[:, 3:6], row[:, 6:9], row[:, 9:12] = p0, e1, e2, normal
        row[:, 12], row[:, 13], row[:, 14] = d00, d01, d11
        row[:, 15] = 1.0 / (d00 * d11 - d01 * d01)
        edges = np.stack([np.linalg.norm(p2 - p1, axis=1), np.sqrt(d11), np.sqrt(d00)], axis=1)  # opposite 0, 1, 2
        row[:, SURF_TRI_TOL:SURF_TRI_TOL + 3] = BARY_TOL * edges / edges.max(axis=1, keepdims=True)
        rows.append(row)

        # Boxes of the triangles widened by the barycentric tolerance, then by the depth.
        lo = np.minimum(np.minimum(p0, p1), p2)
        hi = np.maximum(np.maximum(p0, p1), p2)
        size = hi - lo
        pad = depth + 2.0 * BARY_TOL * size.max(axis=1, keepdims=True)
        lo, hi = lo - pad, hi + pad
        origin = lo.min(axis=0)
        span = hi.max(axis=0) - origin
        # Cell: the median triangle size (or the depth), grown until the grid and its entries
        # stay within a few times the triangle count.
        cell = max(float(np.median(size.max(axis=1))), depth)
        while True:
            dims = np.maximum(np.ceil(span / cell).astype(np.int64), 1)
            i_lo = np.clip(np.floor((lo - origin) / cell).astype(np.int64), 0, dims - 1)
            i_hi = np.clip(np.floor((hi - origin) / cell).astype(np.int64), 0, dims - 1)
            count = np.prod(i_hi - i_lo + 1, axis=1)
            if np.prod(dims) <= 8 * len(t) + 4096 and count.sum() <= 32 * len(t) + 4096:
                break
            cell *= 1.5
        # Every (triangle, cell) pair, triangles ascending within a cell: a fixed candidate order.
        tri_of = np.repeat(np.arange(len(t)), count)
        local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        ext = (i_hi - i_lo + 1)[tri_of]
        k = i_lo[tri_of, 2] + local % ext[:, 2]
        rest = local // ext[:, 2]
        jj = i_lo[tri_of, 1] + rest % ext[:, 1]
        ii = i_lo[tri_of, 0] + rest // ext[:, 1]
        cell_id = (ii * dims[1] + jj) * dims[2] + k
        order = np.argsort(cell_id, kind="stable")
        per_cell = np.bincount(cell_id, minlength=int(np.prod(dims)))
        grids[j, 0:3] = dims
        grids[j, 3] = sum(len(a) for a in starts) - 1
        starts.append(n_entries + np.cumsum(per_cell))
        cell_tris.append(n_tri + tri_of[order])
        n_tri += len(t)
        n_entries += len(order)
        geom[j, 0:3] = origin
        geom[j, 3] = 1.0 / cell
        geom[j, 4] = depth
        area = np.linalg.norm(np.cross(e1, e2), axis=1)
        geom[j, 5:8] = area @ ((p0 + p1 + p2) / 3.0) / area.sum()
    return {
        "surf_grid": grids,
        "surf_cell_start": np.concatenate(starts),
        "surf_cell_tris": np.concatenate(cell_tris) if cell_tris else np.zeros(0, dtype=np.int64),
        "surf_tri": np.concatenate(rows) if rows else np.zeros((0, SURF_TRI_COLUMNS)),
    }


def history_tables(histories) -> HistoryTable:
    """Piecewise-linear histories padded into (k, n) time and value tables plus point counts
    (what loading.tools.interp_history reads)."""
    k = len(histories)
    n = max((len(h.times) for h in histories), default=1)
    times = np.zeros((k, n))
    values = np.zeros((k, n))
    counts = np.zeros(k, dtype=np.int64)
    for i, h in enumerate(histories):
        c = len(h.times)
        times[i, :c] = h.times
        values[i, :c] = h.values
        times[i, c:] = h.times[-1]
        values[i, c:] = h.values[-1]
        counts[i] = c
    return HistoryTable(times, values, counts)

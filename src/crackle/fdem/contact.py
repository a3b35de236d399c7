"""Contact between free surfaces: fragments against fragments, fracture faces, self-contact.

Surface triangles are the tet faces without an intact interface (the outer boundary, failed
interfaces and pre-cracks); surface nodes are their corners. Every surface node is tested
against the surface triangles near it (node-to-triangle penalty, Coulomb friction with a stick
history), which covers both directions of every pair of surfaces.

Broad phase (`rebuild`, serial, between chunks): triangles are binned in a hashed uniform grid
whose cell is the largest inflated triangle box (the NBS idea of Munjiza and Andrews: cost linear
in the number of triangles); each surface node keeps the triangles whose box, inflated by a skin,
holds it. The list stays valid while no node has moved more than half the skin; the driver
rebuilds it when that could happen and when the surface has changed (new failures).

Narrow phase (`contact_forces`, parallel over surface nodes, every step): among its candidates
a node picks the triangle it penetrates least deeply (inside the triangle's projection, within a
depth limit of half the tet's height). The node gets the penalty and friction force; the
triangle's three corners get the opposite force split by barycentric weights. Those reactions
are gathered per node through a list rebuilt each step in a fixed serial order
(`reaction_lists`), so that results do not depend on the thread count and momentum is conserved
exactly.

Exclusions: a node never contacts the faces of its own tet, nor triangles with a corner on the
same mesh point (neighbours across intact interfaces, where the interface itself acts), nor the
partner face of its own failed interface while the pair is still within reach (the interface's
paired contact acts there: one mechanism per pair of points).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..loading.friction import coulomb_update
from ..loading.tools import BARY_TOL
from .extrinsic import state_row
from .topology import FACE_CORNERS, INTACT, cross, edge_vectors, face_corners, twice_area_vector

# Depth, as a fraction of the half tet height, beyond which a new contact starts unloaded.
WAKE_DEPTH = 0.02

Contact = namedtuple(
    "Contact",
    "counts tri_nodes tri_iface tri_tet tri_depth slot_node node_slot slot_area cand_start cand_tri "
    "contact_tri contact_w contact_f contact_gap contact_offset tangential react_start react_src react_k "
    "penalty tet_mu corner_point d_friction",
)
# counts: [n_triangles, n_slots, n_candidates, n_reactions]; penalty: [p] (N/m^3 of contact
# area); tet_mu: friction coefficient per tet; corner_point: mesh point of each exploded node;
# d_friction: per exploded node, friction dissipation of node-to-surface contact (J).
# Arrays indexed by slot or triangle are sized to the current surface and rebuilt with it.


def build_contact(model, previous: "Contact | None" = None) -> Contact:
    """Surface triangles and nodes of the current interface states, with empty candidate lists.

    Friction histories and dissipation carry over from `previous` node by node."""
    tets, ifs = model.tets, model.ifs
    m = len(tets.vol)
    iface = tets.face_iface
    is_surface = iface < 0
    is_surface |= (iface >= 0) & (ifs.state[np.where(iface >= 0, iface, 0)] != INTACT)
    tri_tet, tri_face = np.nonzero(is_surface)
    corners = FACE_CORNERS[tri_face]
    tri_nodes = 4 * tri_tet[:, None] + corners
    n_tri = len(tri_tet)
    slot_node = np.unique(tri_nodes)
    n_slot = len(slot_node)
    node_slot = np.full(4 * m, -1, dtype=np.int32)
    node_slot[slot_node] = np.arange(n_slot, dtype=np.int32)
    area = tets.face_area[tri_tet, tri_face]
    slot_area = model.nodes.area[slot_node]
    tangential = np.zeros((n_slot, 3))
    d_friction = np.zeros(4 * m)
    if previous is not None:
        old = previous.node_slot[slot_node]
        keep = old >= 0
        tangential[keep] = previous.tangential[old[keep]]
        d_friction = previous.d_friction
    return Contact(
        counts=np.array([n_tri, n_slot, 0, 0], dtype=np.int64),
        tri_nodes=tri_nodes.astype(np.int64),
        tri_iface=iface[tri_tet, tri_face].astype(np.int64),
        tri_tet=tri_tet.astype(np.int64),
        tri_depth=0.5 * 3.0 * tets.vol[tri_tet] / area,
        slot_node=slot_node.astype(np.int64),
        node_slot=node_slot,
        slot_area=slot_area,
        cand_start=np.zeros(n_slot + 1, dtype=np.int64),
        cand_tri=np.zeros(0, dtype=np.int64),
        contact_tri=np.full(n_slot, -1, dtype=np.int64),
        contact_w=np.zeros((n_slot, 3)),
        contact_f=np.zeros((n_slot, 3)),
        contact_gap=np.zeros(n_slot),
        contact_offset=np.zeros(n_slot),
        tangential=tangential,
        react_start=np.zeros(n_slot + 1, dtype=np.int64),
        react_src=np.zeros(3 * n_slot, dtype=np.int64),
        react_k=np.zeros(3 * n_slot, dtype=np.int64),
        penalty=np.array([model.contact_penalty]),
        tet_mu=model.tet_friction,
        corner_point=model.corner_point,
        d_friction=d_friction,
    )


def find_candidates(x, c: Contact, skin: float) -> Contact:
    """Broad phase into a fresh candidate list (count, allocate, fill)."""
    total = candidates(x, c, skin, np.zeros(0, dtype=np.int64))
    cand = np.zeros(max(total, 1), dtype=np.int64)
    candidates(x, c, skin, cand)
    return c._replace(cand_tri=cand)


def empty_contact(n_nodes: int, penalty: float = 0.0) -> Contact:
    """Contact switched off: no surface slots (the kernels then skip it)."""
    z = np.zeros(0)
    zi = np.zeros(0, dtype=np.int64)
    return Contact(
        counts=np.zeros(4, dtype=np.int64), tri_nodes=np.zeros((0, 3), dtype=np.int64), tri_iface=zi,
        tri_tet=zi, tri_depth=z, slot_node=zi, node_slot=np.full(n_nodes, -1, dtype=np.int32),
        slot_area=z, cand_start=np.zeros(1, dtype=np.int64), cand_tri=zi, contact_tri=zi,
        contact_w=np.zeros((0, 3)), contact_f=np.zeros((0, 3)), contact_gap=z, contact_offset=z, tangential=np.zeros((0, 3)),
        react_start=np.zeros(1, dtype=np.int64), react_src=zi, react_k=zi, penalty=np.array([penalty]),
        tet_mu=z, corner_point=zi, d_friction=np.zeros(n_nodes),
    )


@njit(cache=True)
def _cell_of(px, py, pz, lo, inv):
    return int(math.floor((px - lo[0]) * inv)), int(math.floor((py - lo[1]) * inv)), int(math.floor((pz - lo[2]) * inv))


@njit(cache=True)
def _key(ix, iy, iz):
    # Hash of a cell index; collisions only add candidates that the box test then rejects.
    return ((ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791)) & ((1 << 40) - 1)


@njit(cache=True)
def candidates(x, c, skin, out):
    """Broad phase: per surface node, the triangles whose box inflated by skin + depth holds it.

    With an empty `out` only counts (returns the total); otherwise writes the CSR list into
    c.cand_start and `out`."""
    fill = out.shape[0] > 0
    corner_point = c.corner_point
    n_tri = c.counts[0]
    n_slot = c.counts[1]
    if n_tri == 0:
        c.cand_start[: n_slot + 1] = 0
        return 0
    lo = np.empty(3)
    for d in range(3):
        lo[d] = np.inf
    box_lo = np.empty((n_tri, 3))
    box_hi = np.empty((n_tri, 3))
    size = 0.0
    for t in range(n_tri):
        pad = skin + c.tri_depth[t]
        for d in range(3):
            a = x[c.tri_nodes[t, 0], d]
            b = x[c.tri_nodes[t, 1], d]
            q = x[c.tri_nodes[t, 2], d]
            box_lo[t, d] = min(a, min(b, q)) - pad
            box_hi[t, d] = max(a, max(b, q)) + pad
            size = max(size, box_hi[t, d] - box_lo[t, d])
            lo[d] = min(lo[d], box_lo[t, d])
    inv = 1.0 / size
    # Each inflated box spans at most 2 cells per axis: up to 8 (key, triangle) entries.
    keys = np.empty(8 * n_tri, dtype=np.int64)
    tris = np.empty(8 * n_tri, dtype=np.int64)
    n_entry = 0
    for t in range(n_tri):
        ax, ay, az = _cell_of(box_lo[t, 0], box_lo[t, 1], box_lo[t, 2], lo, inv)
        bx, by, bz = _cell_of(box_hi[t, 0], box_hi[t, 1], box_hi[t, 2], lo, inv)
        for ix in range(ax, bx + 1):
            for iy in range(ay, by + 1):
                for iz in range(az, bz + 1):
                    keys[n_entry] = _key(ix, iy, iz)
                    tris[n_entry] = t
                    n_entry += 1
    order = np.argsort(keys[:n_entry], kind="mergesort")
    sorted_keys = keys[:n_entry][order]
    sorted_tris = tris[:n_entry][order]
    total = 0
    for s in range(n_slot):
        g = c.slot_node[s]
        if fill:
            c.cand_start[s] = total
        px, py, pz = x[g, 0], x[g, 1], x[g, 2]
        ix, iy, iz = _cell_of(px, py, pz, lo, inv)
        key = _key(ix, iy, iz)
        j = np.searchsorted(sorted_keys, key)
        e = g // 4
        while j < n_entry and sorted_keys[j] == key:
            t = sorted_tris[j]
            j += 1
            if c.tri_tet[t] == e:
                continue
            if not (box_lo[t, 0] <= px <= box_hi[t, 0] and box_lo[t, 1] <= py <= box_hi[t, 1] and box_lo[t, 2] <= pz <= box_hi[t, 2]):
                continue
            p = corner_point[g]
            if corner_point[c.tri_nodes[t, 0]] == p or corner_point[c.tri_nodes[t, 1]] == p or corner_point[c.tri_nodes[t, 2]] == p:
                continue
            if fill:
                out[total] = t
            total += 1
    if fill:
        c.cand_start[n_slot] = total
    c.counts[2] = total
    return total


@njit(cache=True, inline="always")
def _paired_and_near(g, t, x, ifs, c, leader):
    """True if triangle t is the partner face of node g's failed interface and the pair is still
    within reach (the interface's own paired contact then acts)."""
    i = c.tri_iface[t]
    if i < 0:
        return False
    for p in range(3):
        partner = -1
        if ifs.na[i, p] == g:
            partner = ifs.nb[i, p]
        elif ifs.nb[i, p] == g:
            partner = ifs.na[i, p]
        if partner >= 0:
            rg = state_row(g, leader)
            rp = state_row(partner, leader)
            dx = x[rg, 0] - x[rp, 0]
            dy = x[rg, 1] - x[rp, 1]
            dz = x[rg, 2] - x[rp, 2]
            return dx * dx + dy * dy + dz * dz <= ifs.reach[i] * ifs.reach[i]
    return False


@njit(cache=True, inline="always")
def _node_normal(g, x, tets, ifs, leader):
    """Outward normal (not normalised) of node g's own surface: the sum of the area vectors of
    its tet's surface faces that contain it."""
    e = g // 4
    k = g - 4 * e
    nx = 0.0
    ny = 0.0
    nz = 0.0
    for f in range(4):
        if f == k:
            continue
        i = tets.face_iface[e, f]
        if i >= 0 and ifs.state[i] == INTACT:
            continue
        c0, c1, c2 = face_corners(f)
        ax, ay, az = twice_area_vector(x, state_row(4 * e + c0, leader), state_row(4 * e + c1, leader),
                                       state_row(4 * e + c2, leader))
        nx += ax
        ny += ay
        nz += az
    return nx, ny, nz


@njit(parallel=True, cache=True)
def contact_forces(dt, x, v, tets, ifs, c):
    """Narrow phase and forces for every surface node, then the reaction lists (tests use this;
    the step loop calls node_contact itself)."""
    no_clusters = np.zeros(0, dtype=np.int64)
    for s in prange(c.counts[1]):
        node_contact(np.int64(s), dt, x, v, tets, ifs, c, no_clusters)
    reaction_lists(c)


@njit(cache=True)
def node_contact(s, dt, x, v, tets, ifs, c, leader):
    """Narrow phase and force for surface slot s: one contact per node, the least penetrated
    triangle it lies over. Positions and velocities are read at the nodes' state rows (`leader`:
    Ties.leader, see fdem.extrinsic.state_row)."""
    pen = c.penalty[0]
    g = c.slot_node[s]
    rg = state_row(g, leader)
    # Only surfaces that face each other (normals more than 120 degrees apart) touch: this keeps
    # a node from being caught by a face at right angles to the one it crossed.
    mx, my, mz = _node_normal(g, x, tets, ifs, leader)
    m_len = math.sqrt(mx * mx + my * my + mz * mz)
    best = -1
    best_gap = -np.inf
    bw0 = 0.0
    bw1 = 0.0
    bnx = 0.0
    bny = 0.0
    bnz = 0.0
    for j in range(c.cand_start[s], c.cand_start[s + 1]):
        t = c.cand_tri[j]
        a = state_row(c.tri_nodes[t, 0], leader)
        b = state_row(c.tri_nodes[t, 1], leader)
        q = state_row(c.tri_nodes[t, 2], leader)
        ux, uy, uz, wx, wy, wz = edge_vectors(x, a, b, q)
        nx, ny, nz = cross(ux, uy, uz, wx, wy, wz)
        nn = math.sqrt(nx * nx + ny * ny + nz * nz)
        if nn == 0.0:
            continue
        nx /= nn
        ny /= nn
        nz /= nn
        rx = x[rg, 0] - x[a, 0]
        ry = x[rg, 1] - x[a, 1]
        rz = x[rg, 2] - x[a, 2]
        gap = rx * nx + ry * ny + rz * nz
        if gap >= 0.0 or gap < -c.tri_depth[t] or gap <= best_gap:
            continue
        if mx * nx + my * ny + mz * nz >= -0.5 * m_len:
            continue
        # Barycentric coordinates of the projection.
        d00 = ux * ux + uy * uy + uz * uz
        d01 = ux * wx + uy * wy + uz * wz
        d11 = wx * wx + wy * wy + wz * wz
        d20 = rx * ux + ry * uy + rz * uz
        d21 = rx * wx + ry * wy + rz * wz
        den = d00 * d11 - d01 * d01
        l1 = (d11 * d20 - d01 * d21) / den
        l2 = (d00 * d21 - d01 * d20) / den
        l0 = 1.0 - l1 - l2
        # A small tolerance keeps a node lying on an edge or a corner of the other surface in
        # contact: without it round-off lets such a node slip between triangles and wake up deep.
        if l0 < -BARY_TOL or l1 < -BARY_TOL or l2 < -BARY_TOL:
            continue
        # The force acts at the nearest point of the triangle.
        l0 = min(max(l0, 0.0), 1.0)
        l1 = min(max(l1, 0.0), 1.0 - l0)
        l2 = 1.0 - l0 - l1
        if _paired_and_near(g, t, x, ifs, c, leader):
            continue
        best = t
        best_gap = gap
        bw0 = l0
        bw1 = l1
        bnx, bny, bnz = nx, ny, nz
    was_active = c.contact_tri[s] >= 0
    c.contact_tri[s] = best
    if best < 0:
        c.contact_offset[s] = 0.0
        c.contact_f[s, 0] = 0.0
        c.contact_f[s, 1] = 0.0
        c.contact_f[s, 2] = 0.0
        c.contact_gap[s] = 0.0
        c.tangential[s, 0] = 0.0
        c.tangential[s, 1] = 0.0
        c.tangential[s, 2] = 0.0
        return
    bw2 = 1.0 - bw0 - bw1
    c.contact_w[s, 0] = bw0
    c.contact_w[s, 1] = bw1
    c.contact_w[s, 2] = bw2
    # A node that wakes up already deep (it slipped in past an edge the broad or narrow phase
    # did not catch) would get a spring loaded with energy nobody paid for: it starts from its
    # current depth instead, and only further penetration pushes back.
    if not was_active:
        c.contact_offset[s] = best_gap if best_gap < -WAKE_DEPTH * c.tri_depth[best] else 0.0
    gap = min(best_gap - c.contact_offset[s], 0.0)
    c.contact_gap[s] = gap
    k = pen * c.slot_area[s]
    fn = -k * gap
    a = state_row(c.tri_nodes[best, 0], leader)
    b = state_row(c.tri_nodes[best, 1], leader)
    q = state_row(c.tri_nodes[best, 2], leader)
    # Slip velocity of the node relative to the triangle's material point under it.
    mu = 0.5 * (c.tet_mu[g // 4] + c.tet_mu[c.tri_tet[best]])
    tx, ty, tz, lost = coulomb_update(
        c.tangential[s, 0], c.tangential[s, 1], c.tangential[s, 2], bnx, bny, bnz,
        v[rg, 0] - (bw0 * v[a, 0] + bw1 * v[b, 0] + bw2 * v[q, 0]),
        v[rg, 1] - (bw0 * v[a, 1] + bw1 * v[b, 1] + bw2 * v[q, 1]),
        v[rg, 2] - (bw0 * v[a, 2] + bw1 * v[b, 2] + bw2 * v[q, 2]),
        dt, k, mu * fn,
    )
    c.d_friction[g] += lost
    c.tangential[s, 0] = tx
    c.tangential[s, 1] = ty
    c.tangential[s, 2] = tz
    c.contact_f[s, 0] = fn * bnx + tx
    c.contact_f[s, 1] = fn * bny + ty
    c.contact_f[s, 2] = fn * bnz + tz


@njit(cache=True)
def reaction_lists(c):
    """Per surface slot, the (source slot, corner) pairs whose reaction it receives (serial)."""
    n_slot = c.counts[1]
    for s in range(n_slot + 1):
        c.react_start[s] = 0
    for s in range(n_slot):
        t = c.contact_tri[s]
        if t >= 0:
            for k in range(3):
                c.react_start[c.node_slot[c.tri_nodes[t, k]] + 1] += 1
    for s in range(n_slot):
        c.react_start[s + 1] += c.react_start[s]
    fill = c.react_start[:n_slot].copy()
    for s in range(n_slot):
        t = c.contact_tri[s]
        if t >= 0:
            for k in range(3):
                r = c.node_slot[c.tri_nodes[t, k]]
                c.react_src[fill[r]] = s
                c.react_k[fill[r]] = k
                fill[r] += 1
    c.counts[3] = c.react_start[n_slot]


@njit(cache=True, inline="always")
def gathered_contact_force(g, c):
    """Node g's contact force: its own plus its share of the reactions of nodes on its faces."""
    s = c.node_slot[g]
    if s < 0 or c.counts[1] == 0:
        return 0.0, 0.0, 0.0
    fx = c.contact_f[s, 0]
    fy = c.contact_f[s, 1]
    fz = c.contact_f[s, 2]
    for r in range(c.react_start[s], c.react_start[s + 1]):
        q = c.react_src[r]
        w = c.contact_w[q, c.react_k[r]]
        fx -= w * c.contact_f[q, 0]
        fy -= w * c.contact_f[q, 1]
        fz -= w * c.contact_f[q, 2]
    return fx, fy, fz


def contact_energy(c: Contact) -> float:
    """Energy stored in the active node-to-surface penalty springs (normal and stick)."""
    n = int(c.counts[1])
    active = c.contact_tri[:n] >= 0
    if not active.any():
        return 0.0
    k = c.penalty[0] * c.slot_area[:n][active]
    gap = c.contact_gap[:n][active]
    t2 = np.einsum("ij,ij->i", c.tangential[:n][active], c.tangential[:n][active])
    return float(np.sum(0.5 * k * gap * gap + 0.5 * t2 / k))

"""Extrinsic (adaptive) interfaces: a face joins its two tets rigidly until the traction of their
stresses reaches the law's strength; it is then inserted at the law's peak.

While a face is tied, the coincident copies of each of its 3 mesh points move as one node: the
copies of a mesh point that tied faces join form a *cluster*, which sums its members' masses and
forces and gives them one velocity. Clusters only split (a face is inserted, never re-tied), so
cracks open where the inserted faces separate a mesh point's tets into groups, as in the node
splitting of Camacho & Ortiz (1996) and Pandolfi & Ortiz (2002).

Insertion: the interface pass checks each tied face against the Kirchhoff stress of its two
tets from the previous step (tau = J sigma, J = 1 within the strains of a brittle solid) on the
face's current normal: by default the traction of each tet, the more critical one deciding (an
intrinsic face's corners feel the more loaded side: with the two tets' mean instead, the quick
Brazilian disc peaks 39 % above its intrinsic twin, docs/validation.md "Strength objectivity");
Guo-Munjiza opens at Mohr-Coulomb with tension cut-off, the bilinear law at its initiation
criterion (maximum nominal stress). The inserted face's law state
is set so that its traction equals that traction, clamped on the strength envelope: the opening
is shifted (dn_shift) and the shear spring preloaded (slip_plastic), so the traction is
continuous in time (Papoulia, Sam & Vavasis 2003) and the face follows the softening branch from
there: the work done on it from insertion to complete separation is the law's fracture energy.
A face inserted under compression gets no normal shift (compression is the penalty's, never
softened: the pair then carries it from zero gap, as it will once failed).

Energy: insertion moves nothing, so it creates nothing; the law's springs, counted from their
unloaded state, then hold the preload's t^2 / 2p per unit area (4 ft^2 / (3 pn) for a
Guo-Munjiza face inserted in tension), which is booked at once as negative dissipation, so that
energy.damage is the work done on the faces since their insertion. A face that unloads from its
preload returns that energy to the body (an artefact of the finite penalty after insertion):
it shows as negative dissipation, bounded by e_inserted (summary.json: insertion_energy).

Every step stays deterministic for any thread count: insertions are decided per face from the
previous step's stresses, the clusters of the touched mesh points are regrouped serially, and
the node pass runs over mesh points (each owns its copies).

Within kernels.advance a cluster's motion lives on its leader's row of x and v only: every
reader in the step reads a node's state at `state_row` (the interfaces through na_at / nb_at),
so the node pass writes one row per cluster instead of one per copy (about 20 copies a mesh
point: the copies' scattered writes were half the node pass at 50k tets). The copies are given
their leader's state where a cluster splits and when advance returns, so that everything outside
the step (outputs, audits, the contact broad phase) reads every copy.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..solver.integrator import block_kernel, move, update_velocity
from .laws import inserted_preload, insertion_reached, insertion_utilisation, intact_energy
from .laws.row import LAW_SAMPLING, SAMPLE_MEAN

# tied[i]: a face joining its tets rigidly, one released in this step (its clusters still to be
# regrouped), or one carrying its law (intrinsic, inserted, failed, pre-cracked).
FREE, TIED, RELEASED = 0, 1, 2

Ties = namedtuple(
    "Ties",
    "tied vertex_ptr vertex_nodes member_leader node_vertex partner partner_iface leader na_at nb_at tet_stress load",
)
# leader: each node's cluster leader (itself when free), the row of x and v that holds its state
# within a step; na_at / nb_at: ifs.na / ifs.nb through leader, for the interface pass. Without
# tied faces leader is empty and na_at / nb_at are ifs.na / ifs.nb themselves.

# Columns of ties.load, the one record per node that the tet pass writes for the node pass: the
# force (internal and the tools' contact: the integrator only sums them), the external force
# (pressure, gravity: its work is booked at the node's motion), the tools' work, and the node's
# mass. One 64-byte row per node, not five arrays: the node pass gathers the copies of a mesh
# point from scattered nodes, one cache line each (docs/validation.md).
LOAD_FORCE, LOAD_EXTERNAL, LOAD_TOOL_WORK, LOAD_MASS = 0, 3, 6, 7
LOAD_COLUMNS = 8

# Mesh points per block of the node pass.
VERTEX_BLOCK = 1024


def build_ties(corner_point: np.ndarray, n_points: int, na: np.ndarray, nb: np.ndarray, tied: np.ndarray,
               n_tets: int) -> Ties:
    """The cluster tables of an exploded mesh whose faces `tied` start tied (uint8 per interface);
    with none tied, empty tables (the step then takes the intrinsic path)."""
    n_nodes = len(corner_point)
    if not tied.any():
        empty_i = np.zeros(0, dtype=np.int64)
        return Ties(tied, np.zeros(1, dtype=np.int64), empty_i, empty_i, empty_i, np.zeros((0, 3), np.int64),
                    np.zeros((0, 3), np.int64), empty_i, na, nb, np.zeros((0, 6)), np.zeros((0, LOAD_COLUMNS)))
    order = np.lexsort((np.arange(n_nodes), corner_point))
    vertex_ptr = np.zeros(n_points + 1, dtype=np.int64)
    np.add.at(vertex_ptr, corner_point + 1, 1)
    vertex_ptr = np.cumsum(vertex_ptr)
    # The other copy across each of a node's (up to 3) faces, and that face's interface.
    partner = np.full((n_nodes, 3), -1, dtype=np.int64)
    partner_iface = np.full((n_nodes, 3), -1, dtype=np.int64)
    filled = np.zeros(n_nodes, dtype=np.int64)
    ids = np.repeat(np.arange(len(na)), 3)
    for own, other in ((na.reshape(-1), nb.reshape(-1)), (nb.reshape(-1), na.reshape(-1))):
        for node, mate, iface in zip(own, other, ids):
            partner[node, filled[node]] = mate
            partner_iface[node, filled[node]] = iface
            filled[node] += 1
    ties = Ties(
        tied=tied,
        vertex_ptr=vertex_ptr,
        vertex_nodes=order.astype(np.int64),
        member_leader=np.full(n_nodes, -1, dtype=np.int64),
        node_vertex=corner_point.astype(np.int64),
        partner=partner,
        partner_iface=partner_iface,
        leader=np.arange(n_nodes, dtype=np.int64),
        na_at=na.copy(),
        nb_at=nb.copy(),
        tet_stress=np.zeros((n_tets, 6)),
        load=np.zeros((n_nodes, LOAD_COLUMNS)),
    )
    regroup_all(ties, na, nb)
    return ties


@njit(cache=True, inline="always")
def state_row(g, leader):
    """The row of x and v that holds node g's motion within a step: its cluster's leader's (g
    itself when it is free or nothing is tied, `leader` then empty)."""
    return leader[g] if leader.shape[0] > 0 else g


@njit(cache=True)
def regroup_all(ties, na, nb):
    for vertex in range(ties.vertex_ptr.shape[0] - 1):
        regroup(vertex, ties, na, nb)


@njit(cache=True)
def regroup(vertex, ties, na, nb):
    """Clusters of the copies of one mesh point: connected through tied faces; each copy's leader
    is the lowest node of its cluster, and the copies are kept sorted by (leader, node) so that a
    cluster is a contiguous run of vertex_nodes (member_leader: the leader of each entry, read in
    order by the node pass). The interface points of the copies (na, nb) read their leader's row
    from then on (na_at, nb_at)."""
    _new_leaders(vertex, ties)
    _apply_leaders(vertex, ties, na, nb)


@njit(cache=True)
def _new_leaders(vertex, ties):
    """regroup's first half: each copy's new leader into ties.leader (member_leader keeps the old
    ones, in the old order of vertex_nodes)."""
    lo, hi = ties.vertex_ptr[vertex], ties.vertex_ptr[vertex + 1]
    nodes, leader, tied = ties.vertex_nodes, ties.leader, ties.tied
    for j in range(lo, hi):
        leader[nodes[j]] = nodes[j]
    changed = True
    while changed:
        changed = False
        for j in range(lo, hi):
            g = nodes[j]
            for k in range(3):
                q = ties.partner[g, k]
                if q < 0 or tied[ties.partner_iface[g, k]] != TIED:
                    continue
                low = min(leader[g], leader[q])
                if leader[g] != low or leader[q] != low:
                    leader[g] = low
                    leader[q] = low
                    changed = True


@njit(cache=True)
def _apply_leaders(vertex, ties, na, nb):
    """regroup's second half: the faces' points of the copies whose leader changed, then
    vertex_nodes sorted by (leader, node) and member_leader."""
    lo, hi = ties.vertex_ptr[vertex], ties.vertex_ptr[vertex + 1]
    nodes, leader = ties.vertex_nodes, ties.leader
    # The faces' points read their copy's leader: only those of copies whose leader changed (an
    # insertion splits one cluster; the part that keeps the lowest node keeps its leader) need
    # rewriting. member_leader still holds the leaders of `nodes` before this regroup, in their
    # old order (-1 before the first).
    for j in range(lo, hi):
        g = nodes[j]
        if leader[g] == ties.member_leader[j]:
            continue
        for k in range(3):
            i = ties.partner_iface[g, k]
            if i < 0:
                continue
            for p in range(3):
                if na[i, p] == g:
                    ties.na_at[i, p] = leader[g]
                elif nb[i, p] == g:
                    ties.nb_at[i, p] = leader[g]
    # Insertion sort by (leader, node): a handful of copies per mesh point.
    for j in range(lo + 1, hi):
        g = nodes[j]
        k = j - 1
        while k >= lo and (leader[nodes[k]] > leader[g] or (leader[nodes[k]] == leader[g] and nodes[k] > g)):
            nodes[k + 1] = nodes[k]
            k -= 1
        nodes[k + 1] = g
    for j in range(lo, hi):
        ties.member_leader[j] = leader[nodes[j]]


@njit(cache=True, inline="always")
def copies_from_leader(vertex, ties, x, v):
    """Give every copy of a mesh point its cluster leader's position and velocity."""
    nodes, member_leader = ties.vertex_nodes, ties.member_leader
    for j in range(ties.vertex_ptr[vertex], ties.vertex_ptr[vertex + 1]):
        g = nodes[j]
        lead = member_leader[j]
        if g == lead:
            continue
        for d in range(3):
            x[g, d] = x[lead, d]
            v[g, d] = v[lead, d]


@block_kernel
def copies_block(lo, hi, ties, x, v):
    """copies_from_leader for mesh points lo..hi-1 (when kernels.advance returns)."""
    for vertex in range(lo, hi):
        copies_from_leader(vertex, ties, x, v)


@njit(cache=True, inline="always")
def tet_traction(t, tet_stress, nx, ny, nz, weight, other):
    """Normal traction (tension positive) and shear traction vector on the plane of normal n from
    the Kirchhoff stress of tet t (weight 1), or of the mean of tets t and other (weight 0.5)."""
    w = 1.0 - weight
    sxx = weight * tet_stress[t, 0] + w * tet_stress[other, 0]
    syy = weight * tet_stress[t, 1] + w * tet_stress[other, 1]
    szz = weight * tet_stress[t, 2] + w * tet_stress[other, 2]
    sxy = weight * tet_stress[t, 3] + w * tet_stress[other, 3]
    syz = weight * tet_stress[t, 4] + w * tet_stress[other, 4]
    sxz = weight * tet_stress[t, 5] + w * tet_stress[other, 5]
    tx = sxx * nx + sxy * ny + sxz * nz
    ty = sxy * nx + syy * ny + syz * nz
    tz = sxz * nx + syz * ny + szz * nz
    tn = tx * nx + ty * ny + tz * nz
    return tn, tx - tn * nx, ty - tn * ny, tz - tn * nz


@njit(cache=True, inline="always")
def face_traction(ta, tb, tet_stress, nx, ny, nz, law):
    """Normal traction (tension positive) and shear traction vector on the face between tets ta
    (side A) and tb, on the normal n (from side A to side B), that its insertion is checked with,
    and whether it meets the criterion: the more critical of its two tets' (law[LAW_SAMPLING] =
    SAMPLE_EITHER) or their mean stress's (SAMPLE_MEAN)."""
    if law[LAW_SAMPLING] == SAMPLE_MEAN:
        tn, sx, sy, sz = tet_traction(ta, tet_stress, nx, ny, nz, 0.5, tb)
        return tn, sx, sy, sz, insertion_reached(tn, sx * sx + sy * sy + sz * sz, law)
    tn, sx, sy, sz = tet_traction(ta, tet_stress, nx, ny, nz, 1.0, ta)
    tn_b, sx_b, sy_b, sz_b = tet_traction(tb, tet_stress, nx, ny, nz, 1.0, tb)
    ts2 = sx * sx + sy * sy + sz * sz
    ts2_b = sx_b * sx_b + sy_b * sy_b + sz_b * sz_b
    reached = insertion_reached(tn, ts2, law)
    reached_b = insertion_reached(tn_b, ts2_b, law)
    if reached_b and (not reached or insertion_utilisation(tn_b, math.sqrt(ts2_b), law)
                      > insertion_utilisation(tn, math.sqrt(ts2), law)):
        return tn_b, sx_b, sy_b, sz_b, True
    return tn, sx, sy, sz, reached


@njit(cache=True, inline="always")
def try_insert(i, ta, tb, x, na, nb, area, damage, slip_plastic, dn_shift, e_damage, e_inserted, tied, tet_stress,
               law, pn, ps, nx, ny, nz, prestressed=False):
    """Insert tied interface i between tets ta (side A) and tb if the traction of its tets reaches
    the law's strength (face_traction): its law state then carries that traction (clamped on the
    strength envelope; no normal compression) at zero gap, and the energy that state holds is
    booked against e_damage[i] and kept in e_inserted[i]. True when inserted. x is read at the
    rows na, nb (Ties.na_at, nb_at within a step). prestressed (a model with an initial stress,
    fdem.prestress): a face inserted in compression carries it too (its opening shifted by tn / pn,
    which its contact keeps once it fails): in such a model most faces are, and each would
    otherwise drop its share of the initial stress at once."""
    tn, sx, sy, sz, reached = face_traction(ta, tb, tet_stress, nx, ny, nz, law)
    if not reached:
        return False
    ts = math.sqrt(sx * sx + sy * sy + sz * sz)
    shift, cap = inserted_preload(tn, ts, law, pn, prestressed)
    scale = 1.0 if ts <= cap else cap / ts
    for p in range(3):
        # The shear spring ps (s - s_p) at zero slip carries the clamped shear traction.
        slip_plastic[i, p, 0] = -scale * sx / ps
        slip_plastic[i, p, 1] = -scale * sy / ps
        slip_plastic[i, p, 2] = -scale * sz / ps
    dn_shift[i] = shift
    tied[i] = RELEASED
    e_inserted[i] = intact_energy(i, x, na, nb, area, damage, slip_plastic, law, pn, ps, nx, ny, nz, shift)
    e_damage[i] -= e_inserted[i]
    return True


@njit(cache=True)
def released_vertices(ties, na, released_blocks, block, touched, seen):
    """After an interface pass that inserted faces (the blocks flagged in released_blocks): mark
    them free and list the mesh points of their corners in `touched`, each once (seen: a zeroed
    flag per mesh point, zeroed again on return); returns how many. Serial and in interface
    order, so the list does not depend on the threads."""
    tied = ties.tied
    n_if = tied.shape[0]
    n_touched = 0
    for blk in range(released_blocks.shape[0]):
        if not released_blocks[blk]:
            continue
        released_blocks[blk] = 0
        for i in range(blk * block, min(n_if, (blk + 1) * block)):
            if tied[i] == RELEASED:
                tied[i] = FREE
                for p in range(3):
                    vertex = ties.node_vertex[na[i, p]]
                    if not seen[vertex]:
                        seen[vertex] = 1
                        touched[n_touched] = vertex
                        n_touched += 1
    for k in range(n_touched):
        seen[touched[k]] = 0
    return n_touched


# regroup_released and the halves of regroup are compiled as functions, not inlined: inlined
# (numba's inline="always") into kernels.advance's parallel loop, the halves gave other clusters
# than the serial code (the Akantu bar's state hashes differed; found 2026-12-07).
@njit(cache=True)
def regroup_released(vertex, ties, na, nb, x, v):
    """Mesh point `vertex` (released_vertices) after its faces' insertion: its clusters are
    regrouped, each copy that changes cluster taking its old leader's state (x at t, v at
    t - dt / 2) for its new one. A mesh point writes only its own copies' rows and their faces'
    points, so kernels.advance runs them in parallel; one whose faces were inserted by several
    faces at once is regrouped once: its clusters depend on which faces are tied, not on their
    order."""
    _new_leaders(vertex, ties)
    # Within a call of kernels.advance only a leader's row is read (state_row) and copies_block
    # refreshes the others when it returns: only the copies that change cluster need their old
    # leader's state, which no copy here overwrites (an old leader, its cluster's lowest node,
    # stays the leader of its part).
    nodes, leader, member_leader = ties.vertex_nodes, ties.leader, ties.member_leader
    for j in range(ties.vertex_ptr[vertex], ties.vertex_ptr[vertex + 1]):
        g = nodes[j]
        old = member_leader[j]
        if leader[g] != old:
            for d in range(3):
                x[g, d] = x[old, d]
                v[g, d] = v[old, d]
    _apply_leaders(vertex, ties, na, nb)


@block_kernel
def cluster_block(lo, hi, slot, dt, kick, nodes, ties, ctrl, tools, tool_v_next):
    """Mesh points lo..hi-1: each cluster of copies gets the summed mass and forces of its
    members (their ties.load rows) and one central-difference update on its leader's row
    (velocity by `kick`, position by dt: kernels.advance), which holds the cluster's motion (the
    copies' rows are written when advance returns: copies_block). A moving support's reaction
    goes to the tools' force `slot` of this block."""
    x, v = nodes.x, nodes.v
    ptr, members, member_leader, load = ties.vertex_ptr, ties.vertex_nodes, ties.member_leader, ties.load
    alpha = ctrl.damping[0]
    for vertex in range(lo, hi):
        j = ptr[vertex]
        end = ptr[vertex + 1]
        while j < end:
            lead = member_leader[j]
            fx = fy = fz = ex = ey = ez = work = m = 0.0
            k = j
            while k < end and member_leader[k] == lead:
                # Indexed, not a row view: a view costs more here (measured 1.5x the pass).
                g = members[k]
                fx += load[g, LOAD_FORCE]
                fy += load[g, LOAD_FORCE + 1]
                fz += load[g, LOAD_FORCE + 2]
                ex += load[g, LOAD_EXTERNAL]
                ey += load[g, LOAD_EXTERNAL + 1]
                ez += load[g, LOAD_EXTERNAL + 2]
                work += load[g, LOAD_TOOL_WORK]
                m += load[g, LOAD_MASS]
                k += 1
            update_velocity(lead, nodes, (fx, fy, fz), (ex, ey, ez), (0.0, 0.0, 0.0), work, m, alpha, kick, tools,
                            tool_v_next, slot)
            move(lead, x, v, dt)
            j = k

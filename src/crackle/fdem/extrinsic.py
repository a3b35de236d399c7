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
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..solver.integrator import block_kernel, move, update_velocity
from .laws import KIND_BILINEAR, LAW_FT, LAW_KIND, intact_energy
from .laws.row import LAW_SAMPLING, SAMPLE_MEAN
from .laws.bilinear import LAW_TS
from .laws.guo_munjiza import LAW_BETA, shear_cap, shear_strength

# tied[i]: a face joining its tets rigidly, one released in this step (its clusters still to be
# regrouped), or one carrying its law (intrinsic, inserted, failed, pre-cracked).
FREE, TIED, RELEASED = 0, 1, 2

Ties = namedtuple(
    "Ties",
    "tied vertex_ptr vertex_nodes member_leader node_vertex partner partner_iface leader tet_stress load",
)

# Columns of ties.load, the one record per node that the tet pass writes for the node pass: the
# internal force, the external force (pressure, gravity), the tools' contact force and its work,
# and the node's mass. One row per node, not five arrays: the node pass gathers the copies of a
# mesh point from scattered nodes, and fewer cache lines per copy make the extrinsic step 3-5 %
# faster at 50k tets (benchmarks/fdem_passes.py; docs/validation.md).
LOAD_FORCE, LOAD_EXTERNAL, LOAD_TOOL, LOAD_TOOL_WORK, LOAD_MASS = 0, 3, 6, 9, 10
LOAD_COLUMNS = 11

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
                    np.zeros((0, 3), np.int64), empty_i, np.zeros((0, 6)), np.zeros((0, LOAD_COLUMNS)))
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
        member_leader=np.zeros(n_nodes, dtype=np.int64),
        node_vertex=corner_point.astype(np.int64),
        partner=partner,
        partner_iface=partner_iface,
        leader=np.arange(n_nodes, dtype=np.int64),
        tet_stress=np.zeros((n_tets, 6)),
        load=np.zeros((n_nodes, LOAD_COLUMNS)),
    )
    regroup_all(ties)
    return ties


@njit(cache=True)
def regroup_all(ties):
    for vertex in range(ties.vertex_ptr.shape[0] - 1):
        regroup(vertex, ties)


@njit(cache=True)
def regroup(vertex, ties):
    """Clusters of the copies of one mesh point: connected through tied faces; each copy's leader
    is the lowest node of its cluster, and the copies are kept sorted by (leader, node) so that a
    cluster is a contiguous run of vertex_nodes (member_leader: the leader of each entry, read in
    order by the node pass)."""
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
def _reaches(tn, ts2, law):
    """Whether a traction (normal tn, tension positive; squared shear ts2) meets the law's
    insertion criterion: Guo-Munjiza, Mohr-Coulomb with tension cut-off (the effective mixed
    mode: the ellipse in tension); bilinear, the maximum nominal stress. No square root or
    division: every tied face makes this check every step."""
    ft = law[LAW_FT]
    if law[LAW_KIND] != KIND_BILINEAR:
        fs = shear_strength(tn, law)
        if ts2 >= fs * fs:
            return True
        beta = law[LAW_BETA]
        if beta > 0.0 and tn > 0.0:
            return tn * tn + ts2 / (beta * beta) >= ft * ft
        return tn >= ft
    ts0 = law[LAW_TS]
    return tn >= ft or ts2 >= ts0 * ts0


@njit(cache=True, inline="always")
def _utilisation(tn, ts, law):
    """How far a traction is along the insertion criterion (1 on it): which of two tractions that
    both meet it is the more critical."""
    ft = law[LAW_FT]
    if law[LAW_KIND] != KIND_BILINEAR:
        beta = law[LAW_BETA]
        if beta > 0.0 and tn > 0.0:
            return max(math.sqrt(tn * tn + (ts / beta) ** 2) / ft, ts / shear_strength(tn, law))
        return max(tn / ft, ts / shear_strength(tn, law))
    return max(max(tn, 0.0) / ft, ts / law[LAW_TS])


@njit(cache=True, inline="always")
def face_traction(i, na, nb, tet_stress, nx, ny, nz, law):
    """Normal traction (tension positive) and shear traction vector on interface i, on the normal
    n (from side A to side B), that its insertion is checked with, and whether it meets the
    criterion: the more critical of its two tets' (law[LAW_SAMPLING] = SAMPLE_EITHER) or their
    mean stress's (SAMPLE_MEAN)."""
    ta = na[i, 0] // 4
    tb = nb[i, 0] // 4
    if law[LAW_SAMPLING] == SAMPLE_MEAN:
        tn, sx, sy, sz = tet_traction(ta, tet_stress, nx, ny, nz, 0.5, tb)
        return tn, sx, sy, sz, _reaches(tn, sx * sx + sy * sy + sz * sz, law)
    tn, sx, sy, sz = tet_traction(ta, tet_stress, nx, ny, nz, 1.0, ta)
    tn_b, sx_b, sy_b, sz_b = tet_traction(tb, tet_stress, nx, ny, nz, 1.0, tb)
    ts2 = sx * sx + sy * sy + sz * sz
    ts2_b = sx_b * sx_b + sy_b * sy_b + sz_b * sz_b
    reached = _reaches(tn, ts2, law)
    reached_b = _reaches(tn_b, ts2_b, law)
    if reached_b and (not reached or _utilisation(tn_b, math.sqrt(ts2_b), law) > _utilisation(tn, math.sqrt(ts2), law)):
        return tn_b, sx_b, sy_b, sz_b, True
    return tn, sx, sy, sz, reached


@njit(cache=True, inline="always")
def try_insert(i, x, na, nb, area, damage, slip_plastic, dn_shift, e_damage, e_inserted, tied, tet_stress, law,
               pn, ps, nx, ny, nz):
    """Insert tied interface i if the traction of its tets reaches the law's strength (face_traction): its law
    state then carries that traction (clamped on the strength envelope; no normal compression) at
    zero gap, and the energy that state holds is booked against e_damage[i] and kept in
    e_inserted[i]. True when inserted."""
    tn, sx, sy, sz, reached = face_traction(i, na, nb, tet_stress, nx, ny, nz, law)
    if not reached:
        return False
    ts = math.sqrt(sx * sx + sy * sy + sz * sz)
    ft = law[LAW_FT]
    if law[LAW_KIND] != KIND_BILINEAR:  # Guo-Munjiza
        tn_c = min(tn, ft)
        # On the pre-peak curve ft (2 u - u^2), u = dn / dnp.
        shift = 2.0 * ft / pn * (1.0 - math.sqrt(1.0 - tn_c / ft)) if tn_c > 0.0 else 0.0
        # The cap the law applies at zero gap: without a normal preload in compression, its
        # normal stress there is zero. A preload above it would be returned onto it in the first
        # step as if it had slid, booking less than the spring loses.
        cap = shear_cap(max(tn_c, 0.0), 1.0, law)
    else:  # bilinear
        cap = law[LAW_TS]
        shift = min(tn, ft) / pn if tn > 0.0 else 0.0
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
def regroup_released(ties, na, released_blocks, block):
    """After an interface pass that inserted faces: regroup the clusters of their mesh points, in
    interface order (serial, so the result does not depend on the threads). True if any was."""
    tied = ties.tied
    n_if = tied.shape[0]
    inserted = False
    for blk in range(released_blocks.shape[0]):
        if not released_blocks[blk]:
            continue
        inserted = True
        released_blocks[blk] = 0
        for i in range(blk * block, min(n_if, (blk + 1) * block)):
            if tied[i] == RELEASED:
                tied[i] = FREE
                for p in range(3):
                    regroup(ties.node_vertex[na[i, p]], ties)
    return inserted


@block_kernel
def cluster_block(lo, hi, slot, dt, kick, nodes, ties, ctrl, tools, tool_v_next):
    """Mesh points lo..hi-1: each cluster of copies gets the summed mass and forces of its
    members (their ties.load rows), one central-difference update on its leader (velocity by
    `kick`, position by dt: kernels.advance), and the members take its velocity and move with it.
    A moving support's reaction goes to the tools' force `slot` of this block."""
    x, v = nodes.x, nodes.v
    ptr, members, member_leader, load = ties.vertex_ptr, ties.vertex_nodes, ties.member_leader, ties.load
    alpha = ctrl.damping[0]
    for vertex in range(lo, hi):
        j = ptr[vertex]
        end = ptr[vertex + 1]
        while j < end:
            lead = member_leader[j]
            fx = fy = fz = ex = ey = ez = cx = cy = cz = work = m = 0.0
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
                cx += load[g, LOAD_TOOL]
                cy += load[g, LOAD_TOOL + 1]
                cz += load[g, LOAD_TOOL + 2]
                work += load[g, LOAD_TOOL_WORK]
                m += load[g, LOAD_MASS]
                k += 1
            update_velocity(lead, nodes, (fx, fy, fz), (ex, ey, ez), (cx, cy, cz), work, m, alpha, kick, tools,
                            tool_v_next, slot)
            move(lead, x, v, dt)
            # Held in locals: stores into v[g] would otherwise reload the leader's (aliasing).
            vx, vy, vz = v[lead, 0], v[lead, 1], v[lead, 2]
            px, py, pz = x[lead, 0], x[lead, 1], x[lead, 2]
            for r in range(j, k):
                g = members[r]
                v[g, 0] = vx
                v[g, 1] = vy
                v[g, 2] = vz
                x[g, 0] = px
                x[g, 1] = py
                x[g, 2] = pz
            j = k

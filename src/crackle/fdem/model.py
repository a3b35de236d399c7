"""Assemble an FDEM model: exploded mesh, interfaces, tools, supports, pressures.

All state lives in flat numpy arrays grouped in named tuples that the numba kernels read by
attribute (``nodes.x``, ``ifs.damage``...).
"""

from __future__ import annotations

import warnings
from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from ..geometry import TetMesh, internal_faces
from ..loading import Precrack, Pressure, Support, Tool
from ..materials import CONTACT_PENALTY_FACTOR, DEFAULT_PENALTY_FACTOR, BilinearLaw, Material
from .contact import BARY_TOL
from .kernels import FREE, HIDDEN, NO_TOOL, SURF_TRI_COLUMNS, TOOL_BOX, TOOL_CYLINDER, TOOL_PLANE, TOOL_SPHERE, TOOL_SURFACE
from .topology import FACE_CORNERS, INTACT, PRECRACK
from .law import (
    LAW_A,
    LAW_B,
    LAW_C,
    LAW_COLUMNS,
    LAW_CS,
    LAW_FT,
    LAW_GF1,
    LAW_GF2,
    LAW_IZ,
    LAW_KIND,
    LAW_MIX,
    LAW_MIX_EXP,
    LAW_MU,
    LAW_TANPHI,
    LAW_TS,
    KIND_BILINEAR,
    MIX_BK,
    MIX_POWER,
)

Nodes = namedtuple(
    "Nodes",
    "x v mass contact_area force constraint constraint_projection friction tool tool_offset w_external w_damping d_friction",
)
Tets = namedtuple("Tets", "dm_inv vol lam mu face_area face_iface face_side face_pressure")
Interfaces = namedtuple(
    "Interfaces",
    "na nb area pn ps reach law law_table damage state fail_time fail_mode force traction_t slip_plastic e_damage e_friction",
)
Tools = namedtuple(
    "Tools",
    "kind geom disp direction times speeds n mu penalty impulse surf_grid surf_cell_start surf_cell_tris surf_tri",
)
# Surface tools (shape "surface"), all of them concatenated: surf_tri (k, SURF_TRI_COLUMNS)
# triangle rows in each tool's own frame; per tool a uniform grid over the triangles' boxes
# inflated by the contact depth, in CSR form: surf_grid[j] = (cells along x, y, z, first entry
# of tool j in surf_cell_start); surf_cell_start[first + c] .. [first + c + 1] delimits cell c's
# triangles (rows of surf_tri) in surf_cell_tris. Built once: the tools only translate.
Pressures = namedtuple("Pressures", "times values n")
Controls = namedtuple("Controls", "gravity damping")

_SHAPE_CODES = {
    "plane": TOOL_PLANE,
    "box": TOOL_BOX,
    "cylinder": TOOL_CYLINDER,
    "sphere": TOOL_SPHERE,
    "surface": TOOL_SURFACE,
}


@dataclass
class FdemModel:
    """An assembled FDEM model: arrays for the kernels plus what outputs need."""

    mesh: TetMesh
    materials: list[Material]
    tet_material: np.ndarray
    nodes: Nodes
    tets: Tets
    ifs: Interfaces
    tools: Tools
    pressures: Pressures
    controls: Controls
    tool_specs: list[Tool]
    pressure_specs: list[Pressure]
    x0: np.ndarray  # reference positions of the exploded nodes
    stable_dt: float  # largest stable step (no safety factor)
    element_size: float
    contact_penalty: float  # N/m^3 per unit area, for tools and surface contact
    tet_friction: np.ndarray  # Coulomb coefficient of each tet's material between fracture faces
    corner_point: np.ndarray  # mesh point of each exploded node
    contact_enabled: bool = False
    contact_skin: float = 0.0  # m; the candidate lists stay valid for half of it
    warnings: list[str] = field(default_factory=list)

    @property
    def n_tets(self) -> int:
        return self.mesh.n_tets

    @property
    def n_interfaces(self) -> int:
        return len(self.ifs.area)

    def iface_centroids(self, x: np.ndarray | None = None) -> np.ndarray:
        x = self.x0 if x is None else x
        return 0.5 * (x[self.ifs.na].mean(axis=1) + x[self.ifs.nb].mean(axis=1))


def build_fdem_model(
    mesh: TetMesh,
    materials: Material | list[Material],
    tet_material: np.ndarray | None = None,
    tools: list[Tool] = (),
    supports: list[Support] = (),
    pressures: list[Pressure] = (),
    precracks: list[Precrack] = (),
    gravity=(0.0, 0.0, 0.0),
    damping: float = 0.0,
    initial_velocity=None,
    contact: bool = False,
) -> FdemModel:
    """Explode `mesh`, put an interface on every internal face and set up the loads.

    `damping` is a mass-proportional coefficient alpha (1/s): force -alpha m v per node.
    `initial_velocity` is a (3,) vector or an (n_points, 3) array on the mesh points.
    `contact` switches on node-to-surface contact between all free surfaces (fragments, fracture
    faces that slid apart, self-contact); without it only the paired faces of failed interfaces
    and the tools touch. Off by default while it is being validated on fracturing runs.
    """
    materials = [materials] if isinstance(materials, Material) else list(materials)
    if not materials or any(m.interface is None for m in materials):
        raise ValueError("every FDEM material needs an interface law")
    points, conn = mesh.points, mesh.tets
    m = len(conn)
    tet_material = np.zeros(m, dtype=np.int64) if tet_material is None else np.asarray(tet_material, np.int64)
    model_warnings: list[str] = []

    # Exploded nodes: node 4e+k is corner k of tet e.
    x0 = points[conn].reshape(-1, 3).copy()
    corner_point = conn.reshape(-1)
    dm = np.stack([points[conn[:, k]] - points[conn[:, 0]] for k in (1, 2, 3)], axis=2)
    vol = np.linalg.det(dm) / 6.0
    if np.any(vol <= 0):
        raise ValueError("the mesh has inverted or degenerate tets; run geometry.check_tets on it")
    dm_inv = np.linalg.inv(dm)
    face_area = np.empty((m, 4))
    for f in range(4):
        c = FACE_CORNERS[f]
        p0, p1, p2 = (points[conn[:, c[i]]] for i in range(3))
        face_area[:, f] = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    altitude = 3.0 * vol[:, None] / face_area  # height of each tet over each of its faces

    E = np.array([mat.youngs_modulus for mat in materials])[tet_material]
    G = np.array([mat.shear_modulus for mat in materials])[tet_material]
    lam = np.array([mat.lame_lambda for mat in materials])[tet_material]
    mu = G.copy()
    rho = np.array([mat.density for mat in materials])[tet_material]
    mass = np.repeat(rho * vol / 4.0, 4)

    # Interfaces on internal faces.
    topo = internal_faces(conn)
    # Numbered by (A-side tet, face): a block of interfaces then touches a compact range of nodes.
    order = np.lexsort((topo.face_local[:, 0], topo.face_tet[:, 0]))
    ta, tb = topo.face_tet[order, 0], topo.face_tet[order, 1]
    fa, fb = topo.face_local[order, 0], topo.face_local[order, 1]
    corners_a = FACE_CORNERS[fa]  # (k, 3) local corners of A's face, outward from A
    na = 4 * ta[:, None] + corners_a
    point_a = conn[ta[:, None], corners_a]
    # B's corner sitting on the same mesh point as each A corner.
    conn_b = conn[tb]  # (k, 4)
    match = conn_b[:, None, :] == point_a[:, :, None]  # (k, 3, 4)
    corners_b = np.argmax(match, axis=2)
    nb = 4 * tb[:, None] + corners_b
    n_if = len(ta)
    area = face_area[ta, fa]
    h_if = np.minimum(altitude[ta, fa], altitude[tb, fb])
    law_of_material = []
    law_rows = []
    for mat in materials:
        law = mat.interface
        row = np.zeros(LAW_COLUMNS)
        if isinstance(law, BilinearLaw):
            row[LAW_KIND] = KIND_BILINEAR
            row[LAW_FT] = law.tensile_strength
            row[LAW_TS] = law.shear_strength
            row[LAW_GF1] = law.fracture_energy
            row[LAW_GF2] = law.gf_shear
            row[LAW_MIX] = MIX_BK if law.mixed_mode == "bk" else MIX_POWER
            row[LAW_MIX_EXP] = law.mixed_mode_exponent
            row[LAW_MU] = law.friction
            law_of_material.append(len(law_rows))
            law_rows.append(row)
            continue
        row[LAW_FT] = law.tensile_strength
        row[LAW_C] = law.cohesion
        row[LAW_TANPHI] = np.tan(np.radians(law.friction_angle))
        row[LAW_GF1] = law.fracture_energy
        row[LAW_GF2] = law.gf_shear
        row[LAW_A], row[LAW_B], row[LAW_CS] = law.softening
        row[LAW_IZ] = law.softening_area
        row[LAW_MU] = law.friction
        law_of_material.append(len(law_rows))
        law_rows.append(row)
    law_table = np.array(law_rows)
    # The weaker side's law governs an interface between two materials.
    mat_a, mat_b = tet_material[ta], tet_material[tb]
    ft_of = law_table[:, LAW_FT]
    iface_law = np.where(ft_of[mat_a] <= ft_of[mat_b], mat_a, mat_b).astype(np.int16)
    penalty = np.array([getattr(mat.interface, "penalty_factor", DEFAULT_PENALTY_FACTOR) for mat in materials])
    p_side = np.minimum(penalty[mat_a], penalty[mat_b])
    pn = p_side * np.minimum(E[ta], E[tb]) / h_if
    ps = p_side * np.minimum(G[ta], G[tb]) / h_if
    # A bilinear interface's own stiffnesses kn, ks (N/m^3) replace the penalty, intact and
    # failed (contact); the stable step below uses them through pn, ps.
    bilinear = law_table[iface_law, LAW_KIND] == KIND_BILINEAR
    if bilinear.any():
        kn_of = np.array([getattr(mat.interface, "normal_stiffness", 0.0) for mat in materials])
        ks_of = np.array([getattr(mat.interface, "shear_stiffness", 0.0) for mat in materials])
        pn = np.where(bilinear, kn_of[iface_law], pn)
        ps = np.where(bilinear, ks_of[iface_law], ps)
    edge = np.stack(
        [np.linalg.norm(x0[na[:, i]] - x0[na[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1
    )
    reach = edge.max(axis=1)
    state = np.full(n_if, INTACT, dtype=np.int8)
    damage = np.zeros(n_if)

    # Pre-cracks: the selected interfaces start failed (contact only, no cohesion).
    centroid = x0[na].mean(axis=1)
    scale = float(np.max(mesh.bounds()[1] - mesh.bounds()[0]))
    precrack_mask = np.zeros(n_if, dtype=bool)
    for crack in precracks:
        n = np.asarray(crack.normal, float)
        n = n / np.linalg.norm(n)
        tol = crack.tol if crack.tol is not None else 1e-6 * scale
        on_plane = np.all(np.abs((x0[na] - np.asarray(crack.point, float)) @ n) <= tol, axis=1)
        inside = np.all((centroid >= np.asarray(crack.box_min) - tol) & (centroid <= np.asarray(crack.box_max) + tol), axis=1)
        precrack_mask |= on_plane & inside
    if precracks and not precrack_mask.any():
        raise ValueError("no internal face lies on the pre-crack plane inside its box: check [[precracks]] point/normal/box")
    state[precrack_mask] = PRECRACK
    damage[precrack_mask] = 1.0

    face_iface = np.full((m, 4), -1, dtype=np.int32)
    face_side = np.zeros((m, 4), dtype=np.int8)
    face_iface[ta, fa] = np.arange(n_if)
    face_iface[tb, fb] = np.arange(n_if)
    face_side[tb, fb] = 1

    # Pressures on faces.
    face_pressure = np.full((m, 4), -1, dtype=np.int16)
    for pid, load in enumerate(pressures):
        if isinstance(load.faces, str):
            if load.faces != "precrack":
                raise ValueError(f"pressure faces must be 'precrack' or a selection, not {load.faces!r}")
            face_pressure[ta[precrack_mask], fa[precrack_mask]] = pid
            face_pressure[tb[precrack_mask], fb[precrack_mask]] = pid
        else:
            sel = load.faces.mask(points, scale)
            bt, bf = topo.boundary_faces[:, 0], topo.boundary_faces[:, 1]
            chosen = np.all(sel[conn[bt[:, None], FACE_CORNERS[bf]]], axis=1)
            if not chosen.any():
                raise ValueError(f"pressure {pid}: its selection holds no boundary face")
            face_pressure[bt[chosen], bf[chosen]] = pid
    ptimes, pvalues, pn_count = _tables([p.history for p in pressures])

    # Supports: each node keeps the velocity projection of all the supports that hold it.
    normals_of = {}
    for sup in supports:
        sel = sup.where.mask(x0, scale)
        if not sel.any():
            raise ValueError(f"a {sup.kind} support selects no node: check its plane or box")
        if sup.kind == "fixed":
            blocked = np.eye(3)
        elif sup.kind == "roller":
            blocked = np.asarray(sup.normal, float)[None, :]
        else:
            raise ValueError(f"support kind must be 'fixed' or 'roller', not {sup.kind!r}")
        for node in np.flatnonzero(sel):
            normals_of.setdefault(int(node), []).append(blocked)
    constraint = np.full(4 * m, FREE, dtype=np.int16)
    projections = [np.zeros((3, 3))]  # index 0: fixed
    known = {projections[0].round(12).tobytes(): 0}
    for node, blocks in normals_of.items():
        proj = _velocity_projection(np.concatenate(blocks))
        key = proj.round(12).tobytes()
        if key not in known:
            known[key] = len(projections)
            projections.append(proj)
        constraint[node] = known[key]

    # Contact (tools and free surfaces): penalty per unit contact area CONTACT_PENALTY_FACTOR
    # E / h, h the median tet altitude. Much softer than the interfaces on purpose: in the
    # exploded mesh several coincident nodes can press on one triangle corner, and their springs
    # add up there; penetrations stay ~1e-4 h at 100 MPa.
    default_penalty = CONTACT_PENALTY_FACTOR * float(np.max(E)) / float(np.median(altitude))
    tool_kind = np.array([_SHAPE_CODES[t.shape] for t in tools], dtype=np.int64)
    tool_geom = np.array([t.geometry_row() for t in tools]).reshape(len(tools), 12)
    tool_dir = np.array([np.asarray(t.direction, float) / np.linalg.norm(t.direction) for t in tools]).reshape(-1, 3)
    ttimes, tspeeds, tn = _tables([t.speed for t in tools])
    tool_mu = np.array([t.friction for t in tools], dtype=float)
    tool_pen = np.array([t.penalty if t.penalty is not None else default_penalty for t in tools], dtype=float)

    v = np.zeros((4 * m, 3))
    if initial_velocity is not None:
        iv = np.asarray(initial_velocity, dtype=float)
        v[:] = iv if iv.shape == (3,) else iv[corner_point]

    # Faces free at t = 0 (outer boundary, pre-cracks); nodes on none are hidden from the tools.
    free_face = face_iface < 0
    if n_if:
        free_face |= state[np.maximum(face_iface, 0)] == PRECRACK
    contact_area, on_free_face = _contact_area(face_area, free_face)
    nodes = Nodes(
        x=x0.copy(),
        v=v,
        mass=mass,
        contact_area=contact_area,
        force=np.zeros((4 * m, 3)),
        constraint=constraint,
        constraint_projection=np.array(projections),
        friction=np.zeros((4 * m, 3)),
        tool=np.where(on_free_face, NO_TOOL, HIDDEN).astype(np.int8),
        tool_offset=np.zeros(4 * m),
        w_external=np.zeros(4 * m),
        w_damping=np.zeros(4 * m),
        d_friction=np.zeros(4 * m),
    )
    tets = Tets(dm_inv, vol, lam, mu, face_area, face_iface, face_side, face_pressure)
    ifs = Interfaces(
        na=na.astype(np.int64),
        nb=nb.astype(np.int64),
        area=area,
        pn=pn,
        ps=ps,
        reach=reach,
        law=iface_law,
        law_table=law_table,
        damage=damage,
        state=state,
        fail_time=np.full(n_if, np.nan),
        fail_mode=np.zeros(n_if, dtype=np.int8),
        force=np.zeros((n_if, 3, 3)),
        traction_t=np.zeros((n_if, 3, 3)),
        slip_plastic=np.zeros((n_if, 3, 3)),
        e_damage=np.zeros(n_if),
        e_friction=np.zeros(n_if),
    )
    # Surface tools: a node deeper than the median tet altitude behind a triangle is not its
    # contact (penetrations stay ~1e-4 of it), which keeps the far side of a thin tool apart.
    surf = _surface_tool_grids(tools, tool_geom, float(np.median(altitude)))
    tool_arrays = Tools(
        tool_kind, tool_geom, np.zeros((len(tools), 3)), tool_dir, ttimes, tspeeds, tn, tool_mu, tool_pen,
        impulse=np.zeros((len(tools), m, 3)), **surf,
    )
    controls = Controls(np.asarray(gravity, dtype=float), np.array([float(damping)]))

    # Stable step: per node, bulk tet + interfaces + tool springs (eigenvalue bounds).
    grads = np.concatenate([-dm_inv.sum(axis=1, keepdims=True), dm_inv], axis=1)  # (m, 4, 3) grad N_k
    gtg = np.einsum("mki,mkj->mij", grads, grads)
    lam_max_g = np.linalg.eigvalsh(gtg)[:, -1]
    omega2_tet = 4.0 * (3.0 * lam + 2.0 * mu) * lam_max_g / rho  # lambda_max(M^-1 K_e) bound
    # Springs on each face (Gershgorin row sums per node): an interface face carries its pair
    # spring (twice, for the two sides' relative motion) and, once failed, the contact spring
    # instead; an outer face carries surface contact and tool springs.
    face_spring = np.zeros((m, 4))
    pair = 2.0 * np.maximum(np.maximum(pn, ps), default_penalty if contact else 0.0) * area / 3.0
    face_spring[ta, fa] = pair
    face_spring[tb, fb] = pair
    outer = face_iface < 0
    outer_spring = (2.0 * default_penalty if contact else 0.0) + (tool_pen.max() if len(tools) else 0.0)
    face_spring[outer] = outer_spring * face_area[outer] / 3.0
    k_node = np.zeros((m, 4))
    for f in range(4):
        k_node[:, FACE_CORNERS[f]] += face_spring[:, f, None]
    k_node = k_node.ravel()
    omega2 = np.repeat(omega2_tet, 4) + k_node / mass
    stable_dt = float(2.0 / np.sqrt(omega2.max()))

    element_size = mesh.element_size()
    for mat in materials:
        pz = mat.process_zone
        if element_size > pz.advised_element_size:
            model_warnings.append(
                f"element size {element_size * 1e3:.3g} mm is coarser than the advised "
                f"{pz.advised_element_size * 1e3:.3g} mm for material '{mat.name}' (a third of the "
                f"long-crack plastic zone {pz.plastic_zone_long * 1e3:.3g} mm): the fracture process "
                "zone is under-resolved and peak loads will be over-estimated"
            )
    for msg in model_warnings:
        warnings.warn(msg, stacklevel=2)

    return FdemModel(
        mesh=mesh,
        materials=materials,
        tet_material=tet_material,
        nodes=nodes,
        tets=tets,
        ifs=ifs,
        tools=tool_arrays,
        pressures=Pressures(ptimes, pvalues, pn_count),
        controls=controls,
        tool_specs=list(tools),
        pressure_specs=list(pressures),
        x0=x0,
        stable_dt=stable_dt,
        element_size=element_size,
        contact_penalty=default_penalty,
        tet_friction=np.array([mat.interface.friction for mat in materials])[tet_material],
        corner_point=corner_point.astype(np.int64),
        contact_enabled=contact,
        contact_skin=0.25 * element_size,
        warnings=model_warnings,
    )


def _contact_area(face_area: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area each exploded node answers for in contact (tools and surfaces), fixed for the run,
    and whether the node lies on a free face at t = 0.

    A node on the surface at t = 0 gets a third of each of its free faces; a node inside the
    body, exposed only once a crack opens, a third of its three faces' mean. Fixed on purpose:
    a penalty spring whose stiffness changed with the crack pattern while compressed would
    create or destroy energy."""
    m = len(face_area)
    area = np.zeros((m, 4))
    mean_share = np.zeros((m, 4))
    for k in range(4):
        others = [f for f in range(4) if f != k]
        area[:, k] = (face_area[:, others] * free[:, others]).sum(axis=1) / 3.0
        mean_share[:, k] = face_area[:, others].sum(axis=1) / 9.0
    on_free_face = area > 0.0
    return np.where(on_free_face, area, mean_share).reshape(-1), on_free_face.reshape(-1)


def _surface_tool_grids(tools, geom: np.ndarray, depth: float) -> dict:
    """Triangle rows and static contact grids of the surface tools (see `Tools`); fills each
    surface tool's geom row with its grid origin, 1 / cell size and contact depth."""
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
    return {
        "surf_grid": grids,
        "surf_cell_start": np.concatenate(starts),
        "surf_cell_tris": np.concatenate(cell_tris) if cell_tris else np.zeros(0, dtype=np.int64),
        "surf_tri": np.concatenate(rows) if rows else np.zeros((0, SURF_TRI_COLUMNS)),
    }


def _tables(histories) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pad piecewise-linear histories into (k, n) time and value tables plus point counts."""
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
    return times, values, counts


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

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
from ..loading.arrays import HistoryTable, Tools, default_tool_penalty, history_tables
from ..loading.tools import HIDDEN, NO_TOOL
from ..solver.body import BODY_FIELDS, body_arrays
from ..solver.integrator import support_constraints
from ..solver.setup import tools_on_body
from ..materials import Material
from ..materials.random_properties import draw, statistics
from .extrinsic import TIED, VERTEX_BLOCK, Ties, build_ties
from .kernels import TET_BLOCK
from .prestress import preload_interfaces
from .laws import LAW_COLUMNS, LAW_EXTRINSIC
from .time_step import MassScaling, TimeStepReport, scale_masses, time_step, tool_penalty_advice
from .topology import FACE_CORNERS, INTACT, PRECRACK

# Contact (tools and free surfaces): penalty per unit contact area TOOL_PENALTY_FACTOR E / h, h
# the median tet altitude (the usual FDEM order of magnitude, ~10 E / h). Much softer than the
# interfaces on purpose: in the exploded mesh several coincident nodes can press on one triangle
# corner, and their springs add up there; penetrations stay ~1e-4 h at 100 MPa.

# The shared per-node arrays (solver.body; radius 0: a tet node touches the tools with its centre),
# with the nodes' force (the tet pass's gather, which the tied clusters' pass reads).
Nodes = namedtuple("Nodes", BODY_FIELDS + " force")
# s0: each tet's initial stress (fdem.prestress; (m, 6) in scenario.STRESS_ORDER, its second
# Piola-Kirchhoff stress at E = 0), or (0, 6) without one: the step then adds nothing.
Tets = namedtuple("Tets", "dm_inv vol lam mu face_area face_iface face_side face_pressure s0")
Interfaces = namedtuple(
    "Interfaces",
    "na nb area pn ps reach law law_table damage state fail_time fail_mode force force_mid turning traction_t slip_plastic dn_shift "
    "reading_offset pair_entry e_damage e_friction e_inserted prestressed",
)
Controls = namedtuple("Controls", "gravity damping")


@dataclass
class FdemModel:
    """An assembled FDEM model: arrays for the kernels plus what outputs need."""

    mesh: TetMesh
    materials: list[Material]
    tet_material: np.ndarray
    nodes: Nodes
    tets: Tets
    ifs: Interfaces
    ties: Ties  # extrinsic interfaces: which faces are tied and the clusters of node copies
    tools: Tools
    pressures: HistoryTable
    controls: Controls
    tool_specs: list[Tool]
    pressure_specs: list[Pressure]
    x0: np.ndarray  # reference positions of the exploded nodes
    time_step: TimeStepReport  # the stable step and what sets it
    mass_scaling: MassScaling  # mass added to reach run.target_dt (none by default)
    element_size: float
    wave_transit: float  # s: element size over the fastest P-wave speed of the bulk
    contact_penalty: float  # N/m^3 per unit area, for tools and surface contact
    tet_friction: np.ndarray  # Coulomb coefficient of each tet's material between fracture faces
    corner_point: np.ndarray  # mesh point of each exploded node
    contact_enabled: bool = False
    contact_skin: float = 0.0  # m; the candidate lists stay valid for half of it
    # {material: {property: statistics}} of the properties drawn per face (their values: the
    # faces' own law rows, ifs.law_table[ifs.law])
    random_properties: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def n_tets(self) -> int:
        return self.mesh.n_tets

    @property
    def stable_dt(self) -> float:
        """Largest stable step (s, no safety factor) once faces carry their laws."""
        return self.time_step.dt

    @property
    def tied_substeps(self) -> int:
        """How many steps of stable_dt a step of the tied phase holds (1: no tied phase; see
        TIED_STEP_GAIN)."""
        return max(1, int(self.time_step.tied_dt // self.time_step.dt))

    @property
    def n_interfaces(self) -> int:
        return len(self.ifs.area)

    def iface_centroids(self, x: np.ndarray | None = None, ids: np.ndarray | None = None) -> np.ndarray:
        """Centroids of the interfaces `ids` (default all) at positions x (default the reference)."""
        x = self.x0 if x is None else x
        na, nb = (self.ifs.na, self.ifs.nb) if ids is None else (self.ifs.na[ids], self.ifs.nb[ids])
        return 0.5 * (x[na].mean(axis=1) + x[nb].mean(axis=1))


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
    angular_velocity=None,
    end_time: float | None = None,
    target_dt: float | None = None,
    safety: float = 1.0,
    max_added_mass: float = 0.01,
    penalty_keys: dict[str, str] | None = None,
    random_seed: int = 0,
    pair_laws: dict | None = None,
    initial_stress: np.ndarray | None = None,
) -> FdemModel:
    """Explode `mesh`, put an interface on every internal face and set up the loads.

    `damping` is a mass-proportional coefficient alpha (1/s): force -alpha m v per node.
    `initial_velocity` is a (3,) vector or an (n_points, 3) array on the mesh points;
    `angular_velocity` (rad/s, a (3,) vector) adds a rigid spin about the centre of mass.
    `contact` switches on node-to-surface contact between all free surfaces (fragments, fracture
    faces that slid apart, self-contact); without it only the paired faces of failed interfaces
    and the tools touch. Off by default while it is being validated on fracturing runs.
    `end_time` (s), when given, lets the coarse-mesh advice be left out of a run whose loads
    cannot bring any interface to its strength by then (_fracture_reachable).
    `target_dt` (s): mass scaling so that the run's step, `safety` times the stable one, reaches
    it (time_step.scale_masses); refused (ValueError) when that adds more than `max_added_mass` of the mass.
    `penalty_keys` ({tool name: scenario key}) names the key that sets a tool's penalty in the
    advice when it is not tools.NAME.penalty (the [plates]: plates.penalty).
    `random_seed`: of the properties a material draws per face (Material.random).
    `pair_laws`: {(material a, material b): law} for the faces between two materials (both ways
    round); without one, such a face takes the law of the side with the lower tensile strength.
    `initial_stress`: (m, 6) Cauchy stress of each tet at t = 0 (Pa, scenario.STRESS_ORDER); the
    intact intrinsic interfaces are preloaded to carry it (fdem.prestress).
    """
    materials = [materials] if isinstance(materials, Material) else list(materials)
    if not materials or any(m.interface is None for m in materials):
        raise ValueError("every FDEM material needs an interface law")
    m = mesh.n_tets
    tet_material = np.zeros(m, dtype=np.int64) if tet_material is None else np.asarray(tet_material, np.int64)
    scale = float(np.max(mesh.bounds()[1] - mesh.bounds()[0]))

    bulk = _exploded_tets(mesh, materials, tet_material)
    pairs = _interfaces(mesh, materials, tet_material, bulk, pair_laws or {})
    random_properties = _draw_per_face(pairs, materials, bulk.x0, random_seed)
    precrack = _precracks(precracks, bulk.x0, pairs, scale)
    pairs.state[precrack] = PRECRACK
    pairs.damage[precrack] = 1.0
    face_iface, face_side = _face_tables(m, pairs)
    face_pressure = _pressure_faces(pressures, mesh, pairs, precrack, scale)

    median_altitude = float(np.median(bulk.altitude))
    default_penalty = default_tool_penalty(float(np.max(bulk.E)), median_altitude)
    # Surface tools: a node deeper than the median tet altitude behind a triangle is not its
    # contact (penetrations stay ~1e-4 of it); each block of the tet pass writes its own slot of
    # the tool forces, and each block of the extrinsic node pass its own moving supports' reaction.
    slots = max(-(-m // TET_BLOCK), -(-len(mesh.points) // VERTEX_BLOCK))
    nodes = _nodes(bulk, pairs, face_iface, supports, initial_velocity, angular_velocity, scale)
    tool_table, seating = tools_on_body(tools, nodes, default_penalty, median_altitude, slots, "nodes")
    s0 = np.zeros((0, 6)) if initial_stress is None else np.ascontiguousarray(initial_stress, dtype=float)
    tets = Tets(bulk.dm_inv, bulk.vol, bulk.lam, bulk.mu, bulk.face_area, face_iface, face_side, face_pressure, s0)
    n_if = len(pairs.area)
    # Extrinsic laws: their intact faces start tied (no force until inserted).
    extrinsic = (pairs.law_table[pairs.law, LAW_EXTRINSIC] != 0.0) & (pairs.state == INTACT)
    dn_shift, slip_plastic, traction_t = np.zeros(n_if), np.zeros((n_if, 3, 3)), np.zeros((n_if, 3, 3))
    if len(s0):
        dn_shift, slip_plastic, traction_t = preload_interfaces(
            bulk.x0, pairs.na, pairs.ta, pairs.tb, pairs.law, pairs.law_table, pairs.pn, pairs.ps,
            (pairs.state == INTACT) & ~extrinsic, s0, precrack=pairs.state == PRECRACK)
    ifs = Interfaces(
        na=pairs.na.astype(np.int64),
        nb=pairs.nb.astype(np.int64),
        area=pairs.area,
        pn=pairs.pn,
        ps=pairs.ps,
        reach=pairs.reach,
        law=pairs.law,
        law_table=pairs.law_table,
        damage=pairs.damage,
        state=pairs.state,
        fail_time=np.full(n_if, np.nan),
        fail_mode=np.zeros(n_if, dtype=np.int8),
        force=np.zeros((n_if, 3, 3)),
        # Per point pair of a failed face: the force on both its nodes alike (interface.turning_forces).
        force_mid=np.zeros((n_if, 3, 3)),
        # 1 where force_mid holds this step's forces (failed faces, damaged intact ones): one byte
        # for the tet pass's gather to read, not the state and the damage of every face.
        turning=np.zeros(n_if, dtype=np.uint8),
        traction_t=traction_t,
        slip_plastic=slip_plastic,
        dn_shift=dn_shift,
        reading_offset=np.zeros((n_if, 2)),
        # Per point pair of a failed face: the opening it entered paired contact at (kernels._pair_entry);
        # 0 on an intact face, so that a face that fails under compression goes on pressing.
        pair_entry=np.zeros((n_if, 3)),
        e_damage=np.zeros(n_if),
        e_friction=np.zeros(n_if),
        e_inserted=np.zeros(n_if),
        # One element (1) in a model with an initial stress, empty otherwise: a face's
        # compressive dn_shift (fdem.prestress) then stays its reference once it fails, and an
        # extrinsic face inserted in compression gets one (fdem.extrinsic.try_insert).
        prestressed=np.ones(1 if len(s0) else 0, dtype=np.uint8),
    )
    ties = build_ties(bulk.corner_point, len(mesh.points), ifs.na, ifs.nb, np.where(extrinsic, TIED, 0).astype(np.uint8), m)
    tool_penalty = np.max(tool_table.penalty, initial=0.0)
    surface_penalty = default_penalty if contact else 0.0
    step = time_step(bulk, pairs, face_iface, surface_penalty, tool_penalty)
    # The advice reads the unscaled masses: it comes before mass scaling changes them.
    step_advice = tool_penalty_advice(bulk, pairs, face_iface, surface_penalty, tools, tool_table.penalty, step,
                                       penalty_keys or {})
    element_size = mesh.element_size()
    wave_transit = element_size / float(np.max(np.sqrt((bulk.lam + 2.0 * bulk.mu) / bulk.rho)))
    mass_scaling = MassScaling(target_dt)
    if target_dt is not None:
        step_advice = [f"{msg}, before mass scaling (run.target_dt then needs less added mass)" for msg in step_advice]
        mass_scaling = scale_masses(bulk, step, target_dt, safety, max_added_mass)
        step = time_step(bulk, pairs, face_iface, surface_penalty, tool_penalty)
    step.tied_dt = _tied_step(bulk, pairs, face_iface, surface_penalty, tool_penalty, ties, step.dt)
    reachable = end_time is None or _fracture_reachable(
        materials, nodes, tools, pressures, precracks, gravity, scale, element_size, end_time
    )
    model_warnings = ((_resolution_warnings(materials, element_size) if reachable else [])
                      + _orientation_bias_warnings(materials, pairs, bulk.x0) + step_advice + seating)
    for msg in model_warnings:
        warnings.warn(msg, stacklevel=2)

    return FdemModel(
        mesh=mesh,
        materials=materials,
        tet_material=tet_material,
        nodes=nodes,
        tets=tets,
        ifs=ifs,
        ties=ties,
        tools=tool_table,
        pressures=history_tables([p.history for p in pressures]),
        controls=Controls(np.asarray(gravity, dtype=float), np.array([float(damping)])),
        tool_specs=list(tools),
        pressure_specs=list(pressures),
        x0=bulk.x0,
        time_step=step,
        mass_scaling=mass_scaling,
        element_size=element_size,
        wave_transit=wave_transit,
        contact_penalty=default_penalty,
        tet_friction=np.array([mat.interface.friction for mat in materials])[tet_material],
        corner_point=bulk.corner_point.astype(np.int64),
        random_properties=random_properties,
        contact_enabled=contact,
        contact_skin=0.25 * element_size,
        warnings=model_warnings,
    )


@dataclass
class _Bulk:
    """The exploded tets: node 4e+k is corner k of tet e."""

    x0: np.ndarray  # (4m, 3) reference positions
    corner_point: np.ndarray  # (4m,) mesh point of each node
    dm_inv: np.ndarray  # (m, 3, 3) inverse reference edge matrix
    vol: np.ndarray
    face_area: np.ndarray  # (m, 4), face f opposite corner f
    altitude: np.ndarray  # (m, 4) height of each tet over each of its faces
    E: np.ndarray  # per tet
    G: np.ndarray
    lam: np.ndarray
    mu: np.ndarray
    rho: np.ndarray
    mass: np.ndarray  # (4m,) lumped


def _exploded_tets(mesh: TetMesh, materials, tet_material) -> _Bulk:
    points, conn = mesh.points, mesh.tets
    m = len(conn)
    dm = np.stack([points[conn[:, k]] - points[conn[:, 0]] for k in (1, 2, 3)], axis=2)
    vol = np.linalg.det(dm) / 6.0
    if np.any(vol <= 0):
        raise ValueError("the mesh has inverted or degenerate tets; run geometry.check_tets on it")
    face_area = np.empty((m, 4))
    for f in range(4):
        c = FACE_CORNERS[f]
        p0, p1, p2 = (points[conn[:, c[i]]] for i in range(3))
        face_area[:, f] = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    G = np.array([mat.shear_modulus for mat in materials])[tet_material]
    rho = np.array([mat.density for mat in materials])[tet_material]
    return _Bulk(
        x0=points[conn].reshape(-1, 3).copy(),
        corner_point=conn.reshape(-1),
        dm_inv=np.linalg.inv(dm),
        vol=vol,
        face_area=face_area,
        altitude=3.0 * vol[:, None] / face_area,
        E=np.array([mat.youngs_modulus for mat in materials])[tet_material],
        G=G,
        lam=np.array([mat.lame_lambda for mat in materials])[tet_material],
        mu=G.copy(),
        rho=rho,
        mass=np.repeat(rho * vol / 4.0, 4),
    )


@dataclass
class _Pairs:
    """Interfaces on the internal faces, numbered by (A-side tet, face): a block of interfaces
    then touches a compact range of nodes."""

    ta: np.ndarray  # A-side tet and its local face
    fa: np.ndarray
    tb: np.ndarray  # B-side tet and its local face
    fb: np.ndarray
    na: np.ndarray  # (k, 3) A nodes, ordered outward from A
    nb: np.ndarray  # (k, 3) B nodes on the same mesh points
    boundary_faces: np.ndarray  # (tet, local face) of the outer boundary
    area: np.ndarray
    law: np.ndarray  # row of law_table governing each interface (int32: one row per face where properties are drawn)
    law_table: np.ndarray
    pn: np.ndarray  # N/m^3
    ps: np.ndarray
    reach: np.ndarray  # longest edge: how far failed faces may slide and still touch as a pair
    state: np.ndarray
    damage: np.ndarray


def _interfaces(mesh: TetMesh, materials, tet_material, bulk: _Bulk, pair_laws: dict) -> _Pairs:
    conn = mesh.tets
    topo = internal_faces(conn)
    order = np.lexsort((topo.face_local[:, 0], topo.face_tet[:, 0]))
    ta, tb = topo.face_tet[order, 0], topo.face_tet[order, 1]
    fa, fb = topo.face_local[order, 0], topo.face_local[order, 1]
    corners_a = FACE_CORNERS[fa]  # (k, 3) local corners of A's face, outward from A
    na = 4 * ta[:, None] + corners_a
    point_a = conn[ta[:, None], corners_a]
    # B's corner sitting on the same mesh point as each A corner.
    match = conn[tb][:, None, :] == point_a[:, :, None]  # (k, 3, 4)
    nb = 4 * tb[:, None] + np.argmax(match, axis=2)
    n_if = len(ta)
    h_if = np.minimum(bulk.altitude[ta, fa], bulk.altitude[tb, fb])

    # One law row per material, then one per pair of materials with a law of its own; without
    # one, the weaker side's law governs an interface between two.
    laws = [mat.interface for mat in materials]
    mat_a, mat_b = tet_material[ta], tet_material[tb]
    ft_of = np.array([law.tensile_strength for law in laws])
    iface_law = np.where(ft_of[mat_a] <= ft_of[mat_b], mat_a, mat_b).astype(np.int32)
    for (a, b), law in pair_laws.items():
        if a < b:
            iface_law[((mat_a == a) & (mat_b == b)) | ((mat_a == b) & (mat_b == a))] = len(laws)
            laws.append(law)
    law_table = np.array([law.table_row() for law in laws]).reshape(-1, LAW_COLUMNS)
    pn = np.zeros(n_if)
    ps = np.zeros(n_if)
    E_min = np.minimum(bulk.E[ta], bulk.E[tb])
    G_min = np.minimum(bulk.G[ta], bulk.G[tb])
    for row, law in enumerate(laws):
        sel = iface_law == row
        pn[sel], ps[sel] = law.stiffness(E_min[sel], G_min[sel], h_if[sel])
    edge = np.stack([np.linalg.norm(bulk.x0[na[:, i]] - bulk.x0[na[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1)
    return _Pairs(
        ta=ta, fa=fa, tb=tb, fb=fb, na=na, nb=nb, boundary_faces=topo.boundary_faces,
        area=bulk.face_area[ta, fa], law=iface_law, law_table=law_table, pn=pn, ps=ps,
        reach=edge.max(axis=1), state=np.full(n_if, INTACT, dtype=np.int8), damage=np.zeros(n_if),
    )


def _draw_per_face(pairs: _Pairs, materials, x0: np.ndarray, seed: int) -> dict:
    """Where a material draws properties per face ([material.random]), every interface gets its
    own law row with its drawn values (the kernels read a face's row whatever the table's size, so
    a uniform model keeps one row per material and its speed). Returns the drawn values'
    statistics per material and property."""
    if not any(mat.random for mat in materials):
        return {}
    centroid = x0[pairs.na].mean(axis=1)
    rows = pairs.law_table[pairs.law]
    stats_of = {}
    for index, mat in enumerate(materials):
        faces = np.flatnonzero(pairs.law == index)
        law = mat.interface
        for name, spec in mat.random.items():
            column = law.RANDOM[name]
            values = draw(spec, float(pairs.law_table[index, column]), centroid[faces], seed, mat.name, name)
            rows[faces, column] = values
            if name == "fracture_energy" and "fracture_energy_shear" not in mat.random and law.fracture_energy_shear is None:
                rows[faces, law.RANDOM["fracture_energy_shear"]] = values  # mode II follows Gf where it defaults to it
            stats_of.setdefault(mat.name, {})[name] = statistics(spec, centroid[faces], values)
        problem = law.drawn_rows_problem(rows[faces], pairs.pn[faces], pairs.ps[faces]) if mat.random else None
        if problem:
            raise ValueError(f"[material.random] of {mat.name}: {problem}")
    pairs.law_table = rows
    pairs.law = np.arange(len(rows), dtype=np.int32)
    return stats_of


def _precracks(precracks, x0, pairs: _Pairs, scale: float) -> np.ndarray:
    """Interfaces that start failed (contact only, no cohesion): on a pre-crack plane, centroid
    inside its box."""
    na = pairs.na
    centroid = x0[na].mean(axis=1)
    mask = np.zeros(len(na), dtype=bool)
    for crack in precracks:
        n = np.asarray(crack.normal, float)
        n = n / np.linalg.norm(n)
        tol = crack.tol if crack.tol is not None else 1e-6 * scale
        on_plane = np.all(np.abs((x0[na] - np.asarray(crack.point, float)) @ n) <= tol, axis=1)
        inside = np.all((centroid >= np.asarray(crack.box_min) - tol) & (centroid <= np.asarray(crack.box_max) + tol), axis=1)
        mask |= on_plane & inside
    if precracks and not mask.any():
        raise ValueError("no internal face lies on the pre-crack plane inside its box: check [[precracks]] point/normal/box")
    return mask


def _face_tables(m: int, pairs: _Pairs) -> tuple[np.ndarray, np.ndarray]:
    """Per tet face: its interface (-1 on the outer boundary) and whether the tet is its B side."""
    n_if = len(pairs.ta)
    face_iface = np.full((m, 4), -1, dtype=np.int32)
    face_side = np.zeros((m, 4), dtype=np.int8)
    face_iface[pairs.ta, pairs.fa] = np.arange(n_if)
    face_iface[pairs.tb, pairs.fb] = np.arange(n_if)
    face_side[pairs.tb, pairs.fb] = 1
    return face_iface, face_side


def _pressure_faces(pressures, mesh: TetMesh, pairs: _Pairs, precrack: np.ndarray, scale: float) -> np.ndarray:
    """Per tet face, the pressure acting on it (-1: none)."""
    conn = mesh.tets
    face_pressure = np.full((len(conn), 4), -1, dtype=np.int16)
    for pid, load in enumerate(pressures):
        if isinstance(load.faces, str):
            if load.faces != "precrack":
                raise ValueError(f"pressure faces must be 'precrack' or a selection, not {load.faces!r}")
            face_pressure[pairs.ta[precrack], pairs.fa[precrack]] = pid
            face_pressure[pairs.tb[precrack], pairs.fb[precrack]] = pid
        else:
            bt, bf = pairs.boundary_faces[:, 0], pairs.boundary_faces[:, 1]
            chosen = load.faces.face_mask(mesh.points, conn[bt[:, None], FACE_CORNERS[bf]], scale)
            if not chosen.any():
                raise ValueError(f"pressure {pid}: its selection holds no boundary face")
            face_pressure[bt[chosen], bf[chosen]] = pid
    return face_pressure


def _nodes(bulk: _Bulk, pairs: _Pairs, face_iface, supports, initial_velocity, angular_velocity, scale: float) -> Nodes:
    n = len(bulk.x0)
    v = np.zeros((n, 3))
    if initial_velocity is not None:
        iv = np.asarray(initial_velocity, dtype=float)
        v[:] = iv if iv.shape == (3,) else iv[bulk.corner_point]
    if angular_velocity is not None and np.any(angular_velocity):
        centre = bulk.mass @ bulk.x0 / bulk.mass.sum()
        v += np.cross(np.asarray(angular_velocity, dtype=float), bulk.x0 - centre)
    # Faces free at t = 0 (outer boundary, pre-cracks); nodes on none are hidden from the tools.
    free_face = face_iface < 0
    if len(pairs.state):
        free_face |= pairs.state[np.maximum(face_iface, 0)] == PRECRACK
    contact_area, on_free_face = _contact_area(bulk.face_area, free_face)
    supports = support_constraints(supports, bulk.x0, scale)
    return Nodes(**body_arrays(bulk.x0, bulk.mass, contact_area, 0.0, supports, v,
                               np.where(on_free_face, NO_TOOL, HIDDEN)), force=np.zeros((n, 3)))


# A hole's stress concentration: the factor on a pressure's stress in the bound below.
_CONCENTRATION = 3.0


def _fracture_reachable(materials, nodes, tools, pressures, precracks, gravity, scale, element_size,
                        end_time) -> bool:
    """Whether the loads could bring an interface to the weakest tensile strength by end_time,
    by a generous upper bound of the stress they can cause: an impact rho c_p v at the fastest
    relative speed of specimen and tools, a tool's whole travel squeezed into one element
    E u / h, a pressure times a hole's concentration, the weight rho |g| L. A pre-crack under any
    load concentrates stress without bound."""
    ft = min(mat.interface.tensile_strength for mat in materials)
    rho, E = max(mat.density for mat in materials), max(mat.youngs_modulus for mat in materials)
    c_p = max(mat.p_wave_speed for mat in materials)
    tool_speed = max((max(abs(v) for v in t.speed.values) for t in tools), default=0.0)
    node_speed = float(np.sqrt(np.max(np.einsum("ij,ij->i", nodes.v, nodes.v)))) if len(nodes.v) else 0.0
    pressure = max((max(abs(v) for v in p.history.values) for p in pressures), default=0.0)
    loaded = tool_speed > 0 or node_speed > 0 or pressure > 0 or np.any(gravity)
    if precracks and loaded:
        return True
    bound = max(
        rho * c_p * (node_speed + tool_speed),
        E * tool_speed * end_time / element_size,
        _CONCENTRATION * pressure,
        rho * float(np.linalg.norm(gravity)) * scale,
    )
    return bound >= ft


# While every extrinsic face is tied a run takes k = floor(tied / dt) steps at once, and after the
# first insertion it sub-steps each of them k times (fdem.simulation): the step after insertion is
# then the step, never shorter than without the tied phase. Below 2, k = 1: nothing to gain.
TIED_STEP_GAIN = 2.0


def _tied_step(bulk: _Bulk, pairs: _Pairs, face_iface, surface_penalty: float, tool_penalty: float, ties,
               dt: float) -> float:
    """The step while the extrinsic faces are tied (time_step.time_step on the clusters), where
    at least TIED_STEP_GAIN x dt; 0.0 otherwise or without tied faces."""
    tied = ties.tied == TIED
    if not tied.any():
        return 0.0
    cluster = np.unique(ties.leader, return_inverse=True)[1].astype(np.int64)
    tied_dt = time_step(bulk, pairs, face_iface, surface_penalty, tool_penalty, tied=tied, cluster=cluster).dt
    return tied_dt if tied_dt >= TIED_STEP_GAIN * dt else 0.0


def _resolution_warnings(materials, element_size: float) -> list[str]:
    out = []
    for mat in materials:
        pz = mat.process_zone
        if element_size > pz.advised_element_size:
            out.append(
                f"element size {element_size * 1e3:.3g} mm is coarser than the advised "
                f"{pz.advised_element_size * 1e3:.3g} mm for material '{mat.name}' (a third of the "
                f"long-crack plastic zone {pz.plastic_zone_long * 1e3:.3g} mm): the fracture process "
                "zone is under-resolved and peak loads will be over-estimated"
            )
    return out


# A mesh made of one repeated cell (a structured box: 12 face orientations up to sign) offers its
# cracks a few planes; an unstructured one, an orientation per face (631 of 678 faces on the quick
# direct-tension bar). Above this many distinct orientations a mesh counts as unstructured.
STRUCTURED_ORIENTATIONS = 24


def _orientation_bias_warnings(materials, pairs: _Pairs, x0: np.ndarray) -> list[str]:
    """One line per material whose law opens a face on its own normal traction alone (paper 001's
    literal law, the bilinear law's maximum criterion) where its faces are unstructured: a crack
    then zigzags over inclined faces and the specimen reads stronger than its tensile strength."""
    out = []
    for row, mat in enumerate(materials):
        key = mat.interface.opens_on_normal_traction
        if key is None:
            continue
        corners = x0[pairs.na[pairs.law == row]]
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        largest = np.argmax(np.abs(normal), axis=1)
        normal *= np.sign(normal[np.arange(len(normal)), largest])[:, None]  # n and -n: one orientation
        orientations = len(np.unique(np.round(normal, 3), axis=0))
        if orientations > STRUCTURED_ORIENTATIONS:
            out.append(
                f"material '{mat.name}': {key} on an unstructured mesh ({orientations:,} face orientations) opens a face "
                "on its own normal traction alone, so a crack zigzagging over inclined faces makes the specimen "
                "1.2-1.9x stronger than its tensile strength (docs/validation.md, \"Strength objectivity\"); the default "
                "law does not"
            )
    return out


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

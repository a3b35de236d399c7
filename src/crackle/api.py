"""Python entry points: build a scenario into a simulation and run it."""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np

from . import geometry
from .analysis import CrackSettings, FracturePlane
from .geometry import MeshError, TetMesh
from .loading import History, Precrack, Pressure, Selection, Support, Tool, load_surface
from .materials import BilinearLaw, GuoMunjizaLaw, Material
from .scenario import Scenario, ScenarioError, load_scenario, resolve_path
from .solver import RunControl, RunResult, StopConditions, run


def build_specimen(spec, base: Path | None) -> TetMesh:
    return build_specimen_regions(spec, base)[0]


def build_specimen_regions(spec, base: Path | None) -> tuple[TetMesh, np.ndarray | None]:
    """The specimen mesh and its per-tet region ids (walnut, shell: 0 face, 1 suture; else None)."""
    walls = dict(wall=spec.wall, suture_wall=spec.suture_wall, suture_band=spec.suture_band, layers=spec.layers)
    try:
        if spec.shape == "walnut":
            return geometry.walnut_shell(
                spec.length, spec.width, spec.thickness, spec.element_size, center=spec.center, **walls
            )
        if spec.shape == "shell":
            return geometry.shell_from_surface(
                resolve_path(spec.file, base), spec.element_size, suture_normal=spec.suture_normal,
                scale=spec.scale, offset=spec.center, **walls,
            )
    except MeshError as err:
        raise ScenarioError(f"specimen: {err}") from None
    return _build_mesh(spec, base), None


def _build_mesh(spec, base: Path | None) -> TetMesh:
    try:
        if spec.shape in ("box", "beam"):
            make = geometry.structured_box if spec.mesh == "structured" else geometry.gmsh_box
            return make(spec.size, spec.element_size, origin=spec.origin)
        if spec.shape == "sphere":
            return geometry.gmsh_sphere(0.5 * spec.diameter, spec.element_size, center=spec.center)
        if spec.shape in ("disc", "cylinder"):
            return geometry.gmsh_cylinder(0.5 * spec.diameter, spec.thickness, spec.element_size, center=spec.center, axis=spec.axis)
        path = Path(spec.file)
        if not path.is_absolute() and base is not None:
            path = base / path
        return geometry.read_mesh(path)
    except MeshError as err:
        raise ScenarioError(f"specimen: {err}") from None


def build_material(spec) -> Material:
    # The scenario's interface keys are the law's own field names; unset optional ones (None)
    # keep the law's defaults.
    law = spec.interface
    fields = law.model_dump(exclude={"law"}, exclude_none=True)
    interface = (BilinearLaw if law.law == "bilinear" else GuoMunjizaLaw)(**fields)
    return Material(
        density=spec.density,
        youngs_modulus=spec.youngs_modulus,
        poissons_ratio=spec.poissons_ratio,
        name=spec.name,
        interface=interface,
    )


def _history_of(spec) -> History:
    if spec.speed_table is not None:
        return History(tuple(spec.speed_table.time), tuple(spec.speed_table.speed))
    return History.ramp(spec.speed, spec.ramp_time)


def _selection(where) -> Selection:
    return Selection(where.plane_point, where.plane_normal, where.box_min, where.box_max, where.tol)


def rotation_matrix(angle_deg: float, axis) -> np.ndarray:
    """Right-handed rotation by `angle_deg` degrees about `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * (K @ K)


def build_tools(specs, base: Path | None = None, loading=None) -> list[Tool]:
    """Tools of a scenario; `loading` (a LoadingSpec) rotates all of them rigidly about its
    axis through its center: positions, directions, normals, axes and surface vertices."""
    R = None
    if loading is not None and loading.angle % 360.0 != 0.0:
        R = rotation_matrix(loading.angle, loading.axis)
        c0 = np.asarray(loading.center, dtype=float)

    def vec(v):
        return v if R is None else tuple(float(x) for x in R @ np.asarray(v, dtype=float))

    def point(p):
        return p if R is None else tuple(float(x) for x in c0 + R @ (np.asarray(p, dtype=float) - c0))

    tools = []
    for i, t in enumerate(specs):
        surface = {}
        if t.shape == "surface":
            path = resolve_path(t.file, base)
            try:
                vertices, triangles = load_surface(path, scale=t.scale, offset=t.offset)
            except ValueError as err:  # MeshError included
                raise ScenarioError(f"tools.{i}.file: {err}") from None
            if R is not None:
                vertices = c0 + (np.asarray(vertices, dtype=float) - c0) @ R.T
            surface = {"surface": str(path), "vertices": vertices, "triangles": triangles}
        tools.append(
            Tool(
                name=t.name,
                shape=t.shape,
                direction=vec(t.direction),
                speed=_history_of(t),
                friction=t.friction,
                center=point(t.center),
                normal=vec(t.normal),
                size=t.size,
                axes=(vec(t.axes[0]), vec(t.axes[1])),
                axis=vec(t.axis),
                radius=t.radius,
                length=t.length,
                penalty=t.penalty,
                **surface,
            )
        )
    return tools


def touch_specimen(tool: Tool, points: np.ndarray) -> Tool:
    """The tool shifted along its direction so that its leading extreme along the direction lies
    on the specimen's extreme point along it: a platen placed on the mesh as meshed, whatever
    the facets of a curved surface and the loading angle."""
    d = np.asarray(tool.direction, dtype=float)
    d /= np.linalg.norm(d)
    c = np.asarray(tool.center, dtype=float)
    if tool.shape == "sphere":
        lead = float(c @ d) + tool.radius
    else:  # box: the corner furthest along d
        a1 = np.asarray(tool.axes[0], dtype=float)
        a1 /= np.linalg.norm(a1)
        a2 = np.asarray(tool.axes[1], dtype=float)
        a2 = a2 - (a2 @ a1) * a1
        a2 /= np.linalg.norm(a2)
        a3 = np.cross(a1, a2)
        half = 0.5 * np.asarray(tool.size, dtype=float)
        lead = float(c @ d) + sum(h * abs(float(a @ d)) for h, a in zip(half, (a1, a2, a3)))
    shift = float(np.min(points @ d)) - lead
    return dataclasses.replace(tool, center=tuple(float(x) for x in c + shift * d))


def build_pressures(specs, end_time: float) -> list[Pressure]:
    out = []
    for p in specs:
        if p.rate is not None:
            history = History.rate(p.rate, end_time)
        elif p.table is not None:
            history = History(tuple(p.table.time), tuple(p.table.speed))
        else:
            history = History.ramp(p.value, p.ramp_time)
        out.append(Pressure(history, "precrack" if p.faces == "precrack" else _selection(p.where)))
    return out


def build_simulation(scenario: Scenario, base: Path | None = None):
    """The simulation object and run control for a validated scenario."""
    from .fdem.model import build_fdem_model
    from .fdem.simulation import FdemSimulation

    tool_specs = scenario.all_tools()
    tools = build_tools(tool_specs, base, scenario.loading)  # before meshing: a bad surface file fails fast
    mesh, region = build_specimen_regions(scenario.specimen, base)
    tools = [touch_specimen(t, mesh.points) if spec.touch else t for t, spec in zip(tools, tool_specs)]
    material = build_material(scenario.material)
    tet_material = None
    if region is not None and scenario.suture is not None:
        # Material 1 on the suture tets; a face-suture interface takes the weaker law.
        material = [material, build_material(scenario.suture)]
        tet_material = region
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the model keeps its warnings for the summary
            model = build_fdem_model(
                mesh,
                material,
                tet_material,
                tools=tools,
                supports=[Support(s.kind, _selection(s.where), s.normal) for s in scenario.supports],
                pressures=build_pressures(scenario.pressures, scenario.run.end_time),
                precracks=[Precrack(c.point, c.normal, c.box_min, c.box_max, c.tol) for c in scenario.precracks],
                gravity=scenario.run.gravity,
                damping=scenario.run.damping,
                initial_velocity=scenario.specimen.initial_velocity,
                contact=scenario.run.contact,
            )
    except (ValueError, MeshError) as err:
        raise ScenarioError(str(err)) from None
    r = scenario.run
    control = RunControl(
        end_time=r.end_time,
        dt=r.dt,
        safety=r.safety,
        history_samples=r.history_samples,
        field_frames=r.field_frames,
        stop=StopConditions(r.stop.tool_displacement, r.stop.tool, r.stop.force_drop, r.stop.force_drop_hold),
    )
    try:
        from .solver import choose_time_step

        choose_time_step(model.stable_dt, control)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    sim = FdemSimulation(model)
    plane = scenario.analysis.fracture_plane
    if plane is not None:
        size = float(np.max(np.subtract(*mesh.bounds()[::-1])))
        tol = plane.tol if plane.tol is not None else 1e-6 * size
        sim.fracture_plane = FracturePlane(plane.point, plane.normal, plane.direction, tol)
    cracks = scenario.analysis.cracks
    if cracks is not None:
        sim.crack_settings = CrackSettings(
            wall=cracks.wall if cracks.wall is not None else scenario.specimen.wall,
            scale=cracks.scale if cracks.scale is not None else 2.0 * model.element_size,
            top=cracks.top,
        )
    return sim, control


def run_scenario(source, out_dir=None, overrides: list[str] | None = None, quick: bool = False, progress=None) -> RunResult:
    """Validate, build and run a scenario file or shipped example; returns the result."""
    scenario, base = load_scenario(source, overrides, quick)
    sim, control = build_simulation(scenario, base)
    control.progress = progress
    out = Path(out_dir) if out_dir is not None else Path("crackle-out") / scenario.name
    return run(sim, control, out, scenario_name=scenario.name)

"""The shell's scenario sections and the build of a scenario into a ShellSimulation.

[shell] the mid-surface (a rectangle meshed at element_size, or any triangle surface meshio
reads) and its thickness; [material] the elastic constants; [[regions]] triangles with their own
thickness or material; [[cracks]] pre-cracks as polylines on
the surface (cut along the nearest chain of edges); [[edge_loads]] tractions on boundary edges; [[pressures]] the shared section on triangles (a side
to act from, optionally a travelling front);
[fracture] the J-integral's rings and the closed form to compare with. Tools, supports, run
control and outputs are the shared ones.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from ..geometry.meshes import MeshError, read_with_meshio
from ..geometry.specimens import check_file_units
from ..loading import History
from ..loading.arrays import HistoryTable, default_tool_penalty, history_tables
from ..loading.build import selection
from ..scenario import ElasticSpec, ScenarioBase, ScenarioError, Where, resolve_path
from ..materials import Material
from ..materials.random_properties import RandomProperty, check_names
from ..schema import NonNegative, Positive, PositiveOrInf, Strict, Vec3
from ..solver.setup import SetUp, supports_on, tool_stiffness
from .kernels import BLOCK, LoadFactor
from .mesh import SurfaceError, cylinder, edge_path, rectangle, shell_mesh, split_along
from .model import ShellMaterial, build_shell, edge_loads
from .growth import RANDOM_SITE_PROPERTIES, GrowthLaw, RandomSites
from .simulation import CrackTip, ShellSimulation


class ShellSpec(Strict):
    """[shell]: the mid-surface and its thickness."""

    surface: Literal["rectangle", "cylinder", "file"]
    """rectangle: size and element_size, in the x-y plane from origin; cylinder: radius, length and element_size,
    along z from origin (the centre of its first end), open ends, normals outward; file: a triangle surface
    (file)"""
    thickness: Positive
    """m, the shell's thickness"""
    size: tuple[Positive, Positive] | None = None
    """m, rectangle: its sides along x and y"""
    radius: Positive | None = None
    """m, cylinder: the mid-surface's radius"""
    length: Positive | None = None
    """m, cylinder: along z"""
    origin: Vec3 = (0.0, 0.0, 0.0)
    """m, rectangle: its lower corner; cylinder: the centre of its first end"""
    element_size: Positive | None = None
    """m, rectangle and cylinder: the side of their (nearly) square cells, two triangles each"""
    file: str | None = None
    """file: any triangle surface meshio reads (.stl, .msh, .obj, .vtu ...), relative to the scenario's folder; its
    triangles oriented alike"""
    scale: Positive = 1.0
    """file: multiplies its coordinates (e.g. 1e-3 for a file in mm)"""

    @model_validator(mode="after")
    def _keys_of_the_surface(self):
        need = {"rectangle": ("size", "element_size"), "cylinder": ("radius", "length", "element_size"),
                "file": ("file",)}[self.surface]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"surface '{self.surface}' needs {', '.join(missing)}")
        # The sizes in the file's own terms (a rectangle's sides; a cylinder's length and girth).
        sides = {"rectangle": self.size, "cylinder": (self.length, 2.0 * math.pi * self.radius)
                 if self.surface == "cylinder" else None}.get(self.surface)
        if sides is not None:
            if self.element_size > max(sides):
                raise ValueError(f"element_size = {self.element_size:g} m is larger than the {self.surface} "
                                 f"({max(sides):g} m across); sizes are in metres (10 mm is 0.01)")
            if self.thickness >= min(sides):
                raise ValueError(f"thickness = {self.thickness:g} m is not thin against the {self.surface} ({min(sides):g} m "
                                 "across): a Kirchhoff-Love shell is thin; sizes are in metres")
        return self


class ShellMaterialSpec(ElasticSpec):
    """[material] (and [regions.material]): density, elastic constants and the fracture properties drawn per site."""

    random: dict[str, RandomProperty] = {}
    """[material.random.NAME]: [fracture]'s values drawn per site, [fracture]'s value their mean (NAME: toughness, Gc
    per edge at its mid-point; strength, the nucleation strength per vertex of a free edge, at the vertex), in the
    reference configuration, from run.seed; a site between two materials takes the lower value"""

    @model_validator(mode="after")
    def _random_names(self):
        check_names(self.random, RANDOM_SITE_PROPERTIES, "material")
        return self


class RegionSpec(Strict):
    """[[regions]]: triangles with a thickness or material of their own (a later region wins where
    two overlap)."""

    where: Where
    """selects the triangles whose three corners it selects"""
    thickness: Positive | None = None
    """m; default [shell] thickness"""
    material: ShellMaterialSpec | None = None
    """density, elastic constants and [regions.material.random]; default [material]"""


class CrackSpec(Strict):
    """[[cracks]]: a through-crack present from the start."""

    polyline: Annotated[list[Vec3], Field(min_length=2)]
    """m, points on the mid-surface; the crack follows the chain of edges nearest to it, and an end inside the
    surface is a crack tip"""


class EdgeLoadSpec(Strict):
    """[[edge_loads]]: a traction on the boundary edges that `where` selects (both ends selected)."""

    where: Where
    """selects the edges' vertices"""
    traction: Vec3
    """Pa, force per area of the shell's cross-section (x thickness x edge length on each edge)"""
    ramp_time: NonNegative = 0.0
    """s, the traction grows linearly from 0 over this time, then stays"""


class FractureSpec(Strict):
    """[fracture]: the crack tips' J-integral."""

    j_rings: list[tuple[NonNegative, Positive]] = []
    """m, rings (r_in, r_out) about each tip for the J-integral's domain; default three rings at 4-10, 8-14 and 12-18
    element sizes"""
    toughness: PositiveOrInf = math.inf
    """J/m^2, Gc: a tip grows where its J (mean over the rings) reaches it (Griffith; inf: no growth)"""
    max_speed: Positive | None = None
    """m/s, V_max of the speed law V = V_max min(1, (J / Gc - 1)^m); default the Rayleigh wave speed"""
    speed_exponent: Positive = 1.0
    """m of the speed law"""
    criterion: Literal["j", "g"] = "j"
    """what Griffith's check compares with Gc: j, the J-integral (the membrane's Eshelby stress as a domain integral,
    the bending and the loads' shares as the virtual extension reads them), or g, G by virtual crack extension of the
    whole energy; both hold bending and pressure and agree to ~1e-5 (the membrane's two readings)"""
    strength: PositiveOrInf = math.inf
    """Pa: a free edge (the sheet's boundary or a hole's, not a crack's faces, a load or a support holding it in
    plane) starts a crack where its membrane stress along the edge reaches this, running into the sheet normal to
    the edge; the crack then grows by toughness (inf: no nucleation; needs a finite toughness)"""
    kink: Literal["mts", "merr"] = "mts"
    """the direction a growing tip turns to: mts, the maximum tangential stress (Erdogan-Sih: -70.5 deg in pure mode
    II), or merr, the maximum energy release rate of an infinitesimal kink (Hussain-Pu-Underwood, paper 002's
    criterion: -75.2 deg in pure mode II); both from the tip's K_I, K_II (K_III counted with the opening)"""
    reference: Literal["none", "centre-crack", "axial-crack-folias"] = "none"
    """the closed form in summary.json's j_reference: centre-crack, K^2 / E with K = sigma sqrt(pi a) times Tada's
    width factor, for one crack inside a rectangle pulled by its edge loads; axial-crack-folias, (M sigma
    sqrt(pi a))^2 / E for an axial crack in a cylinder under internal pressure (sigma = p R / t), j_bracket the
    values of two estimates of the bulging factor M (Folias, Kiefner) and j_reference their geometric mean"""

    @model_validator(mode="after")
    def _rings_open(self):
        for i, (r_in, r_out) in enumerate(self.j_rings):
            if not r_in < r_out:
                raise ValueError(f"j_rings.{i}: ({r_in:g}, {r_out:g}) m: a ring needs r_in < r_out; give (inner, outer) "
                                 "radii about the tip, e.g. (0.005, 0.01)")
        return self


class Scenario(ScenarioBase):
    method: Literal["shell"]
    """picks this method"""
    reads = frozenset({"run.damping", "pressures"})
    shell: ShellSpec
    """the mid-surface and its thickness"""
    material: ShellMaterialSpec
    """density, elastic constants and the fracture properties drawn per site"""
    regions: list[RegionSpec] = []
    """parts of the surface with their own thickness or material"""
    cracks: list[CrackSpec] = []
    """pre-cracks"""
    edge_loads: list[EdgeLoadSpec] = []
    """tractions on boundary edges"""
    fracture: FractureSpec = FractureSpec()
    """the J-integral's rings and reference"""

    @model_validator(mode="after")
    def _loads_and_references(self):
        ramps = {load.ramp_time for load in self.edge_loads}
        if len(ramps) > 1:
            raise ValueError("edge_loads: give every edge load the same ramp_time (the shell has one load history)")
        for i, pressure in enumerate(self.pressures):
            if pressure.faces != "where" or pressure.wall is None:
                raise ValueError(f'pressures.{i}: on a shell give faces = "where" (a triangle is loaded when its three '
                                 'corners are selected) and wall = "inner" (the pressure pushes along the triangles\' '
                                 'normals) or "outer" (against them)')
            if pressure.front_speed is not None and pressure.front_direction is None and self.shell.surface != "cylinder":
                raise ValueError(f"pressures.{i}.front_direction: needed for a front on a surface that is not a cylinder")
        if self.fracture.reference == "centre-crack" and (self.shell.surface != "rectangle" or len(self.cracks) != 1
                                                          or not self.edge_loads):
            raise ValueError('fracture.reference = "centre-crack" needs surface = "rectangle", one crack and edge '
                             "loads")
        if self.fracture.reference == "axial-crack-folias" and (self.shell.surface != "cylinder"
                                                                or len(self.cracks) != 1 or len(self.pressures) != 1):
            raise ValueError('fracture.reference = "axial-crack-folias" needs surface = "cylinder", one crack and one '
                             "pressure")
        for key, material in [("material", self.material)] + [(f"regions.{i}.material", region.material)
                                                               for i, region in enumerate(self.regions)
                                                               if region.material is not None]:
            for name in material.random:
                if not math.isfinite(getattr(self.fracture, name)):
                    raise ValueError(f"{key}.random.{name}: its mean is fracture.{name}, which is inf (off); give a "
                                     f"finite fracture.{name} or remove [{key}.random.{name}]")
        return self


def build_simulation(scenario: Scenario, base: Path | None = None) -> ShellSimulation:
    spec, mat = scenario.shell, scenario.material
    planned = _planned_triangles(spec)
    setup = SetUp(scenario, base, None if planned is None else (planned, "triangles", "shell.element_size"))
    tools, supports, pressures = setup.tools, setup.supports, setup.pressures
    try:
        mesh = _surface(spec, base)
    except (SurfaceError, MeshError) as err:
        raise ScenarioError(f"shell.{'file' if spec.surface == 'file' else 'size'}: {err}") from None
    if spec.surface == "file":
        try:
            check_file_units(mesh.X, tools, "scale" in spec.model_fields_set, "shell.file")
        except ValueError as err:
            raise ScenarioError(str(err)) from None
    mesh, material = _regions(mesh, scenario)
    tips, pre_cracks = [], []
    for i, crack in enumerate(scenario.cracks):
        try:
            path = edge_path(mesh, crack.polyline)
            if len(path) < 2:
                raise SurfaceError("the polyline is shorter than an element")
            pre_cracks.append(mesh.X[path].copy())
            mesh, opened = split_along(mesh, path)
        except SurfaceError as err:
            raise ScenarioError(f"cracks.{i}.polyline: {err}") from None
        tips += _tips(mesh, path, opened)
    scale = float(np.max(np.ptp(mesh.X, axis=0)))
    clamped = np.zeros(len(mesh.X), dtype=bool)
    for support in supports:
        if support.kind == "clamped":
            clamped |= support.where.mask(mesh.X, scale)
    shell = build_shell(mesh, material, clamped if clamped.any() else None)
    load = np.zeros_like(mesh.X)
    boundary = np.flatnonzero(mesh.boundary)
    for i, edge_load in enumerate(scenario.edge_loads):
        chosen = selection(edge_load.where).mask(mesh.X, scale)
        edges = boundary[chosen[mesh.edge[boundary, 0]] & chosen[mesh.edge[boundary, 1]]]
        if len(edges) == 0:
            raise ScenarioError(f"edge_loads.{i}.where: selects no boundary edge (both ends of an edge must be "
                                "selected); check its plane or box")
        load += edge_loads(mesh, edges, edge_load.traction)
    pressure_table = _pressures(shell, pressures, scale)
    ramp = scenario.edge_loads[0].ramp_time if scenario.edge_loads else 0.0
    factor = LoadFactor(np.array([0.0, ramp]) if ramp > 0 else np.array([0.0]),
                        np.array([0.0, 1.0]) if ramp > 0 else np.array([1.0]), 2 if ramp > 0 else 1)
    constraint, projection, support_tool = supports_on(supports, mesh.X, scale)
    h = mesh.element_size()
    shell.nodes = shell.nodes._replace(load=load, constraint=constraint, projection=projection,
                                       support_tool=support_tool)
    tool_table = setup.tools_on(shell.nodes, default_tool_penalty(mat.youngs_modulus, h), h, -(-len(mesh.X) // BLOCK),
                                "nodes")
    stable_dt = shell.stable_dt(tool_stiffness(tool_table, shell.nodes.area))
    c = math.sqrt(mat.youngs_modulus / (mat.density * (1.0 - mat.poissons_ratio**2)))
    fracture = scenario.fracture
    rings = fracture.j_rings or [(4 * h, 10 * h), (8 * h, 14 * h), (12 * h, 18 * h)]
    growth = None
    if math.isfinite(fracture.strength) and not math.isfinite(fracture.toughness):
        raise ScenarioError("fracture.strength: a crack started at an edge grows by Griffith; give fracture.toughness "
                            "(J/m^2) too, or remove fracture.strength")
    # The materials in region order (_regions) and the properties they draw per site.
    materials = [mat] + [region.material for region in scenario.regions if region.material is not None]
    sites = RandomSites.of([dict(m.random) for m in materials], [m.name for m in materials],
                           {"toughness": fracture.toughness, "strength": fracture.strength}, scenario.run.seed)
    if math.isfinite(fracture.toughness):
        growth = GrowthLaw(fracture.toughness, fracture.max_speed or rayleigh_speed(mat), fracture.speed_exponent,
                           fracture.criterion, fracture.kink, fracture.strength, sites)
    sim = ShellSimulation(shell, tool_table, setup.tool_names, factor, pressure_table, tips, rings, stable_dt,
                          h / c, np.asarray(scenario.run.gravity, float), scenario.run.damping, growth)
    sim.warnings.extend(setup.warnings)
    sim.pre_cracks = pre_cracks
    if sites is not None:
        sim.random_properties = sites.statistics(sim.shell.mesh, [m.name for m in materials])
    if fracture.reference != "none" and len(tips) != 2:
        raise ScenarioError(f'fracture.reference = "{fracture.reference}": the crack must have two tips inside the '
                            "surface")
    if fracture.reference == "centre-crack":
        sim.j_reference = centre_crack_reference(scenario, [mesh.X[tip.vertex] for tip in tips],
                                                 [tip.direction for tip in tips])
    elif fracture.reference == "axial-crack-folias":
        a = 0.5 * float(np.linalg.norm(mesh.X[tips[0].vertex] - mesh.X[tips[1].vertex]))
        sim.j_bracket = folias_bracket(a, spec.radius, spec.thickness, abs(pressures[0].history.values[-1]),
                                       mat.youngs_modulus)
        sim.j_reference = math.sqrt(sim.j_bracket[0] * sim.j_bracket[1])
    return sim


def _regions(mesh, scenario: Scenario):
    """The mesh with each triangle's thickness and region set by [[regions]], and the shell's
    materials: [material] first (region 0), then one per region that names its own."""
    materials = [scenario.material]
    thickness, region = mesh.thickness.copy(), mesh.region.copy()
    scale = float(np.max(np.ptp(mesh.X, axis=0)))
    for i, spec in enumerate(scenario.regions):
        chosen = selection(spec.where).face_mask(mesh.X, mesh.tri, scale)
        if not chosen.any():
            raise ScenarioError(f"regions.{i}.where: selects no triangle (all three corners must be selected); check "
                                "its plane or box")
        if spec.thickness is not None:
            thickness[chosen] = spec.thickness
        if spec.material is not None:
            region[chosen] = len(materials)
            materials.append(spec.material)
    material = ShellMaterial(*(np.array([getattr(m, key) for m in materials])
                               for key in ("density", "youngs_modulus", "poissons_ratio")))
    return replace(mesh, thickness=thickness, region=region), material


def _pressures(shell, pressures, scale) -> HistoryTable:
    """Each pressure's triangles (all three corners selected) in Faces, with its side and a front's
    delays; the histories as a table."""
    mesh, faces = shell.mesh, shell.faces
    centroids = mesh.X[mesh.tri].mean(axis=1)
    for k, pressure in enumerate(pressures):
        chosen = pressure.faces.face_mask(mesh.X, mesh.tri, scale)
        if not chosen.any():
            raise ScenarioError(f"pressures.{k}.where: selects no triangle (all three corners must be selected)")
        faces.pressure[chosen] = k
        faces.pressure_sign[chosen] = 1.0 if pressure.wall == "inner" else -1.0
        if pressure.front_speed is not None:
            direction = np.asarray(pressure.front_direction or (0.0, 0.0, 1.0), float)
            along = (centroids[chosen] - np.asarray(pressure.front_origin, float)) @ (direction / np.linalg.norm(direction))
            faces.pressure_delay[chosen] = along / pressure.front_speed
    return history_tables([p.history for p in pressures] or [History.constant(0.0)])


def _planned_triangles(spec: ShellSpec) -> float | None:
    """About how many triangles shell.element_size asks for (rectangle, cylinder; 4 per cell at most)."""
    if spec.surface == "rectangle":
        return 4.0 * math.prod(max(1.0, L / spec.element_size) for L in spec.size)
    if spec.surface == "cylinder":
        return 4.0 * max(3.0, 2.0 * math.pi * spec.radius / spec.element_size) * max(1.0, spec.length / spec.element_size)
    return None


def _surface(spec: ShellSpec, base: Path | None):
    if spec.surface == "rectangle":
        nx, ny = (max(1, int(round(L / spec.element_size))) for L in spec.size)
        return rectangle(spec.size[0], spec.size[1], nx, ny, spec.thickness, spec.origin)
    if spec.surface == "cylinder":
        around = max(3, int(round(2.0 * math.pi * spec.radius / spec.element_size)))
        along = max(1, int(round(spec.length / spec.element_size)))
        return cylinder(spec.radius, spec.length, around, along, spec.thickness, spec.origin)
    # meshio's failures (and its sys.exit on a file no reader takes) as one MeshError
    surface = read_with_meshio(resolve_path(spec.file, base), hint="give a triangle surface (.stl, .obj, .msh, .vtu)")
    triangles = [block.data for block in surface.cells if block.type == "triangle"]
    if not triangles:
        raise MeshError(f"{spec.file} holds no triangles")
    return shell_mesh(surface.points[:, :3] * spec.scale, np.concatenate(triangles), spec.thickness)


def _tips(mesh, path, opened) -> list[CrackTip]:
    """The ends of a cut path that stayed whole (inside the surface; an end on the boundary
    opens, a mouth), each with the direction the crack last ran."""
    tips = []
    for end, before in ((path[-1], path[-2]), (path[0], path[1])):
        if end not in opened:
            direction = mesh.X[end] - mesh.X[before]
            tips.append(CrackTip(int(end), direction / np.linalg.norm(direction)))
    return tips


def folias_bracket(a: float, radius: float, thickness: float, pressure: float, youngs_modulus: float) -> list[float]:
    """J = (M sigma sqrt(pi a))^2 / E (J/m^2) of an axial crack 2a in a pressurised cylinder,
    sigma = p R / t, for two estimates of the bulging factor with lambda = a / sqrt(R t): Kiefner's
    M = sqrt(1 + 1.255 lambda^2 - 0.0135 lambda^4) and Folias' M = sqrt(1 + 1.61 lambda^2); sorted."""
    lam2 = a * a / (radius * thickness)
    sigma = pressure * radius / thickness
    values = [(m2 * sigma**2 * math.pi * a) / youngs_modulus
              for m2 in (1.0 + 1.255 * lam2 - 0.0135 * lam2 * lam2, 1.0 + 1.61 * lam2)]
    return sorted(values)


def rayleigh_speed(material: ElasticSpec) -> float:
    """m/s, the Rayleigh speed of the shell's material (Material.rayleigh_speed)."""
    return Material(material.density, material.youngs_modulus, material.poissons_ratio).rayleigh_speed


def centre_crack_reference(scenario: Scenario, tips: list[np.ndarray], directions: list[np.ndarray]) -> float:
    """J = K^2 / E (J/m^2) of a centre crack 2a across a strip of width 2b under the traction
    sigma of its edge loads: K = sigma sqrt(pi a) (1 - 0.025 alpha^2 + 0.06 alpha^4)
    sqrt(sec(pi alpha / 2)), alpha = a / b (Tada's handbook; 0.1 %)."""
    a = 0.5 * float(np.linalg.norm(tips[0] - tips[1]))
    along = np.abs(directions[0][:2])
    width = scenario.shell.size[0] if along[0] >= along[1] else scenario.shell.size[1]
    sigma = max(float(np.linalg.norm(load.traction)) for load in scenario.edge_loads)
    alpha = a / (0.5 * width)
    K = sigma * math.sqrt(math.pi * a) * (1 - 0.025 * alpha**2 + 0.06 * alpha**4) * math.sqrt(
        1.0 / math.cos(math.pi * alpha / 2.0))
    return K**2 / scenario.material.youngs_modulus

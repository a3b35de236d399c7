"""FDEM's scenario sections and the build of a validated scenario into an FdemSimulation."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Discriminator, Tag, model_validator

from ..analysis import CrackSettings, FracturePlane
from ..analysis.strength import BrazilianTest, TensionTest, mean_section, pulling_grip
from ..geometry import MeshError
from ..geometry.specimens import check_file_units, planned_tets, specimen_mesh
from ..loading.build import build_precracks, touch_tools, with_named_surfaces
from ..materials import Material
from ..materials.random_properties import RandomProperty, check_names
from ..scenario import (OPTIONAL_KEYS, ElasticSpec, MaterialPlace, PrecrackSpec, ScenarioBase, ScenarioError, Specimen,
                        assign_materials, check_material_tables, check_one_rest, material_pair)
from .laws import LAWS
from .model import build_fdem_model
from ..solver.platen import Platen, PlatenProbe, facing_tool
from ..solver.setup import SetUp
from ..solver.simulation import PeakForceProbe
from .probes import BrazilianProbe, CrackProbe, FractureTipProbe
from .simulation import FdemSimulation


def _law_tag(value):
    law = value.get("law", "guo-munjiza") if isinstance(value, dict) else getattr(value, "law", "guo-munjiza")
    return law if law in LAWS else None


# [material.interface]: one of the laws by its `law` name ("guo-munjiza" when left out); each
# law's parameter class is its own schema.
InterfaceSpec = Annotated[
    Union[tuple(Annotated[cls, Tag(name)] for name, cls in LAWS.items())],
    Discriminator(
        _law_tag,
        custom_error_type="law",
        custom_error_message="law must be one of " + ", ".join(f'"{name}"' for name in LAWS),
    ),
]


class FdemMaterialSpec(ElasticSpec):
    interface: InterfaceSpec
    """[material.interface]: the interface law between tets, by `law`"""
    random: dict[str, RandomProperty] = {}
    """[material.random.NAME]: properties of the interface law drawn per face (NAME: tensile_strength, cohesion
    (guo-munjiza) or shear_strength (bilinear), fracture_energy, fracture_energy_shear), the law's value their mean;
    each face's value at its centroid, from run.seed"""

    @model_validator(mode="after")
    def _random_names(self):
        check_names(self.random, tuple(type(self.interface).RANDOM), "material")
        return self


class FdemNamedMaterial(FdemMaterialSpec, MaterialPlace):
    """[materials.NAME]: one of several materials (the keys of [material]), and where it is: a group of the mesh
    file's or zones; the one with neither fills the rest."""


class Scenario(ScenarioBase):
    """An FDEM scenario: a tet specimen, its material(s) with an interface law, pre-cracks."""

    method: Literal["fdem"] = "fdem"
    """picks this method (the default)"""
    reads = frozenset(OPTIONAL_KEYS)  # every shared key: mass scaling, contact, the analyses, the initial stress
    specimen: Specimen
    """the solid and its mesh"""
    material: FdemMaterialSpec | None = None
    """the bulk's elasticity and the interface law (one material; [materials.NAME] for several)"""
    materials: dict[str, FdemNamedMaterial] = {}
    """[materials.NAME]: several materials, each where its group or zones say (instead of [material])"""
    interfaces: dict[str, InterfaceSpec] = {}
    """[interfaces."A-B"]: the law of the faces between materials A and B (an interfacial zone, a bedding plane);
    default: the law of the one with the lower tensile strength"""
    suture: FdemMaterialSpec | None = None
    """walnut and shell: the suture band's own material (same keys as [material]); without it the suture is
    [material] too and differs only by its wall thickness"""
    precracks: list[PrecrackSpec] = []
    """cracks present at t = 0"""

    @model_validator(mode="after")
    def _fdem_checks(self):
        check_material_tables(self.material, self.materials)
        if self.materials:
            self._check_materials()
        elif self.interfaces:
            raise ValueError("[interfaces] names pairs of [materials.NAME]; with one [material] there is none")
        if self.suture is not None and self.materials:
            raise ValueError("[suture] goes with one [material]; with [materials.NAME] give the suture its own zone")
        if self.suture is not None and self.specimen.shape not in ("walnut", "shell"):
            raise ValueError(f"[suture] is for specimen shapes 'walnut' and 'shell' (this one is '{self.specimen.shape}')")
        if any(p.faces == "precrack" for p in self.pressures) and not self.precracks:
            raise ValueError("a pressure on faces = 'precrack' needs a [[precracks]] entry")
        for i, p in enumerate(self.pressures):
            for key in ("front_speed", "wall"):
                if getattr(p, key) is not None:
                    raise ValueError(f"pressures.{i}.{key}: not available for the FDEM method (a travelling front and "
                                     "wall faces are the meshfree method's, on a tube); remove it")
        cracks = self.analysis.cracks
        if cracks is not None and cracks.wall is None and self.specimen.shape not in ("walnut", "shell"):
            raise ValueError("analysis.cracks.wall: give the shell's wall thickness in m (only walnut and shell specimens know their own)")
        return self


    def _check_materials(self) -> None:
        check_one_rest(self.materials)
        grouped = [name for name, m in self.materials.items() if m.group is not None]
        if grouped and self.specimen.shape != "mesh":
            raise ValueError(f"materials.{grouped[0]}.group: groups come from a mesh file (specimen.shape = \"mesh\"); "
                             "for a built-in shape give zones")
        for key in self.interfaces:
            material_pair(key, list(self.materials))

    def pair_laws(self) -> dict[tuple[int, int], object]:
        """[interfaces."A-B"] by the materials' indices (in [materials] order), both ways round."""
        names = list(self.materials)
        laws = {}
        for key, law in self.interfaces.items():
            a, b = material_pair(key, names)
            laws[names.index(a), names.index(b)] = laws[names.index(b), names.index(a)] = law
        return laws

    def weakest_tensile_strength(self) -> float:
        """Pa: the lowest tensile strength of the materials' and the pairs' laws (a bar's nominal strength's reference)."""
        if self.material is not None:
            return self.material.interface.tensile_strength
        laws = [m.interface for m in self.materials.values()] + list(self.interfaces.values())
        return min(law.tensile_strength for law in laws)


def build_material(spec: FdemMaterialSpec, name: str | None = None) -> Material:
    return Material(
        density=spec.density,
        youngs_modulus=spec.youngs_modulus,
        poissons_ratio=spec.poissons_ratio,
        name=spec.name if name is None else name,
        interface=spec.interface,
        random=dict(spec.random),
    )


# gmsh meshes curved specimens with at least a few elements around a circle and through a thin
# part, whatever size is asked for. Asked-for sizes give a mean edge of 0.95-1.25 of it; below
# this fraction the request was overridden.
_CLAMPED_BELOW = 0.7


def _clamped_size_warning(spec: Specimen, mesh) -> str:
    """A warning when gmsh meshed a specimen much finer than specimen.element_size asks."""
    gmsh_meshed = spec.shape in ("disc", "cylinder", "sphere") or (spec.shape in ("box", "beam") and spec.mesh == "unstructured")
    if not gmsh_meshed or spec.element_size is None:
        return ""
    achieved = mesh.element_size()
    if achieved >= _CLAMPED_BELOW * spec.element_size:
        return ""
    return (
        f"specimen.element_size = {spec.element_size * 1e3:.3g} mm is too coarse for this {spec.shape}: gmsh meshed it at "
        f"{achieved * 1e3:.3g} mm (mean edge; it keeps a few elements around curved and through thin parts), "
        f"{mesh.n_tets:,} tets; the run uses that mesh: set element_size <= {achieved * 1e3:.2g} mm to say what you get"
    )


# Tets across the smallest aggregate below which it is a few tets or none (by centroid).
_TETS_ACROSS_AGGREGATE = 2.0


def _unresolved_aggregates(scenario: Scenario, mesh) -> list[str]:
    """A warning per aggregates zone whose smallest aggregates are under two element sizes across."""
    h = scenario.specimen.element_size or mesh.element_size()
    out = []
    for name, spec in scenario.materials.items():
        for k, zone in enumerate(spec.zones):
            if zone.shape == "aggregates" and zone.min_diameter < _TETS_ACROSS_AGGREGATE * h:
                out.append(f"materials.{name}.zones.{k}: min_diameter = {zone.min_diameter * 1e3:.3g} mm is under "
                           f"{_TETS_ACROSS_AGGREGATE:g} elements of {h * 1e3:.3g} mm: the smallest aggregates are a "
                           f"tet or two, or none (a tet takes them by its centroid); set specimen.element_size <= "
                           f"{zone.min_diameter / _TETS_ACROSS_AGGREGATE * 1e3:.2g} mm (a third of min_diameter "
                           f"resolves them)")
    return out


def _initial_stress(scenario: Scenario, mesh) -> np.ndarray | None:
    """Each tet's initial stress ([initial_stress] at its centroid), or None."""
    spec = scenario.initial_stress
    return None if spec is None else spec.at(mesh.points[mesh.tets].mean(axis=1))


def build_simulation(scenario: Scenario, base: Path | None = None) -> FdemSimulation:
    """The FdemSimulation of a validated scenario; ScenarioError for what cannot be built."""
    planned = planned_tets(scenario.specimen)
    setup = SetUp(scenario, base, None if planned is None else (
        planned, "tets", "specimen.element_size",
        "; a specimen in mm reads 1000x too large: its size, diameter and thickness are in metres too"))
    tools, supports, pressures = setup.tools, setup.supports, setup.pressures
    try:
        mesh, region = specimen_mesh(scenario.specimen, base, _zone_planes(scenario))
    except MeshError as err:
        raise ScenarioError(f"specimen: {err}") from None
    if scenario.specimen.shape in ("mesh", "shell"):
        try:
            check_file_units(mesh.points, tools, "scale" in scenario.specimen.model_fields_set, "specimen.file")
        except ValueError as err:
            raise ScenarioError(str(err)) from None
    tools = touch_tools(tools, scenario.all_tools(), lambda tool: mesh.points)
    try:
        supports, pressures = with_named_surfaces(supports, pressures, mesh.points, mesh.surfaces)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    tet_material, pair_laws = None, {}
    if scenario.materials:
        material = [build_material(spec, name) for name, spec in scenario.materials.items()]
        try:
            tet_material = assign_materials(scenario.materials, mesh.points[mesh.tets].mean(axis=1), mesh.groups)
        except ValueError as err:
            raise ScenarioError(str(err)) from None
        pair_laws = scenario.pair_laws()
    else:
        material = build_material(scenario.material)
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
                supports=supports,
                pressures=pressures,
                precracks=build_precracks(scenario.precracks),
                gravity=scenario.run.gravity,
                damping=scenario.run.damping,
                initial_velocity=scenario.specimen.initial_velocity,
                angular_velocity=scenario.specimen.angular_velocity,
                contact=scenario.run.contact,
                end_time=scenario.run.end_time,
                target_dt=scenario.run.target_dt,
                safety=scenario.run.safety,
                max_added_mass=scenario.run.max_added_mass,
                penalty_keys=scenario.plates.penalty_keys() if scenario.plates is not None else None,
                random_seed=scenario.run.seed,
                pair_laws=pair_laws,
                initial_stress=_initial_stress(scenario, mesh),
            )
    except (ValueError, MeshError) as err:
        raise ScenarioError(str(err)) from None
    sizing = _clamped_size_warning(scenario.specimen, mesh)
    if sizing:
        model.warnings.insert(0, sizing)
    model.warnings += _unresolved_aggregates(scenario, mesh) + scenario.initial_stress_warnings()
    sim = FdemSimulation(model)
    _strength_test(sim, scenario, tools, supports, mesh, pressures)
    plane = scenario.analysis.fracture_plane
    if plane is not None:
        size = float(np.max(np.subtract(*mesh.bounds()[::-1])))
        tol = plane.tol if plane.tol is not None else 1e-6 * size
        sim.probes.append(FractureTipProbe(FracturePlane(plane.point, plane.normal, plane.direction, tol)))
    cracks = scenario.analysis.cracks
    if cracks is not None:
        sim.probes.append(CrackProbe(CrackSettings(
            wall=cracks.wall if cracks.wall is not None else scenario.specimen.wall,
            scale=cracks.scale if cracks.scale is not None else 2.0 * model.element_size,
            top=cracks.top,
        )))
    return sim


def _zone_planes(scenario: Scenario) -> tuple:
    """The planes bounding the materials' layer and half-space zones across the specimen, which a
    generated mesh is cut along (geometry.meshes.cut_along_planes): bedding planes of planar faces."""
    spec = scenario.specimen
    if not scenario.materials or spec.extent() is None:
        return ()
    center = (np.asarray(spec.origin) + 0.5 * np.asarray(spec.size) if spec.shape in ("box", "beam")
              else np.asarray(spec.center, float))
    return tuple(plane for material in scenario.materials.values() for zone in material.zones
                 for plane in zone.planes(center, spec.extent()))


# Specimens a pair of platens tests in compression (a core, a prism, a meshed sample).
_COMPRESSION_SHAPES = ("cylinder", "box", "beam", "mesh")


def _covers(tool, points: np.ndarray) -> bool:
    """Whether `tool` is a platen over the specimen's whole section: a plane, or a box whose face
    across its travel spans every point's projection."""
    if tool.shape == "plane":
        return True
    if tool.shape != "box":
        return False
    a, b = (np.asarray(v, float) for v in tool.axes)
    if abs(float(np.cross(a, b) @ np.asarray(tool.direction, float))) < 0.99 * np.linalg.norm(tool.direction):
        return False
    rel = points - np.asarray(tool.center, float)
    return bool(np.all(np.abs(rel @ a) <= 0.5 * tool.size[0]) and np.all(np.abs(rel @ b) <= 0.5 * tool.size[1]))


def _strength_test(sim: FdemSimulation, scenario: Scenario, tools, supports, mesh, pressures) -> None:
    """The strength test the set-up is, if any, for the summary's nominal strengths: a glued grip
    or a moving support pulling the specimen (direct tension), a disc between platens
    (Brazilian), or a core, prism or meshed sample between flat platens (uniaxial compression; with
    a pressure on its side, the triaxial test: the first [[pressures]] on boundary faces is the
    confinement)."""
    spec = scenario.specimen
    grip = pulling_grip(tools, mesh.points, supports, float(np.max(mesh.bounds()[1] - mesh.bounds()[0])))
    if grip is not None:
        section = mean_section(float(mesh.volumes().sum()), mesh.points, tools[grip].direction)
        sim.probes.append(PeakForceProbe(TensionTest(grip, section, scenario.weakest_tensile_strength())))
    elif spec.shape in _COMPRESSION_SHAPES:
        # Two platens, each covering the specimen's section (not three-point bending's rollers).
        platens = [t for t in tools if _covers(t, mesh.points)]
        moving = [t for t in platens if t.moves]
        if len(platens) != 2 or not moving:
            return
        direction = np.asarray(moving[0].direction, float) / np.linalg.norm(moving[0].direction)
        opposite = facing_tool(platens, moving[0], direction)
        if opposite is None:
            return
        along = mesh.points @ direction
        extent = float(along.max() - along.min())
        confinement = next((p.history for p in pressures if not isinstance(p.faces, str)), None)
        sim.probes.append(PlatenProbe(Platen(moving[0].name, direction, extent, opposite),
                                      float(mesh.volumes().sum()) / extent, confinement))
    elif spec.shape == "disc":
        moving = [t for t in tools if t.moves]
        if moving:
            # The loading axis: the first moving platen's direction (rotated with [loading]).
            axis = np.asarray(spec.axis, float) / np.linalg.norm(spec.axis)
            sim.probes.append(BrazilianProbe(BrazilianTest(spec.diameter, spec.thickness, spec.center, tuple(axis),
                                                          tuple(moving[0].direction))))

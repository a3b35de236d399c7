"""The DEM's scenario sections and the build of a scenario into a DemSimulation.

[specimen] as for FDEM (box, disc, cylinder, sphere: the same keys, so one specimen description
runs with either method), filled by [packing] (a random dense packing, or one saved to a file);
[material] the JCFpm parameters of paper 003 Table 1. Tools, supports, run control and outputs
are the shared ones.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from ..analysis.strength import BrazilianTest, TensionTest, pulling_grip
from ..loading.build import selection as build_selection, touch_tools
from ..scenario import (MaterialPlace, ScenarioBase, ScenarioError, Specimen, assign_materials, no_such_file,
                        check_material_tables, check_one_rest, material_pair, refuse_unused_keys, resolve_path)
from ..materials.random_properties import RandomProperty, check_names
from ..schema import NonNegative, Positive, Strict, Vec3
from .build import build_dem_simulation
from .model import RANDOM_BOND_PROPERTIES, BondLaw, GroupedLaws, Joint
from .domains import Box, Cylinder, Sphere
from .packing import Packing, pack_spheres
from .sphere_list import read_sphere_labels, read_sphere_list
from ..solver.setup import SetUp
from ..solver.simulation import PeakForceProbe
from ..solver.platen import Platen, PlatenProbe, facing_tool
from .membrane import Face, Membrane, box_faces, selected_faces
from .prestress import preload, surface_loads
from .probes import BrazilianProbe, FlawProbe, MembraneProbe
from .simulation import DemSimulation


# The [specimen] keys each DEM shape reads (the packing domain's).
DEM_SPECIMEN_KEYS = {"box": {"size", "origin"}, "beam": {"size", "origin"},
                     "disc": {"diameter", "thickness", "center", "axis"},
                     "cylinder": {"diameter", "thickness", "center", "axis"}, "sphere": {"diameter", "center"}}


class DemSpecimen(Specimen):
    """[specimen]: the region the particles fill (the same keys as FDEM's; no element size)."""

    shape: Literal["box", "beam", "disc", "cylinder", "sphere"]
    """box and beam: size, origin; disc and cylinder: diameter, thickness, center, axis; sphere: diameter, center"""

    @model_validator(mode="after")
    def _needs(self):
        need = {"box": ("size",), "beam": ("size",), "disc": ("diameter", "thickness"),
                "cylinder": ("diameter", "thickness"), "sphere": ("diameter",)}[self.shape]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"shape '{self.shape}' needs {', '.join(missing)}")
        if self.element_size is not None:
            raise ValueError("element_size is not used by the DEM: the particle size is packing.mean_radius")
        refuse_unused_keys(self, DEM_SPECIMEN_KEYS)
        return self


class PackingSpec(Strict):
    """[packing]: the particles filling the specimen."""

    mean_radius: Positive | None = None
    """m, (Rmin + Rmax) / 2; the number of particles follows from the porosity"""
    radius_ratio: Annotated[float, Field(ge=1.0)] = 1.86
    """Rmax / Rmin of the uniform radius distribution (paper 003: 1.86)"""
    porosity: Annotated[float, Field(gt=0.0, lt=1.0)] = 0.4
    """void fraction of the specimen the packing aims at: about 0.37 and above for 100k spheres, 0.40 for 2,000,
    0.44 for 300 (the walls loosen the layer beside them); an unreachable one is refused with the porosity reached"""
    particle_density: Positive | None = None
    """spheres per cubed mean diameter, n (2 mean_radius)^3 / V, instead of a porosity (paper 003: 1.47; a packing
    without overlap holds ~1.05): packed without overlap, then grown together and settled, frictionless, as DEM
    codes compact a rock sample by radius growth; the bonds start unloaded at the overlaps that leaves"""
    seed: Annotated[int, Field(ge=0)] = 0
    """of the random packing: the same seed, the same packing"""
    file: str | None = None
    """a packing instead of a new one, relative to the scenario file's folder: saved by crackle (.npz,
    crackle.dem.packing.Packing.save) or made by another code, a text sphere list (any other suffix: one
    'x y z r' line per sphere in m, further columns ignored, # comments; the specimen section gives the
    domain, which must hold every centre); it takes the place of the keys above (a warning says so when
    they are set too)"""
    group_column: Annotated[int, Field(ge=5)] | None = None
    """a text sphere list's column (1-based: 5 is the first after 'x y z r') holding each sphere's group, e.g. the
    material or group id another code wrote: [materials.NAME] take theirs by `group` (its value as written)"""

    @model_validator(mode="after")
    def _one_source(self):
        if self.mean_radius is None and self.file is None:
            raise ValueError("give mean_radius (a new packing) or file (a saved one)")
        if self.group_column is not None and (self.file is None or self.file.lower().endswith(".npz")):
            raise ValueError("group_column: a column of a text sphere list (packing.file, not .npz); remove it or "
                             "give the file")
        return self


class DemMaterial(Strict):
    """[material]: the bonded-particle (JCFpm) parameters of paper 003 Table 1."""

    name: str = "rock"
    density: Positive
    """kg/m^3, of the particles"""
    bond_modulus: Positive
    """Pa, Y: normal stiffness kn = 2 Y Ra Rb / (Ra + Rb) (paper 003 eq. 3; not the sample's Young's modulus)"""
    stiffness_ratio: Positive = 1.0 / 3.0
    """P: shear stiffness kt = P kn"""
    tensile_strength: Positive
    """Pa, t: a bond fails in tension at t Aint, Aint = pi min(Ra, Rb)^2"""
    cohesion: Positive
    """Pa, c: a bond fails in shear at c Aint + Fn tan(friction_angle)"""
    friction_angle: Annotated[float, Field(ge=0.0, lt=90.0)] = 18.0
    """degrees, phi: of bonds, and of failed bonds in compression"""
    contact_friction_angle: Annotated[float, Field(ge=0.0, lt=90.0)] | None = None
    """degrees, phi_c: of contacts that form during the run; default friction_angle"""
    bonds_per_particle: Positive = 12.0
    """N: the mean bond count the interaction range gamma_int is chosen for (paper 003: 12)"""
    local_damping: Annotated[float, Field(ge=0.0, lt=1.0)] = 0.2
    """alpha: local non-viscous damping (paper 003 eq. 5; 0.2 in the paper), a numerical device"""
    random: dict[str, RandomProperty] = {}
    """[material.random.NAME]: bond strengths drawn per bond (NAME: tensile_strength, cohesion), the value above
    their mean; each bond's at its mid-point, from run.seed"""

    @model_validator(mode="after")
    def _plausible(self):
        check_names(self.random, tuple(RANDOM_BOND_PROPERTIES), "material")
        if not 100.0 <= self.density <= 30000.0:
            raise ValueError(f"density = {self.density:g} kg/m^3 is outside 100-30000 (in g/cm^3? 2.5 g/cm^3 is 2500)")
        if not 1e6 <= self.bond_modulus <= 1e13:
            raise ValueError(f"bond_modulus = {self.bond_modulus:g} Pa is outside 1e6-1e13 (in GPa? 50 GPa is 50e9)")
        return self

    def law(self) -> BondLaw:
        phi_c = self.friction_angle if self.contact_friction_angle is None else self.contact_friction_angle
        return BondLaw(self.bond_modulus, self.stiffness_ratio, self.tensile_strength, self.cohesion,
                       math.radians(self.friction_angle), math.radians(phi_c))


class FlawSpec(Strict):
    """[flaw]: a planar pre-existing crack through the specimen along y (paper 003 sections 4-5),
    a segment of `length` in the x-z plane inclined by `angle` from x (z: the loading axis)."""

    kind: Literal["open", "closed"] = "open"
    """open: the particles that reach into the flaw's slot are removed; closed: the bonds across it become
    smooth joints (paper 003 section 3)"""
    center: Vec3
    """m, the flaw's middle"""
    angle: float = 0.0
    """degrees, from the x axis towards z (0: normal to the loading axis z, 90: along it)"""
    length: Positive
    """m, in the x-z plane (paper 003: 20 % of the sample's height)"""
    aperture: NonNegative = 0.0
    """m, open: the slot's width; every particle that reaches into it is removed (0: those the flaw's plane cuts)"""
    normal_stiffness: Positive = 5e9
    """Pa/m, closed: Kn_j, a joint's kn = Kn_j Aint (paper 003 eq. 9; 5 GPa/m in section 5)"""
    shear_stiffness: Positive = 5e9
    """Pa/m, closed: Kt_j, a joint's kt = Kt_j Aint"""
    friction_angle: Annotated[float, Field(ge=0.0, lt=90.0)] = 18.0
    """degrees, closed: phi_j"""
    dilatancy_angle: Annotated[float, Field(ge=0.0, lt=90.0)] = 0.0
    """degrees, closed: psi_j (the normal force grows by kn tan(psi_j) per unit of plastic slip)"""

    def joint(self) -> Joint:
        along, across = self.axes()
        return Joint(np.asarray(self.center, float), across, along, self.length, self.normal_stiffness,
                     self.shear_stiffness, math.radians(self.friction_angle), math.radians(self.dilatancy_angle))

    def removed(self, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """Which particles reach into the slot (a mask)."""
        along, across = self.axes()
        rel = centers - np.asarray(self.center, float)
        return (np.abs(rel @ across) < 0.5 * self.aperture + radii) & (np.abs(rel @ along) <= 0.5 * self.length)

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """The unit vectors along the flaw and normal to it, both in the x-z plane."""
        theta = math.radians(self.angle)
        return np.array([math.cos(theta), 0.0, math.sin(theta)]), np.array([-math.sin(theta), 0.0, math.cos(theta)])


class DemNamedMaterial(DemMaterial, MaterialPlace):
    """[materials.NAME]: one of several particle groups (the keys of [material]) and where its
    particles are: `group`, a label of the sphere file's packing.group_column, or `zones` (by the
    particles' centres); the one with neither fills the rest."""


class DemPairBond(Strict):
    """[interfaces."A-B"]: the bonds between a particle of material A and one of B (their stiffness
    is the two half-springs in series)."""

    tensile_strength: Positive
    """Pa, t of these bonds"""
    cohesion: Positive
    """Pa, c of these bonds"""
    friction_angle: Annotated[float, Field(ge=0.0, lt=90.0)] = 18.0
    """degrees, of these bonds and of the contacts between the two materials"""


class Scenario(ScenarioBase):
    method: Literal["dem"]
    """picks this method"""
    reads = frozenset({"pressures", "initial_stress"})  # pressures on a box's faces (dem.membrane); bonds preloaded by dem.prestress
    specimen: DemSpecimen
    """the region the particles fill"""
    packing: PackingSpec
    """the particles"""
    material: DemMaterial | None = None
    """the bonds and contacts (one material; [materials.NAME] for several)"""
    materials: dict[str, DemNamedMaterial] = {}
    """[materials.NAME]: several particle groups, each in its zones (instead of [material])"""
    interfaces: dict[str, DemPairBond] = {}
    """[interfaces."A-B"]: the bonds between groups A and B; default: those of the group with the lower tensile
    strength"""
    flaw: FlawSpec | None = None
    """a pre-existing crack (optional)"""

    @model_validator(mode="after")
    def _one_or_several_materials(self):
        check_material_tables(self.material, self.materials)
        if self.interfaces and not self.materials:
            raise ValueError("[interfaces] names pairs of [materials.NAME]; with one [material] there is none")
        if self.materials:
            check_one_rest(self.materials)
            grouped = [name for name, m in self.materials.items() if m.group is not None]
            if grouped and self.packing.group_column is None:
                raise ValueError(f"materials.{grouped[0]}.group: groups come from a column of a text sphere list; "
                                 "give packing.file and packing.group_column, or give the material zones")
            for key in ("local_damping", "bonds_per_particle"):
                values = {getattr(m, key) for m in self.materials.values()}
                if len(values) > 1:
                    raise ValueError(f"materials.*.{key}: one value for the whole packing (it is the packing's, not a "
                                     f"group's); got {', '.join(f'{v:g}' for v in sorted(values))}")
            drawn = [name for name, m in self.materials.items() if m.random]
            if drawn:
                raise ValueError(f"materials.{drawn[0]}.random: random bond strengths go with one [material] for now")
            for key in self.interfaces:
                material_pair(key, list(self.materials))
        return self

    def bond_law(self, centers: np.ndarray, labels: np.ndarray | None = None):
        """The BondLaw of [material], or the GroupedLaws of [materials] with each particle's
        group (the sphere file's label, `labels`, or its centre in zones; ValueError for a label
        no material names or a particle none takes) and the pairs' laws."""
        if self.material is not None:
            return self.material.law()
        names = list(self.materials)
        groups = None if labels is None else {label: labels == label for label in np.unique(labels).tolist()}
        group = assign_materials(self.materials, centers, groups, sites="particles")
        laws = tuple(m.law() for m in self.materials.values())
        pairs = {}
        for key, bond in self.interfaces.items():
            a, b = (names.index(n) for n in material_pair(key, names))
            # the contacts between the two: the weaker side's contact friction
            weaker = laws[a] if laws[a].tensile_strength <= laws[b].tensile_strength else laws[b]
            pairs[a, b] = pairs[b, a] = BondLaw(0.0, 0.0, bond.tensile_strength, bond.cohesion,
                                                math.radians(bond.friction_angle), weaker.contact_friction_angle)
        return GroupedLaws(laws, group, pairs)

    def the_material(self) -> DemMaterial:
        """[material], or the material filling the rest: the packing's own settings (damping, bonds per particle)."""
        return self.material or next(m for m in self.materials.values() if not m.zones)

    def weakest_tensile_strength(self) -> float:
        """Pa: the lowest bond tensile strength of the materials and pairs."""
        if self.material is not None:
            return self.material.tensile_strength
        return min(b.tensile_strength for b in [*self.materials.values(), *self.interfaces.values()])

    @model_validator(mode="after")
    def _initial_stress_on_a_box(self):
        if self.initial_stress is not None and self.specimen.shape not in ("box", "beam"):
            raise ValueError(f'initial_stress: the DEM starts from an initial stress on a box specimen (its tractions are '
                             f'taken on the box\'s faces, as the DEM\'s pressures are), not a {self.specimen.shape}; '
                             'make specimen.shape "box" or remove [initial_stress]')
        return self

    @model_validator(mode="after")
    def _no_clamped_supports(self):
        for i, support in enumerate(self.supports):
            if support.kind == "clamped":
                raise ValueError(f'supports.{i}.kind: "clamped" is not available for DEM particles (their spin is not '
                                 'held); use "fixed"')
        return self


def domain_of(spec: DemSpecimen):
    """The packing domain of a specimen section."""
    if spec.shape in ("box", "beam"):
        lo = np.asarray(spec.origin, float)
        return Box(lo, lo + np.asarray(spec.size, float))
    if spec.shape in ("disc", "cylinder"):
        return Cylinder(np.asarray(spec.center, float), 0.5 * spec.diameter, spec.thickness, np.asarray(spec.axis, float))
    return Sphere(np.asarray(spec.center, float), 0.5 * spec.diameter)


def build_packing(scenario: Scenario, base: Path | None) -> Packing:
    spec = scenario.packing
    if spec.file is not None:
        path = resolve_path(spec.file, base)
        if not path.is_file():
            raise no_such_file("packing.file", path)
        try:
            if path.suffix.lower() == ".npz":
                return Packing.load(path)
            return read_sphere_list(path, domain_of(scenario.specimen))
        except (ValueError, UnicodeDecodeError) as err:
            raise ScenarioError(f"packing.file: {path}: {err}") from None
    try:
        return pack_spheres(domain_of(scenario.specimen), porosity=spec.porosity, radius_ratio=spec.radius_ratio,
                            mean_radius=spec.mean_radius, seed=spec.seed, particle_density=spec.particle_density,
                            max_memory=scenario.run.max_memory)
    except ValueError as err:
        raise ScenarioError(str(err)) from None


def build_simulation(scenario: Scenario, base: Path | None = None) -> DemSimulation:
    setup = SetUp(scenario, base)  # the packing checks its own size (pack_spheres)
    tools, supports, pressures = setup.tools, setup.supports, setup.pressures
    loaded = _loaded_faces(scenario)  # before the packing: bad pressures fail fast
    packing = build_packing(scenario, base)
    centers, radii = packing.centers, packing.radii
    labels = None
    if scenario.packing.group_column is not None:
        try:
            labels = read_sphere_labels(resolve_path(scenario.packing.file, base), scenario.packing.group_column)
        except (ValueError, UnicodeDecodeError) as err:
            raise ScenarioError(f"packing.file: {err}") from None
    flaw = scenario.flaw
    if flaw is not None:
        _check_inside(flaw, domain_of(scenario.specimen))
        if flaw.kind == "open":
            kept = ~_in_open_flaw(flaw, centers, radii)
            centers, radii = centers[kept], radii[kept]
            labels = None if labels is None else labels[kept]
    # A touching platen is placed on the particle furthest along its direction (on its surface).
    tools = touch_tools(tools, scenario.all_tools(), lambda tool: centers - radii[:, None] * _unit(tool.direction))
    domain = domain_of(scenario.specimen)
    moving = [i for i, t in enumerate(tools) if t.moves]
    # A moving support (or a glued tool) that pulls the far end: direct tension.
    grip = pulling_grip(tools, centers, supports, float(np.max(np.ptp(centers, axis=0) + 2.0 * radii.max())))
    loaded_area = platen = None
    if moving:
        # The mean cross-section normal to the pulling grip or else the first moving tool (the
        # platen): platen stress = force / it.
        lead = tools[grip if grip is not None else moving[0]]
        direction = _unit(lead.direction)
        along = centers @ direction
        extent = float((along + radii).max() - (along - radii).min())
        loaded_area = domain.volume / extent
        platen = Platen(lead.name, direction, extent, facing_tool(tools, lead, direction))
    mat = scenario.the_material()
    try:
        law = scenario.bond_law(centers, labels)
    except ValueError as err:  # a zone that cannot be built (aggregates that do not fit), a group no material names
        raise ScenarioError(str(err)) from None
    density = mat.density if scenario.material is not None else \
        np.array([m.density for m in scenario.materials.values()])[law.group]
    try:
        sim = build_dem_simulation(
            centers, radii, density, law, bonds_per_particle=mat.bonds_per_particle,
            tools=tools, supports=supports, damping=mat.local_damping, gravity=scenario.run.gravity,
            velocity=np.asarray(scenario.specimen.initial_velocity, float), loaded_area=loaded_area,
            joint=flaw.joint() if flaw is not None and flaw.kind == "closed" else None,
            random=dict(mat.random), seed=scenario.run.seed, material=mat.name,
        )
    except ValueError as err:  # the message names its subject; the key it belongs to, where it does not
        text = str(err)
        field = "material.bonds_per_particle: " if "bonds_per_particle" in text else \
            "flaw: " if "flaw" in text and not text.startswith("flaw") else ""
        raise ScenarioError(f"{field}{text}") from None
    sim.packing = packing
    sim.material_names = list(scenario.materials) or None
    if scenario.packing.file is not None and scenario.packing.mean_radius is not None:
        sim.warnings.append(f"packing.file {scenario.packing.file} is used: packing.mean_radius, porosity, "
                            "radius_ratio, particle_density and seed do not apply")
    elif scenario.packing.particle_density is not None and "porosity" in scenario.packing.model_fields_set:
        sim.warnings.append(f"packing.particle_density = {scenario.packing.particle_density:g} sets the packing: "
                            "packing.porosity does not apply")
    sim.sample_volume = domain.volume
    if loaded:
        sim.set_membrane(Membrane(loaded, [p.history for p in pressures], sim.particles.x, sim.particles.radius))
        sim.probes.append(MembraneProbe())
    if scenario.initial_stress is not None:
        _start_stressed(sim, scenario)
    if flaw is not None:
        sim.probes.append(FlawProbe(flaw))
    if platen is not None and loaded_area:
        confinement = sim.membrane.confinement(platen.direction) if sim.membrane is not None else None
        sim.probes.append(PlatenProbe(platen, loaded_area, confinement))
    if scenario.specimen.shape == "disc" and loaded_area:
        spec, first = scenario.specimen, tools[moving[0]]  # the loading axis: the first moving platen's
        axis = np.asarray(spec.axis, float) / np.linalg.norm(spec.axis)
        sim.probes.append(BrazilianProbe(BrazilianTest(spec.diameter, spec.thickness, spec.center, tuple(axis),
                                                      tuple(first.direction))))
    if grip is not None:
        sim.probes.append(PeakForceProbe(TensionTest(grip, loaded_area, scenario.weakest_tensile_strength())))
    return sim


# [initial_stress] with the DEM: the share of the bonds its preload may take beyond their strength
# (they fail in the first step, with a warning); beyond it the set-up refuses the stress. A random
# packing's bond forces scatter about the mean stress's (measured on a 750-particle cube under
# principal stresses -10/-6/-3 MPa: median 0.9 %, 99th percentile 4.6 % of the strength, the
# largest 101 %, a bond of an outermost particle), so a stress the rock carries well can
# overload a few bonds; one beyond the rock's strength overloads many.
OVERLOADED_SHARE = 0.01
# The net force of [initial_stress]'s tractions and the particles' weight, over the weight, beyond
# which the set-up warns that the packing will accelerate as a body.
UNBALANCED = 1e-3


def _start_stressed(sim: DemSimulation, scenario: Scenario) -> None:
    """[initial_stress]: the bonds preloaded so that the packing carries it at rest (dem.prestress),
    against the stress's tractions on the box's faces and the particles' weight; ScenarioError
    where it would break more than OVERLOADED_SHARE of the bonds at t = 0."""
    spec = scenario.specimen
    lo = np.asarray(spec.origin, float)
    p = sim.particles
    force, torque = surface_loads(p.x, p.radius, box_faces(lo, lo + np.asarray(spec.size, float)),
                                  scenario.initial_stress.at)
    force += p.mass[:, None] * sim.gravity
    preloaded = preload(p, sim.inter, force, torque)
    used = preloaded["utilisation"]
    over = np.flatnonzero(used >= 1.0)
    if len(over):
        worst = over[np.argmax(used[over])]
        bond = preloaded["ids"][worst]
        where = ", ".join(f"{c:.4g}" for c in 0.5 * (p.x[sim.inter.a[bond]] + p.x[sim.inter.b[bond]]))
        said = (f"initial_stress: the packing carries it with {len(over):,} of {len(used):,} bonds beyond their strength "
                f"(up to {used[worst]:.3g}x, at ({where}) m)")
        if len(over) > OVERLOADED_SHARE * len(used):
            raise ScenarioError(f"{said}: more than {OVERLOADED_SHARE:.0%} would fail at t = 0; lower the initial stress "
                                "(its deviatoric or tensile part) or raise material.tensile_strength and cohesion")
        sim.warnings.append(f"{said}: they fail in the first step (the packing's disorder: mostly bonds of the "
                            "outermost particles), booked as damage")
    sim.start_stored()
    sim.warnings.extend(scenario.initial_stress_warnings())
    net_force = force.sum(axis=0)  # what no bond can carry
    weight = float(np.sum(p.mass)) * float(np.linalg.norm(sim.gravity))
    if scenario.initial_stress.density is not None and weight > 0.0 and \
            np.linalg.norm(net_force) > UNBALANCED * weight:
        bulk = float(np.sum(p.mass)) / float(np.prod(spec.size))
        sim.warnings.append(
            f"initial_stress.density = {scenario.initial_stress.density:g} kg/m^3: the stress's gradient and the "
            f"packing's weight do not balance (a net force of {np.linalg.norm(net_force):.3g} N, "
            f"{np.linalg.norm(net_force) / weight:.1%} of the weight): the packing accelerates as a body from t = 0; "
            f"the packing's bulk density is {bulk:.5g} kg/m^3")


def _loaded_faces(scenario: Scenario) -> list[list[Face]]:
    """Per [[pressures]] entry, the faces of the specimen's box it loads (dem.membrane): its
    `where` names them (all four corners on its plane, the centre in its box). ScenarioError for
    what the DEM cannot load."""
    if not scenario.pressures:
        return []
    spec = scenario.specimen
    if spec.shape not in ("box", "beam"):
        raise ScenarioError(f'pressures: the DEM loads the faces of a box specimen (specimen.shape = "box" or '
                            f'"beam"), not a {spec.shape}; remove [[pressures]] or make the specimen a box')
    lo = np.asarray(spec.origin, float)
    faces = box_faces(lo, lo + np.asarray(spec.size, float))
    scale = float(max(spec.size))
    out = []
    for i, p in enumerate(scenario.pressures):
        if p.faces != "where":
            raise ScenarioError(f'pressures.{i}.faces: the DEM has no pre-cracks to load; give faces = "where" and a '
                                '[pressures.where] plane or box naming faces of the specimen\'s box')
        for key in ("front_speed", "wall"):
            if getattr(p, key) is not None:
                raise ScenarioError(f"pressures.{i}.{key}: not available for the DEM (its membrane loads whole faces of "
                                    "the box at once); remove it")
        chosen = selected_faces(build_selection(p.where), faces, scale)
        if not chosen:
            names = ", ".join(f.name for f in faces)
            raise ScenarioError(f"pressures.{i}.where selects no face of the specimen's box (its faces: {names}); a "
                                "face is selected when its four corners lie on the plane and its centre in the box")
        out.append(chosen)
    return out


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _check_inside(flaw: FlawSpec, domain) -> None:
    if float(domain.signed_distance(np.asarray(flaw.center, float)[None, :])[0]) >= 0.0:
        raise ScenarioError(f"flaw.center {list(flaw.center)} lies outside the specimen")
    along, _ = flaw.axes()
    for end in (-0.5, 0.5):
        tip = np.asarray(flaw.center, float) + end * flaw.length * along
        if float(domain.signed_distance(tip[None, :])[0]) >= 0.0:
            raise ScenarioError("flaw.length: the flaw reaches out of the specimen; shorten it or move flaw.center")


def _in_open_flaw(flaw: FlawSpec, centers, radii) -> np.ndarray:
    """The particles that reach into an open flaw's slot (a mask): the packing goes without them."""
    removed = flaw.removed(centers, radii)
    if not removed.any():
        raise ScenarioError("flaw: no particle reaches into the flaw; check flaw.center and flaw.length")
    return removed

"""The meshfree method's scenario sections and the build of a scenario into a MeshfreeSimulation.

[specimen] a box (FDEM's keys; its thinnest side is the wall thickness) or a tube (inner
radius, wall thickness, length, axis, origin) filled by [particles]
(an in-plane spacing, particles through the thickness, the support's dilation factor and the
stabilisation of nodal integration), or particles at the nodes of a tet mesh: a mesh file
(shape "mesh", a solid) or the wall FDEM's shape "shell" builds from a triangle surface
(particles.layers through it; particles.spacing remeshes the surface); [material] the elastic constants, the law (`model`: the J2
elasto-visco-plastic law of paper 000 eqs 14-15, or the thermo-elasto-viscoplastic law of eqs
16-22) and the fracture stress (section 3.3); [[pressures]] on the wall faces, optionally behind
a front travelling along a tube. Tools, supports, run control and outputs are the shared ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..budget import check_model_size
from ..loading.build import build_precracks
from ..scenario import (ElasticSpec, MaterialPlace, PrecrackSpec, ScenarioBase, ScenarioError,
                        Specimen, assign_materials, check_material_tables, check_one_rest, resolve_path)
from ..solver.setup import SetUp
from ..schema import NonNegative, Positive, PositiveOrInf, Strict, Vec3
from .build import MeshfreeBody, SetupError, build_meshfree_simulation
from .material import J2Law, ThermoLaw
from ..geometry.meshes import MeshError, gmsh_sphere, read_mesh
from ..geometry.specimens import BODY_SPECIMEN_RATIO, check_file_units
from ..materials.random_properties import RandomProperty, check_names
from .fracture import RANDOM_PARTICLE_PROPERTIES, draw_thresholds
from .particles import (graded_plate_particles, node_groups, plate_particles, shell_particles, tet_node_particles,
                        tube_particles)
from .simulation import MeshfreeSimulation


class MeshfreeSpecimen(Specimen):
    """[specimen]: the plate or tube the particles fill (FDEM's box keys, or a tube's; no element size), or
    the tet mesh whose nodes are the particles (a mesh file, or a shell walled from a triangle surface)."""

    shape: Literal["box", "beam", "tube", "mesh", "shell"]
    """box and beam: size, origin (the thinnest side is the wall thickness); tube: inner_radius, thickness,
    length, axis, origin; mesh: file, scale (a solid, a particle at each node); shell: file (a closed or open
    triangle surface), wall, scale, center (walled inwards as FDEM's shell, particles.layers through the wall)"""
    origin: Vec3 = (0.0, 0.0, 0.0)
    """m, box and beam: the lower corner; tube: the centre of its first end (the axis starts there)"""
    inner_radius: Positive | None = None
    """m, tube: the radius of its inner wall"""
    thickness: Positive | None = None
    """m, tube: the wall thickness"""
    length: Positive | None = None
    """m, tube: along the axis from origin"""
    axis: Vec3 = (0.0, 0.0, 1.0)
    """tube: its axis (any non-zero vector); the angle around it counts from the coordinate axis least aligned with
    it (x for a tube along z)"""
    file: str | None = None
    """mesh: any tet mesh meshio reads (.msh, .vtu, .inp ...), a particle at each node; shell: a closed or open
    triangle surface (STL or any meshio format), the wall's outer side; relative to the scenario file's folder"""
    wall: Positive | None = None
    """m, shell: the wall thickness (needed), walled inwards from the surface along its vertex normals (an open
    surface: against its triangles' right-hand normals)"""

    @model_validator(mode="after")
    def _needs(self):
        if self.shape in MESH_KEYS:
            return self._mesh_keys()
        need = ("inner_radius", "thickness", "length") if self.shape == "tube" else ("size",)
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"shape '{self.shape}' needs {', '.join(missing)}")
        if self.shape == "tube" and all(c == 0 for c in self.axis):
            raise ValueError("axis must be a non-zero vector")
        tube_only = sorted({"inner_radius", "thickness", "length", "axis"} & self.model_fields_set)
        if self.shape != "tube" and tube_only:
            raise ValueError(f"{', '.join(tube_only)}: only for shape = \"tube\" (a box's sides are size)")
        if self.shape == "tube" and self.size is not None:
            raise ValueError("size: not used by a tube (inner_radius, thickness, length)")
        self._common_keys()
        mesh_only = sorted({"file", "wall", "scale", "center"} & self.model_fields_set)
        if mesh_only:
            raise ValueError(f"{', '.join(mesh_only)}: only for shape = \"mesh\" or \"shell\"")
        return self

    def _common_keys(self):
        if self.element_size is not None:
            raise ValueError("element_size is not used by the meshfree method: the particle spacing is particles.spacing")
        if "layers" in self.model_fields_set:
            raise ValueError("layers: the meshfree method's particles through the thickness are particles.layers")
        if any(w != 0.0 for w in self.angular_velocity):
            raise ValueError("angular_velocity: not available for the meshfree method yet (initial_velocity is)")

    def _mesh_keys(self):
        """mesh and shell: only their keys (MESH_KEYS); a shell's wall given."""
        if self.file is None:
            raise ValueError(f"shape '{self.shape}' needs file")
        self._common_keys()
        other = sorted(self.model_fields_set - MESH_KEYS[self.shape])
        if other:
            raise ValueError(f"{', '.join(other)}: not used by shape = \"{self.shape}\" (its keys: "
                             f"{', '.join(sorted(MESH_KEYS[self.shape] - {'shape'}))})")
        if self.shape == "shell" and self.wall is None:
            raise ValueError("wall: shape = \"shell\" needs the wall thickness (m)")
        return self


# The keys of the specimens whose particles are a tet mesh's nodes (the rest are refused).
MESH_KEYS = {"mesh": {"shape", "file", "scale", "initial_velocity"},
             "shell": {"shape", "file", "wall", "scale", "center", "initial_velocity"}}


class RefineSpec(Strict):
    """[particles.refine]: a plate's particles graded finer about a point (the paper's unstructured plates refined
    under the impact): gmsh triangulates the plate's face, `spacing` within `radius` of `center` growing to
    particles.spacing over `transition`, with particles.layers through the wall on each node's line."""

    center: Vec3
    """m, the point the fine zone is centred on (its projection on the plate's plane)"""
    radius: NonNegative
    """m, the fine zone's radius"""
    spacing: Positive
    """m, the in-plane spacing in the fine zone (smaller than particles.spacing)"""
    transition: Positive | None = None
    """m, the distance beyond the fine zone over which the spacing grows to particles.spacing; default the larger
    of radius and 5 x particles.spacing"""


class ParticlesSpec(Strict):
    """[particles]: the EFG particles filling the specimen and their shape functions."""

    spacing: Positive | None = None
    """m, box, beam, tube (needed): between neighbouring particles along the in-plane sides (adjusted to fit the
    sides exactly); shell: the surface is remeshed to this edge (unset: its triangles as they are); mesh: not used
    (the particles are the mesh's nodes)"""
    layers: int = 3
    """particles through the wall thickness (on both faces and evenly between): 2 or 3 as in paper 000; with 2
    the quadratic basis drops the square of the through-thickness coordinate (a tube or shell needs 3 or more;
    a shell has layers - 1 tets through its wall; mesh: not used)"""
    dilation: Positive = 2.5
    """support radius / the largest particle step (in-plane or through the thickness): the quadratic basis needs
    2.5 or more (below that, edge and corner particles see too few neighbours: a singular moment matrix)"""
    support: Literal["uniform", "local"] | None = None
    """the support radius: "uniform", dilation x the largest step of the whole set (a mesh or shell's: the 90th
    percentile of its tet edges); "local", dilation x each particle's own (the 90th percentile of the edges around
    it, shape.py: the weight belongs to the particle), for a graded set (a mesh, a shell, a refined plate); default
    uniform, local with refine"""
    refine: RefineSpec | None = None
    """box or beam: grade the plate's particles finer about a point (an unstructured set, [particles.refine])"""
    stabilisation: NonNegative = 0.1
    """alpha: the penalty on each particle's displacement against the MLS approximation at it (zero for quadratic
    fields: it stiffens the zero-energy modes of nodal integration, not bending), a stiffness alpha E V over the
    mean squared link length; 0: off"""

    @field_validator("layers")
    @classmethod
    def _enough_layers(cls, n):
        if n < 2:
            raise ValueError(f"layers = {n}: at least 2 particles through the thickness are needed for a gradient "
                             "through it (paper 000 uses 2-3)")
        return n


Finite = Annotated[float, Field(allow_inf_nan=False)]
# Keys of the thermo law only (refused with model = "j2").
THERMO_KEYS = ("initial_temperature", "specific_heat", "taylor_quinney", "thermal_softening", "softening_temperature",
               "youngs_modulus_temperature", "poissons_ratio_temperature", "yield_stress_temperature",
               "thermal_expansion", "thermal_expansion_temperature")


class MeshfreeMaterial(ElasticSpec):
    """[material]: density, elastic constants, the fracture stress (fracture.py) and the law:
    model = "j2" (paper 000 eqs 14-15), flow stress yield_stress (1 + ep /
    reference_plastic_strain)^hardening_exponent (1 + rate / reference_strain_rate)^rate_exponent;
    model = "thermo" (eqs 16-22), plastic rate reference_strain_rate (seq / g)^(1 / rate_exponent)
    with g = yield_stress(T) (1 + ep / reference_plastic_strain)^hardening_exponent (1 -
    thermal_softening (exp((T - T0) / softening_temperature) - 1)) and adiabatic heating."""

    model: Literal["j2", "thermo"] = "j2"
    """the law: j2 (paper 000 eqs 14-15, J2 elasto-visco-plasticity) or thermo (eqs 16-22: the
    thermo-elasto-viscoplastic power law with thermal softening, temperature-dependent elastic constants, thermal
    expansion and adiabatic heating by the plastic work)"""
    yield_stress: PositiveOrInf = math.inf
    """Pa, sigma0: the initial yield stress (inf: elastic; the thermo law needs a finite one)"""
    reference_plastic_strain: Positive | None = None
    """ep0 of eq. 14 (eps0 of eq. 20); with hardening_exponent 1 the hardening modulus is yield_stress / it; unset:
    1 for j2, yield_stress / youngs_modulus for thermo (the paper's eps0)"""
    hardening_exponent: Annotated[float, Field(ge=0.0)] = 0.0
    """1/n of eq. 14, N of eq. 20 (0: perfectly plastic, 1: linear hardening)"""
    reference_strain_rate: Positive = 1.0
    """1/s, the reference plastic strain rate of eq. 15 (j2), of eq. 19 (thermo: the rate at which the flow stress is
    g)"""
    rate_exponent: Annotated[float, Field(ge=0.0)] = 0.0
    """1/m of eq. 15 (j2) or of eq. 19 (thermo: the stress is g (rate / reference_strain_rate)^(1/m)), the
    strain-rate sensitivity (0: rate independent)"""
    initial_temperature: Positive = 293.0
    """K, T0 (thermo): the temperature at the start and the reference of eqs 20 and 22"""
    specific_heat: Positive = 900.0
    """J/(kg K), c (thermo): density x specific_heat x the temperature rise = taylor_quinney x the plastic work
    (adiabatic; aluminium ~900, steel ~450)"""
    taylor_quinney: Annotated[float, Field(ge=0.0, le=1.0)] = 0.9
    """chi (thermo): the share of the plastic work that heats (Taylor-Quinney; 0: no heating)"""
    thermal_softening: NonNegative = 0.0
    """delta of eq. 20 (thermo): the flow stress falls by the factor 1 - delta (exp((T - T0) / kappa) - 1), and
    is 0 where that factor is (0: no thermal softening)"""
    softening_temperature: Positive = 500.0
    """K, kappa of eq. 20 (thermo): the temperature scale of the thermal softening"""
    youngs_modulus_temperature: tuple[Finite, Finite] = (0.0, 0.0)
    """Pa/K, Pa/K^2 (thermo, eq. 22): E(T) = youngs_modulus + a (T - T0) + b (T - T0)^2"""
    poissons_ratio_temperature: tuple[Finite, Finite] = (0.0, 0.0)
    """1/K, 1/K^2 (thermo, eq. 22): nu(T) = poissons_ratio + a (T - T0) + b (T - T0)^2"""
    yield_stress_temperature: tuple[Finite, Finite] = (0.0, 0.0)
    """Pa/K, Pa/K^2 (thermo, eq. 22): sigma0(T) = yield_stress + a (T - T0) + b (T - T0)^2"""
    thermal_expansion: Finite = 0.0
    """1/K, alpha at T0 (thermo, eq. 22): the thermal strain int_T0^T alpha dT on the diagonal of the elastic
    strain (0: none)"""
    thermal_expansion_temperature: tuple[Finite, Finite] = (0.0, 0.0)
    """1/K^2, 1/K^3 (thermo, eq. 22): alpha(T) = thermal_expansion + a (T - T0) + b (T - T0)^2"""
    tensile_strength: PositiveOrInf = math.inf
    """Pa, sigma_t: a particle fails when its maximum principal (Cauchy) stress exceeds fracture_factor x
    tensile_strength, and its links across the crack plane (normal = that principal direction) are removed
    (inf: no fracture)"""
    fracture_factor: Positive = 3.0
    """the fracture stress over the tensile strength (paper 000 section 3.3: 3)"""
    failure_plastic_strain: PositiveOrInf = math.inf
    """a particle also fails when its equivalent plastic strain reaches this (a ductile criterion, Abaqus's ductile
    damage initiation at a constant strain; the crack plane's normal is the maximum principal direction, as for the
    stress; inf: off, the paper's criterion alone)"""
    random: dict[str, RandomProperty] = {}
    """[material.random.NAME]: fracture thresholds drawn per particle (NAME: tensile_strength (the fracture stress is
    fracture_factor x the drawn value), failure_plastic_strain), the value above their mean; each particle's at its
    reference position, from run.seed"""

    @model_validator(mode="after")
    def _random_names(self):
        check_names(self.random, RANDOM_PARTICLE_PROPERTIES, "material")
        for name in self.random:
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"random.{name}: the drawn values' mean is {name}, which is inf (off); give a finite "
                                 f"{name} or remove [material.random.{name}]")
        return self

    @model_validator(mode="after")
    def _keys_of_the_model(self):
        if self.model == "j2":
            for key in THERMO_KEYS:
                if key in self.model_fields_set:
                    raise ValueError(f'{key}: a key of the thermo law; set model = "thermo" or remove it')
        elif not math.isfinite(self.yield_stress):
            raise ValueError('yield_stress: model = "thermo" needs a finite yield stress (sigma0 of eq. 20)')
        return self

    @property
    def fracture_stress(self) -> float:
        """Pa, the maximum principal stress that fails a particle (inf: no fracture)."""
        return self.fracture_factor * self.tensile_strength

    def law(self) -> J2Law:
        if self.model == "j2":
            ep0 = 1.0 if self.reference_plastic_strain is None else self.reference_plastic_strain
            return J2Law(self.youngs_modulus, self.poissons_ratio, self.yield_stress, ep0, self.hardening_exponent,
                         self.reference_strain_rate, self.rate_exponent)
        ep0 = self.reference_plastic_strain or self.yield_stress / self.youngs_modulus
        return ThermoLaw(self.youngs_modulus, self.poissons_ratio, self.yield_stress, ep0, self.hardening_exponent,
                         self.reference_strain_rate, self.rate_exponent, **{k: getattr(self, k) for k in THERMO_KEYS},
                         density=self.density)


class MeshfreeNamedMaterial(MeshfreeMaterial, MaterialPlace):
    """[materials.NAME]: one of the specimen's several materials (the keys of [material]) and where it is: zones
    (a particle by its reference position) or, for a mesh file, a group of its tets; the one with neither fills
    the rest."""


class BodyMaterial(MeshfreeMaterial):
    """[bodies.material]: a body's material, as [material] without fracture (a body does not break)."""

    @model_validator(mode="after")
    def _no_fracture(self):
        for key in ("tensile_strength", "failure_plastic_strain", "fracture_factor", "random"):
            if key in self.model_fields_set:
                raise ValueError(f"{key}: a body besides the specimen does not fracture (paper 000's sphere is "
                                 "\"not allowed to fracture\"); remove it")
        return self


# A ball body's gmsh element at most this share of its radius (4 elements across).
BALL_ELEMENT_MAX_SHARE = 0.5


class BodySpec(Strict):
    """[[bodies]]: a second body of particles beside the specimen (a deformable projectile): a solid
    of its own material, a particle at each node of a tet mesh (a ball gmsh meshes, or a mesh file),
    launched at initial_velocity. It does not fracture; it meets the specimen, and the other bodies,
    by penalty contact between particles (meshfree/contact.py)."""

    name: str = "body"
    """names the body in summary.json (bodies)"""
    shape: Literal["sphere", "mesh"]
    """sphere: radius, center, element_size (gmsh); mesh: file, scale (any tet mesh meshio reads)"""
    radius: Positive | None = None
    """m, sphere"""
    center: Vec3 = (0.0, 0.0, 0.0)
    """m, sphere: its centre"""
    element_size: Positive | None = None
    """m, sphere: the tet edge gmsh aims at (the particles are its nodes)"""
    file: str | None = None
    """mesh: a tet mesh file, relative to the scenario file's folder"""
    scale: Positive = 1.0
    """mesh: the file's coordinates times this are metres"""
    initial_velocity: Vec3 = (0.0, 0.0, 0.0)
    """m/s, every particle's at t = 0"""
    dilation: Positive = 2.5
    """the body's support radius / its largest particle step (particles.dilation's meaning)"""
    material: BodyMaterial
    """density, elastic constants and the law (j2 or thermo), no fracture"""

    @model_validator(mode="after")
    def _keys_of_the_shape(self):
        need = ("radius", "element_size") if self.shape == "sphere" else ("file",)
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"shape '{self.shape}' needs {', '.join(missing)}")
        if self.shape == "sphere" and self.element_size > BALL_ELEMENT_MAX_SHARE * self.radius:
            raise ValueError(f"element_size = {self.element_size:g} m against the ball's radius {self.radius:g} m: "
                             "fewer than 4 elements across the ball, whose few particles would not make a ball; set "
                             f"element_size at most {BALL_ELEMENT_MAX_SHARE * self.radius:.3g} m (radius / 2)")
        other = {"sphere": {"file", "scale"}, "mesh": {"radius", "center", "element_size"}}[self.shape]
        given = sorted(other & self.model_fields_set)
        if given:
            raise ValueError(f"{', '.join(given)}: not used by shape = \"{self.shape}\"")
        return self


class Scenario(ScenarioBase):
    method: Literal["meshfree"]
    """picks this method"""
    # run.contact: the specimen's particles that no link joins meet by particle contact (contact.py).
    reads = frozenset({"run.contact", "run.damping", "pressures"})
    specimen: MeshfreeSpecimen
    """the plate, tube, mesh or shell the particles fill"""
    particles: ParticlesSpec = ParticlesSpec()
    """the particles and their shape functions (a mesh's: dilation and stabilisation only)"""
    material: MeshfreeMaterial | None = None
    """elastic constants, the J2 or thermo law and the fracture stress (one material; [materials.NAME] for several)"""
    materials: dict[str, MeshfreeNamedMaterial] = {}
    """[materials.NAME]: the specimen's several materials, each where its zones or group say (instead of
    [material]); each particle steps with its own material's law, density and fracture thresholds"""
    precracks: list[PrecrackSpec] = []
    """notches and slits present from the start: the links between particles that cross the plane inside the
    box are removed (the same visibility rule as a grown crack, fracture.py)"""
    bodies: list[BodySpec] = []
    """more bodies of particles (a deformable projectile), met by particle contact"""

    @model_validator(mode="after")
    def _one_or_several_materials(self):
        check_material_tables(self.material, self.materials)
        if self.materials:
            check_one_rest(self.materials)
            grouped = [name for name, m in self.materials.items() if m.group is not None]
            if grouped and self.specimen.shape != "mesh":
                raise ValueError(f"materials.{grouped[0]}.group: groups come from a mesh file (specimen.shape = "
                                 "\"mesh\"); for a built-in shape give zones")
        return self

    def specimen_materials(self) -> dict[str, MeshfreeMaterial]:
        """The specimen's materials by name: [material] under its name, or [materials.NAME] in order."""
        return {self.material.name: self.material} if self.material is not None else dict(self.materials)

    @model_validator(mode="after")
    def _particles_of_the_shape(self):
        shape, particles = self.specimen.shape, self.particles
        if shape == "mesh":
            for key in ("spacing", "layers"):
                if key in particles.model_fields_set:
                    raise ValueError(f"particles.{key}: not used by specimen.shape = \"mesh\" (the particles are "
                                     "the mesh's nodes); remove it")
        elif shape != "shell" and particles.spacing is None:
            raise ValueError(f"particles.spacing: specimen.shape = \"{shape}\" needs the particle spacing (m)")
        refine = particles.refine
        if refine is not None:
            if shape not in ("box", "beam"):
                raise ValueError(f"particles.refine: grades a plate (specimen.shape \"box\"), not a {shape}; remove it")
            if refine.spacing >= particles.spacing:
                raise ValueError(f"particles.refine.spacing: {refine.spacing:g} m is not finer than particles.spacing "
                                 f"({particles.spacing:g} m); make it smaller")
        elif particles.support == "local" and shape not in ("mesh", "shell"):
            raise ValueError(f"particles.support: \"local\" follows the spacing of a graded set (a mesh, a shell or "
                             f"particles.refine); a {shape}'s grid is uniform: remove it")
        return self


# Support links per particle that budget.BYTES_PER["particles"] holds (paper 000's plates).
LINKS_BUDGETED = 60
# gmsh's nodes in a ball per cubed element size (measured 0.97-1.46 for 4-40 elements across).
BALL_NODES_PER_CUBED_ELEMENT = 1.5


def _planned_particles(spec, particles) -> list[tuple[float, str, str]]:
    """What particles.spacing (and particles.refine) ask for on a box, beam or tube before any
    particle is made, in particles of the budget's size, each with the key that sets it and what
    the count alone does not say, in the order to check them: the count (particles.spacing or
    particles.refine.spacing), then the count times the share of support links beyond
    LINKS_BUDGETED each (a wall far thicker than the spacing: its through-wall step sets a support
    radius that takes in thousands of neighbours, fewer with more particles.layers). Nothing
    to check for a mesh or surface file (the file bounds it)."""
    a, layers = particles.spacing, particles.layers
    if a is None or spec.shape in ("mesh", "shell"):
        return []
    if spec.shape == "tube":
        thickness = spec.thickness
        area = 2.0 * math.pi * (spec.inner_radius + 0.5 * thickness) * spec.length
        count = area / a**2 * layers
    else:
        thickness, *in_plane = sorted(spec.size)
        count = (in_plane[0] / a + 1.0) * (in_plane[1] / a + 1.0) * layers
        fine = particles.refine
        if fine is not None:  # the fine disc, and the ring where the spacing grows (mean 1 / s^2: 1 / (fine a))
            ring = fine.transition or max(fine.radius, 5.0 * a)
            count += layers * math.pi * (fine.radius**2 / fine.spacing**2
                                         + ((fine.radius + ring) ** 2 - fine.radius**2) / (fine.spacing * a))
            return [(count, "particles.refine.spacing", "")]
    checks = [(count, "particles.spacing", "")]
    across = thickness / max(layers - 1, 1)
    radius = particles.dilation * max(a, across)
    links = math.pi * radius**2 / a**2 * min(layers, 2.0 * radius / across + 1.0)
    if links > LINKS_BUDGETED:
        checks.append((count * links / LINKS_BUDGETED, "particles.layers",
                       f" ({count:,.0f} particles, each support taking in about {links:,.0f} neighbours where paper "
                       f"000's take {LINKS_BUDGETED}: the support radius is dilation x the through-wall step "
                       f"{across:.3g} m; more layers shorten it)"))
    return checks


def _check_body_sizes(bodies, max_memory) -> None:
    """The memory guard on the balls [[bodies]] asks gmsh for (element_size against radius)."""
    for i, body in enumerate(bodies):
        if body.shape == "sphere":
            planned = BALL_NODES_PER_CUBED_ELEMENT * 4.0 / 3.0 * math.pi * (body.radius / body.element_size) ** 3
            check_model_size(planned, "particles", f"bodies.{i}.element_size", max_memory,
                             f"; a radius in mm reads 1000x too large: bodies.{i}.radius is in metres too")


def build_simulation(scenario: Scenario, base: Path | None = None) -> MeshfreeSimulation:
    setup = SetUp(scenario, base)
    tools, supports, pressures = setup.tools, setup.supports, setup.pressures
    spec, particles = scenario.specimen, scenario.particles
    for planned, key, note in _planned_particles(spec, particles):
        setup.check_size(planned, "particles", key, note)
    mesh = None
    try:
        if spec.shape == "mesh":
            mesh = read_mesh(resolve_path(spec.file, base))
            plate = tet_node_particles(mesh.points * spec.scale, mesh.tets)
        elif spec.shape == "shell":
            plate = shell_particles(resolve_path(spec.file, base), spec.wall, particles.layers, spec.scale,
                                    spec.center, particles.spacing)
        elif spec.shape == "tube":
            plate = tube_particles(spec.origin, spec.axis, spec.inner_radius, spec.thickness, spec.length,
                                   particles.spacing, particles.layers)
        elif particles.refine is not None:
            fine = particles.refine
            transition = fine.transition or max(fine.radius, 5.0 * particles.spacing)
            plate = graded_plate_particles(spec.origin, spec.size, particles.spacing, particles.layers, fine.spacing,
                                           fine.center, fine.radius, transition)
        else:
            plate = plate_particles(spec.origin, spec.size, particles.spacing, particles.layers)
    except MeshError as err:
        key = "specimen.wall" if str(err).startswith("the wall") else "specimen.file"  # shell_from_surface's
        key = "particles.refine" if particles.refine is not None else key
        raise ScenarioError(f"{key}: {err}") from None
    except ValueError as err:
        raise ScenarioError(f"particles.{err}") from None
    if spec.shape in ("mesh", "shell"):
        try:
            check_file_units(plate.X, tools, "scale" in spec.model_fields_set, "specimen.file")
        except ValueError as err:
            raise ScenarioError(str(err)) from None
    _check_body_sizes(scenario.bodies, scenario.run.max_memory)
    specimen_size = float(np.max(np.ptp(plate.X, axis=0)))
    bodies = [_body(body, f"bodies.{i}", base, specimen_size) for i, body in enumerate(scenario.bodies)]
    materials = scenario.specimen_materials()
    if scenario.material is not None:
        index, several = None, None
        mat = scenario.material
        density, law = mat.density, mat.law()
    else:
        try:
            groups = None if mesh is None else node_groups(plate.X, mesh.tets, mesh.groups or {})
            index = assign_materials(materials, plate.X, groups, "particles")
        except ValueError as err:
            raise ScenarioError(str(err)) from None
        several = list(materials.values())
        density, law = [m.density for m in several], [m.law() for m in several]
    thresholds = _thresholds(plate.X, materials, index, scenario.run.seed)
    try:
        sim = build_meshfree_simulation(
            plate, density, law, dilation=particles.dilation, stabilisation=particles.stabilisation,
            tools=tools, supports=supports, damping=scenario.run.damping, gravity=scenario.run.gravity,
            velocity=spec.initial_velocity, fracture_stress=thresholds.fracture_stress,
            precracks=build_precracks(scenario.precracks), pressures=pressures,
            failure_plastic_strain=thresholds.failure_plastic_strain, bodies=bodies,
            self_contact=scenario.run.contact,
            support=particles.support or ("local" if particles.refine is not None else "uniform"),
            material=index, names=list(materials),
        )
    except SetupError as err:
        raise ScenarioError(f"{err.field}: {err}") from None
    except ValueError as err:
        raise ScenarioError(f"supports: {err}") from None
    sim.drawn, sim.random_properties = thresholds.drawn, thresholds.statistics or None
    return sim


@dataclass(frozen=True)
class _Thresholds:
    """The specimen's fracture thresholds: the fracture stress (Pa) and the failure plastic strain,
    each one number (one material, nothing drawn) or one per particle; the properties drawn per
    particle ({name: values on every specimen particle}) and their statistics per material."""

    fracture_stress: float | np.ndarray
    failure_plastic_strain: float | np.ndarray
    drawn: dict
    statistics: dict


def _thresholds(X, materials: dict, index, seed: int) -> _Thresholds:
    """Each particle's thresholds from its material (`index`: each particle's position in
    `materials`; None: one material): the material's values, or where its [random] draws them,
    values drawn at the particles' reference positions X from run.seed and the material's name
    (fracture.draw_thresholds; a property one material draws takes the others' plain values
    elsewhere)."""
    if index is None:
        (name, mat), = materials.items()
        drawn, statistics = draw_thresholds(X, mat.random, {k: getattr(mat, k) for k in mat.random}, seed, name)
        stress = mat.fracture_factor * drawn["tensile_strength"] if "tensile_strength" in drawn else mat.fracture_stress
        strain = drawn.get("failure_plastic_strain", mat.failure_plastic_strain)
        return _Thresholds(stress, strain, drawn, {name: statistics} if drawn else {})
    several = list(materials.values())
    strength = np.array([m.tensile_strength for m in several])[index]
    strain = np.array([m.failure_plastic_strain for m in several])[index]
    drawn_names = sorted({k for m in several for k in m.random})
    drawn = {k: {"tensile_strength": strength, "failure_plastic_strain": strain}[k].copy() for k in drawn_names}
    statistics = {}
    for i, (name, mat) in enumerate(materials.items()):
        if not mat.random:
            continue
        own = index == i
        values, statistics[name] = draw_thresholds(X[own], mat.random, {k: getattr(mat, k) for k in mat.random},
                                                   seed, name)
        for k, v in values.items():
            drawn[k][own] = v
    if "tensile_strength" in drawn:
        strength = drawn["tensile_strength"]
    strain = drawn.get("failure_plastic_strain", strain)
    return _Thresholds(np.array([m.fracture_factor for m in several])[index] * strength, strain, drawn, statistics)


def _body(spec: BodySpec, key: str, base: Path | None, specimen_size: float) -> MeshfreeBody:
    """The particles of a [[bodies]] entry (a particle at each node of its tet mesh); a mesh file
    BODY_SPECIMEN_RATIO times the specimen's size (m) is taken for one in mm unless its scale is given."""
    try:
        if spec.shape == "sphere":
            mesh = gmsh_sphere(spec.radius, spec.element_size, spec.center)
            points = mesh.points
        else:
            mesh = read_mesh(resolve_path(spec.file, base))
            points = mesh.points * spec.scale
        particles = tet_node_particles(points, mesh.tets)
    except (MeshError, ValueError) as err:
        raise ScenarioError(f"{key}.{'file' if spec.shape == 'mesh' else 'element_size'}: {err}") from None
    try:
        check_file_units(points, [], spec.shape == "sphere" or "scale" in spec.model_fields_set, f"{key}.file",
                         "the body", ("the specimen", specimen_size), BODY_SPECIMEN_RATIO)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    mat = spec.material
    return MeshfreeBody(particles, mat.density, mat.law(), spec.initial_velocity, spec.dilation, spec.name)

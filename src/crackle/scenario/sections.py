"""What a scenario is: the sections every method shares (`ScenarioBase`, `[run]`, `[[tools]]`,
`[plates]`, `[[supports]]`, `[[pressures]]`, `[initial_stress]`, ...) and the shared section
schemas a method's own `Scenario` is made of (`Specimen`, `ElasticSpec`, `Zone`, ...). Validated
with pydantic; nothing in a scenario is evaluated."""

from __future__ import annotations

import math
from functools import cached_property
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

from pydantic import Field, field_validator, model_validator

from ..schema import NonNegative, Positive, PositiveOrInf, Strict, Vec3

if TYPE_CHECKING:
    import numpy as np

    from ..geometry.aggregates import Aggregates

__all__ = [
    "ANY_SHAPE_KEYS",
    "AnalysisSpec",
    "CracksSpec",
    "ElasticSpec",
    "FracturePlaneSpec",
    "HoleSpec",
    "InitialStressSpec",
    "LoadingSpec",
    "MaterialPlace",
    "OPTIONAL_KEYS",
    "PlatesSpec",
    "PrecrackSpec",
    "PressureSpec",
    "RunSpec",
    "SPECIMEN_KEYS",
    "STRESS_ORDER",
    "ScenarioBase",
    "Specimen",
    "Stop",
    "SupportSpec",
    "ToolSpec",
    "VelocityTable",
    "Where",
    "Zone",
    "assign_materials",
    "check_material_names",
    "check_material_tables",
    "check_one_motion",
    "check_one_rest",
    "fills_the_rest",
    "material_pair",
    "refuse_unused_keys",
    "stress_matrices",
]


# The [specimen] keys each shape reads (FDEM's; the DEM's are fewer): a key set that the shape
# does not read is refused, since the specimen would silently not be the one asked for.
_BOX = {"size", "element_size", "origin", "mesh", "holes"}
_ROUND = {"diameter", "thickness", "element_size", "center", "axis"}
_WALLS = {"element_size", "center", "wall", "suture_wall", "suture_band", "layers"}
SPECIMEN_KEYS = {
    "box": _BOX, "beam": _BOX, "disc": _ROUND, "cylinder": _ROUND,
    "sphere": {"diameter", "element_size", "center"},
    "walnut": _WALLS | {"length", "width", "thickness"},
    "shell": _WALLS | {"file", "scale", "suture_normal"},
    "mesh": {"file", "scale"},
}
# Read by every shape: the shape and the initial motion.
ANY_SHAPE_KEYS = {"shape", "initial_velocity", "angular_velocity"}


def refuse_unused_keys(spec, keys: dict[str, set[str]]) -> None:
    """ValueError naming the keys set in `spec` that its shape does not read (`keys[shape]`)."""
    other = sorted(spec.model_fields_set - keys[spec.shape] - ANY_SHAPE_KEYS)
    if other:
        raise ValueError(f"{', '.join(other)}: not used by shape = \"{spec.shape}\" (its keys: "
                         f"{', '.join(sorted(keys[spec.shape]))})")


class HoleSpec(Strict):
    """[[specimen.holes]]: a cylindrical hole through the whole box (a borehole, a tunnel)."""

    center: Vec3
    """m, a point on its axis"""
    axis: Vec3 = (0.0, 0.0, 1.0)
    """its axis"""
    radius: Positive
    """m"""
    element_size: Positive | None = None
    """m, the tets at its wall, growing to specimen.element_size over `grading`; default specimen.element_size"""
    grading: Positive | None = None
    """m, the distance from the wall over which the tets grow; default 3 radii"""


class Specimen(Strict):
    """[specimen]: the solid's shape and its mesh (FDEM)."""

    shape: Literal["box", "beam", "disc", "cylinder", "sphere", "walnut", "shell", "mesh"]
    """box and beam: structured or gmsh tets; disc, cylinder, sphere: gmsh; walnut: a suture-banded ellipsoidal
    shell (paper 004); shell: walled inwards from a closed surface file; mesh: a tet mesh file"""
    element_size: Positive | None = None
    """m, the target tet edge (box, beam, disc, cylinder, sphere, walnut; shell: remeshes the surface when given)"""
    size: tuple[Positive, Positive, Positive] | None = None
    """m, box and beam: (Lx, Ly, Lz)"""
    origin: Vec3 = (0.0, 0.0, 0.0)
    """m, box and beam: the lower corner"""
    mesh: Literal["structured", "unstructured"] = "structured"
    """box and beam: 24 tets per cubic cell, or gmsh"""
    diameter: Positive | None = None
    """m, disc, cylinder, sphere"""
    thickness: Positive | None = None
    """m, disc and cylinder: extent along the axis; walnut: its thickness T (along y)"""
    center: Vec3 = (0.0, 0.0, 0.0)
    """m, disc, cylinder, sphere, walnut; shell: added to the scaled file points"""
    length: Positive | None = None
    """m, walnut: its length L (along z)"""
    width: Positive | None = None
    """m, walnut: its width W (along x)"""
    wall: Positive = 1.11e-3
    """m, walnut and shell: the face wall thickness"""
    suture_wall: Positive = 1.34e-3
    """m, walnut and shell: the suture's wall thickness (thicker inwards)"""
    suture_band: Positive = 4e-3
    """m, walnut and shell: width of the suture band about its plane (the region of the [suture] material)"""
    layers: Annotated[int, Field(ge=1)] = 1
    """walnut and shell: tets through the wall"""
    scale: Positive = 1.0
    """shell and mesh: factor on the file's points (1e-3 for a file in mm)"""
    suture_normal: Vec3 = (1.0, 0.0, 0.0)
    """shell: normal of the suture plane, which passes through the surface's centroid"""
    axis: Vec3 = (0.0, 0.0, 1.0)
    """disc and cylinder: the axis"""
    file: str | None = None
    """mesh: any tet mesh meshio reads (.msh, .vtu, .inp ...); shell: its closed outer surface (STL or any
    meshio format); relative to the scenario file's folder"""
    holes: list[HoleSpec] = []
    """box and beam with mesh = "unstructured": cylindrical holes through the whole box, each meshed finer at
    its wall when it asks"""
    initial_velocity: Vec3 = (0.0, 0.0, 0.0)
    """m/s, of the whole specimen at t = 0"""
    angular_velocity: Vec3 = (0.0, 0.0, 0.0)
    """rad/s at t = 0, a rigid spin about the centre of mass"""

    @model_validator(mode="after")
    def _needs(self):
        need = {
            "box": ("size", "element_size"),
            "beam": ("size", "element_size"),
            "disc": ("diameter", "thickness", "element_size"),
            "cylinder": ("diameter", "thickness", "element_size"),
            "sphere": ("diameter", "element_size"),
            "walnut": ("length", "width", "thickness", "element_size"),
            "shell": ("file",),
            "mesh": ("file",),
        }[self.shape]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"shape '{self.shape}' needs {', '.join(missing)}")
        refuse_unused_keys(self, SPECIMEN_KEYS)
        if self.holes and self.mesh != "unstructured":
            raise ValueError('holes: a box with holes is meshed by gmsh: set specimen.mesh = "unstructured"')
        extent = self.extent()
        h = self.element_size
        if h is not None and extent is not None:
            # gmsh would clamp a too-large size silently; a tiny one would mesh for hours.
            if h > extent:
                raise ValueError(
                    f"element_size = {h:g} m is larger than the specimen ({extent:g} m across); sizes are in "
                    f"metres (10 mm is 0.01)"
                )
            if h < 1e-5 * extent:
                raise ValueError(
                    f"element_size = {h:g} m is below 1e-5 of the specimen ({extent:g} m across): "
                    f"{(extent / h) ** 3:.1e} elements; sizes are in metres"
                )
        return self

    def extent(self) -> float | None:
        """The specimen's largest dimension (m), where the scenario gives it."""
        dims = {
            "box": self.size, "beam": self.size,
            "disc": (self.diameter, self.thickness), "cylinder": (self.diameter, self.thickness),
            "sphere": (self.diameter,), "walnut": (self.length, self.width, self.thickness),
        }.get(self.shape)
        return max(dims) if dims else None


class ElasticSpec(Strict):
    """[material]: what every method's material has; a method adds its fracture law's section."""

    name: str = "material"
    """a label for messages and summary.json"""
    density: Positive
    """kg/m^3 (10-30,000)"""
    youngs_modulus: Positive
    """Pa (1e5-2e12)"""
    poissons_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)]
    """dimensionless"""

    @field_validator("density")
    @classmethod
    def _density_in_kg_per_m3(cls, rho):
        # Solids from foams (~30) to tungsten (19,300): a value of a few units is g/cm^3 or t/m^3.
        if not 10.0 <= rho <= 30000.0:
            hint = f"; {rho:g} g/cm^3 is {rho * 1000:g} kg/m^3" if rho < 10.0 else ""
            raise ValueError(f"density = {rho:g} kg/m^3 is outside the range of solids (10-30,000 kg/m^3){hint}")
        return rho

    @field_validator("youngs_modulus")
    @classmethod
    def _modulus_in_pa(cls, E):
        # Solids from soft polymers (~1 MPa) to diamond (~1.2 TPa).
        if not 1e5 <= E <= 2e12:
            hint = ""
            if E < 1e5:
                hint = f"; if that is GPa, write {E:g}e9, if MPa, {E:g}e6"
            raise ValueError(f"youngs_modulus = {E:g} Pa is outside the range of solids (1e5-2e12 Pa){hint}")
        return E


class VelocityTable(Strict):
    """A piecewise-linear history: a value at each time, held after the last."""

    time: list[NonNegative]
    """s, increasing"""
    speed: list[float]
    """m/s for a tool (Pa for a pressure table), one per time"""

    @model_validator(mode="after")
    def _a_history(self):
        if not self.time or len(self.time) != len(self.speed):
            raise ValueError(f"time and speed need one value each per row: {len(self.time)} times and "
                             f"{len(self.speed)} values given")
        if not all(math.isfinite(v) for v in self.speed):
            raise ValueError("speed: every value must be a finite number")
        later = [i for i in range(1, len(self.time)) if self.time[i] <= self.time[i - 1]]
        if later:
            i = later[0]
            raise ValueError(f"time must increase: {self.time[i]:g} s (row {i + 1}) follows {self.time[i - 1]:g} s")
        return self


def check_one_motion(spec, motion_keys: tuple[str, ...] = ("speed", "ramp_time")) -> None:
    """A tool or support moves by speed (and ramp_time) or by speed_table, not both: a table given
    beside them was silently preferred. (Zero beside a table is allowed: --set cannot remove a key.)"""
    beside = [k for k in motion_keys if getattr(spec, k)]
    if spec.speed_table is not None and beside:
        raise ValueError(f"speed_table replaces {' and '.join(motion_keys)}: remove {', '.join(beside)} or set "
                         f"{' and '.join(beside)} to 0 (or remove the table)")


class ToolSpec(Strict):
    """[[tools]]: a rigid tool moving by translation along `direction` (plane, box, cylinder, sphere,
    projectile, or a triangle surface from a file)."""

    name: str
    """for history.csv columns (tool.NAME.fx ...) and --set tools.NAME.key"""
    shape: Literal["plane", "box", "cylinder", "sphere", "projectile", "surface"]
    """plane: a half-space; box, cylinder, sphere: solids; projectile: a nose on a cylinder, its tip at center,
    pointing along direction (geometry.projectile); surface: triangles from `file`"""
    direction: Vec3
    """of motion (normalised; need not be a unit vector)"""
    speed: float = 0.0
    """m/s along direction (0: fixed)"""
    ramp_time: NonNegative = 0.0
    """s, linear ramp from 0 to speed"""
    speed_table: VelocityTable | None = None
    """instead of speed and ramp_time: m/s against s"""
    friction: NonNegative = 0.0
    """Coulomb coefficient against the specimen"""
    center: Vec3 = (0.0, 0.0, 0.0)
    """m, plane: a point on it; box, sphere: centre; cylinder: a point on the axis; projectile: the nose's tip"""
    normal: Vec3 = (0.0, 0.0, 1.0)
    """plane: pointing out of the tool, towards the specimen"""
    size: tuple[Positive, Positive, Positive] = (1.0, 1.0, 1.0)
    """m, box: full edge lengths along axes[0], axes[1] and their cross product"""
    axes: tuple[Vec3, Vec3] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    """box: two orthonormal in-plane axes"""
    axis: Vec3 = (0.0, 0.0, 1.0)
    """cylinder: its axis"""
    radius: NonNegative = 0.0
    """m, cylinder, sphere and projectile (its shank's)"""
    length: PositiveOrInf = math.inf
    """m, cylinder: inf for an endless roller; projectile: tip to tail (required)"""
    nose: Literal["conical", "ogival", "hemispherical", "flat"] | None = None
    """projectile: its nose; ogival is a pointed tangent ogive (calibre-radius-head psi: nose_length = radius x
    sqrt(4 psi - 1)); flat: a blunt cylinder"""
    nose_length: Positive | None = None
    """m, projectile with a conical or ogival nose: tip to shank along the axis (an ogive's at least its radius)"""
    penalty: Positive | None = None
    """N/m^3 per unit contact area; default 10 E / h of the specimen"""
    touch: bool = False
    """box and sphere: shift the tool along `direction` (either way) at set-up until it just reaches the
    specimen (no initial gap); a glued tool placed ahead of the specimen along `direction` (a grip that pulls)
    is put on the specimen's far end"""
    seat: bool = False
    """points of the specimen inside the tool at set-up start unloaded where they are: no force until the tool
    pushes them deeper (a platen on a packing from another code whose spheres overlap the box faces, as that
    code's walls seat them); the contacts of points outside it are unchanged"""
    glued: bool = False
    """the points that come within glue_depth of the tool stick to it for good: it pulls as well as pushes and
    they never slip (a glued platen, a gripped end: direct tension); friction is then unused"""
    glue_depth: Positive | None = None
    """m, glued: how close a point must come to stick; default a millionth of the element size (the points a
    touching tool rests on). DEM: about a particle radius to grip the particles near an end"""
    file: str | None = None
    """surface: a triangle file meshio reads (STL, .obj, .ply, .vtu, .msh ...), relative to the scenario
    file's folder"""
    scale: Positive = 1.0
    """surface: factor on the file's points (1e-3 for a file in mm)"""
    offset: Vec3 = (0.0, 0.0, 0.0)
    """m, surface: added to the scaled points"""
    mass: Positive | None = None
    """kg: a free rigid body (a projectile, a drop weight) launched at `speed` along `direction`, then moved
    only by its contact with the specimen (translation, no gravity); unset: the tool follows its speed"""

    @model_validator(mode="after")
    def _shape_needs(self):
        if self.shape in ("cylinder", "sphere", "projectile") and self.radius <= 0:
            raise ValueError(f"a {self.shape} tool needs radius > 0")
        self._projectile_needs()
        if self.shape == "surface" and not self.file:
            raise ValueError("a surface tool needs file = \"...\" (an STL or other triangle surface)")
        surface_only = sorted({"file", "scale", "offset"} & self.model_fields_set)
        if self.shape != "surface" and surface_only:
            raise ValueError(f"{', '.join(surface_only)}: only for shape = \"surface\"")
        if all(c == 0 for c in self.direction):
            raise ValueError("direction must be a non-zero vector")
        if self.glue_depth is not None and not self.glued:
            raise ValueError("glue_depth is for a glued tool: add glued = true, or remove glue_depth")
        if self.seat and self.glued:
            raise ValueError("seat = true is for a tool that pushes; a glued one holds the points it reaches: "
                             "remove one of them")
        if self.touch and self.shape not in ("box", "sphere"):
            raise ValueError("touch = true is for box and sphere tools")
        check_one_motion(self)
        driven = sorted({"ramp_time", "speed_table"} & self.model_fields_set)
        if self.mass is not None and driven:
            raise ValueError(f"{', '.join(driven)}: a tool with a mass is free and starts at `speed`; "
                             "remove mass to drive it, or these keys to launch it")
        return self

    def _projectile_needs(self):
        from ..geometry.projectile import nose_extent  # here: crackle.geometry's meshing imports take 0.1 s

        projectile_only = sorted({"nose", "nose_length"} & self.model_fields_set)
        if self.shape != "projectile":
            if projectile_only:
                raise ValueError(f"{', '.join(projectile_only)}: only for shape = \"projectile\"")
            return
        if self.nose is None:
            raise ValueError("a projectile needs nose = \"conical\", \"ogival\", \"hemispherical\" or \"flat\"")
        pointed = self.nose in ("conical", "ogival")
        if pointed and self.nose_length is None:
            raise ValueError(f"a {self.nose} nose needs nose_length (m, tip to shank)")
        if not pointed and self.nose_length is not None:
            raise ValueError(f"nose_length: a {self.nose} nose has its own length (hemispherical: the radius; flat: "
                             "none); remove it")
        if self.nose == "ogival" and self.nose_length < self.radius:
            raise ValueError(f"nose_length = {self.nose_length:g} m: a pointed tangent ogive is at least as long "
                             f"as its radius {self.radius:g} m (calibre-radius-head >= 0.5)")
        extent = nose_extent(self.nose, self.radius, self.nose_length)
        if not extent < self.length < math.inf:
            raise ValueError(f"length = {self.length:g}: a projectile needs its length, tip to tail, longer than its "
                             f"nose ({extent:g} m)")


class PlatesSpec(Strict):
    """N rigid square plates placed about `center` by their top (polar, from +z) and azimuth
    (from +x toward +y) angles, each moving toward `center` at `speed` (paper 004's multi-point
    loading). Each becomes a box tool named plate1..plateN, tangent to the specimen at the start."""

    polar: list[float]
    """degrees from +z, one per plate"""
    azimuth: list[float]
    """degrees from +x toward +y, one per plate"""
    speed: float = 0.0
    """m/s, each plate toward the centre"""
    ramp_time: NonNegative = 0.0
    """s, linear ramp from 0 to speed"""
    friction: NonNegative = 0.0
    """Coulomb coefficient against the specimen"""
    side: Positive = 0.02
    """m, edge of the square plate"""
    thickness: Positive = 0.005
    """m"""
    center: Vec3 = (0.0, 0.0, 0.0)
    """m, the point the plates move toward"""
    penalty: Positive | None = None
    """Pa/m, every plate's contact penalty; default the method's (a tool's own default)"""

    @model_validator(mode="after")
    def _pairs(self):
        if len(self.polar) != len(self.azimuth):
            raise ValueError(
                f"give one azimuth per top angle: {len(self.polar)} polar and {len(self.azimuth)} azimuth values"
            )
        if not 1 <= len(self.polar) <= 12:
            raise ValueError("between 1 and 12 plates")
        return self

    def tool_specs(self) -> list["ToolSpec"]:
        """The plates as box tools: thin along their direction of motion, touching at the start."""
        out = []
        for k, (theta, phi) in enumerate(zip(self.polar, self.azimuth)):
            th, ph = math.radians(theta), math.radians(phi)
            u = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
            # In-plane axes: e1 normal to u and z (x when u is along z), e2 = u x e1.
            e1 = (-u[1], u[0], 0.0) if abs(u[2]) < 1.0 - 1e-12 else (1.0, 0.0, 0.0)
            n1 = math.hypot(*e1)
            e1 = tuple(c / n1 for c in e1)
            e2 = (u[1] * e1[2] - u[2] * e1[1], u[2] * e1[0] - u[0] * e1[2], u[0] * e1[1] - u[1] * e1[0])
            out.append(ToolSpec(
                name=f"plate{k + 1}", shape="box", direction=tuple(-c for c in u), speed=self.speed,
                ramp_time=self.ramp_time, friction=self.friction,
                center=tuple(c + self.thickness * d for c, d in zip(self.center, u)),
                size=(self.side, self.side, self.thickness), axes=(e1, e2), touch=True, penalty=self.penalty,
            ))
        return out

    def penalty_keys(self) -> dict[str, str]:
        """{plate tool name: the key that sets its penalty}, for advice."""
        return {f"plate{k + 1}": "plates.penalty" for k in range(len(self.polar))}


class LoadingSpec(Strict):
    """A rigid rotation of every tool about `axis` through `center` (the mesh stays put)."""

    angle: float = 0.0
    """degrees, right-handed about axis"""
    axis: Vec3 = (0.0, 0.0, 1.0)
    """of the rotation"""
    center: Vec3 = (0.0, 0.0, 0.0)
    """m, a point on the axis"""

    @field_validator("axis")
    @classmethod
    def _nonzero_axis(cls, v):
        if all(c == 0 for c in v):
            raise ValueError("axis must be a non-zero vector")
        return v


class Zone(Strict):
    """A part of space a material fills (by the cell's centroid, the particle's centre): a box, a
    sphere, the half-space a normal points into, a layer about a plane (with `spacing`, a stack
    of parallel layers: bedding), or random aggregates in a box (a concrete mesostructure)."""

    shape: Literal["box", "sphere", "half-space", "layer", "aggregates"]
    """box (box_min, box_max), sphere (center, radius), half-space (point, normal: the side the normal points to),
    layer (point, normal, thickness; spacing for a stack), aggregates (box_min, box_max, min_diameter, max_diameter,
    volume_fraction; exponent, gap, seed, axis: random non-overlapping spheres, or cylinders along an axis, of a
    Fuller grading placed in the box by take-and-place, the box periodic: aggregates cut by its faces come back
    through the opposite ones, so a specimen inside it holds the fraction, cut by its surface)"""
    box_min: Vec3 | None = None
    """m, box and aggregates: the lower corner (aggregates: e.g. the specimen's bounding box's; the box may be
    larger)"""
    box_max: Vec3 | None = None
    """m, box and aggregates: the upper corner"""
    center: Vec3 | None = None
    """m, sphere"""
    radius: Positive | None = None
    """m, sphere"""
    point: Vec3 | None = None
    """m, half-space and layer: a point on the plane (a layer's mid-plane)"""
    normal: Vec3 | None = None
    """half-space and layer: the plane's normal"""
    thickness: Positive | None = None
    """m, layer: its thickness"""
    spacing: Positive | None = None
    """m, layer: the distance between the mid-planes of a stack of such layers (unset: one layer)"""
    min_diameter: Positive | None = None
    """m, aggregates: the smallest aggregate modelled (finer sand is part of the material that fills the rest); the
    element size should be at most a third to a half of it"""
    max_diameter: Positive | None = None
    """m, aggregates: the largest aggregate"""
    volume_fraction: Annotated[float, Field(gt=0.0, lt=1.0)] | None = None
    """aggregates: the share of the box the aggregates fill (with axis: of its cross-section, by area); random
    take-and-place reaches about 0.45 in 3D and 0.6 in 2D for a Fuller grading over a factor 4 in size"""
    exponent: Positive = 0.5
    """aggregates: n of the Fuller curve, the volume share of the aggregate passing a sieve of size d being
    (d / max_diameter)^n; between min_diameter and max_diameter the sizes follow it, class by class"""
    gap: NonNegative | None = None
    """m, aggregates: the least distance between two aggregates' surfaces (a mortar film); default 0.1 x
    min_diameter"""
    seed: Annotated[int, Field(ge=0)] = 0
    """aggregates: of their sizes and places: the same seed, the same aggregates on any machine and mesh; apart from
    run.seed (the material properties' draws), so `crackle sweep --seeds` keeps the mesostructure: vary this key
    (e.g. --vary materials.aggregate.zones.0.seed=0,1,2) for other ones"""
    axis: Vec3 | None = None
    """aggregates: cylinders along this coordinate axis ([0, 0, 1]: z) through the whole box instead of spheres
    (the 2D mesostructure of a thin disc); grading and fraction are then by area"""

    _NEEDS: ClassVar[dict[str, tuple[str, ...]]] = {
        "box": ("box_min", "box_max"), "sphere": ("center", "radius"), "half-space": ("point", "normal"),
        "layer": ("point", "normal", "thickness"),
        "aggregates": ("box_min", "box_max", "min_diameter", "max_diameter", "volume_fraction"),
    }
    # The keys a shape may leave out (their defaults apply).
    _OPTIONAL: ClassVar[dict[str, tuple[str, ...]]] = {
        "layer": ("spacing",), "aggregates": ("exponent", "gap", "seed", "axis"),
    }

    @model_validator(mode="after")
    def _complete(self):
        needs = self._NEEDS[self.shape]
        zone = f"{'an' if self.shape[0] in 'aeiou' else 'a'} {self.shape} zone"
        missing = [key for key in needs if getattr(self, key) is None]
        if missing:
            raise ValueError(f"{zone} needs {', '.join(missing)}")
        optional = self._OPTIONAL.get(self.shape, ())
        extra = sorted(set(self.model_fields_set) - {"shape", *needs, *optional})
        if extra:
            also = f"; optional: {', '.join(optional)}" if optional else ""
            raise ValueError(f"{', '.join(extra)}: not a key of {zone} (it takes {', '.join(needs)}{also})")
        if self.normal is not None and not any(self.normal):
            raise ValueError("normal must be a non-zero vector")
        if self.shape in ("box", "aggregates") and not all(lo < hi for lo, hi in zip(self.box_min, self.box_max)):
            raise ValueError("box_min must be below box_max in x, y and z")
        if self.spacing is not None and self.spacing <= self.thickness:
            raise ValueError(f"spacing = {self.spacing:g} m is not above thickness = {self.thickness:g} m: the layers "
                             "would fill everything; give a larger spacing or drop it")
        if self.shape == "aggregates":
            self._check_aggregates()
        return self

    def _check_aggregates(self) -> None:
        """What take-and-place cannot do, refused before any aggregate is placed."""
        from ..geometry.aggregates import check_request

        axis = self.aggregate_axis()
        extent = [self.box_max[k] - self.box_min[k] for k in range(3) if k != axis]
        check_request(extent, self.min_diameter, self.max_diameter, self.volume_fraction, self.aggregate_gap())

    def aggregate_axis(self) -> int | None:
        """aggregates: the coordinate (0, 1, 2) the cylinders run along, None for spheres."""
        if self.axis is None:
            return None
        along = [k for k, c in enumerate(self.axis) if c != 0.0]
        if len(along) != 1:
            raise ValueError(f"axis = {list(self.axis)}: aggregates take a coordinate axis ([1, 0, 0], [0, 1, 0] "
                             "or [0, 0, 1]), as their box is aligned with them")
        return along[0]

    def aggregate_gap(self) -> float:
        """m, aggregates: the gap asked for, or its default 0.1 x min_diameter."""
        return self.gap if self.gap is not None else 0.1 * self.min_diameter

    @cached_property
    def placed_aggregates(self) -> "Aggregates":
        """aggregates: the placed set (geometry.aggregates.Aggregates), placed once per zone;
        AggregatePlacementError (a ValueError) when the fraction cannot be placed."""
        from ..geometry.aggregates import place_aggregates

        return place_aggregates(self.box_min, self.box_max, self.min_diameter, self.max_diameter,
                                self.volume_fraction, self.aggregate_gap(), seed=self.seed, exponent=self.exponent,
                                axis=self.aggregate_axis())

    def planes(self, center, radius: float) -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
        """The planes (point, unit normal) that bound a layer (each layer of a stack) or a half-space
        within `radius` of `center` (m): where a generated mesh is cut so that the zone's faces are
        those planes (none for the other shapes)."""
        import numpy as np

        if self.shape not in ("layer", "half-space"):
            return []
        n = np.asarray(self.normal, float) / np.linalg.norm(self.normal)
        mid = float(np.asarray(self.point, float) @ n)
        if self.shape == "half-space":
            offsets = [mid]
        else:
            half, at = 0.5 * self.thickness, float(np.asarray(center, float) @ n)
            if self.spacing is None:
                mids = [mid]
            else:
                first, last = (int(np.floor((at - radius - half - mid) / self.spacing)),
                               int(np.ceil((at + radius + half - mid) / self.spacing)))
                mids = [mid + k * self.spacing for k in range(first, last + 1)]
            offsets = [m + side for m in mids for side in (-half, half)]
            offsets = [d for d in offsets if abs(d - at) < radius]
        return [(tuple(float(v) for v in d * n), tuple(float(v) for v in n)) for d in offsets]

    def contains(self, x) -> "np.ndarray":
        """Which of the points x (m, (k, 3)) lie inside (a box and a layer with their bounds)."""
        import numpy as np

        x = np.asarray(x, dtype=float).reshape(-1, 3)
        if self.shape == "aggregates":
            return self.placed_aggregates.contains(x)
        if self.shape == "box":
            return np.all((x >= np.asarray(self.box_min)) & (x <= np.asarray(self.box_max)), axis=1)
        if self.shape == "sphere":
            return np.linalg.norm(x - np.asarray(self.center), axis=1) <= self.radius
        n = np.asarray(self.normal, float) / np.linalg.norm(self.normal)
        height = (x - np.asarray(self.point, float)) @ n
        if self.shape == "half-space":
            return height >= 0.0
        if self.spacing is not None:
            height = (height + 0.5 * self.spacing) % self.spacing - 0.5 * self.spacing
        return np.abs(height) <= 0.5 * self.thickness


def _check_stack_spacing(zone, positions, key: str) -> None:
    """ValueError when a stack of layers (`spacing`) is spaced wider than the sites span along its
    normal: a stack of one layer at most (a spacing in mm read as metres)."""
    import numpy as np

    if getattr(zone, "spacing", None) is None or len(positions) == 0:
        return
    n = np.asarray(zone.normal, float) / np.linalg.norm(zone.normal)
    extent = float(np.ptp(positions @ n))
    if zone.spacing > extent:
        raise ValueError(f"{key}.spacing = {zone.spacing:g} m is more than the specimen's {extent:.3g} m along the "
                         f"layers' normal: a stack of one layer at most; lengths are in metres (mm meant? write "
                         f"{zone.spacing:g}e-3), or drop spacing for one layer")


def check_material_names(names) -> None:
    """ValueError for a [materials] name that events.csv's material column cannot carry."""
    for name in names:
        if not name or any(ch in name for ch in ',"\r\n'):
            raise ValueError(f"materials.{name!r}: a material's name may not be empty or hold a comma, a quote or a "
                             "line break (events.csv names the material of each failure); rename it")


class MaterialPlace(Strict):
    """Where one of several materials ([materials.NAME]) is: a group of the mesh file's tets or zones; the one
    with neither fills the rest (assign_materials)."""

    group: str | None = None
    """specimen.shape = "mesh": the file's group of tets this material fills (a gmsh physical volume's name, an
    Abaqus *Elset, a meshio cell set); meshfree: a particle, a node of the mesh, takes the group holding the most of
    its cell (a quarter of each tet around it)"""
    zones: list[Zone] = []
    """the zones this material fills (a tet by its centroid, a meshfree particle by its reference position); a later
    material wins where two claim one"""

    @model_validator(mode="after")
    def _one_way(self):
        if self.group is not None and self.zones:
            raise ValueError("give group or zones, not both")
        return self


def material_pair(key: str, names: list[str]) -> tuple[str, str]:
    """The two materials an [interfaces] key "A-B" names (names may hold '-' themselves)."""
    for cut in (i for i, ch in enumerate(key) if ch == "-"):
        a, b = key[:cut], key[cut + 1:]
        if a in names and b in names and a != b:
            return a, b
    raise ValueError(f'interfaces."{key}": not two different materials joined by "-" (materials: {", ".join(names)})')


def check_material_tables(material, materials: dict) -> None:
    """[material] (one material) or [materials.NAME] tables (several): ValueError for both or neither,
    or for a name events.csv cannot carry."""
    if (material is None) == (not materials):
        raise ValueError("give [material] (one material) or [materials.NAME] tables (several), not both"
                         if materials else "[material] is missing (or give [materials.NAME] for several)")
    check_material_names(materials)


def fills_the_rest(material) -> bool:
    """A [materials.NAME] with neither group nor zones: it fills what the others leave."""
    return getattr(material, "group", None) is None and not material.zones


def check_one_rest(materials: dict) -> None:
    """ValueError when more than one of [materials.NAME] fills the rest."""
    rest = [name for name, m in materials.items() if fills_the_rest(m)]
    if len(rest) > 1:
        raise ValueError(f"materials {', '.join(rest)}: only one material may fill the rest (no group, no zones); "
                         "give the others a group or zones")


def assign_materials(materials: dict, positions, groups: dict | None = None, sites: str = "tets") -> "np.ndarray":
    """Each site's material (its index in `materials`, [materials.NAME] in order): the one that
    fills the rest, then each material's group (`groups[name]`: the file's group as the sites' ids
    or a mask over them) or zones (a site by its position, m (n, 3)) in table order, a later one
    winning; ValueError naming what does not match (the groups asked and the file's, sites left
    without a material). `sites` names them in the messages (tets, particles)."""
    import numpy as np

    positions = np.asarray(positions, dtype=float).reshape(-1, 3)
    names = list(materials)
    rest = [i for i, m in enumerate(materials.values()) if fills_the_rest(m)]
    material = np.full(len(positions), rest[0] if rest else -1, dtype=np.int64)
    asked = {m.group for m in materials.values() if getattr(m, "group", None) is not None}
    if asked:
        found = set(groups or {})
        if asked - found or found - asked:
            raise ValueError(
                f"materials.*.group and the file's groups of {sites} do not match: "
                f"named by no material: {', '.join(sorted(found - asked)) or 'none'}; "
                f"in no group of the file: {', '.join(sorted(asked - found)) or 'none'} "
                f"(the file's groups: {', '.join(sorted(found)) or 'none'})")
    for index, (name, m) in enumerate(materials.items()):
        if getattr(m, "group", None) is not None:
            material[groups[m.group]] = index
        for i, zone in enumerate(m.zones):
            _check_stack_spacing(zone, positions, f"materials.{name}.zones.{i}")
            material[zone.contains(positions)] = index
    unassigned = int(np.sum(material < 0))
    if unassigned:
        raise ValueError(f"{unassigned:,} of {len(positions):,} {sites} lie in no material's group or zones: give one "
                         f"of [materials] ({', '.join(names)}) neither group nor zones, to fill the rest")
    return material


class Where(Strict):
    """Nodes or faces chosen by geometry: on a plane and/or inside an axis-aligned box."""

    plane_point: Vec3 | None = None
    """m, a point on the plane"""
    plane_normal: Vec3 | None = None
    """the plane's normal"""
    box_min: Vec3 | None = None
    """m, lower corner of the box"""
    box_max: Vec3 | None = None
    """m, upper corner of the box"""
    radius: Positive | None = None
    """m, on the cylinder of this radius about the line through axis_point along axis_direction (a cylinder's
    side: the faces there whose normal is not along the axis, so not the ends' rim)"""
    axis_point: Vec3 | None = None
    """m, with radius: a point on the cylinder's axis"""
    axis_direction: Vec3 | None = None
    """with radius: the cylinder's axis"""
    group: str | None = None
    """a named surface of the specimen's mesh file (FDEM, specimen.shape = "mesh": a gmsh physical surface, a
    meshio cell set of triangles): its faces (a pressure) or its nodes (a support); with the keys above, the
    part of it they also select"""
    tol: Positive | None = None
    """m, distance to the plane (or cylinder) that counts as on it; default 1e-6 of the specimen size"""

    @model_validator(mode="after")
    def _some(self):
        if (self.plane_point is None) != (self.plane_normal is None):
            raise ValueError("give both plane_point and plane_normal")
        if (self.radius is None) != (self.axis_point is None) or (self.radius is None) != (self.axis_direction is None):
            raise ValueError("a cylinder's side needs radius, axis_point and axis_direction together")
        if self.plane_point is None and self.box_min is None and self.box_max is None and self.radius is None and \
                self.group is None:
            raise ValueError("choose nodes with plane_point + plane_normal, box_min / box_max, radius + axis_point + "
                             "axis_direction and/or group (a named surface of the mesh file)")
        return self


class SupportSpec(Strict):
    """[[supports]]: nodes held fixed, clamped, or on rollers (blocked along `normal`); with a
    speed, the blocked directions move at a prescribed velocity instead (a velocity boundary
    condition: nodes that can be pulled), and the support's reaction is reported like a tool's
    force."""

    kind: Literal["fixed", "roller", "clamped"]
    """fixed: no motion; roller: no motion along normal; clamped: no motion, and on a shell the boundary edges between selected nodes keep their slope (a solid's fixed nodes are already clamped: the same as fixed there; DEM: not available)"""
    where: Where
    """which nodes"""
    normal: Vec3 = (0.0, 0.0, 1.0)
    """roller: the blocked direction"""
    speed: float = 0.0
    """m/s along direction: the blocked directions of the selected nodes move with velocity speed x direction (a roller: its component along normal); 0: they hold still"""
    direction: Vec3 | None = None
    """of the motion (normalised); default: a roller's normal; a fixed or clamped support with a speed needs one"""
    ramp_time: NonNegative = 0.0
    """s, linear ramp from 0 to speed"""
    speed_table: VelocityTable | None = None
    """instead of speed and ramp_time: m/s against s"""
    name: str | None = None
    """a moving support's name in history.csv and summary.json, as a tool's: tool.NAME.fx/fy/fz its reaction on the specimen (N, through the load cell), tool.NAME.ux/uy/uz its displacement; default support1, support2 ... by its place in [[supports]]"""

    @property
    def moves(self) -> bool:
        return self.speed != 0.0 or self.speed_table is not None

    @model_validator(mode="after")
    def _motion(self):
        check_one_motion(self)
        if not self.moves:
            motion_only = sorted({"direction", "ramp_time", "name"} & self.model_fields_set)
            if motion_only:
                raise ValueError(f"{', '.join(motion_only)}: only for a moving support; give speed (or speed_table)")
        elif self.kind != "roller" and self.direction is None:
            raise ValueError(f"a {self.kind} support with a speed needs direction = [x, y, z] (of its motion)")
        if self.direction is not None and all(c == 0 for c in self.direction):
            raise ValueError("direction must be a non-zero vector")
        if self.kind == "roller" and self.moves and self.direction is not None:
            along = sum(a * b for a, b in zip(self.direction, self.normal))
            if abs(along) < 1e-6 * math.hypot(*self.direction) * math.hypot(*self.normal):
                raise ValueError(f"a roller moves its nodes along its normal only (the blocked direction), and "
                                 f"direction = {list(self.direction)} is normal to normal = {list(self.normal)}: it "
                                 "would move nothing; give direction along normal, or kind = \"fixed\" to drive "
                                 "the nodes along direction")
        return self


class PrecrackSpec(Strict):
    """[[precracks]]: internal faces on a plane (within tol) whose centroids lie in the box start
    separated (no cohesion)."""

    point: Vec3
    """m, on the crack plane"""
    normal: Vec3
    """of the crack plane"""
    box_min: Vec3 | None = None
    """m, lower corner of the crack's extent; unset: unbounded"""
    box_max: Vec3 | None = None
    """m, upper corner of the crack's extent; unset: unbounded"""
    tol: Positive | None = None
    """m, distance to the plane that counts as on it; default 1e-6 of the specimen size"""


class PressureSpec(Strict):
    """[[pressures]]: a pressure history (positive pushes into the solid) on faces, optionally
    behind a front travelling along a tube (a detonation)."""

    faces: Literal["precrack", "where"] = "precrack"
    """precrack: both faces of every pre-crack; where: the boundary faces `where` selects (meshfree: the wall
    faces of the surface particles it selects; DEM: faces of the box specimen, loaded as a flexible membrane on
    the outermost particles)"""
    where: Where | None = None
    """faces = "where": a face is selected when its three corners are (meshfree: when its particle is; DEM: a face
    of the box when its four corners lie on the plane and its centre in the box)"""
    wall: Literal["inner", "outer"] | None = None
    """meshfree: only the faces on this wall surface: a tube's inner or outer wall, a plate's face on its origin
    side (inner) or the other (outer) along the thickness; unset: both"""
    rate: float | None = None
    """Pa/s from t = 0 (one of rate, value, table)"""
    value: float | None = None
    """Pa, constant, or the plateau after ramp_time; profile = "taylor": the peak (Chapman-Jouguet) pressure"""
    ramp_time: NonNegative = 0.0
    """s, with value: linear ramp from 0"""
    table: VelocityTable | None = None
    """its time and speed columns read as s and Pa"""
    profile: Literal["history", "taylor"] = "history"
    """history: rate, value or table as given; taylor: the Taylor wave behind a detonation (Beltman and Shepherd
    2002): value x (plateau + (1 - plateau) exp(-tau / decay_time)), tau the time since the front passed (since
    t = 0 without a front); a fixed decay time is a choice (their T ~ x / (3 D) grows with the distance x the
    detonation has run from the ignition: give T at the specimen)"""
    decay_time: Positive | None = None
    """s, profile = "taylor": the exponential decay time T behind the front"""
    plateau: Annotated[float, Field(ge=0.0, le=1.0)] = 0.4
    """profile = "taylor": p3 / p_CJ, the pressure the wave decays to over the peak (about 0.4 for gaseous
    detonations)"""
    front_speed: Positive | None = None
    """m/s, a front travelling along front_direction: a face at s = (X - front_origin) . front_direction (X its
    reference centre) feels the history at t - s / front_speed and nothing before (meshfree tubes; a detonation:
    2300-2400 m/s in paper 000); unset: everywhere at once"""
    front_origin: Vec3 = (0.0, 0.0, 0.0)
    """m, where the front is at t = 0"""
    front_direction: Vec3 | None = None
    """the front's direction of travel; default the tube's axis"""

    @model_validator(mode="after")
    def _one_history(self):
        given = [k for k in ("rate", "value", "table") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of rate, value (with optional ramp_time) or table")
        if self.faces == "where" and self.where is None:
            raise ValueError("faces = 'where' needs a [pressures.where] selection")
        if self.profile == "taylor" and (self.value is None or self.decay_time is None or self.ramp_time):
            raise ValueError("profile = 'taylor' needs value (the peak pressure, Pa) and decay_time (s), no ramp_time")
        if self.profile != "taylor" and (self.decay_time is not None or "plateau" in self.model_fields_set):
            raise ValueError("decay_time and plateau: only with profile = 'taylor'")
        front = sorted({"front_origin", "front_direction"} & self.model_fields_set)
        if self.front_speed is None and front:
            raise ValueError(f"{', '.join(front)}: only with front_speed (m/s)")
        if self.front_direction is not None and all(c == 0 for c in self.front_direction):
            raise ValueError("front_direction must be a non-zero vector")
        return self


# The order of a stress's six components in a scenario, as in every stress crackle writes
# (io.fields.STRESS_COMPONENTS): xx, yy, zz, xy, yz, xz.
STRESS_ORDER = ("xx", "yy", "zz", "xy", "yz", "xz")


def stress_matrices(s) -> "np.ndarray":
    """(k, 6) stresses in STRESS_ORDER as (k, 3, 3) symmetric matrices."""
    import numpy as np

    xx, yy, zz, xy, yz, xz = np.asarray(s, dtype=float).T
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], 1)


class InitialStressSpec(Strict):
    """[initial_stress]: the Cauchy stress the solid carries at t = 0 (an in-situ or geostatic
    stress), tension positive and compression negative as every stress crackle reads and writes: a
    uniform part (`stress`, or `principal` with `directions`) plus, with `density`, the weight of an
    overburden growing with depth (Abaqus's geostatic step, Irazu's in-situ stress): sigma_v =
    -density g depth along `vertical`, sigma_h = k0 sigma_v across it. The model starts in equilibrium
    with it: with boundary tractions that match it (and, for the depth gradient, run.gravity = -g
    vertical) it stays at rest; with free faces it relaxes. FDEM, and the DEM on a box specimen (its
    bonds preloaded: dem.prestress)."""

    stress: tuple[float, float, float, float, float, float] | None = None
    """Pa, the uniform stress as [xx, yy, zz, xy, yz, xz] (the order of the stress written to fields/*.vtu),
    compression negative; or give principal"""
    principal: Vec3 | None = None
    """Pa, the uniform stress by its principal values [s1, s2, s3] (compression negative), s_i along
    directions[i]; instead of stress"""
    directions: tuple[Vec3, Vec3, Vec3] | None = None
    """with principal: the three principal directions, mutually orthogonal (each normalised); default the x, y
    and z axes"""
    density: Positive | None = None
    """kg/m^3, the overburden's density: adds sigma_v = -density g depth along vertical and k0 sigma_v across
    it, depth = surface - X . vertical at a point X (a tet's centroid), none above the surface; unset: no
    gradient"""
    g: Positive = 9.81
    """m/s^2, with density: the gravity of the overburden's weight (the model is in equilibrium with it under
    run.gravity = -g vertical)"""
    vertical: Vec3 = (0.0, 0.0, 1.0)
    """with density: the upward direction (normalised); depth grows against it"""
    surface: float = 0.0
    """m, with density: the ground surface's height along vertical (depth = surface - X . vertical)"""
    k0: Annotated[float, Field(ge=0)] = 1.0
    """with density: the horizontal to vertical stress ratio sigma_h / sigma_v of the gradient (Abaqus's lateral
    coefficient K0; 1: lithostatic, nu / (1 - nu): a laterally confined elastic layer)"""

    @model_validator(mode="after")
    def _one_way(self):
        if self.stress is not None and self.principal is not None:
            raise ValueError("give the uniform stress once: either stress = [xx, yy, zz, xy, yz, xz] or principal = "
                             "[s1, s2, s3] (with directions), not both")
        if self.directions is not None and self.principal is None:
            raise ValueError("directions: only with principal = [s1, s2, s3] (or remove it and give stress)")
        if self.directions is not None:
            d = [_unit(v, f"directions.{k}") for k, v in enumerate(self.directions)]
            for a, b in ((0, 1), (0, 2), (1, 2)):
                dot = sum(p * q for p, q in zip(d[a], d[b]))
                if abs(dot) > 1e-6:
                    raise ValueError(f"directions.{a} and directions.{b} are not orthogonal (cosine {dot:.3g}): give "
                                     "three mutually orthogonal principal directions")
        gradient_only = sorted({"g", "vertical", "surface", "k0"} & self.model_fields_set)
        if self.density is None and gradient_only:
            raise ValueError(f"{', '.join(gradient_only)}: only with density (kg/m^3), the overburden's weight")
        if self.density is not None:
            _unit(self.vertical, "vertical")
            ElasticSpec._density_in_kg_per_m3(self.density)
        if self.stress is None and self.principal is None and self.density is None:
            raise ValueError("give stress = [xx, yy, zz, xy, yz, xz] (Pa), principal = [s1, s2, s3] or density "
                             "(a gradient with depth), or remove [initial_stress]")
        return self

    def uniform(self) -> "np.ndarray":
        """The uniform part as a symmetric 3 x 3 matrix (Pa)."""
        import numpy as np

        if self.stress is not None:
            xx, yy, zz, xy, yz, xz = self.stress
            return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=float)
        if self.principal is not None:
            d = np.eye(3) if self.directions is None else np.array(self.directions, dtype=float)
            d /= np.linalg.norm(d, axis=1)[:, None]
            return np.einsum("k,ki,kj->ij", np.asarray(self.principal, float), d, d)
        return np.zeros((3, 3))

    def at(self, points: "np.ndarray") -> "np.ndarray":
        """The stress at points (n, 3), as (n, 6) in STRESS_ORDER (Pa)."""
        import numpy as np

        points = np.asarray(points, dtype=float)
        full = np.broadcast_to(self.uniform(), (len(points), 3, 3)).copy()
        if self.density is not None:
            v = np.asarray(self.vertical, float) / np.linalg.norm(self.vertical)
            depth = np.maximum(self.surface - points @ v, 0.0)
            vv = np.outer(v, v)
            shape = vv + self.k0 * (np.eye(3) - vv)
            full += (-self.density * self.g * depth)[:, None, None] * shape
        rows, cols = (0, 1, 2, 0, 1, 0), (0, 1, 2, 1, 2, 2)
        return full[:, rows, cols]


def _unit(v, name: str) -> tuple[float, float, float]:
    norm = math.sqrt(sum(c * c for c in v))
    if norm == 0.0:
        raise ValueError(f"{name} must be a non-zero vector")
    return tuple(c / norm for c in v)


class Stop(Strict):
    """[run.stop]: end the run before end_time."""

    tool_displacement: Positive | None = None
    """m, once a tool (`tool`, or any) has moved this far"""
    tool: str | None = None
    """the tool whose displacement counts; default any"""
    force_drop: Annotated[float, Field(gt=0, lt=1)] | None = None
    """after a failure, once the largest tool force has stayed below this fraction of its peak for force_drop_hold"""
    force_drop_hold: NonNegative | None = None
    """s; default 5 % of end_time, at most half the time of the peak force"""

    @model_validator(mode="after")
    def _hold_needs_a_drop(self):
        if self.force_drop_hold is not None and self.force_drop is None:
            raise ValueError("force_drop_hold: it times the force drop, which force_drop sets; set force_drop (e.g. "
                             "0.3) or remove force_drop_hold")
        return self


class RunSpec(Strict):
    """[run]: time integration and what the run writes."""

    end_time: Positive
    """s, simulated time"""
    dt: Positive | None = None
    """s, the step; default safety x the stable step. A larger one is refused, except where the method proves a
    bound at set-up (DEM, lattice: Gershgorin): a given step is then accepted up to that bound"""
    safety: Annotated[float, Field(gt=0, le=1)] = 0.7
    """fraction of the stable step"""
    target_dt: Positive | None = None
    """s, mass scaling: elements whose step is below it get heavier until it is reached (off when unset)"""
    max_added_mass: NonNegative = 0.01
    """fraction of the specimen's mass that target_dt may add; above it the run is refused"""
    damping: NonNegative = 0.0
    """1/s, mass-proportional: a force -damping m v on every node"""
    contact: bool = False
    """contact between free surfaces (fragments, fracture faces): FDEM's failed faces (experimental); meshfree:
    penalty contact between the specimen's particles that no link joins (crack faces closing, petals folding
    back; a second body always meets the specimen so)"""
    gravity: Vec3 = (0.0, 0.0, 0.0)
    """m/s^2"""
    seed: Annotated[int, Field(ge=0)] = 0
    """of the random material properties ([material.random]): the same seed, the same values on any machine and
    thread count; `crackle sweep --seeds N` runs seeds 0 .. N-1"""
    history_samples: Annotated[int, Field(ge=1)] = 400
    """rows of history.csv over end_time (a row at least every 1,000 steps)"""
    field_frames: Annotated[int, Field(ge=0)] = 10
    """ParaView snapshots over end_time (0: none)"""
    load_cell_window: Positive | None = None
    """s, the tool force's averaging window; default 4 element wave transits"""
    max_memory: Positive | None = None
    """bytes the set-up may plan for: a model estimated larger (from its sizes, before anything is allocated)
    is refused with exit 2 naming the key that sets its size (default: the memory this machine has available)"""
    checkpoint: bool = True
    """leave checkpoint.pkl in the output folder, for crackle run --resume"""
    checkpoint_every: Positive = 600.0
    """s of wall time between checkpoints while the run goes (a killed run resumes from the last)"""
    stop: Stop = Stop()
    """stop conditions"""

    @model_validator(mode="after")
    def _hold_within_the_run(self):
        hold = self.stop.force_drop_hold
        if hold is not None and hold >= self.end_time:
            raise ValueError(f"stop.force_drop_hold = {hold:g} s is not shorter than end_time = {self.end_time:g} s: the "
                             f"run could never stop by the force drop; set it below end_time (e.g. "
                             f"{0.05 * self.end_time:.3g} s), or remove it for the default (5 % of end_time)")
        return self


class FracturePlaneSpec(Strict):
    """A planar fracture to follow: its tip and plastic-zone length go to history.csv."""

    point: Vec3
    """m, on the plane, where the growth is measured from"""
    normal: Vec3
    """of the plane"""
    direction: Vec3
    """of growth, in the plane"""
    tol: Positive | None = None
    """m, distance to the plane that counts as on it; default 1e-6 of the specimen size"""


class CracksSpec(Strict):
    """Crack count and main-crack speed of a shell (crackle.analysis.cracks), in summary.json with
    the loading index of the tools' directions."""

    wall: Positive | None = None
    """m; default: the walnut specimen's face wall"""
    scale: Positive | None = None
    """m, linking length; default: twice the element size"""
    top: Vec3 = (0.0, 0.0, 1.0)
    """the main crack is the first to reach the extreme along it"""


# The shared keys only some methods read, each with what to do where it is not read. A method's
# Scenario declares those it reads (`reads`); set in a scenario of a method that does not, they are
# refused with this advice (a key silently ignored is a result the user did not ask for), and
# `crackle keys METHOD` leaves them out. A new method reads none of them until it says so.
OPTIONAL_KEYS = {
    "run.target_dt": "mass scaling is FDEM's (remove it; set run.safety or run.dt for the step)",
    "run.max_added_mass": "mass scaling is FDEM's (remove it)",
    "run.contact": "contact between free surfaces is FDEM's and meshfree's (remove it)",
    "run.damping": "its damping is its material's (DEM: material.local_damping, paper 003 eq. 5)",
    "analysis.fracture_plane": "the fracture-plane tip is FDEM's (remove it)",
    "analysis.cracks": "crack counting is FDEM's (remove it)",
    "initial_stress": "it is not yet available there (FDEM and DEM only for now); remove [initial_stress] or use "
                      "method = \"fdem\"",
    "pressures": "it has no faces to load; remove [[pressures]]",
}


class AnalysisSpec(Strict):
    """[analysis]: measurements added to the history and summary."""

    fracture_plane: FracturePlaneSpec | None = None
    """follow a planar fracture's tip and plastic zone"""
    cracks: CracksSpec | None = None
    """count a shell's cracks and the main crack's speed"""


class ScenarioBase(Strict):
    """The sections every method shares. A method's scenario (crackle.methods) adds its own:
    for FDEM the tet specimen, its material with an interface law, pre-cracks."""

    name: str = "scenario"
    """names the default output folder crackle-out/NAME"""
    description: str = ""
    """free text; its first line is what crackle examples lists"""
    method: str = "fdem"
    """the discretisation: fdem, dem, meshfree, shell, or lattice (a toy that holds the driver to a second method)"""
    tools: list[ToolSpec] = []
    """rigid tools"""
    plates: PlatesSpec | None = None
    """adds plate1..plateN to the tools"""
    loading: LoadingSpec = LoadingSpec()
    """rotates all tools, e.g. a loading angle"""
    supports: list[SupportSpec] = []
    """fixed, clamped and roller supports"""
    pressures: list[PressureSpec] = []
    """pressure histories on faces"""
    initial_stress: InitialStressSpec | None = None
    """the stress the solid carries at t = 0 (FDEM; DEM on a box specimen)"""
    analysis: AnalysisSpec = AnalysisSpec()
    """measurements"""
    run: RunSpec
    """time integration and outputs"""
    quick: dict[str, Any] = {}
    """dotted-key overrides applied by --quick"""

    # The OPTIONAL_KEYS this method reads; each method's Scenario names its own.
    reads: ClassVar[frozenset[str]] = frozenset()

    @classmethod
    def unread_keys(cls) -> dict[str, str]:
        """The OPTIONAL_KEYS the method does not read, each with what to do instead."""
        return {key: advice for key, advice in OPTIONAL_KEYS.items() if key not in cls.reads}

    @model_validator(mode="after")
    def _no_unread_keys(self):
        for key, advice in self.unread_keys().items():
            section, _, name = key.rpartition(".")
            if name in (getattr(self, section) if section else self).model_fields_set:
                raise ValueError(f"{key}: method = \"{self.method}\" does not read it; {advice}")
        return self

    @model_validator(mode="after")
    def _named_surfaces_of_a_mesh_file(self):
        named = [f"{kind}.{i}.where.group" for kind in ("supports", "pressures")
                 for i, item in enumerate(getattr(self, kind)) if item.where is not None and item.where.group]
        if named and not (self.method == "fdem" and getattr(self.specimen, "shape", None) == "mesh"):
            raise ValueError(f"{named[0]}: named surfaces are those of an FDEM specimen's mesh file (method = \"fdem\", "
                             "specimen.shape = \"mesh\"); select by plane, box or cylinder instead")
        return self

    def initial_stress_warnings(self) -> list[str]:
        """What keeps [initial_stress] from starting in equilibrium: a gradient with depth without
        the gravity its weight balances."""
        import numpy as np

        spec = self.initial_stress
        if spec is None or spec.density is None:
            return []
        vertical = np.asarray(spec.vertical, float) / np.linalg.norm(spec.vertical)
        weight = -spec.g * vertical
        if np.linalg.norm(np.asarray(self.run.gravity) - weight) <= 0.01 * spec.g:
            return []
        return [f"initial_stress.density: the stress growing with depth is in equilibrium under its own weight only: "
                f"set run.gravity = [{', '.join(f'{c + 0.0:.4g}' for c in weight)}] (m/s^2), or the specimen moves "
                "from t = 0"]

    @model_validator(mode="after")
    def _tool_names(self):
        names = [t.name for t in self.all_tools()] + [name for _, name in self.support_grips()]
        if len(set(names)) != len(names):
            raise ValueError("tool names must be unique (a moving support's name included)")
        if self.run.stop.tool is not None and self.run.stop.tool not in names:
            raise ValueError(f"run.stop.tool '{self.run.stop.tool}' is not a tool name ({', '.join(names) or 'no tools'})")
        return self

    def all_tools(self) -> list[ToolSpec]:
        """[[tools]] followed by the [plates] as tools."""
        return list(self.tools) + (self.plates.tool_specs() if self.plates is not None else [])

    def support_grips(self) -> list[tuple[int, str]]:
        """The moving supports: (index in [[supports]], name), in order; each also becomes a tool of
        shape "support" after all_tools() (loading.build.build_loading)."""
        return [(i, s.name or f"support{i + 1}") for i, s in enumerate(self.supports) if s.moves]

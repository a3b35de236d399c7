"""A MeshfreeSimulation from particles, a material and the shared loads: what the scenario set-up
and the tests both call."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..loading.arrays import default_tool_penalty, history_tables
from ..solver.body import body_arrays
from ..solver.integrator import support_constraints
from ..solver.setup import tool_stiffness, tools_on_body
from .contact import CONTACT_STIFFNESS, STEP_PAIRS, ParticleContact
from .fracture import LinkBreaking
from .kernels import BLOCK, LINK_FLOAT, Links, Particles, PressedFaces, rest_terms, stabilisation_stiffness
from .material import T_REF, J2Law
from .particles import WALL_SIDES, Cells, WallParticles, wall_columns
from .shape import MAX_CONDITION, basis_terms, nodal_values, smoothed_gradients, support_radii, within_supports
from .simulation import MeshfreeSimulation
from .step import stable_step
from .thickness import Columns, thickness_columns


class SetupError(ValueError):
    """A discretisation that cannot run; `field` is the scenario key to change."""

    def __init__(self, field: str, message: str):
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class MeshfreeBody:
    """A body of particles beside the specimen (a deformable projectile): its own material, initial
    velocity and support dilation. It does not fracture; it meets the specimen (and any other
    body) by the particle contact (contact.py)."""

    particles: WallParticles
    density: float  # kg/m^3
    law: J2Law
    velocity: tuple = (0.0, 0.0, 0.0)  # m/s
    dilation: float = 2.5
    name: str = "body"  # its material's name in summary.json (material_names)


def build_meshfree_simulation(plate: WallParticles, density: float | Sequence[float], law: J2Law | Sequence[J2Law],
                              dilation: float = 2.5, stabilisation: float = 0.1, tools=(), supports=(),
                              damping: float = 0.0, gravity=(0.0, 0.0, 0.0), velocity=None,
                              fracture_stress: float | np.ndarray = math.inf, precracks=(), pressures=(),
                              failure_plastic_strain: float | np.ndarray = math.inf, bodies=(),
                              self_contact: bool = False, support: str = "uniform", material=None,
                              names=None) -> MeshfreeSimulation:
    """The particles of `plate` with support radius dilation x the largest grid step (`support`
    "uniform"; "local": dilation x each particle's own spacing, WallParticles.local_spacing, for
    a graded set) (gradients
    by stabilised conforming nodal integration over the particles' cells, shape.smoothed_gradients), the
    material (density kg/m^3, J2Law; or several: one density and law each, `material` each
    particle's index into them, `names` theirs), the stabilisation alpha (kernels docstring), tools and
    supports (loading.Tool, loading.Support), mass-proportional `damping` (1/s), `gravity`
    (m/s^2), an initial `velocity` (m/s, one for all or one per particle) and the fracture stress
    (Pa, the maximum principal stress that fails a particle; inf: no fracture, fracture.py), the
    equivalent plastic strain that fails one (failure_plastic_strain; inf: none), each one value
    or one per particle of `plate` (drawn per particle: fracture.draw_thresholds), and
    the pre-cracks (loading.Precrack: the links across them removed at the start) and the pressures
    on the wall faces (loading.Pressure, pressure_arrays). `bodies`: more bodies (MeshfreeBody,
    after the specimen's particles in that order), met by the particle contact (contact.py), as
    are the crack faces and fragments of the specimen with `self_contact`."""
    if support == "local" and plate.local_spacing is None:
        raise SetupError("particles.support", f"\"local\" supports follow the spacing of a mesh or shell's particles; "
                         f"a {plate.shape}'s grid is uniform: remove particles.support")
    own = _SpecimenMaterials.of(plate, density, law, material, names)
    shapes = [_Discretised.of(plate, dilation, stabilisation * own.youngs_modulus, support == "local")]
    shapes += [_Discretised.of(b.particles, b.dilation, stabilisation * b.law.youngs_modulus) for b in bodies]
    sizes = [len(d.X) for d in shapes]
    first = np.cumsum([0] + sizes)
    n = int(first[-1])
    X = np.concatenate([d.X for d in shapes])
    # Each particle's row of the law table: the specimen's materials', then one per body.
    body = np.repeat(np.arange(len(shapes), dtype=np.int64), sizes)
    material = np.concatenate([own.index, len(own.laws) - 1 + body[sizes[0]:]])
    link_first = np.cumsum([0] + [len(d.neighbour) for d in shapes[:-1]])
    start = np.concatenate([[0]] + [d.start[1:] + o for d, o in zip(shapes, link_first)])
    neighbour = np.concatenate([d.neighbour + o for d, o in zip(shapes, first)])
    grad_value = np.empty((len(neighbour), 4), dtype=LINK_FLOAT)
    grad_value[:, :3] = np.concatenate([d.grad for d in shapes])
    grad_value[:, 3] = np.concatenate([d.value for d in shapes])
    row = np.repeat(np.arange(n), np.diff(start))
    links = Links(start, neighbour, grad_value, *transposed_links(n, row, neighbour, grad_value),
                  rest_F=np.zeros((n, 9)), rest_eps=np.zeros((n, 3)), link_sums=np.zeros((n, 4)))
    rest_terms(np.arange(n), X, links)
    columns = merge_columns([d.columns for d in shapes], first)
    laws = own.laws + [b.law for b in bodies]
    table = np.stack([w.table() for w in laws])
    volume = np.concatenate([d.plate.volume for d in shapes])
    area = np.concatenate([d.plate.area for d in shapes])
    mass = np.concatenate([own.density * plate.volume]
                          + [b.density * d.plate.volume for b, d in zip(bodies, shapes[1:])])
    scale = float(np.max(np.ptp(X, axis=0)))
    constraint, projection, support_tool = support_constraints(supports, X, scale)
    pressed = pressure_arrays(plate, pressures, scale, n)
    v = np.zeros((n, 3))
    if velocity is not None:
        v[:sizes[0]] = np.asarray(velocity, dtype=float)
    for b, lo, hi in zip(bodies, first[1:], first[2:]):
        v[lo:hi] = np.asarray(b.velocity, dtype=float)
    # The particles on the faces are on the specimen's surface: they meet the tools there (radius 0).
    particles = Particles(
        **body_arrays(X, mass, area, 0.0, (constraint, projection, support_tool), v), X=X, volume=volume.copy(),
        plastic=np.zeros((2 * n, 6)), eq_plastic=np.zeros(2 * n), w_plastic=np.zeros(n), stress=np.zeros((n, 6)),
        deformation=np.tile(np.eye(3).ravel(), (n, 1)), internal=np.zeros((n, 9)), bending=np.zeros((n, 9)),
        stab_k=np.concatenate([d.stab_k for d in shapes]), stab_force=np.zeros((n, 3)),
        thermal=np.column_stack([np.repeat(table[material, T_REF], 2), np.zeros(2 * n)]), material=material,
    )
    h = float(np.min(plate.spacing))
    penalty = default_tool_penalty(float(np.max(own.youngs_modulus)), h)  # the stiffest material's
    tool_table, seating = tools_on_body(tools, particles, penalty, h, -(-n // BLOCK), "particles")
    tool_k = tool_stiffness(tool_table, particles.area)
    contact = None
    if bodies or self_contact:
        radius = np.concatenate([np.broadcast_to(d.contact_radius, (len(d.X),)) for d in shapes])
        spring = CONTACT_STIFFNESS * np.array([w.youngs_modulus for w in laws])[material] * 2.0 * radius
        contact = ParticleContact(X, body, radius, spring, [np.max(d.radius) for d in shapes], self_contact)
        # The step allows STEP_PAIRS pairs at once on a particle, each two equal springs in series.
        tool_k = np.maximum(tool_k, 0.5 * STEP_PAIRS * spring)
    dt, step_ratio = stable_step(particles, links, columns, row, table, tool_k, h)
    c_p = max(math.sqrt((rows[0] + 2.0 * rows[1]) / rho) for rows, rho in zip(table, own.densities))  # the fastest
    breaking = None
    if np.isfinite(fracture_stress).any() or np.isfinite(failure_plastic_strain).any() or precracks:
        cells = merge_cells([d.plate.cells for d in shapes])
        frame = plate.wall_frame
        if frame is not None and bodies:
            frame = np.concatenate([frame, np.tile(np.eye(3), (n - sizes[0], 1, 1))])
        breaking = LinkBreaking(X, volume, cells, shapes[0].radius, shapes[0].terms,
                                stabilisation * own.youngs_modulus, fracture_stress, shapes[0].spacing,
                                links, frame, tool_k, step_ratio, failure_plastic_strain, fracturing=sizes[0])
    sim = MeshfreeSimulation(particles, links, columns, table, tool_table, [t.name for t in tools],
                             float(np.max(shapes[0].radius)),
                             dt, h / c_p, gravity, damping, plate, breaking, pressed,
                             history_tables([p.history for p in pressures]), contact, first,
                             own.names + [b.name for b in bodies])
    sim.element_length = float(h)
    sim.warnings.extend(seating)
    if contact is not None:
        overlapping = contact.overlaps_between_bodies(X)
        if overlapping:
            raise SetupError("bodies", f"{overlapping} particle pairs of different bodies overlap at the start (closer "
                             "than their contact radii, half their spacings): move the bodies apart")
    if precracks:
        try:
            breaking.cut(sim, precracks, scale)
        except ValueError as err:
            raise SetupError(str(err).split(":")[0], str(err)) from None
        # One-sided gradients at the pre-crack faces can be stiffer: the step of the cut links.
        sim.stable_dt = min(dt, stable_step(particles, links, columns, breaking.row, table, tool_k, h)[0])
    return sim


@dataclass(frozen=True)
class _SpecimenMaterials:
    """The specimen's materials: their laws, densities (kg/m^3) and names, and each particle's
    index into them; per particle its density and Young's modulus (Pa), the numbers themselves
    with one material (what a single-material run multiplies by, bit for bit as before)."""

    laws: list
    densities: list
    names: list
    index: np.ndarray
    density: float | np.ndarray
    youngs_modulus: float | np.ndarray

    @classmethod
    def of(cls, plate, density, law, material, names) -> _SpecimenMaterials:
        n = len(plate.X)
        if isinstance(law, J2Law):
            return cls([law], [float(density)], list(names or ["material"]), np.zeros(n, dtype=np.int64), density,
                       law.youngs_modulus)
        laws, densities = list(law), [float(rho) for rho in density]
        index = np.asarray(material, dtype=np.int64)
        if len(densities) != len(laws) or index.shape != (n,) or index.min() < 0 or index.max() >= len(laws):
            raise ValueError("several materials need one density per law and each particle's index into them")
        names = list(names or [f"material{i}" for i in range(len(laws))])
        return cls(laws, densities, names, index, np.asarray(densities)[index],
                   np.array([w.youngs_modulus for w in laws])[index])


@dataclass
class _Discretised:
    """One body's particles with their links (CSR, local numbering), stabilisation and columns
    through the wall."""

    plate: WallParticles
    X: np.ndarray
    spacing: float | np.ndarray  # the largest particle step: one for all, or per particle (local supports)
    radius: float | np.ndarray  # the support radius, dilation x spacing
    terms: np.ndarray  # the basis terms (shape.basis_terms)
    start: np.ndarray
    neighbour: np.ndarray
    grad: np.ndarray
    value: np.ndarray
    stab_k: np.ndarray
    columns: object

    @classmethod
    def of(cls, plate: WallParticles, dilation: float, stab_scale: float | np.ndarray,
           local: bool = False) -> _Discretised:
        X = np.ascontiguousarray(plate.X, dtype=float)
        n = len(X)
        spacing = plate.local_spacing[:, 0].copy() if local else float(np.max(plate.spacing))
        radius = dilation * spacing
        terms = basis_terms(plate.thickness_axis, plate.layers)
        start, neighbour, grad, condition, first_bad = smoothed_gradients(X, plate.volume, plate.cells, radius, terms)
        if first_bad is not None:
            raise SetupError("particles.dilation", (
                f"the moment matrix at {first_bad.round(6).tolist()} m (a quadrature point of a particle's cell) is "
                f"singular: the support radius {dilation:g} x {np.max(spacing):.3g} m holds too few particles "
                f"for the quadratic basis; increase particles.dilation (2.5 or more)"))
        row = np.repeat(np.arange(n), np.diff(start))
        value, stab_k = nodal_stabilisation(X, plate.volume, radius, terms, start, neighbour, row, stab_scale)
        return cls(plate, X, spacing, radius, terms, start, neighbour, grad, value, stab_k,
                   thickness_columns(X, wall_columns(plate)))

    @property
    def contact_radius(self) -> float | np.ndarray:
        """Half the particles' spacing along the wall (a solid's median edge; with local supports
        each particle's median edge): contact.py."""
        p = self.plate
        if np.ndim(self.spacing):
            return 0.5 * p.local_spacing[:, 1]
        if p.thickness_axis is not None and p.shape == "plate":
            return 0.5 * float(np.max(np.delete(p.spacing, p.thickness_axis)))
        return 0.5 * float(p.spacing[0] if p.shape == "tube" else p.spacing[1])


def merge_columns(columns, first) -> Columns:
    """The Columns (thickness.py) of bodies numbered from `first` (their first particles), as one."""
    if len(columns) == 1:
        return columns[0]
    lines_first = np.cumsum([0] + [len(c.lines) for c in columns[:-1]])
    width = max(c.lines.shape[1] if c.lines.size else 0 for c in columns)
    lines = [c.lines + o if c.lines.size else np.zeros((0, width), dtype=np.int64) for c, o in zip(columns, first)]
    if len({ln.shape[1] for ln in lines if len(ln)}) > 1:
        raise SetupError("bodies", "two walled bodies with different particles through the wall")
    member_first = np.cumsum([0] + [len(c.member) for c in columns[:-1]])
    return Columns(
        np.concatenate([[0]] + [c.start[1:] + o for c, o in zip(columns, member_first)]),
        np.concatenate([c.member + o for c, o in zip(columns, first)]),
        np.concatenate([c.coef for c in columns]),
        np.concatenate([[0]] + [c.back_start[1:] + o for c, o in zip(columns, member_first)]),
        np.concatenate([c.back_member + o for c, o in zip(columns, first)]),
        np.concatenate([c.back_coef for c in columns]),
        np.concatenate([c.offset for c in columns]),
        np.concatenate([np.where(c.line >= 0, c.line + o, -1) for c, o in zip(columns, lines_first)]),
        np.concatenate([ln.reshape(-1, width) if len(ln) else np.zeros((0, width), dtype=np.int64) for ln in lines]),
    )


def merge_cells(cells) -> Cells:
    """The integration cells (particles.Cells) of bodies in order, as one."""
    if len(cells) == 1:
        return cells[0]
    row_first = np.cumsum([0] + [len(c.point) for c in cells[:-1]])
    point_first = np.cumsum([0] + [len(c.points) for c in cells[:-1]])
    return Cells(np.concatenate([[0]] + [c.start[1:] + o for c, o in zip(cells, row_first)]),
                 np.concatenate([c.point + o for c, o in zip(cells, point_first)]),
                 np.concatenate([c.weight for c in cells]), np.concatenate([c.points for c in cells]))


def transposed_links(n: int, row: np.ndarray, neighbour: np.ndarray, grad_value: np.ndarray):
    """The transpose of the links of n particles (rows `row`, each in increasing `neighbour`
    order), for the gather: for particle L, every link (I, L) in order of I, as (back_start,
    to_back, back_row, back_grad_value) of kernels.Links. A function of its own: the
    sort's permutation is freed before the step estimate."""
    back_link = np.argsort(neighbour, kind="stable")  # ties in link order: increasing I
    back_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(neighbour, minlength=n), out=back_start[1:])
    to_back = np.empty_like(back_link)
    to_back[back_link] = np.arange(len(back_link))
    return back_start, to_back, row[back_link], grad_value[back_link]


def nodal_stabilisation(X, volume, radius, terms, start, neighbour, row, scale):
    """The stabilisation's values N_K(X_J) (per link) and stiffness k_J (per particle; kernels
    docstring) at set-up; k_J = 0 where the moment matrix at X_J is singular even with the linear
    basis (no approximation to compare with)."""
    n = len(X)
    # The links of J must hold J's own support (shape.nodal_values): check, the cells are the caller's.
    reach = support_radii(radius, n)[neighbour] * (1.0 - 1e-12)
    in_support = np.einsum("ij,ij->i", X[neighbour] - X[row], X[neighbour] - X[row]) < reach ** 2
    if not np.array_equal(np.bincount(row, weights=in_support, minlength=n),
                          within_supports(cKDTree(X), X, X, radius)[0]):
        raise RuntimeError("a particle's links miss part of its own support: its cell's quadrature points lie too "
                           "far out")
    _, value, condition = nodal_values(X, volume, radius, terms, start, neighbour, np.arange(n))
    stab_k = stabilisation_stiffness(X, volume, row, neighbour, np.ones(len(row), dtype=bool), radius, scale)
    stab_k[~np.isfinite(condition) | (condition > MAX_CONDITION)] = 0.0
    return value, stab_k


def pressure_arrays(plate: WallParticles, pressures, scale: float, n: int | None = None) -> PressedFaces:
    """The wall faces (particles.WallFaces) that each pressure loads, gathered per particle: the
    faces of the particles its `where` selects (on its `wall` only, when given), with the delay
    s / front_speed of a travelling front (s the distance of the face's reference centre from
    front_origin along front_direction, default the tube's axis). Raises SetupError naming the
    pressure's key that selects nothing or asks for what this specimen does not have. n: the
    particles of all bodies (the specimen's first; default the specimen's)."""
    surface = plate.surface
    n = len(plate.X) if n is None else n
    rows = []
    for q, load in enumerate(pressures):
        if isinstance(load.faces, str):
            raise SetupError(f"pressures.{q}.faces", "the meshfree method loads the walls' faces only: "
                             "set faces = \"where\" with a [pressures.where] selection")
        chosen = load.faces.mask(plate.X, scale)[surface.particle]
        if load.wall is not None:
            chosen &= surface.side == WALL_SIDES[load.wall]
        if not chosen.any():
            raise SetupError(f"pressures.{q}.where", "selects no particle on the wall surfaces (a tube's inner "
                             "and outer walls, a plate's two faces across its thickness); check the plane or box")
        ids = np.flatnonzero(chosen)
        delay = np.zeros(len(ids))
        if load.front_speed is not None:
            if plate.axis is None:
                raise SetupError(f"pressures.{q}.front_speed", f"a travelling front runs along a tube, this "
                                 f"specimen is a {plate.shape}: remove front_speed or set specimen.shape = \"tube\"")
            direction = plate.axis if load.front_direction is None else np.asarray(load.front_direction, float)
            direction = direction / np.linalg.norm(direction)
            delay = (surface.centre[ids] - np.asarray(load.front_origin, float)) @ direction / load.front_speed
        rows.append((surface.particle[ids], surface.area[ids], np.full(len(ids), q, dtype=np.int64), delay))
    if rows:
        particle, area, which, delay = (np.concatenate(parts) for parts in zip(*rows))
    else:
        particle, area, which, delay = np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0)
    order = np.lexsort((which, particle))  # by particle, then by pressure
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(particle, minlength=n), out=start[1:])
    return PressedFaces(start, np.ascontiguousarray(area[order]), which[order], delay[order])

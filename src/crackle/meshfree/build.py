"""A MeshfreeSimulation from particles, a material and the shared loads: what the scenario set-up
and the tests both call."""

from __future__ import annotations

import math

import numpy as np

from ..loading.arrays import TOOL_PENALTY_FACTOR, history_tables, tool_arrays
from ..solver.integrator import support_constraints
from .fracture import LinkBreaking
from .kernels import BLOCK, Links, Particles, Pressures
from .material import T_REF, J2Law
from .particles import WALL_SIDES, WallParticles
from .shape import basis_terms, quartic_spline_array, smoothed_gradients
from .simulation import MeshfreeSimulation


class SetupError(ValueError):
    """A discretisation that cannot run; `field` is the scenario key to change."""

    def __init__(self, field: str, message: str):
        super().__init__(message)
        self.field = field


def build_meshfree_simulation(plate: WallParticles, density: float, law: J2Law, dilation: float = 2.5,
                              stabilisation: float = 0.1, tools=(), supports=(), damping: float = 0.0,
                              gravity=(0.0, 0.0, 0.0), velocity=None,
                              fracture_stress: float = math.inf, precracks=(), pressures=()) -> MeshfreeSimulation:
    """The particles of `plate` with support radius dilation x the largest grid step (gradients
    by stabilised conforming nodal integration over the particles' cells, shape.smoothed_gradients), the
    material (density kg/m^3, J2Law), the link stabilisation alpha (kernels docstring), tools and
    supports (loading.Tool, loading.Support), mass-proportional `damping` (1/s), `gravity`
    (m/s^2), an initial `velocity` (m/s, one for all or one per particle) and the fracture stress
    (Pa, the maximum principal stress that fails a particle; inf: no fracture, fracture.py) and
    the pre-cracks (loading.Precrack: the links across them removed at the start) and the pressures
    on the wall faces (loading.Pressure, pressure_arrays)."""
    X = np.ascontiguousarray(plate.X, dtype=float)
    n = len(X)
    radius = dilation * float(np.max(plate.spacing))
    terms = basis_terms(plate.thickness_axis, plate.layers)
    start, neighbour, grad, condition, first_bad = smoothed_gradients(X, plate.volume, plate.cells, radius, terms)
    if first_bad is not None:
        raise SetupError("particles.dilation", (
            f"the moment matrix at {first_bad.round(6).tolist()} m (a particle's cell face) is singular: the support "
            f"radius {dilation:g} x {np.max(plate.spacing):.3g} m holds too few particles for the quadratic basis; "
            f"increase particles.dilation (2.5 or more)"))
    row = np.repeat(np.arange(n), np.diff(start))
    dX = X[neighbour] - X[row]
    dist2 = np.einsum("ij,ij->i", dX, dX)
    weight = quartic_spline_array(np.sqrt(dist2) / radius)
    spread = np.bincount(row, weights=weight * dist2, minlength=n)
    table = law.table()
    stiffness = stabilisation * law.youngs_modulus * plate.volume[row] * weight / spread[row]
    # The transpose of the links, for the gather: for particle L, every link (I, L) in order of I.
    back_link = np.lexsort((row, neighbour))
    back_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(neighbour, minlength=n), out=back_start[1:])
    links = Links(start, neighbour, grad, stiffness, np.zeros((len(neighbour), 3)), back_start, back_link,
                  row[back_link])
    scale = float(np.max(np.ptp(X, axis=0)))
    constraint, projection = support_constraints(supports, X, scale)
    loads = pressure_arrays(plate, pressures, scale)
    mass = density * plate.volume
    v = np.zeros((n, 3))
    if velocity is not None:
        v[:] = np.asarray(velocity, dtype=float)
    particles = Particles(
        x=X.copy(), v=v, X=X, mass=mass, volume=plate.volume.copy(), area=plate.area.copy(), constraint=constraint,
        projection=projection, tool=np.full(n, -1, dtype=np.int8), tool_offset=np.zeros(n),
        friction=np.zeros((n, 3)), d_friction=np.zeros(n), w_external=np.zeros(n), w_damping=np.zeros(n),
        plastic=np.zeros((n, 6)), eq_plastic=np.zeros(n), w_plastic=np.zeros(n), stress=np.zeros((n, 6)),
        deformation=np.tile(np.eye(3).ravel(), (n, 1)), internal=np.zeros((n, 9)), stab_sum=np.zeros((n, 3)),
        thermal=np.column_stack([np.full(n, table[T_REF]), np.zeros(n)]),
    )
    h = float(np.min(plate.spacing))
    penalty = TOOL_PENALTY_FACTOR * law.youngs_modulus / h
    tool_table = tool_arrays(list(tools), penalty, h, -(-n // BLOCK))
    tool_k = (tool_table.penalty.max() if len(tools) else 0.0) * particles.area
    dt = stable_step(particles, links, row, dX, table, tool_k)
    c_p = math.sqrt((table[0] + 2.0 * table[1]) / density)
    breaking = None
    if math.isfinite(fracture_stress) or precracks:
        breaking = LinkBreaking(X, plate.volume, plate.cells, radius, terms,
                                stabilisation * law.youngs_modulus, fracture_stress, float(np.max(plate.spacing)), links,
                                plate.wall_frame)
    sim = MeshfreeSimulation(particles, links, table, tool_table, [t.name for t in tools], radius, dt, h / c_p,
                             gravity, damping, plate, breaking, loads)
    if precracks:
        try:
            breaking.cut(sim, precracks, scale)
        except ValueError as err:
            raise SetupError(str(err).split(":")[0], str(err)) from None
        # One-sided gradients at the pre-crack faces can be stiffer: the step of the cut links.
        sim.stable_dt = min(dt, stable_step(particles, links, breaking.row, dX, table, tool_k))
    return sim


def pressure_arrays(plate: WallParticles, pressures, scale: float) -> Pressures:
    """The wall faces (particles.WallFaces) that each pressure loads, gathered per particle: the
    faces of the particles its `where` selects (on its `wall` only, when given), with the delay
    s / front_speed of a travelling front (s the distance of the face's reference centre from
    front_origin along front_direction, default the tube's axis). Raises SetupError naming the
    pressure's key that selects nothing or asks for what this specimen does not have."""
    surface, n = plate.surface, len(plate.X)
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
    times, values, counts = history_tables([p.history for p in pressures])
    return Pressures(start, np.ascontiguousarray(area[order]), which[order], delay[order], times, values, counts)


def stable_step(particles, links, row, dX, law_table, tool_k) -> float:
    """2 / omega_max with omega_max^2 bounded by Gershgorin's theorem on the mass-scaled
    stiffness of the linearised step (block norms): the nodal-integration stiffness
    sum_I V_I C grad N_L(X_I) grad N_M(X_I) (|C| <= 3 lambda + 2 mu), the stabilisation's
    Hessian and the tool penalties. A bound, so the step is stable whatever the mode (measured
    in tests/test_meshfree.py against the highest frequency found)."""
    n = len(particles.mass)
    start, neighbour, grad, k = links.start, links.neighbour, links.grad, links.stiffness
    inv_sqrt_m = 1.0 / np.sqrt(particles.mass)
    gn = np.linalg.norm(grad, axis=1)
    c_norm = 3.0 * law_table[0] + 2.0 * law_table[1]
    # G_I = sum_M |grad N_M(X_I)| / sqrt(m_M)
    G = np.bincount(row, weights=gn * inv_sqrt_m[neighbour], minlength=n)
    elastic = c_norm * np.bincount(neighbour, weights=particles.volume[row] * gn * G[row], minlength=n)
    # Stabilisation: d eps_IJ / d x_M = delta_JM - delta_IM - grad N_M(X_I) . dX_IJ, bounded row by row.
    dlen = np.linalg.norm(dX, axis=1)
    s = inv_sqrt_m[neighbour] + inv_sqrt_m[row] + dlen * G[row]
    Z = np.bincount(row, weights=k * s * dlen, minlength=n)
    stab = (np.bincount(neighbour, weights=k * s, minlength=n) + np.bincount(row, weights=k * s, minlength=n)
            + np.bincount(neighbour, weights=gn * Z[row], minlength=n))
    omega2 = (elastic + stab) * inv_sqrt_m + tool_k / particles.mass
    return float(2.0 / math.sqrt(np.max(omega2)))

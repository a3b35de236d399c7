"""A DemSimulation from particles (centres, radii), a bond law and the shared loads: what the
scenario set-up and the tests both call."""

from __future__ import annotations

import numpy as np

from ..solver.integrator import support_constraints
from ..solver.setup import tool_stiffness, tools_on_body
from .kernels import BLOCK
from .model import (BondLaw, GroupedLaws, Joint, bond_gamma, bonds, draw_bond_strengths, make_particles, normal_stiffness,
                    pair_parameters, stable_dt, with_joints)
from .simulation import DemSimulation

# The contact list holds the pairs closer than Ra + Rb + SKIN x the mean radius: rebuilt when a
# particle could have moved half of it.
SKIN = 0.3
NEW_CONTACTS = 6


def build_dem_simulation(centers, radii, density, law: BondLaw | GroupedLaws, bonds_per_particle: float | None = None,
                         gamma: float | None = None, tools=(), supports=(), damping: float = 0.0,
                         gravity=(0.0, 0.0, 0.0), velocity=None, loaded_area: float | None = None,
                         joint: Joint | None = None, random: dict | None = None, seed: int = 0,
                         material: str = "rock") -> DemSimulation:
    """Particles at `centers` (m) with `radii` (m) and `density` (kg/m^3; one per particle with
    several materials, `law` then GroupedLaws), bonded to every
    neighbour within gamma (Ra + Rb), gamma given or chosen for `bonds_per_particle`.
    `damping`: the local non-viscous damping alpha (0 to 1, paper 003 eq. 5). `tools`,
    `supports`: loading.Tool, loading.Support (a support holds the particles it selects).
    `loaded_area` (m^2): the cross-section the platen stress is taken over. `joint`: a closed
    flaw, the bonds across it made smooth joints. `random`: the bond strengths drawn per bond
    ({property: RandomProperty}) from `seed` and the `material`'s name."""
    centers = np.ascontiguousarray(centers, dtype=float)
    radii = np.asarray(radii, dtype=float)
    if gamma is None:
        if bonds_per_particle is None:
            raise ValueError("give gamma or bonds_per_particle")
        gamma = bond_gamma(centers, radii, bonds_per_particle)
    scale = float(np.max(np.ptp(centers, axis=0) + 2.0 * radii.max()))
    particles = make_particles(centers, radii, density, support_constraints(supports, centers, scale), velocity)
    inter = bonds(particles, law, gamma)
    drawn, drawn_statistics = draw_bond_strengths(particles, inter, law, random or {}, seed, material)
    if joint is not None:
        inter = with_joints(particles, inter, joint)
    mean_radius = float(np.mean(radii))
    # A particle against a tool: the spring of a bond to a particle of infinite radius,
    # 2 Y R, as the penalty (per area) 2 Y / (pi R_mean) times the particle's area pi R^2.
    penalty = 2.0 * law.bond_modulus / (np.pi * mean_radius)
    tool_table, seating = tools_on_body(tools, particles, penalty, 2.0 * float(radii.max()), -(-len(radii) // BLOCK),
                                        "particles")
    tool_k = tool_stiffness(tool_table, particles.area)
    # Contacts that form later come on top of the bonds (the touching pairs are bonded at set-up,
    # so new ones replace broken bonds or close gaps): room for 6 more per particle.
    if isinstance(law, GroupedLaws):
        own = np.arange(len(radii))
        kn, kt = pair_parameters(law, radii, own, own)[:2]  # against a particle of its own kind
        contact_k = 2.0 * NEW_CONTACTS * (kn + kt)
    else:
        contact_k = 2.0 * NEW_CONTACTS * (1.0 + law.stiffness_ratio) * normal_stiffness(law, radii, radii)
    dt = stable_dt(particles, inter, tool_k + contact_k)
    sim = DemSimulation(particles, inter, len(inter.a), law, tool_table, [t.name for t in tools], dt, gravity,
                        damping, SKIN * mean_radius, loaded_area)
    # The bound at set-up, without room for later contacts: what a user's run.dt may reach.
    sim.proven_dt = stable_dt(particles, inter, tool_k)
    sim.warnings.extend(seating)
    sim.gamma = gamma
    sim.drawn, sim.random_properties = drawn, ({material: drawn_statistics} if drawn else None)
    return sim

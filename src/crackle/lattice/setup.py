"""The lattice's scenario section and its build into a LatticeSimulation.

[lattice]: a box `size` (m) from `origin` filled with nodes at `spacing`; each node is joined to
its 6 axial and 12 face-diagonal neighbours by springs of one stiffness k. For such a lattice
C11 = 3k/a, C12 = C44 = k/a, so E = 2.5 k/a and nu = 1/4: k = 0.4 E a reproduces the
[material]'s Young's modulus (its Poisson's ratio is not free here). A spring stretched by more
than `break_strain` breaks (a tension failure). Nodes meet tools at `contact_radius` (default half
the spacing) with a contact area spacing^2.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np

from ..budget import check_model_size
from ..loading.arrays import default_tool_penalty, seat_on_tools, tool_arrays
from ..loading.build import build_loading
from ..scenario import ElasticSpec, ScenarioBase, ScenarioError
from ..schema import NonNegative, Positive, PositiveOrInf, Strict, Vec3
from ..solver.body import body_arrays
from ..solver.integrator import support_constraints
from .kernels import BLOCK, Nodes, Springs
from .simulation import LatticeSimulation



class LatticeSpec(Strict):
    """[lattice]: a box of nodes on a cubic grid joined by springs."""

    size: tuple[Positive, Positive, Positive]
    """m, the box (Lx, Ly, Lz)"""
    spacing: Positive
    """m, between neighbouring nodes"""
    origin: Vec3 = (0.0, 0.0, 0.0)
    """m, the lower corner"""
    break_strain: PositiveOrInf = math.inf
    """a spring breaks beyond this stretch"""
    contact_radius: NonNegative | None = None
    """m, of a node against the tools; default spacing / 2"""


class Scenario(ScenarioBase):
    method: Literal["lattice"]
    """picks this method"""
    reads = frozenset({"run.damping"})
    lattice: LatticeSpec
    """the nodes and springs"""
    material: ElasticSpec
    """density and Young's modulus (the lattice's Poisson's ratio is 1/4)"""


def lattice_arrays(spec: LatticeSpec, material: ElasticSpec):
    """Node positions, lumped masses, springs (a, b, rest length) of the lattice."""
    counts = [int(round(L / spec.spacing)) + 1 for L in spec.size]
    if min(counts) < 2:
        raise ScenarioError("lattice.spacing: larger than the lattice; give at least two nodes along every side")
    a = spec.spacing
    ijk = np.stack(np.meshgrid(*[np.arange(n) for n in counts], indexing="ij"), axis=-1).reshape(-1, 3)
    x = np.asarray(spec.origin, float) + a * ijk
    # Lumped mass: a node on a face, edge or corner owns a half, quarter or eighth of a cell.
    share = np.prod(np.where((ijk == 0) | (ijk == np.array(counts) - 1), 0.5, 1.0), axis=1)
    mass = material.density * a**3 * share
    index = np.full(counts, -1, dtype=np.int64)
    index[tuple(ijk.T)] = np.arange(len(ijk))
    offsets = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1)]
    pairs = []
    for off in offsets:
        other = ijk + np.array(off)
        ok = np.all((other >= 0) & (other < np.array(counts)), axis=1)
        pairs.append(np.stack([np.flatnonzero(ok), index[tuple(other[ok].T)]], axis=1))
    pairs = np.concatenate(pairs)
    rest = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)
    return x, mass, pairs, rest


def build_simulation(scenario: Scenario, base: Path | None = None) -> LatticeSimulation:
    spec = scenario.lattice
    tools, supports, _ = build_loading(scenario, base)  # no pressures: the lattice does not read them
    check_model_size(math.prod(L / spec.spacing + 1.0 for L in spec.size), "lattice nodes", "lattice.spacing",
                     scenario.run.max_memory)
    x, mass, pairs, rest = lattice_arrays(spec, scenario.material)
    n, n_spring = len(x), len(pairs)
    k = np.full(n_spring, 0.4 * scenario.material.youngs_modulus * spec.spacing)
    scale = float(max(spec.size))
    try:
        constraint, projection, support_tool = support_constraints(supports, x, scale)
    except ValueError as err:
        raise ScenarioError(f"supports: {err}") from None
    # Node -> (spring, sign) CSR in spring order: the spring force acts on b, its negative on a.
    ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
    signs = np.concatenate([-np.ones(n_spring), np.ones(n_spring)])
    ids = np.concatenate([np.arange(n_spring), np.arange(n_spring)])
    order = np.lexsort((ids, ends))
    start = np.zeros(n + 1, dtype=np.int64)
    np.add.at(start, ends + 1, 1)
    springs = Springs(
        a=pairs[:, 0].copy(), b=pairs[:, 1].copy(), rest=rest, k=k, intact=np.ones(n_spring, dtype=np.bool_),
        fail_time=np.full(n_spring, np.nan), fail_mode=np.zeros(n_spring, dtype=np.int8), e_damage=np.zeros(n_spring),
        force=np.zeros((n_spring, 3)), node_start=np.cumsum(start), node_spring=ids[order], node_sign=signs[order],
    )
    area = np.full(n, spec.spacing**2)
    penalty = default_tool_penalty(scenario.material.youngs_modulus, spec.spacing)
    tool_table = tool_arrays(tools, penalty, spec.spacing, -(-n // BLOCK))
    radius = 0.5 * spec.spacing if spec.contact_radius is None else spec.contact_radius
    nodes = Nodes(**body_arrays(x, mass, area, radius, (constraint, projection, support_tool)))
    # Stable step (Gershgorin per node): 2 sqrt(m / sum of its spring and tool stiffnesses).
    k_node = np.zeros(n)
    np.add.at(k_node, ends, np.concatenate([k, k]))
    tool_k = (tool_table.penalty.max() if len(tools) else 0.0) * area
    stable_dt = float(np.min(2.0 / np.sqrt((2.0 * k_node + tool_k) / mass)))
    seating = seat_on_tools(tools, tool_table, nodes, "nodes")
    # P-wave speed of the lattice: C11 = 3k/a = 1.2 E.
    wave_transit = spec.spacing / math.sqrt(1.2 * scenario.material.youngs_modulus / scenario.material.density)
    sim = LatticeSimulation(
        nodes, springs, tool_table, [t.name for t in tools], spec.break_strain, stable_dt,
        wave_transit, np.asarray(scenario.run.gravity, float), scenario.run.damping,
    )
    sim.warnings.extend(seating)
    nu = scenario.material.poissons_ratio
    if nu != 0.25:
        sim.warnings.append(f"material.poissons_ratio = {nu:g} is not used: this lattice's Poisson's ratio is 1/4")
    return sim

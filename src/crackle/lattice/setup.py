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

from ..loading.arrays import default_tool_penalty
from ..scenario import ElasticSpec, ScenarioBase, ScenarioError
from ..schema import NonNegative, Positive, PositiveOrInf, Strict, Vec3
from ..solver.body import pair_incidence
from ..solver.setup import SetUp, tool_stiffness
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
    spec, material = scenario.lattice, scenario.material
    setup = SetUp(scenario, base, (math.prod(L / spec.spacing + 1.0 for L in spec.size), "lattice nodes",
                                   "lattice.spacing"))
    x, mass, pairs, rest = lattice_arrays(spec, material)
    n, n_spring = len(x), len(pairs)
    k = np.full(n_spring, 0.4 * material.youngs_modulus * spec.spacing)
    # Each node gathers its springs' forces in spring order (node_start, node_spring, node_sign).
    springs = Springs(pairs[:, 0].copy(), pairs[:, 1].copy(), rest, k, np.ones(n_spring, dtype=np.bool_),
                      np.full(n_spring, np.nan), np.zeros(n_spring, dtype=np.int8), np.zeros(n_spring),
                      np.zeros((n_spring, 3)), *pair_incidence(n, pairs[:, 0], pairs[:, 1]))
    radius = 0.5 * spec.spacing if spec.contact_radius is None else spec.contact_radius
    nodes = Nodes(**setup.body_arrays(x, mass, np.full(n, spec.spacing**2), radius, float(max(spec.size))))
    tools = setup.tools_on(nodes, default_tool_penalty(material.youngs_modulus, spec.spacing), spec.spacing,
                           -(-n // BLOCK), "nodes")
    # Stable step (Gershgorin per node): 2 sqrt(m / sum of its spring and tool stiffnesses).
    k_node = np.bincount(pairs.T.ravel(), np.tile(k, 2), minlength=n)
    stable_dt = float(np.min(2.0 / np.sqrt((2.0 * k_node + tool_stiffness(tools, nodes.area)) / mass)))
    # P-wave speed of the lattice: C11 = 3k/a = 1.2 E.
    wave_transit = spec.spacing / math.sqrt(1.2 * material.youngs_modulus / material.density)
    if material.poissons_ratio != 0.25:
        setup.warnings.append(f"material.poissons_ratio = {material.poissons_ratio:g} is not used: this lattice's "
                              "Poisson's ratio is 1/4")
    return LatticeSimulation(setup, nodes, springs, tools, spec.break_strain, stable_dt, wave_transit)

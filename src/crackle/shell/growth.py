"""Crack growth on the shell (paper 002 sections 5-6): Griffith's criterion on the J-integral, the
crack speed law, and the topology update that moves a tip along the mesh by splitting vertices.

Every GROWTH_CHECK steps (a fixed grid of step numbers, so the run does not depend on how it is
split into calls), each tip's J (the mean over its rings) is compared with Gc. Where J >= Gc the
tip runs at V = V_max min(1, (J / Gc - 1)^m) (the paper's power law in G / Gc - 1, capped at
V_max), its advance accumulating over the checks; once the advance reaches the next edge ahead
(the tip's edge best aligned with its direction), that edge is cut (mesh.split_along): the tip
vertex splits in two and the edge's far end is the new tip (node release). The new mesh's arrays
are rebuilt and the state carried over: positions and velocities of the old vertices, the
parent's for each new copy (the split conserves mass and momentum), the supports and tool state
of the parent, the work counters on the old vertices (the copies start at zero).

The direction: the maximum tangential stress criterion (Erdogan and Sih; K_I and K_II from J and
the crack faces' displacements, jintegral.stress_intensity): straight ahead in mode I, 70.5 deg
off in pure mode II; the cut then takes the tip's edge nearest to that heading, so the path
follows the mesh's edges (no remeshing at the tip yet). Energy: cutting an edge does not
move anything, so no energy appears or vanishes at the cut except the bending energy of the
triangles whose edge became free (their free-edge angle is condensed: `energy.fracture`
books that jump); the membrane energy near the tip is then released by the motion (kinetic,
then damping). The Griffith energy Gc x thickness x extension is in the summary, not the audit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import split_along
from .model import Shell, build_shell

GROWTH_CHECK = 20  # steps between checks


@dataclass
class GrowthLaw:
    toughness: float  # J/m^2, Gc
    max_speed: float  # m/s, V_max
    exponent: float = 1.0  # m
    criterion: str = "j"  # "j": the domain J; "g": G by virtual crack extension

    def speed(self, j: float) -> float:
        """V (m/s) at J (J/m^2): 0 below Gc."""
        if not j >= self.toughness:
            return 0.0
        return self.max_speed * min(1.0, (j / self.toughness - 1.0) ** self.exponent)


@dataclass
class Advance:
    time: float
    position: np.ndarray  # reference, the new tip
    tip: int
    mode: int  # solver.failures code of the tip's mixity


def step_ahead(shell: Shell, vertex: int, direction: np.ndarray) -> tuple[int, float] | None:
    """The neighbour of `vertex` along the edge best aligned with `direction` (within 60 deg),
    and that edge's length; None if there is none (the crack reached a boundary)."""
    mesh = shell.mesh
    edges = np.flatnonzero(np.any(mesh.edge == vertex, axis=1) & ~mesh.boundary)
    best, best_cos, best_length = None, 0.5, 0.0
    for e in edges:
        other = int(mesh.edge[e, 0] if mesh.edge[e, 1] == vertex else mesh.edge[e, 1])
        d = mesh.X[other] - mesh.X[vertex]
        length = float(np.linalg.norm(d))
        cos = float(np.dot(d, direction)) / length
        if cos > best_cos + 1e-12:
            best, best_cos, best_length = other, cos, length
    return None if best is None else (best, best_length)


def cut_edge(shell: Shell, a: int, b: int) -> tuple[Shell, np.ndarray]:
    """The shell with the edge (a, b) cut and its state carried over (module docstring), and the
    vertices the cut opened (a always; b too when it is on a boundary: the crack went through)."""
    mesh, parent = split_along(shell.mesh, np.array([a, b]))
    old, n_old = shell.nodes, len(shell.mesh.X)
    source = np.concatenate([np.arange(n_old), parent])
    new = build_shell(mesh, shell.material, None if shell.clamped is None else shell.clamped[source])
    carried = {}
    for name in ("x", "v", "constraint", "tool", "tool_offset", "friction", "load"):
        carried[name] = getattr(old, name)[source].copy()
    for name in ("w_external", "w_damping", "d_friction"):
        counter = np.zeros(len(source))
        counter[:n_old] = getattr(old, name)
        carried[name] = counter
    carried["load"][n_old:] = 0.0  # the parent keeps its share of an edge load
    new.nodes = new.nodes._replace(projection=old.projection, **carried)
    for name in ("pressure", "pressure_sign", "pressure_delay"):  # the cut keeps the triangles' order
        getattr(new.faces, name)[:] = getattr(shell.faces, name)
    _carry_edge_state(shell, new, source)
    return new, parent


def _carry_edge_state(old: Shell, new: Shell, source: np.ndarray) -> None:
    """The mid-edge rotations, their rates and damping work from each old edge to the new edge
    between the same vertices (a copy counts as its parent); the cut edge's two sides are
    boundary edges, without xi: only its damping work moves, to the first of them."""
    n = len(source)

    def keys(ends):
        a, b = np.sort(ends, axis=1).T
        return a * n + b

    old_keys = keys(old.edges.ends)
    new_keys = keys(source[new.edges.ends])
    order = np.argsort(old_keys)
    at = np.searchsorted(old_keys[order], new_keys)
    match = order[np.minimum(at, len(order) - 1)]
    found = old_keys[match] == new_keys
    first = np.zeros(len(new_keys), dtype=bool)
    first[np.unique(new_keys, return_index=True)[1]] = True
    take = found & first
    interior = new.edges.xi_inertia > 0.0
    for name in ("xi", "xi_rate"):
        getattr(new.edges, name)[take & interior] = getattr(old.edges, name)[match[take & interior]]
    new.edges.xi_damping[take] = old.edges.xi_damping[match[take]]

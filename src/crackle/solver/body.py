"""The per-node arrays every method's body shares (nodes, particles, shell nodes), declared and
built in one place, and taken whole by the shared compiled pieces: the tool contact
(loading.tools.contact_with_tools, seat_points) and the node update
(solver.integrator.update_velocity).

A method declares its own namedtuple as BODY_FIELDS plus its extras (DEM spins, meshfree
stresses, shell load and gathering tables), and the compiled pieces read only the Body fields of
it. The extras are fields of the same flat tuple, not a tuple nested in it: numba's parallel
kernels do not take nested namedtuples.

Fields (n nodes):
  x, v          (n, 3) position at time t, velocity over the half step before t
  mass          (n,)
  area          (n,) contact area: a tool's penalty (N/m^3) times it is the node's contact spring
  radius        (n,) contact radius per node, or (1,) one for all: 0 for a tet node, a sphere's
                radius, half a shell's thickness (loading.tools: the gap is measured from it)
  constraint, projection, support_tool
                the supports (solver.integrator.support_constraints)
  tool, tool_offset, friction, d_friction
                the contact state against the tools (loading.tools.NO_TOOL, HIDDEN)
  w_external, w_damping
                (n,) the work of the external forces and tools, and the damping's loss
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..loading.tools import NO_TOOL
from .integrator import support_constraints

BODY_FIELDS = ("x v mass area radius constraint projection support_tool tool tool_offset friction d_friction "
               "w_external w_damping")
Body = namedtuple("Body", BODY_FIELDS)


def body_arrays(x, mass, area, radius, supports=None, velocity=None, tool=None) -> dict:
    """The Body fields of a body at position x, as keyword arguments for Body or a method's own
    tuple. radius: one for all (a number) or per node; supports: the (constraint, projection,
    support_tool) of support_constraints, or None (nothing held); velocity: (3,) for all, (n, 3),
    or None (at rest); tool: each node's initial contact state, or None (NO_TOOL: free to touch).
    x and area are copied; mass is kept as given (FDEM's mass scaling changes it in place later)."""
    n = len(mass)
    constraint, projection, support_tool = support_constraints((), x, 1.0) if supports is None else supports
    v = np.zeros((n, 3))
    if velocity is not None:
        v[:] = np.asarray(velocity, dtype=float)
    return dict(
        x=np.array(x, dtype=float), v=v, mass=np.asarray(mass, dtype=float), area=np.array(area, dtype=float),
        radius=np.atleast_1d(np.array(radius, dtype=float)), constraint=constraint, projection=projection,
        support_tool=support_tool,
        tool=np.full(n, NO_TOOL, dtype=np.int8) if tool is None else np.asarray(tool, dtype=np.int8),
        tool_offset=np.zeros(n), friction=np.zeros((n, 3)), d_friction=np.zeros(n), w_external=np.zeros(n),
        w_damping=np.zeros(n),
    )


def pair_incidence(n: int, a: np.ndarray, b: np.ndarray):
    """Per point (n of them), the pairs (a[k], b[k]) it is an end of, in pair order, with sign -1
    as a and +1 as b (int8): (start, pair, sign) in CSR form, so that a point gathers its pairs'
    forces in a fixed order (no races, thread-count independent)."""
    k = len(a)
    ends = np.concatenate([a, b])
    ids = np.concatenate([np.arange(k), np.arange(k)])
    signs = np.concatenate([-np.ones(k, dtype=np.int8), np.ones(k, dtype=np.int8)])
    order = np.lexsort((ids, ends))
    start = np.zeros(n + 1, dtype=np.int64)
    np.add.at(start, ends + 1, 1)
    return np.cumsum(start), ids[order].astype(np.int64), signs[order]

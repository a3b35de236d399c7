"""The meshfree step's stability: the stable step from the highest frequency of the linearised
step (Lanczos on the step's own forces, solver.stability) and Gershgorin's cheap bound, per
particle, that the checks after fracture rebuilds refresh (fracture.LinkBreaking._check_step)."""

from __future__ import annotations

import math

import numpy as np

from ..solver import stability
from .kernels import internal_forces
from .material import YIELD
from .shape import csr_positions


def stable_step(particles, links, columns, row, law_table, tool_k, spacing) -> tuple[float, float]:
    """STEP_MARGIN x 2 / omega_max, omega_max^2 the largest eigenvalue of M^-1 K of the
    linearised step estimated by Lanczos (highest_frequency2), and its ratio to Gershgorin's
    bound (gershgorin_frequency2), which calibrates the cheap check after fracture rebuilds.
    row: as gershgorin_frequency2."""
    omega2, _, _ = highest_frequency2(particles, links, columns, law_table, tool_k, spacing)
    ratio = omega2 / gershgorin_frequency2(particles, links, row, law_table, tool_k)
    return stability.STEP_MARGIN * 2.0 / math.sqrt(omega2), ratio


def highest_frequency2(particles, links, columns, law_table, tool_k, spacing) -> tuple[float, float, int]:
    """omega_max^2 (1/s^2) of the linearised step about the reference state
    (solver.stability.highest_frequency2 on kernels.internal_forces, elastic: plasticity only
    softens), with the tool penalties tool_k (N/m, per particle) on every particle."""
    n = len(particles.mass)
    law = law_table.copy()
    law[..., YIELD] = math.inf
    p = particles._replace(x=particles.X.copy(), plastic=np.zeros((2 * n, 6)), eq_plastic=np.zeros(2 * n),
                           w_plastic=np.zeros(n), stress=np.zeros((n, 6)), deformation=np.zeros((n, 9)),
                           internal=np.zeros((n, 9)), bending=np.zeros((n, 9)), stab_force=np.zeros((n, 3)),
                           thermal=particles.thermal.copy())

    def forces(x, out):
        p.x[:] = x
        internal_forces(0.0, p, links, columns, law, out)

    return stability.highest_frequency2(particles.X, particles.mass, forces, spacing, tool_k)


def gershgorin_frequency2(particles, links, row, law_table, tool_k) -> float:
    """A bound on omega_max^2 (1/s^2) by Gershgorin's theorem on the mass-scaled stiffness of the
    linearised step (block norms): the nodal-integration stiffness
    sum_I V_I C grad N_L(X_I) grad N_M(X_I) (|C| <= 3 lambda + 2 mu), the stabilisation's
    Hessian and the tool penalties. Guaranteed but 1.7-12 x the true value (1.3-3.5 x in the step:
    an isotropic grid without tools the most, plate-impact's, where the sphere's penalty weighs,
    the least):
    after fracture rebuilds, times the set-up ratio of the Lanczos estimate to it, the cheap
    estimate of the new omega_max^2 (fracture.LinkBreaking). row: each link's particle I."""
    return float(np.max(gershgorin_bounds(particles, links, row, law_table, tool_k)[2]))


def gershgorin_bounds(particles, links, row, law_table, tool_k):
    """Per particle, the pieces of gershgorin_frequency2: the row sums G_I and S_I below and the
    bound on omega^2 of each particle's row of the mass-scaled stiffness (its maximum is the
    bound). fracture.LinkBreaking keeps them and refreshes those a rebuild changes
    (refresh_gershgorin_bounds)."""
    n, count = len(particles.mass), len(row)
    neighbour, grad, value = links.neighbour, links.grad, links.value
    inv_sqrt_m = 1.0 / np.sqrt(particles.mass)
    # The per-link terms are formed in blocks of links (_per_link: whole-array temporaries were
    # the set-up's peak memory); each sum over the links is still one bincount, in link order.
    gn = _per_link(count, lambda r: np.linalg.norm(grad[r], axis=1))
    c_norm = _stiffness_norm(law_table)[particles.material]
    # G_I = sum_M |grad N_M(X_I)| / sqrt(m_M)
    G = np.bincount(row, weights=_per_link(count, lambda r: gn[r] * inv_sqrt_m[neighbour[r]]), minlength=n)
    elastic = np.bincount(
        neighbour, weights=_per_link(count, lambda r: c_norm[row[r]] * particles.volume[row[r]] * gn[r] * G[row[r]]),
        minlength=n)
    # Stabilisation: Hessian sum_J k_J D_JL D_JM with D_JM = d eps_J / d u_M = delta_JM - N_M(X_J):
    # row L bounded by sum_J k_J |D_JL| S_J, S_J = sum_M |D_JM| / sqrt(m_M).
    D = _per_link(count, lambda r: np.abs((row[r] == neighbour[r]) - value[r]))
    S = np.bincount(row, weights=_per_link(count, lambda r: D[r] * inv_sqrt_m[neighbour[r]]), minlength=n)
    stab = np.bincount(neighbour, weights=_per_link(count, lambda r: particles.stab_k[row[r]] * D[r] * S[row[r]]),
                       minlength=n)
    return G, S, (elastic + stab) * inv_sqrt_m + tool_k / particles.mass


def refresh_gershgorin_bounds(bounds, particles, links, law_table, tool_k, rows) -> None:
    """Update gershgorin_bounds' (G, S, omega2) in place after the links of the particles `rows`
    (increasing) changed: their row sums, then the column sums of every particle they link to,
    through the transposed links (the same terms summed in the same order: the numbers a full
    recomputation gives)."""
    G, S, omega2 = bounds
    inv_sqrt_m = 1.0 / np.sqrt(particles.mass)
    tool_k = np.broadcast_to(tool_k, particles.mass.shape)
    pos, first = csr_positions(links.start, rows)
    local = np.repeat(np.arange(len(rows)), np.diff(first))
    J = links.neighbour[pos]
    G[rows] = np.bincount(local, weights=np.linalg.norm(links.grad[pos], axis=1) * inv_sqrt_m[J], minlength=len(rows))
    S[rows] = np.bincount(local, weights=np.abs((rows[local] == J) - links.value[pos]) * inv_sqrt_m[J],
                          minlength=len(rows))
    cols = np.unique(J)
    pos, first = csr_positions(links.back_start, cols)
    local = np.repeat(np.arange(len(cols)), np.diff(first))
    I = links.back_row[pos]
    gn = np.linalg.norm(links.back_grad[pos], axis=1)
    D = np.abs((I == cols[local]) - links.back_value[pos])
    c_norm = _stiffness_norm(law_table)[particles.material]
    elastic = np.bincount(local, weights=c_norm[I] * particles.volume[I] * gn * G[I], minlength=len(cols))
    stab = np.bincount(local, weights=particles.stab_k[I] * D * S[I], minlength=len(cols))
    omega2[cols] = (elastic + stab) * inv_sqrt_m[cols] + tool_k[cols] / particles.mass[cols]


def _stiffness_norm(law_table) -> float:
    """|C| <= 3 lambda + 2 mu: each material's (row's) share of Gershgorin's bound."""
    return 3.0 * law_table[..., 0] + 2.0 * law_table[..., 1]


def _per_link(count: int, term, block: int = 1 << 18) -> np.ndarray:
    """term(r) for the slices r of `count` links, block by block, into one array: elementwise
    the same numbers as term(slice(None)), with temporaries of one block only."""
    out = np.empty(count)
    for first in range(0, count, block):
        r = slice(first, first + block)
        out[r] = term(r)
    return out

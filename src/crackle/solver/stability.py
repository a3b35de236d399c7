"""The stable step of a method whose stiffness is only available as its own force kernel: the
largest eigenvalue of the mass-scaled linearised step M^-1/2 K M^-1/2 by Lanczos. Used by the
meshfree particles and the shell, where per-element bounds (Gershgorin) are several times too
pessimistic.

The step is STEP_MARGIN x 2 / omega. Lanczos approaches omega_max from below; the value used,
Ritz value + residual bound (an eigenvalue lies within the bound of the Ritz value), is above
omega_max^2 once the top Ritz value has converged to it (measured +0.7 %). The margin covers a
start vector poor in the top mode and the geometric stiffness that the linearisation about the
unstressed state leaves out (~stress / E, 1e-3 for a metal)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.linalg import eigh_tridiagonal

STEP_MARGIN = 0.95
# The iteration ends when the residual bound is LANCZOS_TOLERANCE of the Ritz value, after at
# least LANCZOS_MIN_ITERATIONS: a small residual alone can come early, before the top mode has
# entered the Krylov space (measured: at 1 % after 8 iterations, a Ritz value 11 % low).
LANCZOS_TOLERANCE = 1e-3
LANCZOS_MIN_ITERATIONS = 20
LANCZOS_ITERATIONS = 150  # at most
LANCZOS_SEED = 0  # the start vector: seeded normal numbers (every mode present, fixed)
# Displacement of the finite difference of the forces (central: the quadratic term of a St.
# Venant-Kirchhoff material cancels; the cubic one is ~ this squared), relative to the smallest
# spacing.
PROBE = 1e-4


def highest_frequency2(X: np.ndarray, mass: np.ndarray, forces: Callable[[np.ndarray, np.ndarray], None],
                       spacing: float, tool_k: np.ndarray | float = 0.0, linear: bool = False) -> tuple[float, float, int]:
    """omega_max^2 (1/s^2) of the linearised step about the positions X, by Lanczos on
    M^-1/2 K M^-1/2 (no reorthogonalisation: that makes ghost copies, never larger values).
    K v is the central difference of `forces(x, out)` (the method's internal forces at
    positions x into out, elastic: plasticity only softens) about X, plus the tool penalties
    tool_k (N/m, per node) on every node, the worst case of any contact set (adding a positive
    semi-definite diagonal only raises eigenvalues). `linear`: the forces are linear in x and zero
    at X, so one evaluation gives K v. Supports are left out: a constraint only
    lowers omega_max (interlacing). Returns (the largest Ritz value + its residual bound, that
    residual bound, iterations). Deterministic: a seeded start vector, numpy's pairwise sums and
    thread-independent force kernels."""
    n = len(mass)
    x = X.copy()
    inv_sqrt_m = (1.0 / np.sqrt(mass))[:, None]
    diagonal = (np.broadcast_to(tool_k, (n,)) / mass)[:, None]
    plus, minus = np.zeros((n, 3)), np.zeros((n, 3))

    def apply(q):
        u = q * inv_sqrt_m
        s = PROBE * spacing / np.max(np.abs(u))
        np.add(X, s * u, out=x)
        forces(x, plus)
        if linear:
            return -plus / s * inv_sqrt_m + diagonal * q
        np.subtract(X, s * u, out=x)
        forces(x, minus)
        return (minus - plus) / (2.0 * s) * inv_sqrt_m + diagonal * q

    q = np.random.default_rng(LANCZOS_SEED).standard_normal((n, 3))
    q /= math.sqrt(np.sum(q * q))
    q_prev = np.zeros_like(q)
    alphas, betas = [], []
    beta = 0.0
    for k in range(LANCZOS_ITERATIONS):
        w = apply(q)
        a = float(np.sum(q * w))
        w -= a * q + beta * q_prev
        alphas.append(a)
        beta = math.sqrt(np.sum(w * w))
        values, vectors = eigh_tridiagonal(np.array(alphas), np.array(betas))
        theta, residual = float(values[-1]), beta * abs(float(vectors[-1, -1]))
        if (k + 1 >= LANCZOS_MIN_ITERATIONS and residual <= LANCZOS_TOLERANCE * theta) or beta == 0.0:
            break
        betas.append(beta)
        q_prev, q = q, w / beta
    return theta + residual, residual, k + 1


def stable_step(X, mass, forces, spacing, tool_k=0.0) -> float:
    """STEP_MARGIN x 2 / omega_max (highest_frequency2)."""
    omega2, _, _ = highest_frequency2(X, mass, forces, spacing, tool_k)
    return STEP_MARGIN * 2.0 / math.sqrt(omega2)

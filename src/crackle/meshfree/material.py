"""The meshfree material: St. Venant-Kirchhoff elasticity with J2 elasto-visco-plasticity (paper
000 section 3.1, eqs 14-15), in the total-Lagrangian measures the particles carry: the
Green-Lagrange strain E = (F^T F - I) / 2 splits additively into elastic and plastic parts, the
second Piola-Kirchhoff stress S = lambda tr(E - Ep) I + 2 mu (E - Ep), and the von Mises
equivalent of S's deviator s, seq = sqrt(3/2 s:s), may not exceed the flow stress

    g(ep) = sigma0 (1 + ep / ep0)^(1/n)                    (eq. 14, hardening)
    sigma_eff = g(ep) (1 + ep_rate / ep_rate0)^(1/m)        (eq. 15, rate dependence)

with ep the equivalent plastic strain. The update is a radial return (backward Euler): the
trial deviator is scaled back until seq_trial - 3 mu dep = g(ep + dep) (1 + dep / (dt
ep_rate0))^(1/m), solved by a safeguarded Newton iteration; the plastic strain grows by
dep 3 s / (2 seq) and the plastic work per reference volume by seq dep. With 1/n = 1 the
hardening is linear (modulus sigma0 / ep0), with 1/n = 0 perfectly plastic; 1/m = 0 is rate
independent. Measured with these measures the model is objective (rigid rotations leave E and S
unchanged) and is the small-strain J2 model for small strains; it is not the paper's
Jaumann-rate update (eq. 16 onwards), which is for large plastic strains.

Tensors are 6-vectors in the order xx yy zz xy yz xz (tensor components, not engineering shear).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# Rows of the law table the kernels read.
LAMBDA, MU, YIELD, EP0, HARDENING, RATE0, RATE_EXP = range(7)


@dataclass(frozen=True)
class J2Law:
    youngs_modulus: float  # Pa
    poissons_ratio: float
    yield_stress: float = math.inf  # Pa, sigma0 (inf: elastic)
    reference_plastic_strain: float = 1.0  # ep0
    hardening_exponent: float = 0.0  # 1/n
    reference_strain_rate: float = 1.0  # 1/s, ep_rate0
    rate_exponent: float = 0.0  # 1/m

    def table(self) -> np.ndarray:
        E, nu = self.youngs_modulus, self.poissons_ratio
        lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
        mu = E / (2.0 * (1.0 + nu))
        return np.array([lam, mu, self.yield_stress, self.reference_plastic_strain, self.hardening_exponent,
                         self.reference_strain_rate, self.rate_exponent], dtype=float)


@njit(cache=True, inline="always")
def flow_stress(ep, dep, dt, law):
    """The flow stress at plastic strain ep + dep reached at the rate dep / dt, and its
    derivative with respect to dep (eqs 14-15)."""
    s0, ep0, hexp, rate0, mexp = law[YIELD], law[EP0], law[HARDENING], law[RATE0], law[RATE_EXP]
    base = 1.0 + (ep + dep) / ep0
    g = s0 * base**hexp
    dg = s0 * hexp / ep0 * base ** (hexp - 1.0) if hexp != 0.0 else 0.0
    if mexp == 0.0:
        return g, dg
    rate = 1.0 + dep / (dt * rate0)
    factor = rate**mexp
    dfactor = mexp / (dt * rate0) * rate ** (mexp - 1.0)
    return g * factor, dg * factor + g * dfactor


@njit(cache=True, inline="always")
def stress_update(g, e0, e1, e2, e3, e4, e5, plastic, eq_plastic, dt, law):
    """Second Piola-Kirchhoff stress (s0..s5) of particle g at the Green-Lagrange strain e0..e5,
    with the radial return updating plastic[g] (6) and eq_plastic[g], and the plastic work per
    reference volume of this update (J/m^3): returns (s0, s1, s2, s3, s4, s5, work). Scalars in
    and out: the block kernels that call it cannot allocate."""
    lam, mu = law[LAMBDA], law[MU]
    ee0 = e0 - plastic[g, 0]
    ee1 = e1 - plastic[g, 1]
    ee2 = e2 - plastic[g, 2]
    tr = ee0 + ee1 + ee2
    s0 = lam * tr + 2.0 * mu * ee0
    s1 = lam * tr + 2.0 * mu * ee1
    s2 = lam * tr + 2.0 * mu * ee2
    s3 = 2.0 * mu * (e3 - plastic[g, 3])
    s4 = 2.0 * mu * (e4 - plastic[g, 4])
    s5 = 2.0 * mu * (e5 - plastic[g, 5])
    if law[YIELD] == math.inf:
        return s0, s1, s2, s3, s4, s5, 0.0
    mean = (s0 + s1 + s2) / 3.0
    d0 = s0 - mean
    d1 = s1 - mean
    d2 = s2 - mean
    seq = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (s3 * s3 + s4 * s4 + s5 * s5)))
    ep = eq_plastic[g]
    g0, _ = flow_stress(ep, 0.0, dt, law)
    if seq <= g0:
        return s0, s1, s2, s3, s4, s5, 0.0
    # phi(dep) = seq - 3 mu dep - flow(dep): positive at 0, negative at seq / (3 mu), decreasing.
    lo = 0.0
    hi = seq / (3.0 * mu)
    dep = 0.0
    for _ in range(60):
        flow, dflow = flow_stress(ep, dep, dt, law)
        phi = seq - 3.0 * mu * dep - flow
        if phi > 0.0:
            lo = dep
        else:
            hi = dep
        if abs(phi) <= 1e-13 * seq or hi - lo <= 1e-15 * hi:
            break
        step = dep + phi / (3.0 * mu + dflow)
        dep = step if lo < step < hi else 0.5 * (lo + hi)
    scale = 1.5 * dep / seq
    de0 = scale * d0
    de1 = scale * d1
    de2 = scale * d2
    de3 = scale * s3
    de4 = scale * s4
    de5 = scale * s5
    plastic[g, 0] += de0
    plastic[g, 1] += de1
    plastic[g, 2] += de2
    plastic[g, 3] += de3
    plastic[g, 4] += de4
    plastic[g, 5] += de5
    eq_plastic[g] = ep + dep
    work = (seq - 3.0 * mu * dep) * dep
    return (s0 - 2.0 * mu * de0, s1 - 2.0 * mu * de1, s2 - 2.0 * mu * de2, s3 - 2.0 * mu * de3,
            s4 - 2.0 * mu * de4, s5 - 2.0 * mu * de5, work)


@njit(cache=True)
def material_point(strain, plastic, eq_plastic, dt, law):
    """One material point's stress (6) at the strain (6), updating its plastic state
    (plastic (1, 6), eq_plastic (1,)); returns (stress, plastic work per volume). For tests and
    scripts; the kernels call stress_update."""
    s0, s1, s2, s3, s4, s5, work = stress_update(0, strain[0], strain[1], strain[2], strain[3], strain[4],
                                                 strain[5], plastic, eq_plastic, dt, law)
    return np.array([s0, s1, s2, s3, s4, s5]), work

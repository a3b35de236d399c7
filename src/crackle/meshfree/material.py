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
unchanged) and is the small-strain J2 model for small strains.

The thermo-elasto-viscoplastic law (`model = "thermo"`, paper 000 section 3.2, eqs 16-22, the
model of Zhou, Ravichandran & Rosakis) in the same measures:

    S = lambda(T) tr(Ee) I + 2 mu(T) Ee,   Ee = E - Ep - theta(T) I,   theta = int_T0^T alpha dT
    rate = rate0 (seq / g(ep, T))^m                                    (eq. 19, no elastic range)
    g(ep, T) = sigma0(T) (1 + ep / ep0)^N (1 - delta (exp((T - T0) / kappa) - 1))   (eq. 20)
    E, nu, alpha, sigma0: quadratics in T - T0                         (eq. 22)
    rho c dT = chi seq dep                                             (adiabatic heating)

(the rows RATE_EXP and HARDENING hold 1/m and N). Eq. 16 is a rate form in the Jaumann rate of
the Kirchhoff stress, updated in the paper by the rate-tangent method of Peirce, Shih &
Needleman. crackle keeps its total-Lagrangian radial return instead: the St. Venant-Kirchhoff
form is objective by construction (no rotation terms to integrate), its stored energy is a
potential the audit can measure, and it needs nothing beyond the particle's F, where a Jaumann
update would need the spin and an incrementally rotated stress per particle. The price is the
J2 law's: exact for small elastic strains, not the paper's hypoelastic response at large ones.
The return is backward Euler in the plastic strain increment dep with the rate dep / dt and the
temperature the increment's own work gives, seq_trial - 3 mu dep = g(ep + dep, T + chi
(seq_trial - 3 mu dep) dep / (rho c)) (dep / (dt rate0))^(1/m), solved by the same safeguarded
Newton iteration; with no elastic range, a particle skips it where the explicit estimate of dep
is negligible (NEGLIGIBLE_FLOW). The
moduli and the thermal strain of the trial are those of the step's starting temperature (an
explicit split of the thermo-mechanical coupling, first order in the step's temperature
change); the stress returned is re-evaluated at the new temperature, so that it is the
derivative of the stored energy the audit measures, and the stored energy the temperature
change takes out at fixed strain is booked per particle (thermal[:, 1], energy.thermal).

Tensors are 6-vectors in the order xx yy zz xy yz xz (tensor components, not engineering shear).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..materials.elasticity import energy_density, svk_stress

# Rows of the law table the kernels read: the J2 law's, then the thermo law's (zero for J2).
LAMBDA, MU, YIELD, EP0, HARDENING, RATE0, RATE_EXP = range(7)
(MODEL, T_REF, HEATING, SOFTENING, SOFTENING_T, E_REF, NU_REF, E_T1, E_T2, NU_T1, NU_T2, YIELD_T1, YIELD_T2,
 ALPHA_0, ALPHA_T1, ALPHA_T2) = range(7, 23)
J2, THERMO = 0.0, 1.0  # the MODEL row
# The thermo law has no elastic range: a particle whose explicit plastic strain increment
# dt rate0 (seq / g)^m would change its stress by less than this fraction of seq skips the
# solve (the increment it drops is below rounding: ~1e-8 of the stress over 1e4 steps).
NEGLIGIBLE_FLOW = 1e-12


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
        row = np.zeros(23)
        row[:7] = [lam, mu, self.yield_stress, self.reference_plastic_strain, self.hardening_exponent,
                   self.reference_strain_rate, self.rate_exponent]
        return row


@dataclass(frozen=True)
class ThermoLaw(J2Law):
    """The thermo-elasto-viscoplastic law (eqs 19-22): hardening_exponent is N, rate_exponent
    1/m (0: rate independent), reference_plastic_strain eps0 (the paper's sigma0 / E)."""

    initial_temperature: float = 293.0  # K, T0
    density: float = 2700.0  # kg/m^3
    specific_heat: float = 900.0  # J/(kg K)
    taylor_quinney: float = 0.9  # chi
    thermal_softening: float = 0.0  # delta
    softening_temperature: float = 500.0  # K, kappa
    youngs_modulus_temperature: tuple = (0.0, 0.0)  # Pa/K, Pa/K^2
    poissons_ratio_temperature: tuple = (0.0, 0.0)  # 1/K, 1/K^2
    yield_stress_temperature: tuple = (0.0, 0.0)  # Pa/K, Pa/K^2
    thermal_expansion: float = 0.0  # 1/K, alpha at T0
    thermal_expansion_temperature: tuple = (0.0, 0.0)  # 1/K^2, 1/K^3

    def table(self) -> np.ndarray:
        row = super().table()
        row[MODEL:] = [THERMO, self.initial_temperature,
                       self.taylor_quinney / (self.density * self.specific_heat), self.thermal_softening,
                       self.softening_temperature, self.youngs_modulus, self.poissons_ratio,
                       *self.youngs_modulus_temperature, *self.poissons_ratio_temperature,
                       *self.yield_stress_temperature, self.thermal_expansion, *self.thermal_expansion_temperature]
        return row


@njit(cache=True, inline="always")
def thermo_elasticity(T, law):
    """lambda, mu (Pa) and the thermal strain theta = int_T0^T alpha dT at temperature T (eq. 22)."""
    d = T - law[T_REF]
    E = law[E_REF] + d * (law[E_T1] + d * law[E_T2])
    nu = law[NU_REF] + d * (law[NU_T1] + d * law[NU_T2])
    theta = d * (law[ALPHA_0] + d * (0.5 * law[ALPHA_T1] + d * law[ALPHA_T2] / 3.0))
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu)), theta


def thermal_strain(T, law) -> np.ndarray:
    """theta(T) of thermo_elasticity for an array of temperatures (0 for the J2 law, whose
    expansion rows are 0)."""
    return np.array([thermo_elasticity(t, law)[2] for t in np.asarray(T, dtype=float)])


@njit(cache=True, inline="always")
def thermo_flow(ep, T, law):
    """g(ep, T) of eq. 20 with sigma0(T) of eq. 22, and its derivatives with respect to ep and T.
    Where thermal softening or sigma0(T) would make it negative the material has no strength
    left: g = 0."""
    d = T - law[T_REF]
    s0 = law[YIELD] + d * (law[YIELD_T1] + d * law[YIELD_T2])
    ds0 = law[YIELD_T1] + 2.0 * d * law[YIELD_T2]
    ep0, N = law[EP0], law[HARDENING]
    base = 1.0 + ep / ep0
    h = base**N
    dh = N / ep0 * base ** (N - 1.0) if N != 0.0 else 0.0
    delta = law[SOFTENING]
    soft, dsoft = 1.0, 0.0
    if delta != 0.0:
        grow = math.exp(d / law[SOFTENING_T])
        soft = 1.0 - delta * (grow - 1.0)
        dsoft = -delta * grow / law[SOFTENING_T]
    g = s0 * h * soft
    if g <= 0.0:
        return 0.0, 0.0, 0.0
    return g, s0 * dh * soft, (ds0 * soft + s0 * dsoft) * h


@njit(cache=True, inline="always")
def elastic_energy(g, ee0, ee1, ee2, ee3, ee4, ee5, thermal, law):
    """Stored energy per reference volume of particle g at the strain less its plastic strain
    ee (the thermo law's thermal strain and moduli at its temperature thermal[g, 0])."""
    if law[MODEL] != THERMO:
        return energy_density(ee0, ee1, ee2, ee3, ee4, ee5, law[LAMBDA], law[MU])
    lam, mu, theta = thermo_elasticity(thermal[g, 0], law)
    return energy_density(ee0 - theta, ee1 - theta, ee2 - theta, ee3, ee4, ee5, lam, mu)


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
def deviator(s0, s1, s2, s3, s4, s5):
    """The normal components of the stress deviator and the von Mises stress sqrt(3/2 s:s)."""
    mean = (s0 + s1 + s2) / 3.0
    d0 = s0 - mean
    d1 = s1 - mean
    d2 = s2 - mean
    return d0, d1, d2, math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (s3 * s3 + s4 * s4 + s5 * s5)))


@njit(cache=True, inline="always")
def _narrowed(phi, dep, lo, hi, seq):
    """The return map's bracket [lo, hi] on the plastic increment narrowed by phi(dep) (positive
    below the root), and whether the iteration has converged (phi or the bracket negligible)."""
    if phi > 0.0:
        lo = dep
    else:
        hi = dep
    return lo, hi, abs(phi) <= 1e-13 * seq or hi - lo <= 1e-15 * hi


@njit(cache=True, inline="always")
def stress_update(g, e0, e1, e2, e3, e4, e5, plastic, eq_plastic, thermal, dt, law):
    """Second Piola-Kirchhoff stress (s0..s5) of particle g at the Green-Lagrange strain e0..e5,
    with the radial return updating plastic[g] (6) and eq_plastic[g] (and for the thermo law
    the temperature thermal[g, 0] and the released energy thermal[g, 1]), and the plastic work
    per reference volume of this update (J/m^3): returns (s0, s1, s2, s3, s4, s5, work). Scalars
    in and out: the block kernels that call it cannot allocate."""
    if law[MODEL] == THERMO:
        return thermo_update(g, e0, e1, e2, e3, e4, e5, plastic, eq_plastic, thermal, dt, law)
    lam, mu = law[LAMBDA], law[MU]
    s0, s1, s2, s3, s4, s5 = svk_stress(lam, mu, e0 - plastic[g, 0], e1 - plastic[g, 1], e2 - plastic[g, 2],
                                        e3 - plastic[g, 3], e4 - plastic[g, 4], e5 - plastic[g, 5])
    if law[YIELD] == math.inf:
        return s0, s1, s2, s3, s4, s5, 0.0
    d0, d1, d2, seq = deviator(s0, s1, s2, s3, s4, s5)
    # Below the initial yield stress no flow stress is lower (hardening >= 0, the rate factor 1
    # at dep = 0): elastic without its powers, most points of most steps.
    if seq <= law[YIELD] and law[HARDENING] >= 0.0:
        return s0, s1, s2, s3, s4, s5, 0.0
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
        lo, hi, converged = _narrowed(phi, dep, lo, hi, seq)
        if converged:
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


@njit(cache=True, inline="always")
def thermo_update(g, e0, e1, e2, e3, e4, e5, plastic, eq_plastic, thermal, dt, law):
    """stress_update for the thermo law (module docstring): the trial at the starting temperature
    T, the backward-Euler return with the flow stress at the temperature the increment's work
    gives, the stress at the new temperature; thermal[g, 1] gains the stored energy per
    reference volume that the temperature change released at fixed strain."""
    T = thermal[g, 0]
    lam, mu, theta = thermo_elasticity(T, law)
    ee0 = e0 - plastic[g, 0] - theta
    ee1 = e1 - plastic[g, 1] - theta
    ee2 = e2 - plastic[g, 2] - theta
    ee3 = e3 - plastic[g, 3]
    ee4 = e4 - plastic[g, 4]
    ee5 = e5 - plastic[g, 5]
    s0, s1, s2, s3, s4, s5 = svk_stress(lam, mu, ee0, ee1, ee2, ee3, ee4, ee5)
    d0, d1, d2, seq = deviator(s0, s1, s2, s3, s4, s5)
    if seq == 0.0:
        return s0, s1, s2, s3, s4, s5, 0.0
    ep = eq_plastic[g]
    g0, _, _ = thermo_flow(ep, T, law)
    mexp, rate0, heating = law[RATE_EXP], law[RATE0], law[HEATING]
    hi = seq / (3.0 * mu)
    dep = 0.5 * hi
    if mexp == 0.0:  # rate independent: an elastic range after all
        if seq <= g0:
            return s0, s1, s2, s3, s4, s5, 0.0
    elif g0 > 0.0:
        # log of the explicit estimate dt rate0 (seq / g0)^m (logs: m may be huge)
        guess = math.log(dt * rate0) + math.log(seq / g0) / mexp
        if guess <= math.log(NEGLIGIBLE_FLOW * hi):
            return s0, s1, s2, s3, s4, s5, 0.0
        if guess < math.log(hi):
            dep = math.exp(guess)
    # phi(dep) = seq - 3 mu dep - g(ep + dep, T(dep)) (dep / (dt rate0))^(1/m): seq at 0, <= 0 at hi.
    lo = 0.0
    for _ in range(60):
        q = seq - 3.0 * mu * dep
        gv, dg_ep, dg_T = thermo_flow(ep + dep, T + heating * q * dep, law)
        dg = dg_ep + dg_T * heating * (seq - 6.0 * mu * dep)
        rate, drate = 1.0, 0.0
        if mexp != 0.0:
            rate = (dep / (dt * rate0)) ** mexp
            drate = mexp * rate / dep
        phi = q - gv * rate
        lo, hi, converged = _narrowed(phi, dep, lo, hi, seq)
        if converged:
            break
        step = dep + phi / (3.0 * mu + dg * rate + gv * drate)
        # Out of the bracket: bisect, geometrically once the root is bracketed away from 0
        # (the increments span many decades).
        dep = step if lo < step < hi else (math.sqrt(lo * hi) if lo > 0.0 else 0.5 * hi)
    q = seq - 3.0 * mu * dep
    T_new = T + heating * q * dep
    scale = 1.5 * dep / seq
    plastic[g, 0] += scale * d0
    plastic[g, 1] += scale * d1
    plastic[g, 2] += scale * d2
    plastic[g, 3] += scale * s3
    plastic[g, 4] += scale * s4
    plastic[g, 5] += scale * s5
    eq_plastic[g] = ep + dep
    thermal[g, 0] = T_new
    # The stress of the new state: strain less the new plastic strain, at the new temperature.
    ee0 = e0 - plastic[g, 0]
    ee1 = e1 - plastic[g, 1]
    ee2 = e2 - plastic[g, 2]
    ee3 = e3 - plastic[g, 3]
    ee4 = e4 - plastic[g, 4]
    ee5 = e5 - plastic[g, 5]
    lam1, mu1, theta1 = thermo_elasticity(T_new, law)
    before = energy_density(ee0 - theta, ee1 - theta, ee2 - theta, ee3, ee4, ee5, lam, mu)
    ee0 -= theta1
    ee1 -= theta1
    ee2 -= theta1
    thermal[g, 1] += before - energy_density(ee0, ee1, ee2, ee3, ee4, ee5, lam1, mu1)
    s0, s1, s2, s3, s4, s5 = svk_stress(lam1, mu1, ee0, ee1, ee2, ee3, ee4, ee5)
    return s0, s1, s2, s3, s4, s5, q * dep


@njit(cache=True)
def _material_point(strain, plastic, eq_plastic, thermal, dt, law):
    s0, s1, s2, s3, s4, s5, work = stress_update(0, strain[0], strain[1], strain[2], strain[3], strain[4],
                                                 strain[5], plastic, eq_plastic, thermal, dt, law)
    return np.array([s0, s1, s2, s3, s4, s5]), work


def material_point(strain, plastic, eq_plastic, dt, law, thermal=None):
    """One material point's stress (6) at the strain (6), updating its plastic state
    (plastic (1, 6), eq_plastic (1,)) and, for the thermo law, thermal (1, 2): temperature (K)
    and released energy per volume (J/m^3), at T0 and 0 if not given; returns (stress, plastic
    work per volume). For tests and scripts; the kernels call stress_update."""
    if thermal is None:
        thermal = np.array([[law[T_REF], 0.0]])
    return _material_point(np.asarray(strain, dtype=float), plastic, eq_plastic, thermal, dt, law)

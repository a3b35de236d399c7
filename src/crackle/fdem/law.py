"""Guo-Munjiza interface law as numba device functions (paper 001, eqs 3 and 6-8).

Model (per unit area, for one integration point of an interface):

* Normal branch. Opening dn (positive = separation). Compression (dn < 0) is a penalty
  sigma = p_n dn and never damages. In tension the undamaged curve is
  sigma_el = f_t (2x - x^2), x = dn/dnp, up to the peak f_t at dnp = 2 f_t / p_n (the initial
  slope equals the penalty p_n), and f_t beyond it.
* Shear branch, the same shape with peak f_s = c - sigma_n tan(phi) (eq. 3), sigma_n the
  point's normal stress capped by the tension cut-off f_t, and dsp = 2 f_s / p_s.
* Damage D (eq. 8) from the interface's centroid opening and slip:
  D = sqrt(Dn^2 + Ds^2), Dn = <dn - dnp> / (dnc - dnp), Ds = <ds - dsp> / (dsc - dsp), capped
  at 1 and never decreasing. Stresses are z(D) times the undamaged curves (eq. 7 gives z).
* Stored energy phi = Phi_comp(dn) + z(D) (Phi_n(dn) + Phi_s(ds)), with Phi the integrals of the
  undamaged curves. So unloading is elastic along the damaged curve z(D) sigma_el back to the
  origin, and the dissipation of a damage step is (z(D_old) - z(D_new)) (Phi_n + Phi_s) >= 0.
  Phi_s depends on f_s and so on the current normal stress: as in the paper, the shear branch is
  a potential only at constant normal stress, and a closed (dn, ds) loop below the peak under a
  changing normal stress is not exactly conservative (the audit shows it as imbalance).
* dnc is set so that a full mode-I separation dissipates exactly Gf:
  (2/3) f_t dnp + f_t (dnc - dnp) Iz = Gf, Iz = integral of z over [0, 1] (0.3863 with the
  default constants; the paper's d_c = 3 Gf / f is the same relation with Iz ~ 1/3 and dnp ~ 0).
  The same holds in shear with Gf_II and f_s.

Bilinear cohesive law (paper 004; Camanho-Davila mixed-mode formulation), selected per law row by
LAW_KIND = KIND_BILINEAR; the interface's own stiffnesses kn, ks (N/m^3) are its pn, ps:

* Tractions tn = (1 - D) kn dn in opening, kn dn in compression (never damaged), shear vector
  ts = (1 - D) ks s: linear to the origin on unloading (secant), a potential at fixed D.
* Initiation (maximum nominal stress): max(kn <dn> / tn0, ks |s| / ts0) = 1.
* Effective opening dm = sqrt(<dn>^2 + |s|^2), effective stiffness K = (kn <dn>^2 + ks |s|^2) / dm^2
  (so the undamaged energy is K dm^2 / 2), initiation opening d0 = dm / max(...) at the current
  mode mix, final opening df = 2 Gc / (K d0), linear softening
  D = df (dm - d0) / (dm (df - d0)), never decreasing; a complete failure at a fixed mix
  dissipates K d0 df / 2 = Gc per unit area.
* Mixed mode from the energy ratio B = ks |s|^2 / (kn <dn>^2 + ks |s|^2) (G_II / G_T):
  Benzeggagh-Kenane Gc = GIc + (GIIc - GIc) B^eta, or the power law
  ((1 - B) Gc / GIc)^alpha + (B Gc / GIIc)^alpha = 1.
"""

from __future__ import annotations

import math

from numba import njit

# Columns of the per-law parameter table.
LAW_FT, LAW_C, LAW_TANPHI, LAW_GF1, LAW_GF2, LAW_A, LAW_B, LAW_CS, LAW_IZ, LAW_MU = range(10)
# Appended for the bilinear law (zero, unused, in a Guo-Munjiza row; LAW_FT, LAW_GF1, LAW_GF2 and
# LAW_MU are shared): law kind, shear strength ts0, mixed-mode rule and its exponent.
LAW_KIND, LAW_TS, LAW_MIX, LAW_MIX_EXP = range(10, 14)
LAW_COLUMNS = 14
KIND_GUO_MUNJIZA, KIND_BILINEAR = 0, 1
MIX_POWER, MIX_BK = 0, 1


@njit(cache=True, inline="always")
def softening(d, a, b, c):
    if d <= 0.0:
        return 1.0
    if d >= 1.0:
        return 0.0
    decay = 1.0 - (a + b - 1.0) / (a + b) * math.exp(d * (a + c * b) / ((a + b) * (1.0 - a - b)))
    return decay * (a * (1.0 - d) + b * (1.0 - d) ** c)


@njit(cache=True, inline="always")
def peak_curve(delta, peak, delta_p):
    """Undamaged curve f (2x - x^2) up to the peak at delta_p, flat f beyond; delta >= 0."""
    if delta >= delta_p:
        return peak
    x = delta / delta_p
    return peak * (2.0 * x - x * x)


@njit(cache=True, inline="always")
def peak_curve_energy(delta, peak, delta_p):
    """Integral of peak_curve from 0 to delta."""
    if delta >= delta_p:
        return peak * delta_p * (2.0 / 3.0) + peak * (delta - delta_p)
    x = delta / delta_p
    return peak * delta_p * (x * x - x * x * x / 3.0)


# Energy per unit area up to the start of softening, over peak x delta_p: the normal branch's
# pre-peak curve f (2x - x^2) holds 2/3; the shear branch (elastic ps up to the cap at delta_p / 2,
# then the cap) 1/4 + 1/2.
PRE_PEAK_NORMAL = 2.0 / 3.0
PRE_PEAK_SHEAR = 3.0 / 4.0


@njit(cache=True, inline="always")
def critical_opening(peak, delta_p, gf, iz, pre_peak):
    """Opening at which the softening curve reaches zero, so that the full curve holds gf."""
    soft = gf - peak * delta_p * pre_peak
    # A penalty so soft that the pre-peak part alone exceeds gf: keep a short softening branch
    # (set-up warns about this case).
    if soft < 0.05 * gf:
        soft = 0.05 * gf
    return delta_p + soft / (peak * iz)


@njit(cache=True, inline="always")
def shear_strength(sigma_n, law):
    """Mohr-Coulomb with tension cut-off (eq. 3): sigma_n tension-positive, capped at f_t."""
    s = sigma_n
    if s > law[LAW_FT]:
        s = law[LAW_FT]
    fs = law[LAW_C] - s * law[LAW_TANPHI]
    # Keep a small positive strength so that dsp stays finite.
    floor = 1e-6 * law[LAW_C] + 1e-12
    return fs if fs > floor else floor


@njit(cache=True, inline="always")
def normal_stress(dn, pn, z, law):
    """Normal stress (tension positive) at opening dn for penalty pn and softening factor z."""
    if dn < 0.0:
        return pn * dn
    dnp = 2.0 * law[LAW_FT] / pn
    return z * peak_curve(dn, law[LAW_FT], dnp)


# ---------------------------------------------------------------------------------------------
# Bilinear cohesive law.


@njit(cache=True, inline="always")
def mixed_mode_energy(b, law):
    """Critical energy Gc (J/m^2) at the energy mode ratio b = G_II / (G_I + G_II)."""
    g1 = law[LAW_GF1]
    g2 = law[LAW_GF2]
    e = law[LAW_MIX_EXP]
    if b <= 0.0:
        return g1
    if b >= 1.0:
        return g2
    if law[LAW_MIX] == MIX_BK:
        return g1 + (g2 - g1) * b**e
    return (((1.0 - b) / g1) ** e + (b / g2) ** e) ** (-1.0 / e)


@njit(cache=True, inline="always")
def bilinear_damage(dn, ds, kn, ks, law):
    """Damage that the opening dn and slip magnitude ds alone give (0 up to initiation, 1 from
    the final opening on) and the energy mode ratio B = G_II / G_T there."""
    dnp = dn if dn > 0.0 else 0.0
    en = kn * dnp * dnp
    es = ks * ds * ds
    e = en + es
    if e <= 0.0:
        return 0.0, 0.0
    b = es / e
    f_n = kn * dnp / law[LAW_FT]
    f_s = ks * ds / law[LAW_TS]
    f = f_n if f_n > f_s else f_s
    if f <= 1.0:
        return 0.0, b
    dm = math.sqrt(dnp * dnp + ds * ds)
    k = e / (dm * dm)
    d0 = dm / f
    df = 2.0 * mixed_mode_energy(b, law) / (k * d0)
    # Set-up refuses pure-mode snap-back (Gc <= t0^2 / 2k); keep a mixed mode finite anyway.
    if df < d0 * (1.0 + 1e-9):
        df = d0 * (1.0 + 1e-9)
    if dm >= df:
        return 1.0, b
    return df * (dm - d0) / (dm * (df - d0)), b

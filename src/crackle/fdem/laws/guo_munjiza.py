"""Guo-Munjiza interface law (paper 001, eqs 3 and 6-8): its parameters, its row of the law
table, and its forces and stored energy on an intact interface, side by side.

Model (per unit area, for one integration point of an interface):

* Normal branch. Opening dn (positive = separation). Compression (dn < 0) is a penalty
  sigma = p_n dn and never damages. In tension the undamaged curve is
  sigma_el = f_t (2x - x^2), x = dn/dnp, up to the peak f_t at dnp = 2 f_t / p_n (the initial
  slope equals the penalty p_n), and f_t beyond it.
* Shear: an elastic spring p_s on the slip beyond a plastic slip, capped at z(D) f_s(sigma_n)
  with f_s = c - sigma_n tan(phi) (eq. 3), sigma_n the point's normal stress capped by the
  tension cut-off f_t; the excess becomes plastic slip and dissipates. (The paper's
  f_s (2x - x^2) curve of the total slip has no potential when sigma_n varies and pumps energy
  into a crushed zone.) Its peak opening dsp = 2 f_s / p_s sets the shear damage.
* Damage D (eq. 8) from the interface's centroid opening and slip:
  D = sqrt(Dn^2 + Ds^2), Dn = <dn - dnp> / (dnc - dnp), Ds = <ds - dsp> / (dsc - dsp), capped
  at 1 and never decreasing. Stresses are z(D) times the undamaged curves (eq. 7 gives z).
* Stored energy phi = Phi_comp(dn) + z(D) Phi_n(dn) + the shear spring's, with Phi the integrals
  of the undamaged curves. Unloading is elastic along the damaged curve back to the origin, and
  a damage step dissipates (z(D_old) - z(D_new)) Phi_n >= 0 plus what the falling shear cap
  releases.
* dnc is set so that a full mode-I separation dissipates exactly Gf:
  (2/3) f_t dnp + f_t (dnc - dnp) Iz = Gf, Iz = integral of z over [0, 1] (0.3863 with the
  default constants; the paper's d_c = 3 Gf / f is the same relation with Iz ~ 1/3 and dnp ~ 0).
  The same holds in shear with Gf_II and f_s.
* Extrinsic insertion (insertion = "extrinsic"): the face carries nothing until the stress of its
  two tets reaches the strength; it is then inserted at the peak (fdem.extrinsic shifts its
  opening by dn_shift and preloads its shear spring, so the traction goes on from the continuum's)
  and follows the softening branch from there. The work done on the face from its insertion to
  its complete separation is Gf: in tension the softening from the peak holds all of it
  (f_t (dnc - dnp) Iz = Gf); in shear the spring starts at its elastic limit (the slip counts
  from dsp / 2), and the plateau at the cap up to dsp plus the softening hold Gf_II.
"""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

import numpy as np
from numba import njit
from pydantic import Field
from pydantic import model_validator
from pydantic.dataclasses import dataclass

from ...schema import STRICT_DATACLASS, NonNegative, Positive, check_unit_slips
from ...solver.failures import failure_mode
from ..interface import opening, opening_earlier
from ..topology import FAILED
from .row import LAW_EXTRINSIC, LAW_FT, OWN, new_row

# Softening constants of the Munjiza/Guo curve z(D) (paper 001, eq. 7), fitted to direct-tension
# tests of concrete.
DEFAULT_SOFTENING = (0.63, 1.8, 6.0)

# Interface penalty: p_n = penalty_factor * E / h and p_s = penalty_factor * G / h, h the smaller
# altitude of the two tets onto the shared face. Each interface then adds about 1/penalty_factor
# of a tet's own compliance. Measured softening of the intact exploded mesh in uniaxial tension:
# 2.7 % at 100, 1.4 % at 200, 0.3 % at 1000 (tests/fdem/test_fdem_elastic.py checks < 3 % at the
# default). The price is the time step, which shrinks as 1/sqrt(penalty_factor) once the
# interfaces are the stiffest part (the usual FDEM trade-off).
DEFAULT_PENALTY_FACTOR = 200.0
# With extrinsic insertion the intact body has no springs to soften it: the penalty only acts on
# inserted faces (their unloading and, once failed, their contact), so it is set as soft as the
# contact penalty and the step stays near the bulk tets' (a closed face penetrates stress x h / E).
EXTRINSIC_PENALTY_FACTOR = 2.0

# The law's own columns of its table row.
LAW_C, LAW_TANPHI, LAW_GF1, LAW_GF2, LAW_A, LAW_B, LAW_CS, LAW_IZ, LAW_BETA = range(OWN, OWN + 9)
# The columns of the interfaces' reading_offset (the effective mixed mode's slip offsets).
CLOSED_READING, OPEN_READING = 0, 1


@dataclass(frozen=True, config=STRICT_DATACLASS)
class GuoMunjizaLaw:
    """Guo-Munjiza interface law: Mohr-Coulomb with tension cut-off and z(D) softening (paper 001).

    tensile_strength ft (Pa), cohesion c (Pa) and friction_angle phi (degrees) give the peaks:
    f_t in tension and f_s = c - sigma_n tan(phi) in shear (eq. 3). fracture_energy Gf (mode I,
    J/m^2) and fracture_energy_shear (mode II, defaults to Gf) are the energies one unit area
    dissipates from intact to failed. softening: the constants (a, b, c) of z(D). friction: the
    Coulomb coefficient between the faces once failed. penalty_factor: p_n = factor E / h.
    insertion: "intrinsic" (every internal face carries the law from the start, the paper's
    FDEM) or "extrinsic" (a face is inserted when its traction reaches the strength).
    """

    tensile_strength: Positive
    """Pa, ft: the peak in tension"""
    cohesion: Positive
    """Pa, c: the shear peak f_s = c - sigma_n tan(phi)"""
    friction_angle: Annotated[float, Field(ge=0, lt=90)]
    """degrees, phi"""
    fracture_energy: Positive
    """J/m^2, Gf (mode I): dissipated by a unit area from intact to failed"""
    fracture_energy_shear: Positive | None = None
    """J/m^2, mode II; default Gf"""
    softening: tuple[Positive, Positive, Positive] = DEFAULT_SOFTENING
    """the constants (a, b, c) of the softening curve z(D) (paper 001, eq. 7)"""
    friction: NonNegative = 0.6
    """Coulomb coefficient between the faces once failed"""
    penalty_factor: Positive | None = None
    """interface penalty p_n = factor E / h (h: the smaller tet altitude onto the face); default 200
    intrinsic, 2 extrinsic"""
    insertion: Literal["intrinsic", "extrinsic"] = "intrinsic"
    """"intrinsic": every internal face carries the law from the start; "extrinsic": a face is
    inserted (at the peak of the law) when the traction of its two tets reaches the strength"""
    insertion_stress: Literal["either", "mean"] = "either"
    """extrinsic: the stress a tied face is checked with: "either" (the traction of each of its two tets; the face
    opens when the more critical reaches the strength, as an intrinsic face's corners feel the more loaded side)
    or "mean" (the traction of the two tets' mean stress, which smooths a concentration under a platen away:
    docs/validation.md, "Strength objectivity")"""
    mixed_mode: Literal["effective", "paper"] = "effective"
    """how tension and shear combine on an opening face: "effective" (the default; Camacho-Ortiz: in tension
    the tractions stay within the ellipse (tn / ft)^2 + (ts / (shear_ratio ft))^2 <= z(D)^2, the damage follows
    the effective opening sqrt(dn^2 + shear_ratio^2 ds^2) alone, and the shear penalty is shear_ratio^2 p_n, so
    a face opens when the magnitude of its traction reaches ft, whatever its orientation) or "paper" (paper
    001's literal law: the normal curve and the Mohr-Coulomb shear cap act apart, so a face inclined to the
    pull opens only when its own normal traction reaches ft; on an unstructured mesh, where a crack zigzags
    over inclined faces, a specimen then reads 1.3-1.9 ft: docs/validation.md, "Strength objectivity")"""
    shear_ratio: Positive = 1.0
    """mixed_mode = "effective": beta, the shear strength of an opening face over ft (1: the face opens when
    the magnitude of its traction reaches ft)"""
    law: Literal["guo-munjiza"] = "guo-munjiza"
    """picks this law (the default)"""

    kind: ClassVar[int] = 0

    @model_validator(mode="after")
    def _no_unit_slip(self):
        check_unit_slips(self)
        return self
    # What [material.random] may draw per face: the property and its column of the law row.
    RANDOM: ClassVar[dict[str, int]] = {"tensile_strength": LAW_FT, "cohesion": LAW_C, "fracture_energy": LAW_GF1,
                                        "fracture_energy_shear": LAW_GF2}

    def drawn_rows_problem(self, rows: np.ndarray, pn: np.ndarray, ps: np.ndarray) -> str | None:
        """Why faces with drawn strengths and energies (their law rows) cannot be run, or None: any
        positive values soften (the critical opening follows Gf / ft)."""
        return None

    @property
    def gf_shear(self) -> float:
        return self.fracture_energy if self.fracture_energy_shear is None else self.fracture_energy_shear

    @property
    def penalty(self) -> float:
        """The penalty factor in use (the default depends on the insertion)."""
        if self.penalty_factor is not None:
            return self.penalty_factor
        return EXTRINSIC_PENALTY_FACTOR if self.insertion == "extrinsic" else DEFAULT_PENALTY_FACTOR

    @property
    def softening_area(self) -> float:
        return softening_integral(*self.softening)

    def table_row(self) -> np.ndarray:
        row = new_row(self.kind, self.tensile_strength, self.friction, self.insertion, self.insertion_stress)
        row[LAW_C] = self.cohesion
        row[LAW_TANPHI] = np.tan(np.radians(self.friction_angle))
        row[LAW_GF1] = self.fracture_energy
        row[LAW_GF2] = self.gf_shear
        row[LAW_A], row[LAW_B], row[LAW_CS] = self.softening
        row[LAW_IZ] = self.softening_area
        # 0: Mohr-Coulomb with tension cut-off; > 0: the effective mixed mode's beta.
        row[LAW_BETA] = self.shear_ratio if self.mixed_mode == "effective" else 0.0
        return row

    @property
    def opens_on_normal_traction(self) -> str | None:
        """The setting that makes a face inclined to a pull open on its own normal traction alone
        (paper 001's literal law: the face-orientation bias of an unstructured mesh), or None."""
        return 'mixed_mode = "paper"' if self.mixed_mode == "paper" else None

    def stiffness(self, youngs_modulus, shear_modulus, altitude):
        """Interface penalties (p_n, p_s) in N/m^3 for the given moduli and tet altitude: p_s from G, or
        with the effective mixed mode beta^2 p_n (Camacho and Ortiz's, which makes the traction
        ellipse and the effective opening agree: a face's elastic tractions reach the ellipse as its
        effective opening reaches the peak's)."""
        pn = self.penalty * youngs_modulus / altitude
        if self.mixed_mode == "effective":
            return pn, self.shear_ratio**2 * pn
        return pn, self.penalty * shear_modulus / altitude


def softening_z(damage: float, a: float, b: float, c: float) -> float:
    """Remaining fraction of strength at damage D in [0, 1] (paper 001, eq. 7)."""
    d = min(max(damage, 0.0), 1.0)
    decay = 1.0 - (a + b - 1.0) / (a + b) * math.exp(d * (a + c * b) / ((a + b) * (1.0 - a - b)))
    return decay * (a * (1.0 - d) + b * (1.0 - d) ** c)


def softening_integral(a: float, b: float, c: float, n: int = 2000) -> float:
    """Integral of z(D) over D in [0, 1] (Simpson); 0.3863 for the default constants.

    The paper approximates it by 1/3 to get d_c = 3 Gf / f (eq. 5); we use the exact value so
    that a full separation dissipates exactly Gf.
    """
    h = 1.0 / n
    s = softening_z(0.0, a, b, c) + softening_z(1.0, a, b, c)
    for i in range(1, n):
        s += (4 if i % 2 else 2) * softening_z(i * h, a, b, c)
    return s * h / 3.0


# ---------------------------------------------------------------------------------------------
# Compiled pieces.


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
# An extrinsic face is inserted at the peak: nothing of Gf before the softening in tension, the
# plateau at the cap (dsp / 2 long) in shear.
PRE_PEAK_NORMAL_EXTRINSIC = 0.0
PRE_PEAK_SHEAR_EXTRINSIC = 1.0 / 2.0


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
def shear_cap(sigma, z, law):
    """The shear cap of a point at normal stress sigma and softening z: z f_s(sigma) (Mohr-Coulomb
    with tension cut-off); with the effective mixed mode (law[LAW_BETA] = beta > 0), in tension
    also within the ellipse (sigma / (z ft))^2 + (tau / (beta z ft))^2 <= 1."""
    cap = z * shear_strength(sigma, law)
    beta = law[LAW_BETA]
    if beta > 0.0 and sigma > 0.0:
        room = (z * law[LAW_FT]) ** 2 - sigma * sigma
        ellipse = beta * math.sqrt(room) if room > 0.0 else 0.0
        if ellipse < cap:
            cap = ellipse
    return cap


@njit(cache=True, inline="always")
def normal_stress(dn, pn, z, law):
    """Normal stress (tension positive) at opening dn for penalty pn and softening factor z."""
    if dn < 0.0:
        return pn * dn
    dnp = 2.0 * law[LAW_FT] / pn
    return z * peak_curve(dn, law[LAW_FT], dnp)


@njit(cache=True, inline="always")
def _opening_energy(dn, ft, dnp):
    """Phi_n(dn): the undamaged normal free energy per unit area at opening dn (none in
    compression, which is the separate penalty)."""
    return peak_curve_energy(dn, ft, dnp) if dn > 0.0 else 0.0


@njit(cache=True, inline="always")
def _normal_potential(x, na, nb, i, area, law, pn, nx, ny, nz, dn_shift):
    """Sum over the 3 points of A/3 * Phi_n(dn), the undamaged normal free energy in opening;
    the cohesive energy in opening is z(D) times it."""
    ft = law[LAW_FT]
    dnp = 2.0 * ft / pn
    total = 0.0
    for p in range(3):
        dn, sx, sy, sz = opening(x, na, nb, i, p, nx, ny, nz)
        total += _opening_energy(dn + dn_shift, ft, dnp)
    return total * area / 3.0


@njit(cache=True, inline="always")
def _cohesive_shear_trial(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps):
    """Elastic shear traction ps (s - s_p) of point p of intact interface i: slip s beyond its
    plastic slip s_p, which is kept in the global frame and projected on the current tangent plane
    (it only grows on a damaging interface, whose rotation before failure is small)."""
    px = slip_plastic[i, p, 0]
    py = slip_plastic[i, p, 1]
    pz = slip_plastic[i, p, 2]
    pdn = px * nx + py * ny + pz * nz
    return ps * (sx - px + pdn * nx), ps * (sy - py + pdn * ny), ps * (sz - pz + pdn * nz)


@njit(cache=True, inline="always")
def _return_to_cap(slip_plastic, i, p, sx, sy, sz, ps, tx, ty, tz, cap, hx, hy, hz):
    """The trial shear traction t of point p of intact interface i (the spring ps on s - s_p, from
    its total slip s), which exceeds the cap z(D) f_s(sigma_n), returned onto it (the excess becomes
    plastic slip dp), and the energy the return dissipates per unit area. Written from the total
    slip, it needs no stored traction: while the interface sticks, the shear costs one read of s_p
    (and the caller skips this).

    The audit measures the spring at the half step x - v dt / 2, so the dissipation that closes it
    to second order is t dp + ps |dp|^2 / 2 - ps dp . h, h the slip over the half step before x
    (h = (hx, hy, hz) = dt / 2 (v_B - v_A)): (t_trial^2 - cap^2) / 2 ps - (t_trial - cap) h . t_hat.
    A pure cap drop releases (t_trial^2 - cap^2) / 2 ps; steady sliding dissipates cap |dp|."""
    t_trial = math.sqrt(tx * tx + ty * ty + tz * tz)
    along = (hx * tx + hy * ty + hz * tz) / t_trial
    lost = (t_trial - cap) * ((t_trial + cap) / (2.0 * ps) - along)
    scale = cap / t_trial
    tx *= scale
    ty *= scale
    tz *= scale
    slip_plastic[i, p, 0] = sx - tx / ps
    slip_plastic[i, p, 1] = sy - ty / ps
    slip_plastic[i, p, 2] = sz - tz / ps
    return tx, ty, tz, lost


@njit(cache=True, inline="always")
def _slip_curve(fs, ps, law, extrinsic):
    """The Mohr-Coulomb slip reading at shear strength fs: the elastic limit dsp, the critical slip
    dsc and the slip at which damage starts (an extrinsic face's spring starts at its elastic
    limit, dsp / 2 of an intrinsic one)."""
    dsp = 2.0 * fs / ps
    dsc = critical_opening(fs, dsp, law[LAW_GF2], law[LAW_IZ], PRE_PEAK_SHEAR_EXTRINSIC if extrinsic else PRE_PEAK_SHEAR)
    return dsp, dsc, 0.5 * dsp if extrinsic else dsp


@njit(cache=True, inline="always")
def _align_other_reading(reading_offset, i, d, dn_c, ds_c, dnp, dnc, law, ps, extrinsic):
    """The effective mixed mode reads a face's damage from its effective opening while it is open
    and from its slip against Mohr-Coulomb's (its cap 5x higher under paper 001's c = 5 ft, its
    critical slip shorter) while it is closed. Both read the total slip, so a face that slid open
    and then closed would read a damage it never went through (a face at 0.5 failed at once).
    So the reading the face is not in gets the slip it would read beyond d, if any, as an offset
    (the open one at dn = 0, the closed one at sigma = 0): if the face switches it goes on from d.
    A face with less slip than that keeps its reading (slip it has not made is not counted: with
    the offset negative, a face damaged by opening alone failed in shear as soon as it closed,
    and the quick disc shattered into 224 pieces)."""
    if dn_c > 0.0:
        dsp, dsc, start = _slip_curve(law[LAW_C], ps, law, extrinsic)
        reading_offset[i, CLOSED_READING] = max(0.0, ds_c - (start + d * (dsc - dsp)))
    else:
        reading_offset[i, OPEN_READING] = max(0.0, ds_c - (dnp + d * (dnc - dnp)) / law[LAW_BETA])


@njit(cache=True, inline="always")
def intact_step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
                law, pn, ps, nx, ny, nz, dn_shift, reading_offset):
    """One step of intact interface i with paper 001's Mohr-Coulomb mixed mode (_step)."""
    return _step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
                 law, pn, ps, nx, ny, nz, dn_shift, reading_offset, False)


@njit(cache=True, inline="always")
def intact_step_effective(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic,
                          e_damage, law, pn, ps, nx, ny, nz, dn_shift, reading_offset):
    """One step of intact interface i with the effective mixed mode (_step)."""
    return _step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
                 law, pn, ps, nx, ny, nz, dn_shift, reading_offset, True)


@njit(cache=True, inline="always")
def _step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
          law, pn, ps, nx, ny, nz, dn_shift, reading_offset, effective):
    """One step of intact interface i: damage from the centroid opening and slip (eq. 8,
    irreversible), the point tractions into force[i] (B side; A gets their negatives), the energy
    the step dissipates into e_damage[i]. Always True: a face that fails this step still carries
    its compression and releases its shear spring here. dn_shift: the normal opening the law sees
    at zero gap (0, or an extrinsic face's shift at insertion)."""
    a3 = area / 3.0
    # The three point openings, read once (the stores below may alias x for the compiler, so it
    # would reload them).
    dn0, s0x, s0y, s0z = opening(x, na, nb, i, 0, nx, ny, nz)
    dn1, s1x, s1y, s1z = opening(x, na, nb, i, 1, nx, ny, nz)
    dn2, s2x, s2y, s2z = opening(x, na, nb, i, 2, nx, ny, nz)
    dn0 += dn_shift
    dn1 += dn_shift
    dn2 += dn_shift
    dn_c = (dn0 + dn1 + dn2) / 3.0
    sx_c = (s0x + s1x + s2x) / 3.0
    sy_c = (s0y + s1y + s2y) / 3.0
    sz_c = (s0z + s1z + s2z) / 3.0
    ds_c = math.sqrt(sx_c * sx_c + sy_c * sy_c + sz_c * sz_c)
    a, b, c = law[LAW_A], law[LAW_B], law[LAW_CS]
    d_old = damage[i]
    z_old = softening(d_old, a, b, c)
    ft = law[LAW_FT]
    dnp = 2.0 * ft / pn
    extrinsic = law[LAW_EXTRINSIC] != 0.0
    dnc = critical_opening(ft, dnp, law[LAW_GF1], law[LAW_IZ], PRE_PEAK_NORMAL_EXTRINSIC if extrinsic else PRE_PEAK_NORMAL)
    dsp, dsc, ds_start = _slip_curve(shear_strength(normal_stress(dn_c, pn, z_old, law), law), ps, law, extrinsic)
    # The opening that damages the normal branch: the centroid's normal opening, or with the
    # effective mixed mode and the face open, sqrt(dn^2 + beta^2 ds^2), which then also stands
    # for the slip: the Mohr-Coulomb branch's own slip damage would count it twice (a face opened
    # at 45 deg failed at 0.2 Gf).
    # `effective` is a constant of each caller: the compiler drops the other mode's branches.
    # There the two readings see the slip from their own offset (reading_offset[i]: 0 until the
    # face is damaged, so an intact face does not read it: the stream cost the intrinsic step
    # ~13 %), so that a face that closes or opens carries on from its damage.
    dn_damage = dn_c
    ds_damage = ds_c
    if effective:
        if dn_c > 0.0:
            slip = ds_c
            if d_old > 0.0:
                slip -= reading_offset[i, OPEN_READING]
                if slip < 0.0:
                    slip = 0.0
            beta = law[LAW_BETA]
            dn_damage = math.sqrt(dn_c * dn_c + beta * beta * slip * slip)
            ds_damage = 0.0
        elif d_old > 0.0:
            ds_damage = ds_c - reading_offset[i, CLOSED_READING]
    d_n = (dn_damage - dnp) / (dnc - dnp) if dn_damage > dnp else 0.0
    d_s = (ds_damage - ds_start) / (dsc - dsp) if ds_damage > ds_start else 0.0
    d_new = math.sqrt(d_n * d_n + d_s * d_s)
    if d_new > 1.0:
        d_new = 1.0
    if effective and (d_new > 0.0 or d_old > 0.0):
        _align_other_reading(reading_offset, i, max(d_new, d_old), dn_c, ds_c, dnp, dnc, law, ps, extrinsic)
    z = z_old
    if d_new > d_old:
        z = softening(d_new, a, b, c)
        damage[i] = d_new
        # Energy released by the damage step, booked at the half step x - v dt / 2 where the
        # audit measures the stored energy, so that it closes to second order in dt (at x itself
        # it books dz times half a step's opening work too much). The shear spring releases its
        # part through the cap, below.
        h = 0.5 * dt
        e_damage[i] += (z_old - z) * a3 * (
            _opening_energy(opening_earlier(dn0, h, v, na[i, 0], nb[i, 0], nx, ny, nz), ft, dnp)
            + _opening_energy(opening_earlier(dn1, h, v, na[i, 1], nb[i, 1], nx, ny, nz), ft, dnp)
            + _opening_energy(opening_earlier(dn2, h, v, na[i, 2], nb[i, 2], nx, ny, nz), ft, dnp)
        )
        if d_new >= 1.0:
            state[i] = FAILED
            fail_time[i] = t
            fail_mode[i] = failure_mode(d_s * d_s / (d_n * d_n + d_s * d_s))
    # Shear: the spring capped at z(D) f_s(sigma_n); the cap dissipates (at failure z = 0 releases
    # what the spring still holds).
    lost = 0.0
    for p, dn, sx, sy, sz in ((0, dn0, s0x, s0y, s0z), (1, dn1, s1x, s1y, s1z), (2, dn2, s2x, s2y, s2z)):
        sigma = normal_stress(dn, pn, z, law)
        cap = shear_cap(sigma, z, law) if effective else z * shear_strength(sigma, law)
        tx, ty, tz = _cohesive_shear_trial(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps)
        released = 0.0
        if tx * tx + ty * ty + tz * tz > cap * cap:
            # The velocities are read only where the spring reaches the cap (so that the reads
            # stay off the sticking faces' path: ~14 % of the intrinsic step).
            a = na[i, p]
            b = nb[i, p]
            h = 0.5 * dt
            tx, ty, tz, released = _return_to_cap(slip_plastic, i, p, sx, sy, sz, ps, tx, ty, tz, cap,
                                                  h * (v[b, 0] - v[a, 0]), h * (v[b, 1] - v[a, 1]),
                                                  h * (v[b, 2] - v[a, 2]))
        lost += released
        force[i, p, 0] = -(sigma * nx + tx) * a3
        force[i, p, 1] = -(sigma * ny + ty) * a3
        force[i, p, 2] = -(sigma * nz + tz) * a3
    e_damage[i] += lost * a3
    return True


@njit(cache=True, inline="always")
def intact_energy(i, x, na, nb, area, damage, slip_plastic, law, pn, ps, nx, ny, nz, dn_shift):
    """Energy stored in intact interface i: compression penalty, shear springs and z(D) times the
    undamaged normal energy in opening."""
    a3 = area / 3.0
    z = softening(damage[i], law[LAW_A], law[LAW_B], law[LAW_CS])
    springs = 0.0
    for p in range(3):
        dn, sx, sy, sz = opening(x, na, nb, i, p, nx, ny, nz)
        dn += dn_shift
        if dn < 0.0:
            springs += 0.5 * pn * dn * dn * a3
        tx, ty, tz = _cohesive_shear_trial(slip_plastic, i, p, sx, sy, sz, nx, ny, nz, ps)
        springs += 0.5 * (tx * tx + ty * ty + tz * tz) / ps * a3
    return springs + z * _normal_potential(x, na, nb, i, area, law, pn, nx, ny, nz, dn_shift)


# -- extrinsic insertion (fdem.extrinsic calls these through the law registry) ------------------
@njit(cache=True, inline="always")
def insertion_reached(tn, ts2, law):
    """Whether a tied face's traction (normal tn, tension positive; squared shear ts2) opens it:
    Mohr-Coulomb with tension cut-off; with the effective mixed mode, the ellipse in tension. No
    square root or division: every tied face makes this check every step."""
    ft = law[LAW_FT]
    fs = shear_strength(tn, law)
    if ts2 >= fs * fs:
        return True
    beta = law[LAW_BETA]
    if beta > 0.0 and tn > 0.0:
        return tn * tn + ts2 / (beta * beta) >= ft * ft
    return tn >= ft


@njit(cache=True, inline="always")
def insertion_utilisation(tn, ts, law):
    """How far a traction is along insertion_reached's criterion (1 on it)."""
    ft = law[LAW_FT]
    beta = law[LAW_BETA]
    if beta > 0.0 and tn > 0.0:
        return max(math.sqrt(tn * tn + (ts / beta) ** 2) / ft, ts / shear_strength(tn, law))
    return max(tn / ft, ts / shear_strength(tn, law))


@njit(cache=True, inline="always")
def inserted_preload(tn, ts, law, pn, prestressed):
    """The law state that carries a face's traction at zero gap when it is inserted: the opening
    shift and the cap on its shear traction. In tension the opening sits on the pre-peak curve
    ft (2 u - u^2), u = dn / dnp; a compression is no shift (the penalty's from zero gap), except
    in a prestressed model (tn / pn, which its contact keeps once failed)."""
    ft = law[LAW_FT]
    tn_c = min(tn, ft)
    shift = 2.0 * ft / pn * (1.0 - math.sqrt(1.0 - tn_c / ft)) if tn_c > 0.0 else 0.0
    if prestressed and tn_c < 0.0:
        shift = tn_c / pn
    # The cap the law applies at zero gap: without a normal preload in compression, its normal
    # stress there is zero. A preload above it would be returned onto it in the first step as if
    # it had slid, booking less than the spring loses.
    cap = shear_cap(tn_c if prestressed else max(tn_c, 0.0), 1.0, law)
    return shift, cap

"""Bilinear cohesive (traction-separation) law of paper 004, Camanho-Davila mixed mode: its
parameters, its row of the law table, and its forces and stored energy on an intact interface,
side by side. The interface's own stiffnesses kn, ks (N/m^3) are its penalties pn, ps, intact
and (as contact) once failed.

* Tractions tn = (1 - D) kn dn in opening, kn dn in compression (never damaged), shear vector
  ts = (1 - D) ks s: linear to the origin on unloading (secant), a potential at fixed D.
* Initiation: the quadratic nominal stress criterion (kn <dn> / tn0)^2 + (ks |s| / ts0)^2 = 1
  (initiation = "quadratic", the default; Camanho and Davila's, Abaqus's QUADS), or the maximum
  nominal stress max(kn <dn> / tn0, ks |s| / ts0) = 1 (initiation = "maximum", paper 004's
  eq. 3, Abaqus's MAXS). Under the maximum a face inclined at theta to a pull sigma opens only
  when sigma cos^2(theta) reaches tn0, so an unstructured specimen reads above tn0
  (docs/validation.md, "Strength objectivity").
* Effective opening dm = sqrt(<dn>^2 + |s|^2), effective stiffness K = (kn <dn>^2 + ks |s|^2) / dm^2
  (so the undamaged energy is K dm^2 / 2), initiation opening d0 = dm / f at the current mode
  mix (f: the criterion's left side, of degree one in the opening), final opening df = 2 Gc / (K d0), linear softening
  D = df (dm - d0) / (dm (df - d0)), never decreasing; a complete failure at a fixed mix
  dissipates K d0 df / 2 = Gc per unit area.
* Mixed mode from the energy ratio B = ks |s|^2 / (kn <dn>^2 + ks |s|^2) (G_II / G_T):
  Benzeggagh-Kenane Gc = GIc + (GIIc - GIc) B^eta, or the power law
  ((1 - B) Gc / GIc)^alpha + (B Gc / GIIc)^alpha = 1.
* Extrinsic insertion (insertion = "extrinsic"): the face carries nothing until the stress of its
  two tets reaches the initiation criterion; it is then inserted with its opening shifted by
  dn_shift and its slip by slip_offset (fdem.extrinsic) so that its traction goes on from the
  continuum's at initiation; df is set so that the work done on the face from there to its
  complete separation is Gc: K d0 (df - d0) / 2 = Gc.
"""

from __future__ import annotations

import math
from typing import ClassVar, Literal

import numpy as np
from numba import njit
from pydantic import model_validator
from pydantic.dataclasses import dataclass

from ...schema import STRICT_DATACLASS, NonNegative, Positive, check_unit_slips
from ...solver.failures import failure_mode
from ..interface import opening
from ..topology import FAILED
from .row import LAW_EXTRINSIC, LAW_FT, OWN, new_row

# Benzeggagh-Kenane exponent of Camanho & Davila (2002), and the power-law exponent of the
# quadratic (Ye) criterion.
DEFAULT_BK_EXPONENT = 1.45
DEFAULT_POWER_EXPONENT = 2.0
MIX_POWER, MIX_BK = 0, 1

# The law's own columns of its table row: shear strength ts0, GIc, GIIc, mixed-mode rule and its
# exponent.
LAW_TS, LAW_GF1, LAW_GF2, LAW_MIX, LAW_MIX_EXP, LAW_INITIATION = range(OWN, OWN + 6)
INITIATIONS = ("quadratic", "maximum")
INITIATION_QUADRATIC, INITIATION_MAXIMUM = 0, 1


@dataclass(frozen=True, config=STRICT_DATACLASS)
class BilinearLaw:
    """Bilinear cohesive law, paper 004; Camanho-Davila mixed mode.

    tensile_strength tn0 and shear_strength ts0 (Pa) are the nominal strengths (initiation when
    (<tn>/tn0)^2 + (ts/ts0)^2 = 1, or max(<tn>/tn0, ts/ts0) = 1 with initiation = "maximum"; the
    normal traction counted only in tension); fracture_energy GIc
    and fracture_energy_shear GIIc (J/m^2, GIIc defaults to GIc) the energies a unit area
    dissipates from intact to failed in pure mode I and II; normal_stiffness kn and
    shear_stiffness ks (N/m^3: a value in N/mm^3 times 1e9) the initial stiffnesses per unit area,
    also the contact penalties once failed. mixed_mode "bk" (Benzeggagh-Kenane, bk_exponent eta,
    default 1.45) or "power" (power law, power_exponent alpha, default 2) gives Gc at a mode mix.
    friction: Coulomb coefficient once failed.
    """

    tensile_strength: Positive
    """Pa, tn0: initiation when (<tn>/tn0)^2 + (ts/ts0)^2 = 1 (normal traction counted in tension only; see
    initiation)"""
    shear_strength: Positive
    """Pa, ts0"""
    fracture_energy: Positive
    """J/m^2, GIc: dissipated by a unit area from intact to failed in pure mode I"""
    normal_stiffness: Positive
    """N/m^3, kn per unit area (a value in N/mm^3 times 1e9); also the contact penalty once failed. Abaqus's
    traction-separation elasticity (*ELASTIC, TYPE=TRACTION) with its default constitutive thickness of 1 in the
    model's length unit is this same number: E_nn = 636.36 MPa over 1 mm is 636.36 N/mm^3"""
    shear_stiffness: Positive
    """N/m^3, ks per unit area"""
    stiffness_per: Literal["area", "element"] = "area"
    """how kn and ks are read: "area", the same per-area stiffness on every face; "element", the values of a face
    whose tets' smaller altitude is reference_altitude, each face's scaled by reference_altitude / h (h that altitude:
    kn = (kn_ref reference_altitude / E) E / h, the factor x E / h of intrinsic cohesive modelling), so that the
    interfaces hold the same share of the compliance at any mesh"""
    reference_altitude: Positive | None = None
    """m, stiffness_per = "element": the altitude h the given kn and ks belong to (a mesh's median altitude is ~0.7 of
    its element size: 0.69 mm for the walnut at 0.95 mm)"""
    fracture_energy_shear: Positive | None = None
    """J/m^2, GIIc in pure mode II; default GIc"""
    initiation: Literal["quadratic", "maximum"] = "quadratic"
    """when a face starts to soften: "quadratic" ((<tn>/tn0)^2 + (ts/ts0)^2 = 1, Camanho-Davila, Abaqus QUADS) or
    "maximum" (max(<tn>/tn0, ts/ts0) = 1: paper 004's eq. 3, Abaqus MAXS; a face inclined to the pull then opens on
    its normal traction alone, and an unstructured specimen reads above tn0: docs/validation.md, "Strength
    objectivity")"""
    mixed_mode: Literal["bk", "power"] = "bk"
    """Gc at a mode mix: Benzeggagh-Kenane or power law"""
    bk_exponent: Positive | None = None
    """eta of "bk"; default 1.45"""
    power_exponent: Positive | None = None
    """alpha of "power"; default 2"""
    friction: NonNegative = 0.6
    """Coulomb coefficient between the faces once failed"""
    insertion: Literal["intrinsic", "extrinsic"] = "intrinsic"
    """"intrinsic": every internal face carries the law from the start; "extrinsic": a face is
    inserted (at initiation) when the traction of its two tets meets the initiation criterion"""
    insertion_stress: Literal["either", "mean"] = "either"
    """extrinsic: the stress a tied face is checked with: "either" (the traction of each of its two tets; the face
    opens when the more critical reaches the strength, as an intrinsic face's corners feel the more loaded side)
    or "mean" (the traction of the two tets' mean stress, which smooths a concentration under a platen away:
    docs/validation.md, "Strength objectivity")"""
    law: Literal["bilinear"] = "bilinear"
    """picks this law"""

    kind: ClassVar[int] = 1
    # What [material.random] may draw per face: the property and its column of the law row.
    RANDOM: ClassVar[dict[str, int]] = {"tensile_strength": LAW_FT, "shear_strength": LAW_TS,
                                        "fracture_energy": LAW_GF1, "fracture_energy_shear": LAW_GF2}

    @model_validator(mode="after")
    def _consistent(self):
        check_unit_slips(self)
        if (self.stiffness_per == "element") != (self.reference_altitude is not None):
            raise ValueError('stiffness_per = "element" and reference_altitude go together: give the element size (m) '
                             'the stiffnesses belong to, or leave both out for stiffnesses per area')
        if self.mixed_mode == "bk" and self.power_exponent is not None:
            raise ValueError('power_exponent is for mixed_mode = "power" (this law uses "bk": set bk_exponent)')
        if self.mixed_mode == "power" and self.bk_exponent is not None:
            raise ValueError('bk_exponent is for mixed_mode = "bk" (this law uses "power": set power_exponent)')
        # An extrinsic face starts softening at initiation: it cannot snap back.
        problem = snap_back(self) if self.insertion == "intrinsic" else None
        if problem:
            raise ValueError(problem)
        return self

    @property
    def gf_shear(self) -> float:
        return self.fracture_energy if self.fracture_energy_shear is None else self.fracture_energy_shear

    def drawn_rows_problem(self, rows: np.ndarray, kn: np.ndarray, ks: np.ndarray) -> str | None:
        """Why faces with drawn strengths and energies (their law rows) would snap back, or None."""
        if self.insertion != "intrinsic":
            return None
        for g, t0, k, what in ((rows[:, LAW_GF1], rows[:, LAW_FT], kn, "mode I"), (rows[:, LAW_GF2], rows[:, LAW_TS], ks, "mode II")):
            snaps = g <= t0 * t0 / (2.0 * k)
            if snaps.any():
                return (f"{int(snaps.sum()):,} of {len(rows):,} faces drew a {what} strength and fracture energy whose "
                        "softening snaps back (Gc <= t0^2 / 2k): lower the strength's spread or raise the fracture "
                        "energy or the interface stiffness")
        return None

    @property
    def mixed_mode_exponent(self) -> float:
        if self.mixed_mode == "bk":
            return DEFAULT_BK_EXPONENT if self.bk_exponent is None else self.bk_exponent
        return DEFAULT_POWER_EXPONENT if self.power_exponent is None else self.power_exponent

    def table_row(self) -> np.ndarray:
        row = new_row(self.kind, self.tensile_strength, self.friction, self.insertion, self.insertion_stress)
        row[LAW_TS] = self.shear_strength
        row[LAW_GF1] = self.fracture_energy
        row[LAW_GF2] = self.gf_shear
        row[LAW_MIX] = MIX_BK if self.mixed_mode == "bk" else MIX_POWER
        row[LAW_MIX_EXP] = self.mixed_mode_exponent
        row[LAW_INITIATION] = INITIATIONS.index(self.initiation)
        return row

    @property
    def opens_on_normal_traction(self) -> str | None:
        """The setting that makes a face inclined to a pull open on its own normal traction alone
        (the maximum criterion: the face-orientation bias of an unstructured mesh), or None."""
        return 'initiation = "maximum"' if self.initiation == "maximum" else None

    def stiffness(self, youngs_modulus, shear_modulus, altitude):
        """(kn, ks) for every interface: per area, whatever the bulk and the mesh, or scaled by
        reference_altitude / altitude (stiffness_per = "element")."""
        altitude = np.asarray(altitude, dtype=float)
        if self.stiffness_per == "area":
            scale = np.ones_like(altitude)
        else:
            # The altitude the stiffnesses belong to is the mesh's scale: a hundred times off, a length in mm.
            median = float(np.median(altitude)) if altitude.size else self.reference_altitude
            if not 0.01 <= self.reference_altitude / median <= 100.0:
                raise ValueError(f"reference_altitude = {self.reference_altitude:g} m against the mesh's median tet "
                                 f"altitude {median:.3g} m: a length in mm? (write {self.reference_altitude:g}e-3)")
            scale = self.reference_altitude / altitude
        return self.normal_stiffness * scale, self.shear_stiffness * scale


def snap_back(law) -> str | None:
    """Why the law's softening would snap back (Gc below the elastic energy t0^2 / 2k at the
    peak, so df < d0) in pure mode I or II, or None."""
    for g, g_name, t0, t_name, k, k_name in (
        (law.fracture_energy, "fracture_energy", law.tensile_strength, "tensile_strength", law.normal_stiffness, "normal_stiffness"),
        (law.gf_shear, "fracture_energy_shear", law.shear_strength, "shear_strength", law.shear_stiffness, "shear_stiffness"),
    ):
        peak = t0 * t0 / (2.0 * k)
        if g <= peak:
            return (
                f"{g_name} = {g:g} J/m^2 is not above the elastic energy at the peak, "
                f"{t_name}^2 / (2 {k_name}) = {peak:g} J/m^2: the softening would snap back; "
                f"raise {g_name} or {k_name}, or lower {t_name}"
            )
    return None


# ---------------------------------------------------------------------------------------------
# Compiled pieces.


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
def initiation_index(tn, ts, law):
    """The initiation criterion's left side for the normal traction tn (tension, >= 0) and the
    shear traction magnitude ts: 1 on the criterion, of degree one in the traction."""
    f_n = tn / law[LAW_FT]
    f_s = ts / law[LAW_TS]
    if law[LAW_INITIATION] == INITIATION_MAXIMUM:
        return f_n if f_n > f_s else f_s
    return math.sqrt(f_n * f_n + f_s * f_s)


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
    f = initiation_index(kn * dnp, ks * ds, law)
    if f <= 1.0:
        return 0.0, b
    dm = math.sqrt(dnp * dnp + ds * ds)
    k = e / (dm * dm)
    d0 = dm / f
    df = 2.0 * mixed_mode_energy(b, law) / (k * d0)
    if law[LAW_EXTRINSIC] != 0.0:
        df += d0  # inserted at initiation: the softening alone holds Gc
    # Set-up refuses pure-mode snap-back (Gc <= t0^2 / 2k); keep a mixed mode finite anyway.
    if df < d0 * (1.0 + 1e-9):
        df = d0 * (1.0 + 1e-9)
    if dm >= df:
        return 1.0, b
    return df * (dm - d0) / (dm * (df - d0)), b


@njit(cache=True, inline="always")
def _point(x, na, nb, i, p, nx, ny, nz, slip_offset, dn_shift):
    """Opening and slip of point p of intact interface i as the law counts them: the gap's, plus
    dn_shift and less the slip offset (both 0 but on an inserted extrinsic face); the offset is
    kept in the global frame and projected on the current tangent plane."""
    dn, sx, sy, sz = opening(x, na, nb, i, p, nx, ny, nz)
    ox = slip_offset[i, p, 0]
    oy = slip_offset[i, p, 1]
    oz = slip_offset[i, p, 2]
    on = ox * nx + oy * ny + oz * nz
    return dn + dn_shift, sx - ox + on * nx, sy - oy + on * ny, sz - oz + on * nz


@njit(cache=True, inline="always")
def _potential(x, na, nb, i, area, kn, ks, nx, ny, nz, slip_offset, dn_shift):
    """Sum over the 3 points of A/3 * (kn <dn>^2 + ks |s|^2) / 2: the undamaged energy in opening
    and shear; the cohesive energy there is (1 - D) times it."""
    total = 0.0
    for p in range(3):
        dn, sx, sy, sz = _point(x, na, nb, i, p, nx, ny, nz, slip_offset, dn_shift)
        if dn > 0.0:
            total += kn * dn * dn
        total += ks * (sx * sx + sy * sy + sz * sz)
    return 0.5 * total * area / 3.0


@njit(cache=True, inline="always")
def _potential_mid(x, v, dt, na, nb, i, area, kn, ks, nx, ny, nz, slip_offset, dn_shift):
    """_potential at the half step x - v dt / 2 (v: the velocities of the step that led to x): the
    energy a damage step releases, booked there so that the audit of the explicit scheme closes
    to second order in dt (at x itself it drifts by dD x half a step's work)."""
    total = 0.0
    h = 0.5 * dt
    for p in range(3):
        a = na[i, p]
        b = nb[i, p]
        dx = x[b, 0] - x[a, 0] - h * (v[b, 0] - v[a, 0]) - slip_offset[i, p, 0]
        dy = x[b, 1] - x[a, 1] - h * (v[b, 1] - v[a, 1]) - slip_offset[i, p, 1]
        dz = x[b, 2] - x[a, 2] - h * (v[b, 2] - v[a, 2]) - slip_offset[i, p, 2]
        dn = dx * nx + dy * ny + dz * nz
        sx = dx - dn * nx
        sy = dy - dn * ny
        sz = dz - dn * nz
        dn += dn_shift
        if dn > 0.0:
            total += kn * dn * dn
        total += ks * (sx * sx + sy * sy + sz * sz)
    return 0.5 * total * area / 3.0


@njit(cache=True, inline="always")
def intact_step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_offset, e_damage,
                law, kn, ks, nx, ny, nz, dn_shift):
    """One step of intact interface i: damage from the centroid's effective opening
    (irreversible), then the point tractions (1 - D) kn dn (kn dn in compression) and
    (1 - D) ks s into force[i]. Returns False once the interface has failed (D = 1): the caller
    then treats it as a failed pair in the same step. slip_offset and dn_shift: what the law adds
    to the gap (non-zero on an inserted extrinsic face only)."""
    a3 = area / 3.0
    dn0, s0x, s0y, s0z = _point(x, na, nb, i, 0, nx, ny, nz, slip_offset, dn_shift)
    dn1, s1x, s1y, s1z = _point(x, na, nb, i, 1, nx, ny, nz, slip_offset, dn_shift)
    dn2, s2x, s2y, s2z = _point(x, na, nb, i, 2, nx, ny, nz, slip_offset, dn_shift)
    # The centroid's opening and slip magnitude (the mean of the 3 points) set the damage.
    dn_c = dn0 / 3.0 + dn1 / 3.0 + dn2 / 3.0
    sx_c = s0x / 3.0 + s1x / 3.0 + s2x / 3.0
    sy_c = s0y / 3.0 + s1y / 3.0 + s2y / 3.0
    sz_c = s0z / 3.0 + s1z / 3.0 + s2z / 3.0
    ds_c = math.sqrt(sx_c * sx_c + sy_c * sy_c + sz_c * sz_c)
    d_old = damage[i]
    d_new, mix = bilinear_damage(dn_c, ds_c, kn, ks, law)
    d = d_old
    if d_new > d_old:
        d = d_new
        damage[i] = d
        # The stored energy the damage step releases (at the half step: see the function).
        e_damage[i] += (d - d_old) * _potential_mid(x, v, dt, na, nb, i, area, kn, ks, nx, ny, nz, slip_offset, dn_shift)
        if d >= 1.0:
            state[i] = FAILED
            fail_time[i] = t
            fail_mode[i] = failure_mode(mix)  # the energy ratio G_II / G_T
            return False  # its friction traction starts at zero: intact pairs never write it
    s = 1.0 - d
    for p, dn, sx, sy, sz in ((0, dn0, s0x, s0y, s0z), (1, dn1, s1x, s1y, s1z), (2, dn2, s2x, s2y, s2z)):
        sigma = kn * dn if dn < 0.0 else s * kn * dn
        tx = s * ks * sx
        ty = s * ks * sy
        tz = s * ks * sz
        force[i, p, 0] = -(sigma * nx + tx) * a3
        force[i, p, 1] = -(sigma * ny + ty) * a3
        force[i, p, 2] = -(sigma * nz + tz) * a3
    return True


@njit(cache=True, inline="always")
def intact_energy(i, x, na, nb, area, damage, slip_offset, law, kn, ks, nx, ny, nz, dn_shift):
    """Energy stored in intact interface i: the compression penalty and (1 - D) times the
    undamaged energy in opening and shear."""
    a3 = area / 3.0
    comp = 0.0
    for p in range(3):
        dn, sx, sy, sz = _point(x, na, nb, i, p, nx, ny, nz, slip_offset, dn_shift)
        if dn < 0.0:
            comp += 0.5 * kn * dn * dn * a3
    return comp + (1.0 - damage[i]) * _potential(x, na, nb, i, area, kn, ks, nx, ny, nz, slip_offset, dn_shift)


# -- extrinsic insertion (fdem.extrinsic calls these through the law registry) ------------------
@njit(cache=True, inline="always")
def insertion_reached(tn, ts2, law):
    """Whether a tied face's traction (normal tn, tension positive; squared shear ts2) meets the
    initiation criterion (quadratic or maximum nominal stress). No square root or division: every
    tied face makes this check every step."""
    ft = law[LAW_FT]
    ts0 = law[LAW_TS]
    if law[LAW_INITIATION] == INITIATION_MAXIMUM:
        return tn >= ft or ts2 >= ts0 * ts0
    tn_plus = tn if tn > 0.0 else 0.0
    return tn_plus * tn_plus * (ts0 * ts0) + ts2 * (ft * ft) >= (ft * ts0) ** 2


@njit(cache=True, inline="always")
def insertion_utilisation(tn, ts, law):
    """How far a traction is along the initiation criterion (1 on it)."""
    return initiation_index(max(tn, 0.0), ts, law)


@njit(cache=True, inline="always")
def inserted_preload(tn, ts, law, pn, prestressed):
    """The law state that carries a face's traction at zero gap when it is inserted: the opening
    shift (kn dn = tn, capped at ft) and the cap on its shear traction. The maximum criterion
    clamps each component on its own strength; the quadratic one brings the traction back onto
    the criterion along its own direction. A compression is no shift (the penalty's from zero
    gap), except in a prestressed model."""
    ft = law[LAW_FT]
    if law[LAW_INITIATION] == INITIATION_MAXIMUM:
        return (min(tn, ft) / pn if tn > 0.0 or prestressed else 0.0), law[LAW_TS]
    over = initiation_index(max(tn, 0.0), ts, law)
    back = 1.0 / over if over > 1.0 else 1.0
    return (back * tn / pn if tn > 0.0 else (tn / pn if prestressed else 0.0)), back * ts

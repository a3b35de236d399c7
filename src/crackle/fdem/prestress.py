"""Initial stress of an FDEM model ([initial_stress]): each tet's stress at t = 0 and the law
state of the intact interfaces that carries it.

A tet with initial stress S0 (its value at the tet's centroid, Tets.s0) has the second
Piola-Kirchhoff stress S = C:E + S0 (kernels._tet_forces): at E = 0 it carries S0 and pushes its
own nodes with it. In the exploded mesh those nodes are held by the interfaces only, so an intact
interface must carry the traction S0 . n at zero gap, or the mesh flies apart. Each intact face
gets it as an initial opening, the gap the law would need to carry that traction: the normal
opening shifted by dn_shift (the Guo-Munjiza pre-peak curve inverted in tension, the penalty in
compression; the bilinear law's kn) and the shear spring preloaded through slip_plastic (the
bilinear law's slip offset), as an extrinsic face is at its insertion (fdem.extrinsic.try_insert).
Chosen over an explicit traction term added to the law's forces because the law then sees the
prestressed state itself: a face under initial tension is that much nearer its strength, a face
under compression has the Mohr-Coulomb cap of its normal stress, and the stored energy of the
offsets (t^2 / 2p per unit area) is the interface's initial energy, with no new array in the step.

What the offsets do not carry (limits):
- The traction is one per face, from the mean of its two tets' initial stresses (they differ
  where the stress grows with depth: the interface is then in equilibrium with the mean, and the
  difference, of order density g h, is what the tets' weight balances; a run relaxes by strains of
  order density g h / E there).
- Guo-Munjiza's damage reads the slip itself, not the preloaded spring: a face preloaded in shear
  reaches its cap (and slides plastically) earlier by the preload, but its damage starts after the
  same slip as without it: the plateau at the cap is longer by t0 / p_s (an energy below the
  pre-peak one, t0 dsp / 2, against Gf).
- The shear preload is kept in the global frame, as the plastic slip is: a block that turns far
  (tens of degrees) does not turn its interfaces' shear preload with it (the tets' S0 does turn).
- Faces that fail keep the compressive part of their shift as their contact's reference
  (kernels._interface_block, Interfaces.prestressed): a face failing in shear under confinement
  goes on pressing with the initial compression instead of dropping it. Pre-cracked faces start
  with that shift and their Coulomb springs carrying the initial shear up to mu |t_n| (beyond it
  they slide from the first step); a tensile traction across a pre-crack opens it.
- The stable step leaves out the initial stress's geometric stiffness (|S0| / E, ~1e-3 for rock
  at depth, against the safety factor's 30 %).
- Extrinsic faces start tied: the tied tets carry S0 as one continuum (no traction needed), and a
  face inserted later starts at the traction of its tets' stress, which includes S0
  (try_insert reads the stress _tet_forces keeps, S0 included), compression included in a
  prestressed model (try_insert's `prestressed`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .laws import KIND_BILINEAR, LAW_FT, LAW_KIND, LAW_MU
from .laws.bilinear import initiation_index
from .laws.guo_munjiza import LAW_BETA, shear_cap, shear_strength
from ..scenario import stress_matrices


@njit(cache=True)
def _preload(normal, s0a, s0b, law_of, law_table, pn, ps, chosen, dn_shift, slip_plastic, utilisation):
    """For each chosen face i (normal[i]: from side A to side B; s0a, s0b: its two tets' initial
    stresses in STRESS_ORDER): the traction of their mean stress, the opening shift and shear
    preload that carry it at zero gap (dn_shift[i], slip_plastic[i, p] for its 3 points), and how
    far it is along the face's strength (utilisation[i]: >= 1 where the face would fail at t = 0)."""
    for i in range(normal.shape[0]):
        if not chosen[i]:
            continue
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        sxx = 0.5 * (s0a[i, 0] + s0b[i, 0])
        syy = 0.5 * (s0a[i, 1] + s0b[i, 1])
        szz = 0.5 * (s0a[i, 2] + s0b[i, 2])
        sxy = 0.5 * (s0a[i, 3] + s0b[i, 3])
        syz = 0.5 * (s0a[i, 4] + s0b[i, 4])
        sxz = 0.5 * (s0a[i, 5] + s0b[i, 5])
        tx = sxx * nx + sxy * ny + sxz * nz
        ty = sxy * nx + syy * ny + syz * nz
        tz = sxz * nx + syz * ny + szz * nz
        tn = tx * nx + ty * ny + tz * nz
        tx -= tn * nx
        ty -= tn * ny
        tz -= tn * nz
        ts = math.sqrt(tx * tx + ty * ty + tz * tz)
        law = law_table[law_of[i]]
        ft = law[LAW_FT]
        if law[LAW_KIND] == KIND_BILINEAR:
            shift = tn / pn[i]
            used = initiation_index(max(tn, 0.0), ts, law)
        else:
            if tn >= ft:
                shift = 0.0
                used = tn / ft
            else:
                # Guo-Munjiza: on the pre-peak curve ft (2 u - u^2), u = dn / dnp, in tension; the
                # penalty pn dn in compression.
                shift = 2.0 * ft / pn[i] * (1.0 - math.sqrt(1.0 - tn / ft)) if tn > 0.0 else tn / pn[i]
                cap = shear_cap(tn, 1.0, law) if law[LAW_BETA] > 0.0 else shear_strength(tn, law)
                used = max(ts / cap, tn / ft)
        dn_shift[i] = shift
        utilisation[i] = used
        for p in range(3):
            # The shear spring ps (s - s_p) carries the shear traction at zero slip.
            slip_plastic[i, p, 0] = -tx / ps[i]
            slip_plastic[i, p, 1] = -ty / ps[i]
            slip_plastic[i, p, 2] = -tz / ps[i]


def face_normals(x0: np.ndarray, na: np.ndarray) -> np.ndarray:
    """Unit normals of the faces (from side A to side B) in the reference: the orientation of
    interface.mid_face."""
    p = x0[na]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None]


def preload_interfaces(x0, na, ta, tb, law_of, law_table, pn, ps, chosen, s0,
                       precrack=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dn_shift (n_if,), slip_plastic (n_if, 3, 3) and traction_t (n_if, 3, 3) that make the
    `chosen` faces (intact, intrinsic) carry the traction of their tets' initial stresses s0 (m, 6)
    at zero gap, and the `precrack` faces its compression (a shift the failed faces' contact keeps,
    kernels._interface_block) and its shear up to friction (their Coulomb springs' traction; a
    shear beyond mu |t_n| slides from the first step, as a closed crack would); ValueError naming
    [initial_stress] where the traction reaches an intact face's strength."""
    n_if = len(na)
    dn_shift = np.zeros(n_if)
    slip_plastic = np.zeros((n_if, 3, 3))
    traction_t = np.zeros((n_if, 3, 3))
    utilisation = np.zeros(n_if)
    normal = face_normals(x0, na)
    _preload(normal, s0[ta], s0[tb], law_of.astype(np.int64), law_table, pn, ps, chosen.astype(np.bool_), dn_shift,
             slip_plastic, utilisation)
    over = np.flatnonzero(utilisation >= 1.0)
    if len(over):
        worst = over[np.argmax(utilisation[over])]
        where = x0[na[worst]].mean(axis=0)
        raise ValueError(
            f"initial_stress: its traction reaches the interface strength on {len(over):,} of {int(chosen.sum()):,} "
            f"faces (up to {utilisation[worst]:.3g}x the strength, at ({', '.join(f'{c:.4g}' for c in where)}) m): they "
            "would fail at t = 0; lower the initial stress (a tensile or deviatoric part beyond the strength) or raise "
            "the interface strength (tensile_strength, cohesion)")
    if precrack is not None and precrack.any():
        ids = np.flatnonzero(precrack)
        n = normal[ids]
        sigma = stress_matrices(0.5 * (s0[ta[ids]] + s0[tb[ids]]))
        t = np.einsum("kij,kj->ki", sigma, n)
        tn = np.einsum("ki,ki->k", t, n)
        ts = t - tn[:, None] * n
        pressed = tn < 0.0
        dn_shift[ids] = np.where(pressed, tn / pn[ids], 0.0)
        cap = law_table[law_of[ids], LAW_MU] * np.maximum(-tn, 0.0)
        size = np.linalg.norm(ts, axis=1)
        scale = np.where(size > cap, cap / np.where(size > 0.0, size, 1.0), 1.0)
        traction_t[ids] = (scale[:, None] * ts)[:, None, :]
    return dn_shift, slip_plastic, traction_t

"""Interface laws of FDEM, chosen by name (`law` in [material.interface]).

Each law is one file: its parameters (a validated dataclass that is also its scenario schema),
its row of the law table (`table_row`), its interface stiffness (`stiffness`) and its compiled
`intact_step` (forces, damage, dissipation of an intact interface), `intact_energy` (what it
stores) and, for extrinsic insertion, `insertion_reached`, `insertion_utilisation` and
`inserted_preload` (when a tied face opens, and the state it starts from), side by side. Adding a
law: its file, plus one entry in LAWS and one branch in each dispatcher below; a law written as
another's arithmetic under other parameters (linear.py) needs its file and the LAWS entry only.
Failed and pre-cracked faces are the same for every law (paired contact with Coulomb friction,
fdem.kernels).
"""

from __future__ import annotations

from numba import njit

from . import bilinear, guo_munjiza
from .bilinear import BilinearLaw
from .guo_munjiza import GuoMunjizaLaw
from .linear import LinearLaw
from .row import LAW_COLUMNS, LAW_EXTRINSIC, LAW_FT, LAW_KIND, LAW_MU

# name -> parameter class; the class's `kind` is its code in the law table: the compiled law that
# steps it (a law written as another's arithmetic, as the linear law is the bilinear one, shares
# its code; the dispatchers below have one branch per code).
LAWS = {"guo-munjiza": GuoMunjizaLaw, "bilinear": BilinearLaw, "linear": LinearLaw}
KIND_BILINEAR = BilinearLaw.kind
assert {law.kind for law in LAWS.values()} <= {GuoMunjizaLaw.kind, KIND_BILINEAR}


@njit(cache=True, inline="always")
def intact_step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force, slip_plastic, e_damage,
                law, pn, ps, nx, ny, nz, dn_shift, reading_offset):
    """The law of row `law` on intact interface i; False when it failed and acts as a failed pair
    from this step on."""
    if law[LAW_KIND] == KIND_BILINEAR:
        return bilinear.intact_step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force,
                                    slip_plastic, e_damage, law, pn, ps, nx, ny, nz, dn_shift)
    if law[guo_munjiza.LAW_BETA] > 0.0:
        return guo_munjiza.intact_step_effective(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode,
                                                 force, slip_plastic, e_damage, law, pn, ps, nx, ny, nz, dn_shift,
                                                 reading_offset)
    return guo_munjiza.intact_step(i, t, dt, x, v, na, nb, area, damage, state, fail_time, fail_mode, force,
                                   slip_plastic, e_damage, law, pn, ps, nx, ny, nz, dn_shift, reading_offset)


@njit(cache=True, inline="always")
def intact_energy(i, x, na, nb, area, damage, slip_plastic, law, pn, ps, nx, ny, nz, dn_shift):
    """Energy stored in intact interface i under the law of row `law`."""
    if law[LAW_KIND] == KIND_BILINEAR:
        return bilinear.intact_energy(i, x, na, nb, area, damage, slip_plastic, law, pn, ps, nx, ny, nz, dn_shift)
    return guo_munjiza.intact_energy(i, x, na, nb, area, damage, slip_plastic, law, pn, ps, nx, ny, nz, dn_shift)


@njit(cache=True, inline="always")
def insertion_reached(tn, ts2, law):
    """Extrinsic insertion: whether a tied face's traction (tn, tension positive; squared shear
    ts2) reaches the strength of the law of row `law` (its insertion_reached)."""
    if law[LAW_KIND] == KIND_BILINEAR:
        return bilinear.insertion_reached(tn, ts2, law)
    return guo_munjiza.insertion_reached(tn, ts2, law)


@njit(cache=True, inline="always")
def insertion_utilisation(tn, ts, law):
    """Extrinsic insertion: how far a traction is along the law's insertion criterion (1 on it)."""
    if law[LAW_KIND] == KIND_BILINEAR:
        return bilinear.insertion_utilisation(tn, ts, law)
    return guo_munjiza.insertion_utilisation(tn, ts, law)


@njit(cache=True, inline="always")
def inserted_preload(tn, ts, law, pn, prestressed):
    """Extrinsic insertion: (opening shift, shear cap) of the law state that carries the traction
    at zero gap (the law's inserted_preload)."""
    if law[LAW_KIND] == KIND_BILINEAR:
        return bilinear.inserted_preload(tn, ts, law, pn, prestressed)
    return guo_munjiza.inserted_preload(tn, ts, law, pn, prestressed)


__all__ = ["KIND_BILINEAR", "LAWS", "LAW_COLUMNS", "LAW_EXTRINSIC", "LAW_FT", "LAW_KIND", "LAW_MU", "BilinearLaw", "GuoMunjizaLaw",
           "LinearLaw", "inserted_preload", "insertion_reached",
           "insertion_utilisation", "intact_energy", "intact_step"]

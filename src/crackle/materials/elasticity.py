"""St. Venant-Kirchhoff elasticity in the total-Lagrangian measures, compiled inline: the strain
and stress chain FDEM's tets and the meshfree particles share (the shell's plane-stress membrane
has its own, in 2D). Component order xx yy zz xy yz xz (io.fields.STRESS_COMPONENTS)."""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def green_lagrange(f00, f01, f02, f10, f11, f12, f20, f21, f22):
    """Green-Lagrange strain E = (F^T F - I) / 2 of F (row-major f_rc)."""
    return (0.5 * (f00 * f00 + f10 * f10 + f20 * f20 - 1.0), 0.5 * (f01 * f01 + f11 * f11 + f21 * f21 - 1.0),
            0.5 * (f02 * f02 + f12 * f12 + f22 * f22 - 1.0), 0.5 * (f00 * f01 + f10 * f11 + f20 * f21),
            0.5 * (f01 * f02 + f11 * f12 + f21 * f22), 0.5 * (f00 * f02 + f10 * f12 + f20 * f22))


@njit(cache=True, inline="always")
def svk_stress(lam, mu, ee0, ee1, ee2, ee3, ee4, ee5):
    """St. Venant-Kirchhoff: the second Piola-Kirchhoff stress of the elastic strain ee0..ee5."""
    tr = ee0 + ee1 + ee2
    return (lam * tr + 2.0 * mu * ee0, lam * tr + 2.0 * mu * ee1, lam * tr + 2.0 * mu * ee2, 2.0 * mu * ee3,
            2.0 * mu * ee4, 2.0 * mu * ee5)


@njit(cache=True, inline="always")
def energy_density(ee0, ee1, ee2, ee3, ee4, ee5, lam, mu):
    """The St. Venant-Kirchhoff stored energy per reference volume of the elastic strain ee."""
    tr = ee0 + ee1 + ee2
    return 0.5 * lam * tr * tr + mu * (ee0 * ee0 + ee1 * ee1 + ee2 * ee2 + 2.0 * (ee3 * ee3 + ee4 * ee4 + ee5 * ee5))

"""Coulomb friction with a stick spring: the one stick-slip update every contact uses (tools
against any method's nodes or particles; in FDEM also failed interface pairs and node-to-surface
contact)."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def coulomb_update(tx, ty, tz, nx, ny, nz, rx, ry, rz, dt, k, cap):
    """New tangential force t on a point sliding at relative velocity r over a surface of unit
    normal n, and the energy the step dissipates.

    The previous t is carried into the current tangent plane keeping its magnitude, the stick
    spring k adds -k r_t dt (r_t: tangential part of r), and a t beyond the Coulomb cap is
    returned onto it. Lost: the plastic slip times the cap, and, when the cap itself has fallen
    below the carried t (a damaging cohesive interface), the stored energy t^2 / 2k above the
    cap's, released before the step slips. t, k and cap may be per unit area
    (tractions) or per node (forces): the dissipation is then per unit area or per node.
    """
    rn = rx * nx + ry * ny + rz * nz
    rx -= rn * nx
    ry -= rn * ny
    rz -= rn * nz
    # Squared magnitudes throughout: one square root per call while sticking.
    t_old2 = tx * tx + ty * ty + tz * tz
    tn = tx * nx + ty * ny + tz * nz
    tx -= tn * nx
    ty -= tn * ny
    tz -= tn * nz
    t_proj2 = tx * tx + ty * ty + tz * tz
    cap2 = cap * cap
    lost = 0.0
    if t_old2 > cap2:
        lost = (t_old2 - cap2) / (2.0 * k)
        t_old2 = cap2
    if t_proj2 > 0.0:
        s = math.sqrt(t_old2 / t_proj2)
        tx *= s
        ty *= s
        tz *= s
    tx -= k * rx * dt
    ty -= k * ry * dt
    tz -= k * rz * dt
    t_trial2 = tx * tx + ty * ty + tz * tz
    if t_trial2 > cap2:
        t_trial = math.sqrt(t_trial2)
        lost += (t_trial - cap) / k * cap
        s = cap / t_trial
        tx *= s
        ty *= s
        tz *= s
    return tx, ty, tz, lost

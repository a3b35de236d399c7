"""Coulomb friction with a stick spring: the one stick-slip update every contact in FDEM uses
(failed interface pairs, tools, node-to-surface contact)."""

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
    t_old = math.sqrt(tx * tx + ty * ty + tz * tz)
    tn = tx * nx + ty * ny + tz * nz
    tx -= tn * nx
    ty -= tn * ny
    tz -= tn * nz
    t_proj = math.sqrt(tx * tx + ty * ty + tz * tz)
    lost = 0.0
    if t_old > cap:
        lost = (t_old * t_old - cap * cap) / (2.0 * k)
        t_old = cap
    if t_proj > 0.0:
        s = t_old / t_proj
        tx *= s
        ty *= s
        tz *= s
    tx -= k * rx * dt
    ty -= k * ry * dt
    tz -= k * rz * dt
    t_trial = math.sqrt(tx * tx + ty * ty + tz * tz)
    if t_trial > cap:
        lost += (t_trial - cap) / k * cap
        s = cap / t_trial
        tx *= s
        ty *= s
        tz *= s
    return tx, ty, tz, lost

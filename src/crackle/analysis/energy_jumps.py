"""Crack bursts read from the dissipated energy (paper 004, section 3.2 and Fig. 12: "each sudden
change in damage dissipation energy represents the generation of a new crack").

A crack that runs releases energy at Gc x wall x speed; crushing under a plate and the slow
growth of damage before the peak release it far more slowly. A jump is therefore a maximal run of
history intervals over which the dissipation rate is at least Gc x wall x JUMP_SPEED, JUMP_SPEED a
fraction of the Rayleigh speed (a crack running at that speed through the wall): the rule has the
material's own scales in it, not the mesh's or the sampling's (as long as the history resolves a
burst: a burst shorter than one interval is averaged over it). The jumps' count is the paper's crack
count by energy, their start times its crack times, beside the geometric count
(analysis.cracks)."""

from __future__ import annotations

import numpy as np

JUMP_SPEED = 0.05  # x the Rayleigh speed: the slowest running crack a jump counts


def energy_jumps(time, dissipated, threshold_rate: float) -> list[tuple[float, float, float]]:
    """(start, end, energy released) (s, s, J) of each jump in the dissipated energy
    `dissipated` (J) sampled at `time` (s): a maximal run of consecutive intervals whose rate is
    at least `threshold_rate` (W)."""
    t = np.asarray(time, dtype=float)
    e = np.asarray(dissipated, dtype=float)
    if len(t) < 2:
        return []
    dt = np.diff(t)
    rate = np.divide(np.diff(e), dt, out=np.zeros_like(dt), where=dt > 0.0)
    fast = rate >= threshold_rate
    jumps = []
    k = 0
    while k < len(fast):
        if not fast[k]:
            k += 1
            continue
        start = k
        while k < len(fast) and fast[k]:
            k += 1
        jumps.append((float(t[start]), float(t[k]), float(e[k] - e[start])))
    return jumps

"""Where cracking starts on a pre-existing flaw (paper 003 section 4.2: wing cracks start from the
flaw's middle when it is normal to the load and move to its tips as it inclines)."""

from __future__ import annotations

import numpy as np

# The earliest failures that locate the initiation: enough to average over a few particles'
# worth of bonds, few enough to come before the damage spreads over the sample.
FIRST_FAILURES = 40


def initiation_along_flaw(positions, times, center, along, across, length, count: int = FIRST_FAILURES) -> float:
    """The median distance from the flaw's middle, along the flaw, of the first `count` failures
    near it, in units of half its length: 0 at the middle, 1 at a tip. "Near": within 1.5 half
    lengths along the flaw and one half length across it (the wings start there). nan when no
    failure is near."""
    half = 0.5 * float(length)
    rel = np.asarray(positions, float) - np.asarray(center, float)
    s = rel @ np.asarray(along, float) / half
    n = rel @ np.asarray(across, float) / half
    near = np.flatnonzero((np.abs(s) < 1.5) & (np.abs(n) < 1.0))
    if near.size == 0:
        return float("nan")
    first = near[np.argsort(np.asarray(times, float)[near], kind="stable")[:count]]
    return float(np.median(np.abs(s[first])))

"""Failure records, shared by every method: the failure modes and the recorder that turns a
method's failure arrays (an interface, bond or link each) into the rows of events.csv."""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit


class FailureMode(IntEnum):
    """How a bond, link or interface failed; the code is what the compiled kernels store."""

    NONE = 0
    TENSION = 1
    SHEAR = 2
    MIXED = 3


# The modes' names in events.csv, indexed by code.
MODE_NAMES = tuple(m.name.lower() for m in FailureMode)
# Plain ints for compiled code.
MODE_TENSION, MODE_SHEAR, MODE_MIXED = int(FailureMode.TENSION), int(FailureMode.SHEAR), int(FailureMode.MIXED)
# The mode angle (atan of the shear part over the normal part of the failure measure) below which
# a failure counts as tension and above which as shear (the Guo-Munjiza angles).
_TENSION_BELOW = math.sin(math.radians(15.0)) ** 2
_SHEAR_ABOVE = math.sin(math.radians(75.0)) ** 2


@njit(cache=True, inline="always")
def failure_mode(shear_share):
    """Mode code from the shear share sin^2 of the mode angle (s^2 / (n^2 + s^2) of the normal and
    shear parts of the failure measure, or an energy ratio G_II / G_T): tension below 15 deg,
    shear above 75 deg, mixed between."""
    if shear_share < _TENSION_BELOW:
        return MODE_TENSION
    if shear_share > _SHEAR_ABOVE:
        return MODE_SHEAR
    return MODE_MIXED


def material_labels(material_a: np.ndarray, material_b: np.ndarray, names: list[str]) -> list[str]:
    """The material of each failure from the materials (indices into `names`) on its two sides:
    the material's name where both sides are in it, else the pair "A-B" (in the order of `names`)."""
    low, high = np.minimum(material_a, material_b), np.maximum(material_a, material_b)
    return [names[i] if i == j else f"{names[i]}-{names[j]}" for i, j in zip(low.tolist(), high.tolist())]


class FailureRecorder:
    """Reports each failure once: call `new` between chunks with the current failure arrays."""

    def __init__(self, n: int):
        self._reported = np.zeros(n, dtype=bool)

    def new(self, failed: np.ndarray, fail_time: np.ndarray, fail_mode: np.ndarray, positions):
        """Failures not reported yet, in the order of their time then id: (times, xyz, mode names,
        ids). `failed` is a mask over the method's bonds; `positions(ids)` gives their (k, 3)
        positions in the reference (undeformed) configuration: where on the specimen each
        failure is, the same whenever it is reported (so events.csv does not depend on how
        often the history is sampled)."""
        ids = np.flatnonzero(failed & ~self._reported)
        self._reported[ids] = True
        ids = ids[np.lexsort((ids, fail_time[ids]))]
        modes = [MODE_NAMES[k] for k in fail_mode[ids]]
        return fail_time[ids], positions(ids), modes, ids

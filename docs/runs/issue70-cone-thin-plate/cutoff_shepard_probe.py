"""Issue 70 probe (measurement only): the triaxiality cut-off of cutoff_probe.py together with a
constant-basis (Shepard) level below the linear fallback of shape.mls_values, so that a particle cut
on many planes keeps the neighbours it still sees instead of detaching.

    python docs/runs/issue70-cone-thin-plate/cutoff_shepard_probe.py docs/runs/issue70-cone-thin-plate/cone-thin-plate.toml \
        150 -0.3333333 OUT material.tensile_strength=inf material.failure_plastic_strain=0.3      # about 2 min
"""
import runpy, sys
from pathlib import Path
import numpy as np
import crackle.meshfree.shape as shape

orig = shape.mls_values
def mls_values(points, X, volume, start, neighbour, radius, terms, linear_fallback=False,
               max_condition=shape.MAX_CONDITION):
    value, condition = orig(points, X, volume, start, neighbour, radius, terms, linear_fallback, max_condition)
    bad = np.flatnonzero(~np.isfinite(condition) | (condition > max_condition))
    if linear_fallback and len(bad):
        pos, sub_start = shape.csr_positions(start, bad)
        sub_value = np.zeros(len(pos)); sub_condition = np.zeros(len(bad))
        shape._values_at(np.ascontiguousarray(points[bad], dtype=float), X, np.asarray(volume, float), sub_start,
                         neighbour[pos], shape.support_radii(radius, len(X)), terms[terms < 1], sub_value, sub_condition)
        value[pos] = sub_value
        condition[bad] = sub_condition
    return value, condition
shape.mls_values = mls_values
runpy.run_path(str(Path(__file__).with_name("cutoff_probe.py")), run_name="__main__")

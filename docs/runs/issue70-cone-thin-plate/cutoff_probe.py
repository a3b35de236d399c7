"""Issue 70 probe (a measurement, not a feature): the ductile criterion counts a particle's plastic
strain only while its stress triaxiality is above a cut-off (Bao and Wierzbicki's -1/3: no ductile
fracture in compression), the increments summed at each fracture check.

    python docs/runs/issue70-cone-thin-plate/cutoff_probe.py docs/runs/issue70-cone-thin-plate/cone-thin-plate.toml \
        150 -0.3333333 OUT material.tensile_strength=inf material.failure_plastic_strain=0.3      # about 2.5 min
"""
import sys, json
from pathlib import Path
import numpy as np
import crackle.meshfree.fracture as fr
from crackle.api import run_scenario

cutoff = float(sys.argv[3])
orig_check = fr.LinkBreaking.check
def check(self, sim, dt):
    eq = sim.per_particle(sim.particles.eq_plastic)
    if not hasattr(self, "_counted"):
        self._counted = np.zeros_like(eq); self._last = np.zeros_like(eq)
    c = sim.cauchy_stress()
    mean = c[:, :3].mean(axis=1)
    dev = c.copy(); dev[:, :3] -= mean[:, None]
    vm = np.sqrt(1.5 * (np.sum(dev[:, :3] ** 2, axis=1) + 2 * np.sum(dev[:, 3:] ** 2, axis=1)))
    eta = mean / np.maximum(vm, 1.0)
    inc = eq - self._last
    self._counted += np.where(eta > cutoff, inc, 0.0)
    self._last = eq.copy()
    counted = self._counted
    orig_pp = sim.per_particle
    sim.per_particle = lambda a: counted if a is sim.particles.eq_plastic else orig_pp(a)
    try:
        return orig_check(self, sim, dt)
    finally:
        del sim.per_particle
fr.LinkBreaking.check = check
out = Path(sys.argv[4])
res = run_scenario(sys.argv[1], out, overrides=[f"run.end_time={float(sys.argv[2])*1e-6}", "run.field_frames=2"] + sys.argv[5:],
                   progress=False, plots=False)
s = res.summary
print({k: s.get(k) for k in ("status", "petals", "petals_by_reach", "hole_diameter", "failed_particles", "detached_particles",
                             "largest_loose_piece", "energy_error")})

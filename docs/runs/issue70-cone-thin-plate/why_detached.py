"""Why the cone probe's particles are detached: a moment matrix left singular by the cracks
(too few visible neighbours even for the linear basis), or the guard on steep rebuilt gradients
(meshfree/fracture.py, `_rebuild`)? Wraps the two functions the rebuild decides with, runs the
scenario to 150 us and counts the detached particles by reason.

    python docs/runs/issue70-cone-thin-plate/why_detached.py docs/runs/issue70-cone-thin-plate/cone-thin-plate.toml \
        material.tensile_strength=inf material.failure_plastic_strain=0.3      # about 2.5 min
"""
import sys
from pathlib import Path

import numpy as np

import crackle.meshfree.fracture as fr
from crackle.scenario import load_scenario
from crackle.api import build_simulation
from crackle.solver.driver import choose_time_step

state = {"limit": None, "bad": set(), "steep": set()}
orig_cg, orig_gs = fr.cell_gradients, fr._gradient_sums

def cg(*a, **k):
    out = orig_cg(*a, **k)
    r, col, grad, condition, _, owner = out
    bad = ~np.isfinite(condition) | (condition > fr.REBUILD_CONDITION)
    state["bad"].update(int(i) for i in owner[bad])
    return out

def gs(r, grad, n):
    sums = orig_gs(r, grad, n)
    if state["limit"] is not None:
        state["steep"].update(int(i) for i in np.flatnonzero(sums > state["limit"]))
    return sums

fr.cell_gradients, fr._gradient_sums = cg, gs
sc, base = load_scenario(Path(sys.argv[1]), overrides=sys.argv[2:])
sim, control = build_simulation(sc, base)
state["limit"] = sim.breaking.gradient_limit
dt = choose_time_step(sim, control)
sim.advance(int(round(1.5e-4 / dt)), dt)
det = set(np.flatnonzero(sim.breaking.detached).tolist())
bad, steep = state["bad"] & det, state["steep"] & det
print(f"detached {len(det)}: singular only {len(bad - steep)}, steep only {len(steep - bad)}, both {len(bad & steep)}, "
      f"neither recorded {len(det - bad - steep)}; failed {int(sim.breaking.failed.sum())}, "
      f"detached without failing {len(det - set(np.flatnonzero(sim.breaking.failed).tolist()))}")

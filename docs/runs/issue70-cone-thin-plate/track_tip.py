"""Issue 70 probe: does the rigid cone push the plate's particles ahead of its tip aside, or carry
them? The positions (radius from the axis, z; mm) of the 9 particles nearest the axis in one
octant, all three layers, as the tip passes (F: failed, D: detached), beside the tip's z.

    python docs/runs/issue70-cone-thin-plate/track_tip.py docs/runs/issue70-cone-thin-plate/cone-thin-plate.toml \
        material.tensile_strength=inf material.failure_plastic_strain=0.3      # about 20 s
"""
import sys, math
from pathlib import Path
import numpy as np
from crackle.scenario import load_scenario
from crackle.api import build_simulation
from crackle.solver.driver import choose_time_step
sc, base = load_scenario(Path(sys.argv[1]), overrides=sys.argv[2:])
sim, control = build_simulation(sc, base)
dt = choose_time_step(sim, control)
X = sim.breaking.X
r0 = np.hypot(X[:, 0], X[:, 1])
pick = np.flatnonzero((r0 < 1.6e-3) & (X[:, 0] >= 0) & (X[:, 1] >= 0) & (X[:, 1] <= X[:, 0]))
for k in pick:
    print(f"  X = ({X[k,0]*1e3:.2f}, {X[k,1]*1e3:.2f}, {X[k,2]*1e3:.2f}) mm, r0 {r0[k]*1e3:.2f}")
for t_us in (2, 4, 5, 6, 7, 8, 9, 10, 12, 14):
    steps = int(round((t_us * 1e-6 - sim.time) / dt))
    if steps > 0:
        sim.advance(steps, dt)
    z_tip = 0.0021 + sim.tools.disp[0, 2]
    x = sim.particles.x
    row = []
    for k in pick:
        r = math.hypot(x[k, 0], x[k, 1])
        flag = "D" if sim.breaking.detached[k] else ("F" if sim.breaking.failed[k] else " ")
        row.append(f"({r*1e3:.2f},{x[k,2]*1e3:+.2f}){flag}")
    print(f"t {sim.time*1e6:5.2f} tip {z_tip*1e3:+.2f}: " + " ".join(row))

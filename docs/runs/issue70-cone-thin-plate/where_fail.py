"""Issue 70 probe: the stress state and the motion of each particle of the cone probe as it fails
(stress triaxiality eta = mean stress / von Mises stress, Cauchy, the mean of its two Gauss points;
its radial and axial displacement), by ring of its initial distance r0 from the axis.

    python docs/runs/issue70-cone-thin-plate/where_fail.py docs/runs/issue70-cone-thin-plate/cone-thin-plate.toml 60 \
        material.tensile_strength=inf material.failure_plastic_strain=0.3      # about 45 s
"""
import sys
from pathlib import Path
import numpy as np
import crackle.meshfree.fracture as fr
from crackle.scenario import load_scenario
from crackle.api import build_simulation
from crackle.solver.driver import choose_time_step

rec = []
orig_fail = fr.LinkBreaking.fail
def fail(self, sim, ids, normals, dt):
    c = sim.cauchy_stress()[ids]
    mean = c[:, :3].mean(axis=1)
    dev = c.copy(); dev[:, :3] -= mean[:, None]
    vm = np.sqrt(1.5 * (np.sum(dev[:, :3] ** 2, axis=1) + 2 * np.sum(dev[:, 3:] ** 2, axis=1)))
    X = self.X[ids]; x = sim.particles.x[ids]
    r0 = np.hypot(X[:, 0], X[:, 1]); er = X[:, :2] / np.maximum(r0, 1e-12)[:, None]
    u = x - X
    ur = np.einsum("ka,ka->k", u[:, :2], er)
    # hoop direction e_theta = (-ey, ex): the normal's hoop part (a radial crack's normal is hoop)
    eth = np.stack([-er[:, 1], er[:, 0]], axis=1)
    hoop_normal = np.abs(np.einsum("ka,ka->k", normals[:, :2], eth))
    eq = sim.per_particle(sim.particles.eq_plastic)[ids]
    for k in range(len(ids)):
        rec.append((sim.time, r0[k], X[k, 2], ur[k], u[k, 2], mean[k] / max(vm[k], 1.0), vm[k], c[k, :3].max(), eq[k],
                    hoop_normal[k]))
    return orig_fail(self, sim, ids, normals, dt)
fr.LinkBreaking.fail = fail
sc, base = load_scenario(Path(sys.argv[1]), overrides=sys.argv[3:])
sim, control = build_simulation(sc, base)
dt = choose_time_step(sim, control)
sim.advance(int(round(float(sys.argv[2]) * 1e-6 / dt)), dt)
a = np.array(rec)
R = 0.00635
print(f"{len(a)} failures by {sim.time*1e6:.1f} us")
for lo, hi in ((0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0), (1.0, 1.25), (1.25, 2.0), (2.0, 9.0)):
    m = (a[:, 1] >= lo * R) & (a[:, 1] < hi * R)
    if not m.any():
        continue
    s = a[m]
    print(f"r0/R {lo:.2f}-{hi:.2f}: {m.sum():4d} failed, t {np.median(s[:,0])*1e6:5.2f} us, u_r {np.median(s[:,3])*1e3:+.3f} mm, "
          f"u_z {np.median(s[:,4])*1e3:+.3f} mm, triaxiality median {np.median(s[:,5]):+.2f} (min {s[:,5].min():+.2f}, "
          f"max {s[:,5].max():+.2f}), share under compression (eta<-1/3) {np.mean(s[:,5] < -1/3):.2f}, "
          f"eta<0 {np.mean(s[:,5] < 0):.2f}, eq plastic {np.median(s[:,8]):.2f}, crack normal hoop part {np.median(s[:,9]):.2f}")

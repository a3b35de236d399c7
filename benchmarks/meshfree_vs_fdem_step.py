"""Paper 000's claim, measured on crackle: the stable step of the meshfree (EFG) plate against
crackle's own 3D finite elements (FDEM tets) on the same wall.

The wall: a 100 x 100 x 10 mm aluminium plate (E = 71 GPa, nu = 0.3, 2700 kg/m^3), free, with a
uniform initial velocity (the step's cost does not depend on the state; no tools).

- meshfree: 3 particles through the thickness (5 mm apart), in-plane spacing 5 mm (the same
  resolution as the thickness) and 15 mm (plate-impact's: "the time step based on nodal
  distances in circumferential direction", as the paper does);
- FDEM: structured tets (24 per cubic cell) with element_size 10/3 mm, 3 cells through the
  thickness; the interfaces intrinsic (crackle's default: every face a cohesive penalty spring,
  200 E / h) and extrinsic (faces tied until the law is inserted: the bulk tets set the step).
  Interface strengths far above any stress here (nothing breaks).

For each: the stable step (the method's own estimate, sim.stable_dt) and the driver's step (0.7
x it), the cost of a step (median of --repeats timed repeats of --seconds each) and the time to
solution for --end-time of physical time at the driver's step (steps x cost per step).

    python benchmarks/meshfree_vs_fdem_step.py --threads 2
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

PLATE = """
name = "{name}"
method = "{method}"
[specimen]
shape = "box"
size = [0.1, 0.1, 0.01]
origin = [-0.05, -0.05, 0.0]
initial_velocity = [0.0, 0.0, -1.0]
{specimen}
[material]
density = 2700.0
youngs_modulus = 71e9
poissons_ratio = 0.3
{material}
[run]
end_time = 1e-4
"""
FDEM_MATERIAL = """[material.interface]
tensile_strength = 1e10
cohesion = 1e10
friction_angle = 30.0
fracture_energy = 1e6
insertion = "{insertion}"
"""


def cases():
    yield "meshfree, 3 layers, spacing 5 mm", "meshfree", "", "[particles]\nspacing = 0.005\nlayers = 3\n"
    yield "meshfree, 3 layers, spacing 15 mm", "meshfree", "", "[particles]\nspacing = 0.015\nlayers = 3\n"
    for insertion in ("intrinsic", "extrinsic"):
        yield (f"FDEM tets, 3 through the wall, {insertion}", "fdem", f"element_size = {0.01 / 3}",
               FDEM_MATERIAL.format(insertion=insertion))


def measure(label, method, specimen, extra, seconds, repeats, end_time) -> dict:
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    text = PLATE.format(name="wall", method=method, specimen=specimen if method == "fdem" else "",
                        material=extra if method == "fdem" else "")
    if method == "meshfree":
        text += extra
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "wall.toml"
        path.write_text(text)
        scenario, base = load_scenario(path)
        t0 = time.perf_counter()
        sim, control = build_simulation(scenario, base)
        build_s = time.perf_counter() - t0
    dt = control.safety * sim.stable_dt
    sim.advance(10, dt)  # compile or load the cache
    t0 = time.perf_counter()
    sim.advance(10, dt)
    steps = max(10, int(seconds / ((time.perf_counter() - t0) / 10)))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.advance(steps, dt)
        times.append((time.perf_counter() - t0) / steps)
    per_step = statistics.median(times)
    n_steps = int(round(end_time / dt))
    summary = sim.summary()
    return {"case": label, "method": method, "size": summary.get("particles", summary.get("elements")),
            "stable_dt": sim.stable_dt, "dt": dt, "seconds_per_step": per_step, "steps": n_steps,
            "time_to_solution_s": n_steps * per_step, "build_s": build_s, "repeat_seconds": times}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="target duration of one timed repeat")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--end-time", type=float, default=1e-4, help="s of physical time for the time to solution")
    parser.add_argument("--threads", type=int, default=None, help="numba threads (numba.set_num_threads)")
    args = parser.parse_args()
    if args.threads:
        import numba

        numba.set_num_threads(args.threads)
    rows = [measure(*case, args.seconds, args.repeats, args.end_time) for case in cases()]
    reference = next(r for r in rows if r["method"] == "fdem" and "extrinsic" in r["case"])
    for r in rows:
        print(f"{r['case']:<44} {r['size']:>7,} {'particles' if r['method'] == 'meshfree' else 'tets':<9} "
              f"stable step {r['stable_dt']:.3e} s ({r['stable_dt'] / reference['stable_dt']:5.2f} x the tets'), "
              f"{r['seconds_per_step'] * 1e3:7.3f} ms/step, {r['steps']:>6,} steps to {args.end_time:g} s: "
              f"{r['time_to_solution_s']:7.2f} s")
    print(json.dumps({"end_time": args.end_time, "cases": rows}))


if __name__ == "__main__":
    main()

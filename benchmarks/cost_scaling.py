"""Seconds per step against element count (paper 001 Fig. 19: linear).

Set-up: the `single-fracture` example at element sizes 20, 10, 5 and 2.5 mm (432 to 221,184
tets), each warmed up for 20 steps (the pressure on the pre-crack just starting) and then
timed over --steps steps (the complete step: interfaces, bulk, pressures, integration), median
of --repeats repeats. A least-squares line seconds_per_step = a + b * tets is fitted; its slope,
intercept and R^2 are printed. The last line is one JSON object:

    {"rows": [{"element_size", "tets", "seconds_per_step", "tet_steps_per_s", "threads"}, ...],
     "fit": {"slope_s_per_tet_step", "intercept_s", "r2"}}

    python benchmarks/cost_scaling.py --threads 2
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=float, nargs="+", default=[0.02, 0.01, 0.005, 0.0025])
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=None)
    args = p.parse_args(argv)

    import numba

    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    if args.threads:
        numba.set_num_threads(args.threads)
    rows = []
    for size in args.sizes:
        scenario, base = load_scenario("single-fracture", [f"specimen.element_size={size}"])
        sim, control = build_simulation(scenario, base)
        dt = control.safety * sim.stable_dt
        sim.advance(20, dt)  # compile / load the cache
        runs = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            sim.advance(args.steps, dt)
            runs.append(time.perf_counter() - t0)
        sps = statistics.median(runs) / args.steps
        row = {"element_size": size, "tets": sim.model.n_tets, "seconds_per_step": sps,
               "tet_steps_per_s": sim.model.n_tets / sps, "threads": numba.get_num_threads()}
        rows.append(row)
        print(f"h {size * 1e3:5.2f} mm | {row['tets']:7d} tets | {sps * 1e3:9.4f} ms/step | "
              f"{row['tet_steps_per_s'] / 1e6:6.2f} M tet-steps/s", flush=True)
    n = np.array([r["tets"] for r in rows], float)
    t = np.array([r["seconds_per_step"] for r in rows], float)
    slope, intercept = np.polyfit(n, t, 1)
    r2 = 1.0 - np.sum((t - (slope * n + intercept)) ** 2) / np.sum((t - t.mean()) ** 2)
    fit = {"slope_s_per_tet_step": float(slope), "intercept_s": float(intercept), "r2": float(r2)}
    print(f"seconds/step = {intercept:.3e} + {slope:.3e} x tets, R^2 = {r2:.5f}")
    print(json.dumps({"rows": rows, "fit": fit}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

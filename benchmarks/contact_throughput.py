"""Cost of surface contact per step against the number of surface triangles.

Set-up: the `sphere-impact-fast` example (100 mm sphere of the example's material, 100 m/s onto
a rigid base) at several element sizes, each timed in three states:

* `intact`: at t = 0, the outer surface only;
* `shattered`: every interface failed (each tet its own fragment, all still touching its
  neighbours): the most surface a mesh can have;
* `after-impact` (smallest mesh only, or --impact-sizes): the real fragmented state, the quick
  example run for 100 us after the sphere touched the base.

Per state, `sim.advance` (the complete step, broad phase rebuilds included) is timed with surface
contact on and again with it off on a copy of the same state: contact_seconds_per_step is the
difference. Median of --repeats repeats. The last line is one JSON object:

    {"rows": [{"element_size", "state", "tets", "surface_triangles", "contact_seconds_per_step",
               "seconds_per_step", "tet_steps_per_s", "steps", "threads"}, ...],
     "linear_fit": {"exponent": ..., "ratio_cost_per_triangle_max_over_min": ...}}

exponent: slope of log(contact cost) against log(surface triangles) over all rows (1 = linear);
ratio: contact seconds per triangle-step, largest over smallest, among the rows.

    python benchmarks/contact_throughput.py --threads 2
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import sys
import time

import numpy as np


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=float, nargs="+", default=[0.02, 0.01, 0.007],
                   help="element sizes in m (default 0.02 0.01 0.007)")
    p.add_argument("--impact-sizes", type=float, nargs="*", default=[0.02],
                   help="element sizes also timed after a real impact (default 0.02)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--steps", type=int, default=200, help="steps per timed repeat (default 200)")
    p.add_argument("--threads", type=int, default=None)
    return p.parse_args(argv)


def build(size: float):
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario("sphere-impact-fast", [f"specimen.element_size={size}"])
    sim, control = build_simulation(scenario, base)
    return sim, control.safety * sim.stable_dt


def shatter(sim) -> None:
    from crackle.fdem.topology import FAILED

    sim.model.ifs.state[:] = FAILED
    sim.model.ifs.damage[:] = 1.0


def surface_triangles(sim) -> int:
    from crackle.fdem.contact import build_contact

    return int(build_contact(sim.model).counts[0])


def time_steps(sim, dt, steps, repeats) -> float:
    sim.advance(2, dt)  # compile / load the cache, build the contact lists
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.advance(steps, dt)
        runs.append(time.perf_counter() - t0)
    return statistics.median(runs) / steps


def measure(sim, dt, size, state, args) -> dict:
    import numba

    from crackle.fdem.contact import empty_contact

    without = copy.deepcopy(sim)
    without.model.contact_enabled = False
    without.contact = empty_contact(4 * sim.model.n_tets, sim.model.contact_penalty)
    with_contact = time_steps(sim, dt, args.steps, args.repeats)
    bare = time_steps(without, dt, args.steps, args.repeats)
    row = {
        "element_size": size,
        "state": state,
        "tets": sim.model.n_tets,
        "surface_triangles": surface_triangles(sim),
        "contact_seconds_per_step": max(with_contact - bare, 0.0),
        "seconds_per_step": with_contact,
        "tet_steps_per_s": sim.model.n_tets / with_contact,
        "steps": args.steps,
        "threads": numba.get_num_threads(),
    }
    print(f"h {size * 1e3:5.1f} mm {state:>12} | {row['tets']:7d} tets | {row['surface_triangles']:7d} triangles | "
          f"contact {row['contact_seconds_per_step'] * 1e3:8.3f} ms/step of {with_contact * 1e3:8.3f} | "
          f"{row['tet_steps_per_s'] / 1e6:6.3f} M tet-steps/s", flush=True)
    return row


def main(argv=None) -> int:
    args = parse_args(argv)
    import numba

    if args.threads:
        numba.set_num_threads(args.threads)
    rows = []
    for size in args.sizes:
        sim, dt = build(size)
        rows.append(measure(sim, dt, size, "intact", args))
        if size in args.impact_sizes:
            impact, dt_i = build(size)
            impact.advance(int(1.05e-4 / dt_i), dt_i)  # touches at 5 us, then 100 us of breaking
            rows.append(measure(impact, dt_i, size, "after-impact", args))
        shatter(sim)
        rows.append(measure(sim, dt, size, "shattered", args))
    tri = np.array([r["surface_triangles"] for r in rows], float)
    cost = np.array([r["contact_seconds_per_step"] for r in rows], float)
    ok = cost > 0
    exponent = float(np.polyfit(np.log(tri[ok]), np.log(cost[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")
    per_tri = cost[ok] / tri[ok]
    fit = {"exponent": exponent, "ratio_cost_per_triangle_max_over_min": float(per_tri.max() / per_tri.min())}
    print(f"contact cost ~ triangles^{exponent:.2f}; cost per triangle-step varies by x{fit['ratio_cost_per_triangle_max_over_min']:.2f}")
    print(json.dumps({"rows": rows, "linear_fit": fit}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Cost of one meshfree fracture event (crackle.meshfree.fracture.LinkBreaking.fail) against the
model size: the links across the failed particle's crack removed, the particles that lost some
rebuilt, the released energy booked. On the 140k-particle tube the step doubled once cracks
grew (docs/validation.md, paper 000): this is that cost, measured alone.

Set-up, per size: the meshfree_throughput plate (10 mm aluminium, 3 layers, 15 mm in-plane
spacing) with the fracture stress on, strained by a uniform stretch of 1e-3 along x so that the
released energy is not zero. Procedure: fail `--events` particles one call at a time (mid-plane
particles along the plate's centre line, cracks normal to x, as a crack running along y), each
call timed; the median and the whole call's share of a step are reported. Each size in its own
process.

    python benchmarks/meshfree_fracture_rebuild.py                      # ~10k, ~50k, ~140k particles
    python benchmarks/meshfree_fracture_rebuild.py --sizes 10000 --events 5

Output: one line per size, then a JSON object: {"sizes": [{"particles", "links", "events",
"ms_per_event", "ms_per_event_runs", "broken_links", "damage_J", "threads"}]}.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from meshfree_throughput import LAYERS, SPACING, THICKNESS


def one_size(n_particles: int, events: int) -> dict:
    import math

    import numpy as np

    from crackle.meshfree.build import build_meshfree_simulation
    from crackle.meshfree.material import J2Law
    from crackle.meshfree.particles import plate_particles

    side = max(3, round(math.sqrt(n_particles / LAYERS))) - 1
    size = side * SPACING
    plate = plate_particles((-0.5 * size, -0.5 * size, 0.0), (size, size, THICKNESS), SPACING, LAYERS)
    sim = build_meshfree_simulation(plate, 2700.0, J2Law(71e9, 0.3), fracture_stress=450e6)
    p = sim.particles
    p.x[:] = p.X * np.array([1.001, 1.0, 1.0])
    x0 = p.X[np.argmin(np.abs(p.X[:, 0])), 0]
    mid = np.flatnonzero((np.abs(p.X[:, 0] - x0) < 1e-9) & (np.abs(p.X[:, 2] - 0.5 * THICKNESS) < 1e-9))
    mid = mid[np.argsort(p.X[mid, 1])]
    centre = int(np.argmin(np.abs(p.X[mid, 1])))
    order = mid[centre:centre + events]
    dt = 0.7 * sim.stable_dt
    times = []
    for c in order:
        t0 = time.perf_counter()
        sim.breaking.fail(sim, np.array([c]), np.array([[1.0, 0.0, 0.0]]), dt)
        times.append(time.perf_counter() - t0)
    return {
        "particles": len(p.X),
        "links": len(sim.links.neighbour),
        "events": len(times),
        "ms_per_event": 1e3 * statistics.median(times),
        "ms_per_event_runs": [round(1e3 * t, 2) for t in times],
        "broken_links": sim.breaking.broken_links,
        "damage_J": sim.breaking.damage,
        "threads": int(os.environ.get("NUMBA_NUM_THREADS", "0")) or None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 50_000, 140_000])
    parser.add_argument("--events", type=int, default=8)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(one_size(args.one, args.events)))
        return
    env = dict(os.environ)
    if args.threads:
        env["NUMBA_NUM_THREADS"] = str(args.threads)
    rows = []
    for n in args.sizes:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--events", str(args.events)],
                             capture_output=True, text=True, env=env, check=True)
        row = json.loads(out.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(f"{row['particles']:>9,} particles {row['links']:>11,} links: {row['ms_per_event']:8.1f} ms per event "
              f"(runs {row['ms_per_event_runs']}), {row['broken_links']} links broken, damage {row['damage_J']:.3g} J",
              flush=True)
    print(json.dumps({"sizes": rows}))


if __name__ == "__main__":
    main()

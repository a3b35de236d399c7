"""What sets the FDEM extrinsic step after the first insertion, and what each way out would gain.

After its first insertion an extrinsic run steps at the stable step of the exploded mesh with
every face carrying its law (`model.stable_dt`); before it, at the tied step of the conforming
mesh (`time_step.tied_dt`). Issue 68 item 3 names three ways to lengthen the step after the first
insertion. This script measures the step each would give, on the models of
fracture_time_to_solution.py (the Akantu anchor's bar, the Brazilian disc):

  penalty   the interface penalty scaled by each of `--penalty-scales` (a penalty chosen from the
            bulk step; scale 1e-6 is the exploded mesh without springs, the floor of any law
            without an elastic branch: its steps are then set by the bulk tets alone);
  adaptive  the step of the mesh as it is at each of `--times`: the faces inserted so far carry
            their law, the others stay tied (the clusters of copies move as one): what a step
            recomputed after every insertion would take;
  bulk      the tets' own steps (minimum, 1st percentile, median): what sub-cycling the tets
            next to inserted faces could reach at best.

Every step is time_step.time_step's (Lanczos on the assembled step, the element bound beside
it), without the run's safety factor. The model is built as the benchmark builds it; the
arguments build_fdem_model hands to time_step are captured to recompute the step.

    python benchmarks/step_after_insertion.py                       # bar, 3.6 mm (50,835 tets)
    python benchmarks/step_after_insertion.py --size 6 --times 6 10 20
    python benchmarks/step_after_insertion.py --case disc --quick --times 20 40 60
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fracture_time_to_solution as fts  # noqa: E402


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--case", choices=("bar", "disc"), default="bar")
    p.add_argument("--size", type=float, default=3.6, help="bar: gmsh element size in mm (default 3.6)")
    p.add_argument("--quick", action="store_true", help="disc: the example's quick form")
    p.add_argument("--times", type=float, nargs="+", default=[6.0, 10.0, 14.0, 20.0],
                   help="simulated times (us) at which the adaptive step is measured")
    p.add_argument("--penalty-scales", type=float, nargs="+", default=[1.0, 0.5, 0.25, 0.1, 1e-6])
    p.add_argument("--safety", type=float, default=0.7, help="the run's step = safety x the stable step")
    return p.parse_args(argv)


def build(args, captured: list):
    """The case's simulation, with the arguments of its model's first time_step call in `captured`."""
    import crackle.fdem.model as fdem_model

    exact = fdem_model.time_step

    def capture(*a, **k):
        if not captured:
            captured.append(a)
        return exact(*a, **k)

    fdem_model.time_step = capture
    try:
        if args.case == "bar":
            mesh_file = fts.write_bar_mesh(Path(tempfile.mkdtemp()) / "bar.msh", args.size * 1e-3)
            return fts.bar_simulation(mesh_file, "extrinsic")
        return fts.disc_simulation("extrinsic", args.quick)[0]
    finally:
        fdem_model.time_step = exact


def main(argv=None) -> None:
    from crackle.fdem.extrinsic import TIED
    from crackle.fdem.time_step import time_step

    args = parse_args(argv)
    captured: list = []
    sim = build(args, captured)
    bulk, pairs, face_iface, surface_penalty, tool_penalty = captured[0][:5]
    model, report = sim.model, sim.model.time_step
    ns = 1e9
    print(f"{args.case}: {model.n_tets:,} tets, {model.n_interfaces:,} interfaces")
    print(f"  tied step {report.tied_dt * ns:.1f} ns; every face carrying its law {report.dt * ns:.1f} ns "
          f"({report.estimate}, set by the {report.kind}; element bound {report.bound_dt * ns:.1f} ns)")
    print(f"  the tets' own steps: min {report.bulk_dt.min() * ns:.1f}, 1st percentile "
          f"{np.percentile(report.bulk_dt, 1) * ns:.1f}, median {np.median(report.bulk_dt) * ns:.1f} ns")

    print("\n  penalty scale | step (ns) | x today | set by | element bound (ns)")
    pn, ps = pairs.pn.copy(), pairs.ps.copy()
    for scale in args.penalty_scales:
        pairs.pn, pairs.ps = pn * scale, ps * scale
        r = time_step(bulk, pairs, face_iface, surface_penalty, tool_penalty)
        print(f"  {scale:g} | {r.dt * ns:.1f} | {r.dt / report.dt:.2f} | {r.kind} | {r.bound_dt * ns:.1f}")
    pairs.pn, pairs.ps = pn, ps

    print("\n  t (us) | faces inserted | failed | adaptive step (ns) | x today | element bound (ns) | wall of the estimate (s)")
    dt = args.safety * sim.stable_dt
    for t in sorted(args.times):
        n = int(round((t * 1e-6 - sim.time) / dt))
        if n > 0:
            sim.advance(n, dt)
        tied = model.ties.tied == TIED
        cluster = np.unique(model.ties.leader, return_inverse=True)[1] if len(model.ties.leader) else None
        start = time.perf_counter()
        r = time_step(bulk, pairs, face_iface, surface_penalty, tool_penalty, tied=tied, cluster=cluster)
        wall = time.perf_counter() - start
        print(f"  {sim.time * 1e6:.2f} | {np.count_nonzero(~tied):,} of {len(tied):,} | {sim.broken:,} | "
              f"{r.dt * ns:.1f} | {r.dt / report.dt:.2f} | {r.bound_dt * ns:.1f} | {wall:.2f}")


if __name__ == "__main__":
    main()

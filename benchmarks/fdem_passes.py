"""Where the FDEM step's time goes: each pass of the step alone, on the throughput beam
(benchmarks/fdem_throughput.py's four-point bending, ~50k tets), intrinsic and extrinsic.

Per insertion mode: build, run 200 steps (contact under the platens), then time the interface
pass, the tet pass, (extrinsic) the node pass over the tied clusters, each 10 calls, and the
whole step, 10 calls of 10 steps, 5 rounds interleaved; prints the median and the rounds in ms.
Each pass alone runs on the current state (the tet pass of an intrinsic model also moves the
nodes: harmless for timing).

With `--case bar`: the Akantu anchor's bar of fracture_time_to_solution.py (extrinsic, 3.6 mm,
50,835 tets), its passes timed at each of `--at-us` simulated times (by default 4 us: every face
tied; 10 us: faces inserting; 18 us: faces failing), the whole step per compiled step (the
driver's step is 5 of them once a face is inserted): where the inserting phase's extra cost goes.

    python benchmarks/fdem_passes.py                # 2 threads by default (numba's)
    python benchmarks/fdem_passes.py --tets 13000
    python benchmarks/fdem_passes.py --case bar --threads 2
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from numba import njit, prange

sys.path.insert(0, str(Path(__file__).parent))
import fdem_throughput  # noqa: E402

from crackle.fdem import kernels  # noqa: E402
from crackle.fdem.extrinsic import VERTEX_BLOCK, cluster_block  # noqa: E402
from crackle.fdem.simulation import FdemSimulation  # noqa: E402


@njit(parallel=True)
def _tet_pass(dt, nodes, tets, ifs, contact, tools, ctrl, ties):
    n_tet = tets.vol.shape[0]
    pressure_now = np.zeros(1)
    v_prev = np.zeros((max(tools.kind.shape[0], 1), 3))
    v_next = np.zeros((max(tools.kind.shape[0], 1), 3))
    for blk in prange((n_tet + kernels.TET_BLOCK - 1) // kernels.TET_BLOCK):
        lo = blk * kernels.TET_BLOCK
        kernels._tet_block(lo, min(lo + kernels.TET_BLOCK, n_tet), np.int64(blk), dt, dt, nodes, tets, ifs, contact,
                           tools, pressure_now, v_prev, v_next, ctrl, ties)


@njit(parallel=True)
def _cluster_pass(dt, nodes, ties, ctrl, tools):
    n_vertex = ties.vertex_ptr.shape[0] - 1
    v_next = np.zeros((max(tools.kind.shape[0], 1), 3))
    for blk in prange((n_vertex + VERTEX_BLOCK - 1) // VERTEX_BLOCK):
        lo = blk * VERTEX_BLOCK
        cluster_block(lo, min(lo + VERTEX_BLOCK, n_vertex), np.int64(blk), dt, dt, nodes, ties, ctrl, tools, v_next)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tets", type=int, default=50_000, help="about this many tets")
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's)")
    parser.add_argument("--case", choices=("beam", "bar"), default="beam")
    parser.add_argument("--at-us", type=float, nargs="+", default=[4.0, 10.0, 18.0],
                        help="bar: simulated times (us) at which the passes are timed")
    args = parser.parse_args()
    if args.threads:
        import numba

        numba.set_num_threads(args.threads)
    warnings.simplefilter("ignore")
    if args.case == "bar":
        import tempfile

        import fracture_time_to_solution as fts

        mesh_file = fts.write_bar_mesh(Path(tempfile.mkdtemp()) / "bar.msh", 3.6e-3)
        sim = fts.bar_simulation(mesh_file, "extrinsic")
        dt = 0.7 * sim.stable_dt
        for at in sorted(args.at_us):
            sim.advance(max(0, int(round((at * 1e-6 - sim.time) / dt))), dt)
            label = f"bar at {sim.time * 1e6:.2f} us ({np.count_nonzero(sim.model.ties.tied != 1):,} faces inserted, " \
                    f"{sim.broken:,} failed; {sim.substeps} compiled step(s) of {dt / sim.substeps * 1e9:.3g} ns a driver step)"
            time_passes(sim, dt, label)
        return
    for insertion in ("intrinsic", "extrinsic"):
        model, dt, _ = fdem_throughput.build(args.tets, 4e-3, insertion=insertion)
        sim = FdemSimulation(model)
        sim.advance(200, dt)
        time_passes(sim, dt, f"{insertion}: {sim.model.n_tets:,} tets, step {dt * 1e9:.3g} ns")


def time_passes(sim, dt, label: str) -> None:
    """Each pass alone (10 calls of one step) and the whole step (10 calls of one driver step, per
    compiled step), 5 rounds interleaved, each round on a copy of the simulation (the state timed
    is `sim`'s, whatever the passes move): the median and the rounds in ms. The passes run at the
    compiled step (dt / sim.substeps)."""
    substeps = sim.substeps
    step = dt / substeps
    passes = {
        "interface": lambda s: kernels.interface_forces(0.0, step, s.model.nodes.x, s.model.nodes.v, s.model.ifs,
                                                        s.model.ties),
        "tet": lambda s: _tet_pass(step, s.model.nodes, s.model.tets, s.model.ifs, s.contact, s.model.tools,
                                   s.model.controls, s.model.ties),
    }
    if len(sim.model.ties.leader):
        passes["cluster"] = lambda s: _cluster_pass(step, s.model.nodes, s.model.ties, s.model.controls, s.model.tools)
    # Calls of one driver step: advance gives the copies their leaders' state once per call
    # (extrinsic.copies_block), as a run's chunks do.
    passes["whole step"] = lambda s: s.advance(1, dt)
    compiled_steps = {name: substeps if name == "whole step" else 1 for name in passes}
    for run in passes.values():
        run(copy.deepcopy(sim))  # compile
    rounds = {name: [] for name in passes}
    for _ in range(5):
        for name, run in passes.items():
            probe = copy.deepcopy(sim)
            t0 = time.perf_counter()
            for _ in range(10):
                run(probe)
            rounds[name].append((time.perf_counter() - t0) / (10 * compiled_steps[name]) * 1e3)
    print(label)
    for name, ms in rounds.items():
        print(f"  {name:10s} {statistics.median(ms):7.2f} ms  ({' '.join(f'{t:.2f}' for t in ms)})")


if __name__ == "__main__":
    main()

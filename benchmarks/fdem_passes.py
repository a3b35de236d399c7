"""Where the FDEM step's time goes: each pass of the step alone, on the throughput beam
(benchmarks/fdem_throughput.py's four-point bending, ~50k tets), intrinsic and extrinsic.

Per insertion mode: build, run 200 steps (contact under the platens), then time the interface
pass, the tet pass, (extrinsic) the node pass over the tied clusters, each 10 calls, and the
whole step, 10 calls of 10 steps, 5 rounds interleaved; prints the median and the rounds in ms.
Each pass alone runs on the current state (the tet pass of an intrinsic model also moves the
nodes: harmless for timing).

    python benchmarks/fdem_passes.py                # 2 threads by default (numba's)
    python benchmarks/fdem_passes.py --tets 13000
"""

from __future__ import annotations

import argparse
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
    args = parser.parse_args()
    if args.threads:
        import numba

        numba.set_num_threads(args.threads)
    warnings.simplefilter("ignore")
    for insertion in ("intrinsic", "extrinsic"):
        model, dt, _ = fdem_throughput.build(args.tets, 4e-3, insertion=insertion)
        sim = FdemSimulation(model)
        sim.advance(200, dt)
        m = sim.model
        passes = {
            "interface": lambda: kernels.interface_forces(0.0, dt, m.nodes.x, m.nodes.v, m.ifs, m.ties),
            "tet": lambda: _tet_pass(dt, m.nodes, m.tets, m.ifs, sim.contact, m.tools, m.controls, m.ties),
        }
        if insertion == "extrinsic":
            passes["cluster"] = lambda: _cluster_pass(dt, m.nodes, m.ties, m.controls, m.tools)
        # Calls of 10 steps, as a run's chunks: advance gives the copies their leaders' state
        # once per call (extrinsic.copies_block), not once per step.
        passes["whole step"] = lambda: sim.advance(10, dt)
        steps_per_call = {name: 10 if name == "whole step" else 1 for name in passes}
        for run in passes.values():
            run()  # compile
        rounds = {name: [] for name in passes}
        for _ in range(5):
            for name, run in passes.items():
                t0 = time.perf_counter()
                for _ in range(10):
                    run()
                rounds[name].append((time.perf_counter() - t0) / (10 * steps_per_call[name]) * 1e3)
        print(f"{insertion}: {m.n_tets:,} tets, step {dt * 1e9:.3g} ns")
        for name, ms in rounds.items():
            print(f"  {name:10s} {statistics.median(ms):7.2f} ms  ({' '.join(f'{t:.2f}' for t in ms)})")


if __name__ == "__main__":
    main()

"""Where the DEM step's time goes, and the floor of its memory traffic: the interaction pass and
the particle pass alone on dem_throughput.py's sample (100k particles at the paper's packing
density, 12 bonds each, both platens pressing), each beside a kernel that makes the same reads
and writes with the arithmetic stripped (the pass's memory floor with today's data layout).

Build (the packing from dem_throughput's cache), 20 steps, then each pass and its floor 10 calls
a round, 5 rounds interleaved (the state each floor scribbles on is put back after it); prints
the median and the rounds in ms, and the particle-steps per second the two floors together
would allow.

    python benchmarks/dem_passes.py                  # 2 threads by default (numba's)
    python benchmarks/dem_passes.py --particles 10000
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
from dem_throughput import PACKING_CACHE, PARTICLE_DENSITY, build_sample  # noqa: E402

from crackle.dem import kernels  # noqa: E402


@njit(parallel=True)
def _interaction_pass(dt, particles, inter):
    n_inter = inter.a.shape[0]
    for blk in prange((n_inter + kernels.BLOCK - 1) // kernels.BLOCK):
        lo = blk * kernels.BLOCK
        kernels._interaction_block(lo, min(lo + kernels.BLOCK, n_inter), 0.0, dt, particles, inter)


@njit(parallel=True)
def _interaction_floor(particles, inter):
    """Every array the interaction pass reads, read; shear and transfer rows written; no physics."""
    x, v, w, radius = particles.x, particles.v, particles.spin, particles.radius
    a_of, b_of, state, d0, kn, kt = inter.a, inter.b, inter.state, inter.d0, inter.kn, inter.kt
    fn_max, cohesion, tan_phi, shear, transfer = inter.fn_max, inter.cohesion, inter.tan_phi, inter.shear, inter.transfer
    n_inter = a_of.shape[0]
    for blk in prange((n_inter + kernels.BLOCK - 1) // kernels.BLOCK):
        for i in range(blk * kernels.BLOCK, min(n_inter, (blk + 1) * kernels.BLOCK)):
            a = a_of[i]
            b = b_of[i]
            s = d0[i] + kn[i] + kt[i] + fn_max[i] + cohesion[i] + tan_phi[i] + state[i] + radius[a] + radius[b]
            for d in range(3):
                s += x[b, d] - x[a, d] + v[b, d] - v[a, d] + w[b, d] + w[a, d]
            for d in range(3):
                shear[i, d] = 0.5 * (shear[i, d] + s)
            for d in range(kernels.TRANSFER_COLUMNS):
                transfer[i, d] = s


@njit(parallel=True)
def _particle_pass(dt, particles, inter, tools, gravity, alpha, membrane_area, membrane_moment, membrane_x):
    n = particles.x.shape[0]
    n_tool = tools.kind.shape[0]
    v_prev = np.zeros((max(n_tool, 1), 3))
    v_next = np.zeros((max(n_tool, 1), 3))
    pressure_now = np.zeros(max(membrane_area.shape[0], 1))
    for blk in prange((n + kernels.BLOCK - 1) // kernels.BLOCK):
        lo = blk * kernels.BLOCK
        kernels._particle_block(lo, min(lo + kernels.BLOCK, n), np.int64(blk), dt, particles, inter, tools, v_prev,
                                v_next, gravity, alpha, membrane_area, membrane_moment, membrane_x, pressure_now)


@njit(parallel=True)
def _particle_floor(particles, inter, out):
    """The particle pass's gather of its interactions' transfer rows and its particle rows read and
    written; no physics."""
    transfer, start, entry, sign = inter.transfer, inter.start, inter.entry, inter.sign
    x, v, w, mass, inertia = particles.x, particles.v, particles.spin, particles.mass, particles.inertia
    n = x.shape[0]
    for blk in prange((n + kernels.BLOCK - 1) // kernels.BLOCK):
        for g in range(blk * kernels.BLOCK, min(n, (blk + 1) * kernels.BLOCK)):
            s = mass[g] + inertia[g]
            for r in range(start[g], start[g + 1]):
                i = entry[r]
                for d in range(kernels.TRANSFER_COLUMNS):
                    s += sign[r] * transfer[i, d]
            for d in range(3):
                x[g, d] += 1e-30 * s
                v[g, d] += 1e-30 * s
                w[g, d] += 1e-30 * s
            out[g] = s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=100_000, help="about this many particles")
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's)")
    args = parser.parse_args()
    if args.threads:
        import numba

        numba.set_num_threads(args.threads)
    warnings.simplefilter("ignore")
    sim = build_sample(args.particles, PARTICLE_DENSITY, PACKING_CACHE)[0]
    dt = 0.7 * sim.stable_dt
    sim.advance(20, dt)
    p, inter = sim.particles, sim.inter
    out = np.zeros(len(p.radius))
    # The floors scribble on the state: each is followed by putting it back.
    kept = [p.x, p.v, p.spin, inter.shear, inter.transfer]
    saved = [a.copy() for a in kept]
    passes = {
        "interaction": lambda: _interaction_pass(dt, p, inter),
        "interaction floor": lambda: _interaction_floor(p, inter),
        # No membrane on this sample: the step's empty membrane arrays (no_membrane).
        "particle": lambda: _particle_pass(dt, p, inter, sim.tools, sim.gravity, sim.damping, *sim._membrane_args[:3]),
        "particle floor": lambda: _particle_floor(p, inter, out),
    }
    rounds = {name: [] for name in passes}
    for r in range(6):  # the first round compiles and is dropped
        for name, run in passes.items():
            t0 = time.perf_counter()
            for _ in range(10):
                run()
            if r:
                rounds[name].append((time.perf_counter() - t0) / 10 * 1e3)
            for a, b in zip(kept, saved):
                a[:] = b
    print(f"{len(p.radius):,} particles, {len(inter.a):,} interactions")
    for name, ms in rounds.items():
        print(f"  {name:18s} {statistics.median(ms):7.2f} ms  ({' '.join(f'{t:.2f}' for t in ms)})")
    floor = statistics.median(rounds["interaction floor"]) + statistics.median(rounds["particle floor"])
    print(f"  the two floors: {floor:.2f} ms a step, at most {len(p.radius) / floor * 1e-3:.2f} M particle-steps/s "
          "with this layout")


if __name__ == "__main__":
    main()

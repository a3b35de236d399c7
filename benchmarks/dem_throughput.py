"""Throughput of the bonded-particle DEM step (interaction pass, particle pass, tools, spins).

Set-up, per size: a box twice as tall as wide packed with the paper-003 radius distribution
(Rmax/Rmin = 1.86, seed 1) at its packing density, 1.47 spheres per cubed mean diameter
(`--particle-density`, the examples' default; 0: porosity 0.40 without overlaps, as before
2026-11-27), bonded to 12 bonds per particle with the Table 1
parameters, between two frictionless box platens; the top one moves down at 0.1 m/s so that the
platens press on the sample while the step is timed (elastic range: no bond breaks in the timed
steps). dt = 0.7 x the stable step.

Procedure, per size: pack (timed: `packing_s`; the packing is kept in `--packing-cache`, keyed by
its arguments and the packing code's source, so that a later run with the same ones loads it:
`packing_s` is then the load's), build, warm up (the first call compiles or loads the numba
cache), then time `--steps` steps `--repeats` times and keep the median. Each size runs
in its own Python process, so that `peak_rss_mb` belongs to that size alone.

Output: one line per size, then one JSON object on the last line:

    {"sizes": [{"particles", "bonds", "interactions", "packing_s", "seconds_per_step",
                "particle_steps_per_s", "bytes_per_particle", "peak_rss_mb", "threads", "bandwidth_gb_s",
                "bandwidth_fraction"}, ...]}

bytes_per_particle: nbytes of every array of the particles and interactions (bonds and listed
contacts) over the particle count: each is streamed through at least once a step, so it is also a
lower bound on the bytes a particle-step moves. bandwidth_fraction: that times the
particle-steps per second over this machine's triad bandwidth with the same threads
(benchmarks/bandwidth.py, `bandwidth_gb_s`).

    python benchmarks/dem_throughput.py --threads 2                 # 10k and 100k particles
    python benchmarks/dem_throughput.py --sizes 10000 --repeats 3
    python benchmarks/dem_throughput.py --sizes 10000 --particle-density 0   # porosity 0.40
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

# Paper 003's packing density (spheres per cubed mean diameter) and where packed samples are kept.
PARTICLE_DENSITY = 1.47
PACKING_CACHE = os.path.join(tempfile.gettempdir(), "crackle-bench-packings")


def cached_packing(domain, cache_dir: str, **kwargs):
    """pack_spheres(domain, **kwargs), kept as centres and radii in cache_dir under a key of the
    arguments and the source of the packer and its domains (the same seed packs the same spheres
    bit for bit)."""
    import hashlib
    from pathlib import Path

    from crackle.dem import domains as domains_module, packing as packing_module
    from crackle.dem.packing import Packing, pack_spheres

    key = hashlib.sha1(Path(packing_module.__file__).read_bytes() + Path(domains_module.__file__).read_bytes())
    key.update(repr((domain.lo.tolist(), domain.hi.tolist(), sorted(kwargs.items()))).encode())
    path = Path(cache_dir) / f"packing-{key.hexdigest()[:16]}.npz"
    if path.exists():
        return Packing.load(path)
    packing = pack_spheres(domain, **kwargs)
    path.parent.mkdir(parents=True, exist_ok=True)
    packing.save(path)
    return packing


MEAN_RADIUS = 1e-3  # m


def sample_packing(n_particles: int, particle_density: float, cache_dir: str):
    """n spheres packed in a side x side x 2 side box at the density (or at porosity 0.4 with
    particle_density 0): the packing, the side (m) and the seconds the packing took (or its load)."""
    import numpy as np

    from crackle.dem.domains import Box

    if particle_density > 0.0:
        volume = n_particles * (2.0 * MEAN_RADIUS) ** 3 / particle_density
    else:
        volume = n_particles * 4.0 / 3.0 * math.pi * MEAN_RADIUS**3 * 1.05 / 0.6
    side = (volume / 2.0) ** (1.0 / 3.0)
    started = time.perf_counter()
    packing = cached_packing(Box(np.zeros(3), np.array([side, side, 2 * side])), cache_dir, porosity=0.4,
                             mean_radius=MEAN_RADIUS, seed=1, particle_density=particle_density or None)
    return packing, side, time.perf_counter() - started


def table1_law():
    """Paper 003's Table 1 bond law."""
    from crackle.dem.model import BondLaw

    return BondLaw(50e9, 1.0 / 3.0, 4.5e6, 45e6, math.radians(18.0), math.radians(18.0))


def build_sample(n_particles: int, particle_density: float, cache_dir: str):
    """The benchmark's sample: n spheres packed in a 1 x 1 x 2 box at the density (or at porosity
    0.4 with particle_density 0), bonded with paper 003's Table 1 law between two platens, the top
    one moving down. Returns the simulation, the packing and the seconds the packing took."""
    from crackle.dem.build import build_dem_simulation
    from crackle.loading import History, Tool

    mean_radius = MEAN_RADIUS
    packing, side, packing_s = sample_packing(n_particles, particle_density, cache_dir)
    plate = (3 * side, 3 * side, 10 * mean_radius)
    top = Tool("top", "box", (0.0, 0.0, -1.0), History.ramp(0.1, 1e-5),
               center=(0.5 * side, 0.5 * side, 2 * side + 5 * mean_radius), size=plate)
    bottom = Tool("bottom", "box", (0.0, 0.0, 1.0), History.constant(0.0),
                  center=(0.5 * side, 0.5 * side, -5 * mean_radius), size=plate)
    sim = build_dem_simulation(packing.centers, packing.radii, 2500.0, table1_law(), bonds_per_particle=12.0,
                               tools=[top, bottom], damping=0.2)
    return sim, packing, packing_s


def one_size(n_particles: int, steps: int, repeats: int, particle_density: float, cache_dir: str) -> dict:
    import numba

    sim, packing, packing_s = build_sample(n_particles, particle_density, cache_dir)
    dt = 0.7 * sim.stable_dt
    sim.advance(20, dt)  # compile or load the cache
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.advance(steps, dt)
        times.append((time.perf_counter() - t0) / steps)
    per_step = statistics.median(times)
    arrays = list(sim.particles) + list(sim.inter)
    nbytes = sum(a.nbytes for a in arrays if hasattr(a, "nbytes"))
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    from bandwidth import memory_bandwidth  # after the peak RSS: its arrays are 768 MB

    bandwidth = memory_bandwidth()
    return {
        "particles": len(packing.radii),
        "bonds": sim.n_bonds,
        "interactions": len(sim.inter.a),
        "broken": sim.broken,
        "packing_s": packing_s,
        "seconds_per_step": per_step,
        "particle_steps_per_s": len(packing.radii) / per_step,
        "bytes_per_particle": nbytes / len(packing.radii),
        "peak_rss_mb": peak_rss_mb,
        "threads": numba.get_num_threads(),
        "repeat_seconds": times,
        "bandwidth_gb_s": bandwidth / 1e9,
        "bandwidth_fraction": nbytes / per_step / bandwidth,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000], help="particle counts")
    parser.add_argument("--steps", type=int, default=200, help="steps per timed repeat")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's)")
    parser.add_argument("--particle-density", type=float, default=PARTICLE_DENSITY,
                        help="spheres per cubed mean diameter (0: porosity 0.40 without overlaps)")
    parser.add_argument("--packing-cache", default=PACKING_CACHE,
                        help="folder of packed samples kept between runs (default: in the temp folder)")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one size
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_size(args.one, args.steps, args.repeats, args.particle_density, args.packing_cache)))
        return
    env = dict(os.environ)
    if args.threads:
        env["NUMBA_NUM_THREADS"] = str(args.threads)
    rows = []
    for n in args.sizes:
        proc = subprocess.run([sys.executable, __file__, "--one", str(n), "--steps", str(args.steps), "--repeats",
                               str(args.repeats), "--particle-density", str(args.particle_density),
                               "--packing-cache", args.packing_cache],
                              env=env, capture_output=True, text=True, check=True)
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(f"{row['particles']:>8,} particles {row['bonds']:>9,} bonds: {row['seconds_per_step'] * 1e3:8.2f} ms/step, "
              f"{row['particle_steps_per_s'] / 1e6:6.2f} M particle-steps/s, {row['bytes_per_particle']:6.0f} B/particle, "
              f"packing {row['packing_s']:.1f} s, peak RSS {row['peak_rss_mb']:.0f} MB, {row['threads']} threads, "
              f"at least {100 * row['bandwidth_fraction']:.0f} % of the {row['bandwidth_gb_s']:.1f} GB/s triad bandwidth")
    print(json.dumps({"sizes": rows}))


if __name__ == "__main__":
    main()

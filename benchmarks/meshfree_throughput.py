"""Throughput of the complete meshfree (EFG) step (stress pass, gather, tool contact, integrator).

Set-up, per size: a square aluminium plate 10 mm thick, 3 particles through the thickness at a
15 mm in-plane spacing (the plate-impact example's discretisation and J2 law: E = 71 GPa, yield
150 MPa), clamped on its four edges, with a rigid 40 mm sphere starting 0.1 mm above its centre
and moving down at 300 m/s, so that it is in contact (and the plate yields under it) during the
timed steps. No fracture (the checks are between steps, numpy). dt = 0.7 x the stable step (the
driver's default).

Procedure, per size: build (timed: `build_s`, the Lanczos stable step included: `stable_step_s`),
warm up (the first call compiles or loads the numba cache; 20 steps), pick the step count so that
one repeat takes about `--seconds`, time `--repeats` repeats and keep the median. Each size runs in
its own Python process, so that `peak_rss_mb` (getrusage maxrss, build included) belongs to that
size alone.

Output: one line per size, then one JSON object on the last line:

    {"sizes": [{"particles", "links", "steps", "seconds_per_step", "particle_steps_per_s",
                "bytes_per_particle", "peak_rss_mb", "build_peak_rss_mb", "threads", "dt", "build_s",
                "stable_step_s", "repeat_seconds", "cpu_utilisation", "cpu_seconds_per_step",
                "idle_percent_before", "forces_seconds_per_step", "forces_fraction", "bandwidth_gb_s",
                "bandwidth_fraction"}, ...]}

bytes_per_particle: nbytes of every array of the particles and the links over the particle count.
Each is streamed through at least once a step (the links by the gradient pass and again,
transposed, by the gather), so it is also a lower bound on the bytes a particle-step moves:
bandwidth_fraction = bytes_per_particle x particle_steps_per_s / this machine's triad bandwidth
with the same threads (benchmarks/bandwidth.py: `bandwidth_gb_s`), the share of the memory
system the step uses at the least.
build_peak_rss_mb: maxrss when the build returns, the set-up's own peak (peak_rss_mb also counts
the steps, and the copy of the state that the forces timing makes).
cpu_seconds_per_step: process CPU time per step (all threads; median of the repeats): on a shared
machine, where the wall time counts the waits for a core, it is the steadier measure of the work.
forces_seconds_per_step: the stress pass and the gather alone (kernels.internal_forces, the same
passes the step runs; median of the same repeats), so the rest of the step (tool contact,
supports, integrator) is the difference; forces_fraction its share of the step.

    python benchmarks/meshfree_throughput.py --threads 2         # ~50k and ~280k particles
    python benchmarks/meshfree_throughput.py --threads 1 --repeats 3
    python benchmarks/meshfree_throughput.py --quick              # ~2k particles, a smoke test
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
import time

from fdem_throughput import machine_idle_percent

SPACING = 0.015  # m, in-plane
THICKNESS = 0.01  # m
LAYERS = 3


def build(n_particles: int):
    """The clamped plate with about n_particles particles and the sphere above its centre."""
    import numpy as np

    from crackle.loading import History, Selection, Support, Tool
    from crackle.meshfree.build import build_meshfree_simulation
    from crackle.meshfree.material import J2Law
    from crackle.meshfree.particles import plate_particles

    side = max(3, round(math.sqrt(n_particles / LAYERS))) - 1  # grid steps along each in-plane side
    size = side * SPACING
    plate = plate_particles((-0.5 * size, -0.5 * size, 0.0), (size, size, THICKNESS), SPACING, LAYERS)
    sphere = Tool("sphere", "sphere", (0.0, 0.0, -1.0), History.constant(300.0), center=(0.0, 0.0, THICKNESS + 0.0201),
                  radius=0.02)
    edges = []
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            point, normal = np.zeros(3), np.zeros(3)
            point[axis], normal[axis] = sign * 0.5 * size, 1.0
            edges.append(Support("fixed", Selection(plane_point=tuple(point), plane_normal=tuple(normal))))
    law = J2Law(71e9, 0.3, yield_stress=150e6)
    return build_meshfree_simulation(plate, 2700.0, law, tools=[sphere], supports=edges)


def model_bytes(sim) -> int:
    return sum(a.nbytes for a in (*sim.particles, *sim.links) if hasattr(a, "nbytes"))


def one_size(n_particles: int, seconds: float, repeats: int) -> dict:
    import numba
    import numpy as np

    from crackle.meshfree import step as mf_step
    from crackle.meshfree.kernels import internal_forces

    started = time.perf_counter()
    step_time = []
    lanczos = mf_step.highest_frequency2

    def timed(*args):  # the set-up's Lanczos estimate, timed apart
        t0 = time.perf_counter()
        out = lanczos(*args)
        step_time.append(time.perf_counter() - t0)
        return out

    mf_step.highest_frequency2 = timed
    sim = build(n_particles)
    mf_step.highest_frequency2 = lanczos
    build_s = time.perf_counter() - started
    build_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    dt = 0.7 * sim.stable_dt
    sim.advance(20, dt)  # compile or load the cache
    t0 = time.perf_counter()
    sim.advance(20, dt)
    steps = max(10, int(seconds / ((time.perf_counter() - t0) / 20)))
    idle = machine_idle_percent()
    times, cpu = [], []
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        sim.advance(steps, dt)
        times.append((time.perf_counter() - t0) / steps)
        cpu.append(time.process_time() - c0)
    per_step = statistics.median(times)
    # The stress pass and the gather alone, on a copy of the state (the stress pass writes it).
    p = sim.particles._replace(**{k: getattr(sim.particles, k).copy() for k in
                                  ("plastic", "eq_plastic", "w_plastic", "stress", "deformation", "internal",
                                   "bending", "stab_force", "thermal")})
    links = sim.links
    force = np.zeros_like(p.x)
    internal_forces(dt, p, links, sim.columns, sim.law, force)
    force_times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            internal_forces(dt, p, links, sim.columns, sim.law, force)
        force_times.append((time.perf_counter() - t0) / steps)
    n = len(sim.particles.x)
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    from bandwidth import memory_bandwidth  # after the peak RSS: its arrays are 768 MB

    bandwidth = memory_bandwidth()
    return {
        "particles": n,
        "links": int(len(sim.links.neighbour) - n),
        "steps": steps,
        "seconds_per_step": per_step,
        "particle_steps_per_s": n / per_step,
        "bytes_per_particle": model_bytes(sim) / n,
        "peak_rss_mb": peak_rss_mb,
        "build_peak_rss_mb": build_rss_mb,
        "threads": numba.get_num_threads(),
        "dt": dt,
        "build_s": build_s,
        "stable_step_s": sum(step_time),
        "repeat_seconds": times,
        "cpu_utilisation": sum(cpu) / (sum(times) * steps * numba.get_num_threads()),
        "cpu_seconds_per_step": statistics.median(cpu) / steps,
        "idle_percent_before": idle,
        "forces_seconds_per_step": statistics.median(force_times),
        "forces_fraction": statistics.median(force_times) / per_step,
        "max_plastic_strain": float(np.max(sim.particles.eq_plastic)),
        "bandwidth_gb_s": bandwidth / 1e9,
        "bandwidth_fraction": model_bytes(sim) / per_step / bandwidth,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50_000, 280_000], help="particle counts (about)")
    parser.add_argument("--seconds", type=float, default=3.0, help="target duration of one timed repeat")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's)")
    parser.add_argument("--quick", action="store_true", help="one small size, short repeats: a smoke test")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one size
    args = parser.parse_args()
    if args.one:
        if args.threads:
            import numba

            numba.set_num_threads(args.threads)
        print(json.dumps(one_size(args.one, args.seconds, args.repeats)))
        return
    if args.quick:
        args.sizes, args.seconds = [2_000], 0.3
    env = dict(os.environ)
    rows = []
    for n in args.sizes:
        argv = [sys.executable, __file__, "--one", str(n), "--seconds", str(args.seconds), "--repeats",
                str(args.repeats)] + (["--threads", str(args.threads)] if args.threads else [])
        proc = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(f"{row['particles']:>8,} particles {row['links']:>10,} links: {row['seconds_per_step'] * 1e3:8.2f} ms/step, "
              f"{row['particle_steps_per_s'] / 1e6:6.2f} M particle-steps/s, {row['bytes_per_particle']:6.0f} B/particle, "
              f"forces {100 * row['forces_fraction']:.0f} % of the step, peak RSS {row['peak_rss_mb']:.0f} MB "
              f"(build {row['build_peak_rss_mb']:.0f} MB), "
              f"{row['threads']} threads, build {row['build_s']:.1f} s (stable step {row['stable_step_s']:.1f} s), "
              f"CPU utilisation {row['cpu_utilisation']:.2f} ({row['cpu_seconds_per_step'] * 1e3:.2f} CPU ms/step), "
              f"at least {100 * row['bandwidth_fraction']:.0f} % of the {row['bandwidth_gb_s']:.1f} GB/s triad bandwidth")
        if (row["idle_percent_before"] or 100.0) < 90.0 or row["cpu_utilisation"] < 0.85:
            print(f"warning: {row['particles']} particles: the machine looked busy (idle "
                  f"{row['idle_percent_before']}, utilisation {row['cpu_utilisation']:.2f}); timings are unreliable",
                  file=sys.stderr)
    print(json.dumps({"sizes": rows}))


if __name__ == "__main__":
    main()

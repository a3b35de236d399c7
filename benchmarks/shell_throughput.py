"""Throughput of the shell's explicit step (edge angles, face membrane and moments, hinge forces,
node gather with tools and the integrator, the mid-edge rotations' step) and the cost of one J-integral.

Set-up, per size: a square 1 mm steel sheet of about N triangles (a structured rectangle), free,
with a centre crack of 20 cells, every node given a random velocity (in plane and out of it,
0.1 m/s: membrane and bending both work); dt = 0.7 x the stable step (Lanczos, the driver's
default safety). Warm up (compile or cache load, 10 steps), pick the step count so that one
repeat takes about --seconds, time --repeats repeats and keep the median. Then the J-integral at
one tip over a ring of 4-10 cells (median of 5 calls). Each size runs in its own process, so that
peak_rss_mb (maxrss) belongs to it.

Output: one line per size, then one JSON object on the last line:

    {"sizes": [{"triangles", "nodes", "threads", "steps", "seconds_per_step", "triangle_steps_per_s",
                "bytes_per_triangle", "peak_rss_mb", "build_s", "j_integral_s", "bandwidth_gb_s",
                "bandwidth_fraction"}, ...]}

bytes_per_triangle: the nodes', faces' and edges' arrays over the triangle count, all read every
step (a lower bound on the bytes a triangle-step moves); bandwidth_fraction = bytes_per_triangle x
triangle_steps_per_s / this machine's triad bandwidth with the same threads (benchmarks/bandwidth.py).

    python benchmarks/shell_throughput.py --threads 2          # 100k and 1M triangles
    python benchmarks/shell_throughput.py --quick               # 10k triangles, a smoke test
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


def measure(n_triangles: int, seconds: float, repeats: int) -> dict:
    import numpy as np

    from crackle.loading.arrays import tool_arrays
    from crackle.shell.jintegral import j_integral
    from crackle.shell.kernels import BLOCK, NO_PRESSURE, LoadFactor, advance
    from crackle.shell.mesh import edge_path, rectangle, split_along
    from crackle.shell.model import ShellMaterial, build_shell

    started = time.perf_counter()
    cells = max(24, round(math.sqrt(n_triangles / 2)))
    h = 1e-3
    size = cells * h
    mesh = rectangle(size, size, cells, cells, 1e-3, origin=(-0.5 * size, -0.5 * size, 0.0))
    a = 10 * h
    mesh, _ = split_along(mesh, edge_path(mesh, [(-a, 0, 0), (a, 0, 0)]))
    shell = build_shell(mesh, ShellMaterial(7800.0, 2e11, 0.3))
    n = len(mesh.X)
    shell.nodes.v[:] = np.random.default_rng(0).uniform(-0.1, 0.1, (n, 3))
    tools = tool_arrays([], 0.0, h, -(-n // BLOCK))
    factor = LoadFactor(np.array([0.0]), np.array([1.0]), 1)
    dt = 0.7 * shell.stable_dt() / 0.95
    build_s = time.perf_counter() - started
    args = (shell.nodes, shell.faces, shell.edges, tools, factor, NO_PRESSURE, np.zeros(3), 0.0)
    advance(10, 0, dt, *args)
    t0 = time.perf_counter()
    advance(10, 10, dt, *args)
    per_step = (time.perf_counter() - t0) / 10
    steps = max(10, int(seconds / per_step))
    times = []
    first = 20
    for _ in range(repeats):
        t0 = time.perf_counter()
        advance(steps, first, dt, *args)
        times.append(time.perf_counter() - t0)
        first += steps
    seconds_per_step = statistics.median(times) / steps
    j_times = []
    for _ in range(5):
        t0 = time.perf_counter()
        j_integral(shell, shell.nodes.x, (a, 0.0, 0.0), (1.0, 0.0, 0.0), 4 * h, 10 * h)
        j_times.append(time.perf_counter() - t0)
    arrays = [*shell.nodes, *shell.faces, *shell.edges]
    nbytes = sum(x.nbytes for x in arrays if isinstance(x, np.ndarray))
    m = len(mesh.tri)
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    from bandwidth import memory_bandwidth  # after the peak RSS: its arrays are 768 MB

    bandwidth = memory_bandwidth()
    return {
        "triangles": m, "nodes": n, "threads": int(os.environ.get("NUMBA_NUM_THREADS", "0") or 0), "steps": steps,
        "seconds_per_step": seconds_per_step, "triangle_steps_per_s": m / seconds_per_step,
        "bytes_per_triangle": nbytes / m, "peak_rss_mb": peak_rss_mb,
        "build_s": build_s, "j_integral_s": statistics.median(j_times),
        "finite": bool(np.isfinite(shell.nodes.x).all()),
        "bandwidth_gb_s": bandwidth / 1e9, "bandwidth_fraction": nbytes / seconds_per_step / bandwidth,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--sizes", type=int, nargs="*", default=[100_000, 1_000_000])
    parser.add_argument("--seconds", type=float, default=5.0, help="per repeat")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="10k triangles, 1 s repeats")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one, args.seconds, args.repeats)))
        return
    sizes = [10_000] if args.quick else args.sizes
    seconds = 1.0 if args.quick else args.seconds
    results = []
    for size in sizes:
        env = dict(os.environ, NUMBA_NUM_THREADS=str(args.threads))
        done = subprocess.run([sys.executable, __file__, "--one", str(size), "--seconds", str(seconds), "--repeats",
                               str(args.repeats)], env=env, check=True, capture_output=True, text=True)
        r = json.loads(done.stdout.strip().splitlines()[-1])
        results.append(r)
        print(f"{r['triangles']:>9,} triangles, {r['threads']} threads: {r['triangle_steps_per_s'] / 1e6:6.2f} M "
              f"triangle-steps/s ({r['seconds_per_step'] * 1e3:.2f} ms/step), {r['bytes_per_triangle']:.0f} B/triangle, "
              f"peak {r['peak_rss_mb']:.0f} MB, J-integral {r['j_integral_s'] * 1e3:.1f} ms, build {r['build_s']:.1f} s, "
              f"at least {100 * r['bandwidth_fraction']:.0f} % of the {r['bandwidth_gb_s']:.1f} GB/s triad bandwidth")
    print(json.dumps({"sizes": results}))


if __name__ == "__main__":
    main()

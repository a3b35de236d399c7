"""Throughput of the complete FDEM step (bulk, interfaces, tool contact, integration).

Set-up, per size: a structured_box beam (24 tets per cell, square cross-section, length about
four times the depth) of the paper-001 rock, in four-point bending: two rigid box platens resting
on the top face move down with a ramped speed (so they are in contact during the timing), the
bottom is held by a fixed line support at one end and a roller line support at the other.
dt = 0.8 * model.stable_dt.

Procedure, per size: build the model, warm up (the first call compiles or loads the numba cache
and is not timed), estimate the step time, then time `steps` steps `--repeats` times and keep the
median. Each size runs in its own Python process by default, so that `peak_rss_mb` (getrusage
maxrss, model build included) belongs to that size alone; --in-process turns this off.

Output: one human-readable line per size, then LAST one JSON object on one line:

    {"sizes": [{"tets": ..., "interfaces": ..., "steps": ..., "seconds_per_step": ...,
                "tet_steps_per_s": ..., "bytes_per_tet": ..., "peak_rss_mb": ...,
                "threads": ..., <extra keys>}, ...], "threads": N}

bytes_per_tet: nbytes of every numpy array in the model's nodes/tets/ifs/tools/pressures/controls/ties
tuples plus model.x0, over the tet count: the step reads them all, so it is also a lower bound on
the bytes a tet-step moves; bandwidth_fraction = bytes_per_tet x tet_steps_per_s / this
machine's triad bandwidth with the same threads (benchmarks/bandwidth.py: bandwidth_gb_s), the
share of the memory system the step reaches at least. Extra keys per size: contact_bytes_per_tet (arrays of
the simulation's node-to-surface contact state, not counted in bytes_per_tet), cells, dt,
simulated_us_per_s (the time to solution: dt / seconds_per_step, in us of simulated time a second),
tool_contact_nodes (nodes touching a platen at the end: contact is exercised), build_s,
repeat_seconds, cpu_utilisation (process CPU time / (wall x threads) over the
repeats) and idle_percent_before (idle share of the machine over 1 s before timing). The last two
expose a busy machine: a warning goes to stderr when idle < 90 % or utilisation < 0.85.

--breakdown adds, per size, the interface pass alone (crackle.fdem.kernels.interface_forces at
the current state, median of the same repeats): `interface_seconds_per_step` and
`interface_fraction` (its share of the complete step).

Examples:

    python benchmarks/fdem_throughput.py --threads 2
    python benchmarks/fdem_throughput.py --sizes 50000 --repeats 5 --seconds 2 --breakdown
    python benchmarks/fdem_throughput.py --law bilinear --sizes 13000 50000   # paper-004 walnut law
    python benchmarks/fdem_throughput.py --insertion extrinsic --sizes 50000   # tied faces, node pass
    python benchmarks/fdem_throughput.py --mesh gmsh --sizes 50000             # unstructured, Morton-ordered
    python benchmarks/fdem_throughput.py --mesh file --sizes 50000             # the same read from a .msh file
    python benchmarks/fdem_throughput.py --mesh file-order --sizes 50000       # in gmsh's own order
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
import warnings

# Targets from the issue (200k tets on 2 cores).
TARGET_TET_STEPS_PER_S = 5.0e6
TARGET_BYTES_PER_TET = 2048.0

TETS_PER_CELL = 24
ASPECT = 4  # beam length / depth (cells)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[50000, 200000],
                   help="approximate tet counts (default: 50000 200000)")
    p.add_argument("--law", choices=("guo-munjiza", "bilinear"), default="guo-munjiza",
                   help="interface law: the paper-001 rock (Guo-Munjiza) or the paper-004 walnut face (bilinear)")
    p.add_argument("--insertion", choices=("intrinsic", "extrinsic"), default="intrinsic",
                   help="interfaces carrying the law from the start, or tied until inserted (fdem.extrinsic)")
    p.add_argument("--repeats", type=int, default=3, help="timed repeats per size, median kept (default 3)")
    p.add_argument("--threads", type=int, default=None,
                   help="numba threads (numba.set_num_threads); default: numba's default")
    p.add_argument("--seconds", type=float, default=3.0,
                   help="target duration of one timed repeat, sets the step count (default 3)")
    p.add_argument("--steps", type=int, default=None, help="fixed step count per repeat (overrides --seconds)")
    p.add_argument("--cell", type=float, default=4e-3,
                   help="cell edge of the structured box in m (default 4 mm; 24 tets per cell)")
    p.add_argument("--mesh", choices=("structured", "gmsh", "file", "file-order"), default="structured",
                   help="the beam meshed by structured_box (default) or by gmsh (unstructured, the same "
                        "box, its element size set for about the --sizes tet count); file: that gmsh mesh "
                        "written to a .msh and read back as a scenario's `specimen.file` is; file-order: the "
                        "gmsh mesh in gmsh's own order, as a file's mesh was stepped before it was ordered")
    p.add_argument("--breakdown", action="store_true",
                   help="also time the interface pass alone (interface_forces)")
    p.add_argument("--in-process", action="store_true",
                   help="run all sizes in this process (peak_rss_mb is then cumulative)")
    p.add_argument("--_child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.repeats < 1:
        p.error("--repeats must be >= 1")
    if args.threads is not None and args.threads < 1:
        p.error("--threads must be >= 1")
    if any(s < TETS_PER_CELL for s in args.sizes):
        p.error(f"--sizes must be >= {TETS_PER_CELL}")
    return args


def beam_cells(target_tets: int) -> tuple[int, int, int]:
    """Cells (nx, ny, nz) of a beam with square section, nx ~ ASPECT * ny, ~target_tets tets."""
    cells = target_tets / TETS_PER_CELL
    n = max(1, round((cells / ASPECT) ** (1.0 / 3.0)))
    nx = max(1, round(cells / (n * n)))
    return nx, n, n


def material(law: str, insertion: str = "intrinsic"):
    """The paper-001 rock with the Guo-Munjiza law, or the paper-004 walnut face (Table 1) with
    the bilinear law; `insertion` of the interfaces."""
    from crackle.fdem.laws import BilinearLaw, GuoMunjizaLaw
    from crackle.materials import Material

    if law == "bilinear":
        return Material(1250.0, 11.6e9, 0.29, BilinearLaw(7e6, 7e6, 770.0, 636.36e9, 636.36e9, friction=0.3,
                                                                  insertion=insertion),
                        name="walnut face")
    return Material(2340.0, 26e9, 0.2, GuoMunjizaLaw(3e6, 15e6, 30.0, 10.0, insertion=insertion), name="rock")


def gmsh_beam(size, target_tets: int, kind: str = "gmsh"):
    """The box meshed by gmsh with about target_tets tets: meshed once at a guessed element size,
    then again at the size scaled by the cube root of the count's ratio; in the order a scenario's
    gmsh mesh gets (locality_order), or (kind "file") written to a gmsh file and read back as a
    scenario's specimen file is, or (kind "file-order") in gmsh's own order."""
    import tempfile
    import types
    from pathlib import Path

    import meshio

    from crackle.geometry import gmsh_box
    from crackle.geometry.meshes import locality_order
    from crackle.geometry.specimens import specimen_mesh

    h = (size[0] * size[1] * size[2] * 6.0 / target_tets) ** (1.0 / 3.0)
    mesh = gmsh_box(size, h)
    h *= (len(mesh.tets) / target_tets) ** (1.0 / 3.0)
    mesh = gmsh_box(size, h)
    if kind == "file-order":
        return mesh, h
    if kind == "file":
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "beam.msh"
            meshio.write(path, meshio.Mesh(mesh.points, [("tetra", mesh.tets)]), file_format="gmsh22", binary=False)
            return specimen_mesh(types.SimpleNamespace(shape="mesh", file=str(path), scale=1.0), None)[0], h
    return locality_order(mesh)[0], h


def build(target_tets: int, cell: float, law: str = "guo-munjiza", insertion: str = "intrinsic",
          mesh_kind: str = "structured"):
    """Four-point bending of a beam: model and time step."""
    from crackle.fdem.model import build_fdem_model
    from crackle.geometry import structured_box
    from crackle.loading import History, Selection, Support, Tool

    rock = material(law, insertion)
    nx, ny, nz = beam_cells(target_tets)
    L, W, H = nx * cell, ny * cell, nz * cell
    if mesh_kind != "structured":
        mesh, h = gmsh_beam((L, W, H), target_tets, mesh_kind)
        reach = 0.5 * h  # the line supports take the bottom nodes within half an element
    else:
        mesh = structured_box((L, W, H), cell)
        reach = 1e-3 * cell

    tol = 1e-3 * cell
    # Line supports along y on the bottom face, one cell in from each end.
    xs_left, xs_right = (cell, L - cell) if nx >= 3 else (0.0, L)
    supports = [
        Support("fixed", Selection(plane_point=(0, 0, 0), plane_normal=(0, 0, 1),
                                   box_min=(xs_left - reach, -1, -1), box_max=(xs_left + reach, 1, 1), tol=tol)),
        Support("roller", Selection(plane_point=(0, 0, 0), plane_normal=(0, 0, 1),
                                    box_min=(xs_right - reach, -1, -1), box_max=(xs_right + reach, 1, 1), tol=tol),
                normal=(0.0, 0.0, 1.0)),
    ]
    # Two platens at the thirds, resting on the top face (bottom face at z = H), wider than the
    # beam, moving down at a speed ramped from 0 to 0.05 m/s over 1 ms.
    speed = History.ramp(0.05, 1e-3)
    tools = [
        Tool(name=name, shape="box", direction=(0.0, 0.0, -1.0), speed=speed, friction=0.3,
             center=(xc, 0.5 * W, H + cell), size=(2.0 * cell, W + 4.0 * cell, 2.0 * cell))
        for name, xc in (("left", L / 3.0), ("right", 2.0 * L / 3.0))
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # process-zone resolution advice: irrelevant here
        model = build_fdem_model(mesh, rock, tools=tools, supports=supports)
    return model, 0.8 * model.stable_dt, (nx, ny, nz)


def machine_idle_percent(seconds: float = 1.0) -> float | None:
    """Idle share of all CPUs over `seconds` (Linux /proc/stat), None where unavailable.

    Other processes on the machine slow the timed steps (CPU and memory bandwidth): the
    benchmark reports this so that a busy machine shows in the numbers."""
    def read():
        with open("/proc/stat") as fh:
            vals = [int(v) for v in fh.readline().split()[1:]]
        return sum(vals), vals[3] + (vals[4] if len(vals) > 4 else 0)

    try:
        total0, idle0 = read()
        time.sleep(seconds)
        total1, idle1 = read()
    except (OSError, ValueError, IndexError):
        return None
    return 100.0 * (idle1 - idle0) / max(total1 - total0, 1)


def model_bytes(model) -> int:
    """Bytes of every numpy array in the model's state tuples, plus x0, each array once (without
    tied faces the ties' na_at / nb_at are ifs.na / nb themselves)."""
    import numpy as np

    arrays = {id(model.x0): model.x0}
    for group in (model.nodes, model.tets, model.ifs, model.tools, model.pressures, model.controls, model.ties):
        arrays.update((id(a), a) for a in group if isinstance(a, np.ndarray))
    return sum(a.nbytes for a in arrays.values())


def contact_bytes(sim) -> int:
    """Bytes of the arrays of the simulation's node-to-surface contact state (0 if it has none);
    not part of bytes_per_tet, reported beside it."""
    import numpy as np

    state = getattr(sim, "contact", None)
    if not isinstance(state, tuple):
        return 0
    return sum(a.nbytes for a in state if isinstance(a, np.ndarray))


def peak_rss_mb() -> float:
    # ru_maxrss is in KiB on Linux (bytes on macOS).
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def run_size(target_tets: int, args) -> dict:
    import numba

    from crackle.fdem.kernels import interface_forces
    from crackle.fdem.simulation import FdemSimulation

    t_build = time.perf_counter()
    model, dt, cells = build(target_tets, args.cell, args.law, args.insertion, args.mesh)
    sim = FdemSimulation(model)
    build_s = time.perf_counter() - t_build

    # Warm-up: the first call compiles (or loads the cache); a second short call settles caches.
    sim.advance(1, dt)
    sim.advance(2, dt)
    if args.steps is not None:
        steps = max(1, args.steps)
    else:
        probe = 3
        t0 = time.perf_counter()
        sim.advance(probe, dt)
        per_step = (time.perf_counter() - t0) / probe
        steps = max(5, int(math.ceil(args.seconds / max(per_step, 1e-9))))

    idle = machine_idle_percent()
    timings, cpu = [], []
    for _ in range(args.repeats):
        c0 = os.times()
        t0 = time.perf_counter()
        sim.advance(steps, dt)
        timings.append(time.perf_counter() - t0)
        c1 = os.times()
        cpu.append((c1.user - c0.user) + (c1.system - c0.system))
    seconds_per_step = statistics.median(timings) / steps
    n_tets = model.n_tets
    tool_nodes = int((model.nodes.tool >= 0).sum())

    row = {
        "tets": n_tets,
        "interfaces": model.n_interfaces,
        "steps": steps,
        "seconds_per_step": seconds_per_step,
        "tet_steps_per_s": n_tets / seconds_per_step,
        "bytes_per_tet": model_bytes(model) / n_tets,
        "peak_rss_mb": peak_rss_mb(),
        "threads": numba.get_num_threads(),
        "law": args.law,
        "insertion": args.insertion,
        "contact_bytes_per_tet": contact_bytes(sim) / n_tets,
        "cells": list(cells),
        "mesh": args.mesh,
        "dt": dt,
        # An extrinsic run's tied phase (0: none): the step while every face is tied.
        "tied_dt": float(model.time_step.tied_dt),
        # Time to solution: simulated time per second of wall time at the run's step (0.8 x the
        # stable one): what a longer stable step buys at the same cost per step.
        "simulated_us_per_s": 1e6 * dt / seconds_per_step,
        "tool_contact_nodes": tool_nodes,
        # Process CPU time / (wall time x threads) over the timed repeats: well below 1 means
        # the threads did not get their cores (another process, fewer cores than threads).
        "cpu_utilisation": sum(cpu) / (sum(timings) * numba.get_num_threads()),
        "idle_percent_before": idle,
        "build_s": build_s,
        "repeat_seconds": timings,
    }

    if args.breakdown:
        ifs, x, v = model.ifs, model.nodes.x, model.nodes.v
        interface_forces(sim.time, dt, x, v, ifs, model.ties)  # compile / load
        itimings = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            for _ in range(steps):
                interface_forces(sim.time, dt, x, v, ifs, model.ties)
            itimings.append(time.perf_counter() - t0)
        if_per_step = statistics.median(itimings) / steps
        row["interface_seconds_per_step"] = if_per_step
        row["interface_fraction"] = if_per_step / seconds_per_step
        row["peak_rss_mb"] = peak_rss_mb()

    # The model's arrays are all read (and the state written) every step: at least this many
    # bytes move per step; their rate against this machine's triad bandwidth with the same
    # threads is the share of the memory system the step reaches (after the peak RSS: the
    # triad's arrays are 768 MB).
    from bandwidth import memory_bandwidth

    bandwidth = memory_bandwidth()
    row["bandwidth_gb_s"] = bandwidth / 1e9
    row["bandwidth_fraction"] = model_bytes(model) / seconds_per_step / bandwidth
    return row


def human_line(r: dict) -> str:
    line = (
        f"{r['tets']:>8d} tets {r['interfaces']:>8d} ifaces | {r['steps']:>5d} steps x{len(r['repeat_seconds'])} | "
        f"{r['seconds_per_step'] * 1e3:8.3f} ms/step | {r['tet_steps_per_s'] / 1e6:6.2f} M tet-steps/s | "
        f"{r['bytes_per_tet']:6.0f} B/tet | peak RSS {r['peak_rss_mb']:7.1f} MB | {r['threads']} threads | "
        f"{r['tool_contact_nodes']} nodes on tools | step {r['dt'] * 1e9:.3g} ns (tied {r['tied_dt'] * 1e9:.3g}), "
        f"{r['simulated_us_per_s']:.3g} us simulated per s | at least {100 * r['bandwidth_fraction']:.0f} % of the "
        f"{r['bandwidth_gb_s']:.1f} GB/s triad bandwidth"
    )
    if "interface_seconds_per_step" in r:
        line += (f" | interface pass {r['interface_seconds_per_step'] * 1e3:.3f} ms/step "
                 f"({100 * r['interface_fraction']:.0f}%)")
    return line


def busy_warning(r: dict) -> str | None:
    idle, util = r.get("idle_percent_before"), r.get("cpu_utilisation", 1.0)
    if (idle is not None and idle < 90.0) or util < 0.85:
        return (f"warning: {r['tets']} tets: the machine looked busy (idle before timing "
                f"{'n/a' if idle is None else f'{idle:.0f}%'}, CPU utilisation {util:.2f}); timings are unreliable")
    return None


def child_argv(size: int, args) -> list[str]:
    argv = [sys.executable, os.path.abspath(__file__), "--_child", "--sizes", str(size),
            "--repeats", str(args.repeats), "--seconds", str(args.seconds), "--cell", str(args.cell),
            "--law", args.law, "--insertion", args.insertion, "--mesh", args.mesh]
    if args.threads is not None:
        argv += ["--threads", str(args.threads)]
    if args.steps is not None:
        argv += ["--steps", str(args.steps)]
    if args.breakdown:
        argv.append("--breakdown")
    return argv


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.threads is not None:
        # numba caps set_num_threads at NUMBA_NUM_THREADS (default: the core count).
        current = int(os.environ.get("NUMBA_NUM_THREADS", "0") or 0)
        if args.threads > (current or os.cpu_count() or 1):
            os.environ["NUMBA_NUM_THREADS"] = str(args.threads)
    import numba

    if args.threads is not None:
        numba.set_num_threads(args.threads)
    threads = numba.get_num_threads()

    rows = []
    if args.in_process or args._child:
        for size in args.sizes:
            rows.append(run_size(size, args))
            if not args._child:
                print(human_line(rows[-1]), flush=True)
                if busy_warning(rows[-1]):
                    print(busy_warning(rows[-1]), file=sys.stderr, flush=True)
    else:
        for size in args.sizes:
            proc = subprocess.run(child_argv(size, args), stdout=subprocess.PIPE, text=True)
            if proc.returncode != 0:
                print(f"size {size}: benchmark process failed with code {proc.returncode}", file=sys.stderr)
                return proc.returncode
            rows.extend(json.loads(proc.stdout.strip().splitlines()[-1])["sizes"])
            print(human_line(rows[-1]), flush=True)
            if busy_warning(rows[-1]):
                print(busy_warning(rows[-1]), file=sys.stderr, flush=True)

    if not args._child:
        for r in rows:
            if r["tets"] >= 150000:
                ok_speed = r["tet_steps_per_s"] >= TARGET_TET_STEPS_PER_S
                ok_mem = r["bytes_per_tet"] <= TARGET_BYTES_PER_TET
                print(
                    f"targets at {r['tets']} tets, {r['threads']} threads: "
                    f"{r['tet_steps_per_s'] / 1e6:.2f} M tet-steps/s vs >= {TARGET_TET_STEPS_PER_S / 1e6:g} M "
                    f"({'met' if ok_speed else 'NOT met'}); {r['bytes_per_tet']:.0f} B/tet vs <= "
                    f"{TARGET_BYTES_PER_TET:.0f} ({'met' if ok_mem else 'NOT met'})",
                    flush=True,
                )
    print(json.dumps({"sizes": rows, "threads": threads}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

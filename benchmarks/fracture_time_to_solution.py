"""Time to solution through fracture: FDEM from rest to its broken state, wall time per phase.

Runs a model with `FdemSimulation.advance` in chunks of `--chunk-us` of simulated time (the
driver's step: safety x `sim.stable_dt`, which for an extrinsic run is the tied phase's long
step; after the first insertion each driver step is `sim.substeps` compiled steps), times each
chunk, and sorts the chunks into four phases by what the simulation exposes after the chunk:

  tied        extrinsic: every face still tied (`ties.tied`; while `sim.tied_phase` lasts, the
              driver's step is one long compiled step); intrinsic, its counterpart: no face has
              reached its strength yet (every `ifs.damage` is 0: a Guo-Munjiza face is damaged
              from its peak on, where an extrinsic face is inserted)
  inserting   a face has reached its strength (extrinsic: inserted, `ties.tied` no longer TIED;
              intrinsic: damaged) and none has failed yet (`sim.broken` == 0)
  failing     faces fail: from the chunk of the first failure to the last chunk in which
              `sim.broken` rose
  contact     after the last chunk in which `sim.broken` rose: the fragments move apart or press
              on each other (empty when faces still fail at the end of the run)

A chunk in which the phase changed counts in the later phase: the boundaries are exact to one
chunk; the exact times are reported beside them (`tied_until`: `sim.tied_until`, the first and
last failure: `ifs.fail_time`). Per phase: wall time, simulated time, wall seconds per simulated
microsecond, driver steps, compiled steps, the compiled step (ns), ms per compiled step, and
tet-steps per second (tets x compiled steps / wall). With `--repeat N` each case runs N times
(each from a fresh build, after one untimed warm-up run of two chunks that compiles or loads the
numba cache); every timed number is the median over the repeats (the phases' steps are the same
in every repeat: the run is deterministic).

Cases:

  bar    the Akantu anchor's bar (issue 68): a 200 x 50 x 50 mm box meshed by gmsh at element size
         `--size` mm (3.6 mm: 50,835 tets), written as a gmsh 2.2 ascii file (what Akantu reads:
         benchmarks/peers/akantu_bar.py reads the same file) and read back with `read_mesh`, then in
         locality order (`--file-order` keeps the file's: issue 68 item 4); paper 001's rock
         (E 26 GPa, nu 0.2, 2340 kg/m^3, Guo-Munjiza ft 3 MPa, c 15 MPa, phi 30 deg) with
         Gf = 10 J/m^2; at rest but for the initial velocity v_x = 20 /s x (x - x_mid) (a strain
         rate of 20 /s pulling the bar apart); no supports, no tools; to `--until-us` (20 us).
  disc   the shipped `brazilian-disc` example as its scenario builds it (`--quick`: its quick
         form, 4 mm mesh; the full form is the paper's 1.2 mm mesh), to its run.end_time or
         `--until-us`.

Output: one table per case and insertion mode, the peak RSS, and with `--json PATH` every number.

    python benchmarks/fracture_time_to_solution.py --threads 2                    # bar, ~50k tets, 20 us
    python benchmarks/fracture_time_to_solution.py --case bar --size 12 --until-us 10 --repeat 1
    python benchmarks/fracture_time_to_solution.py --case disc --quick --json disc.json
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import tempfile
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

PHASES = ("tied", "inserting", "failing", "contact")

# The bar of the Akantu anchor (issue 68): size (m), rock, pull.
BAR_SIZE = (0.2, 0.05, 0.05)
BAR_DENSITY, BAR_YOUNGS, BAR_POISSON = 2340.0, 26e9, 0.2
BAR_TENSILE_STRENGTH, BAR_COHESION, BAR_FRICTION_ANGLE = 3e6, 15e6, 30.0
BAR_FRACTURE_ENERGY = 10.0  # J/m^2
BAR_STRAIN_RATE = 20.0  # 1/s


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--case", nargs="+", choices=("bar", "disc"), default=["bar"],
                   help="the Akantu anchor's bar and/or the brazilian-disc example (default: bar)")
    p.add_argument("--insertion", nargs="+", choices=("intrinsic", "extrinsic"), default=["intrinsic", "extrinsic"],
                   help="material.interface.insertion (default: both)")
    p.add_argument("--size", type=float, default=3.6,
                   help="bar: gmsh element size in mm (default 3.6: 50,835 tets)")
    p.add_argument("--file-order", action="store_true",
                   help="bar: keep the mesh file's tet order (default: locality order, as a generated mesh)")
    p.add_argument("--quick", action="store_true", help="disc: the example's quick form (4 mm mesh)")
    p.add_argument("--until-us", type=float, default=None,
                   help="simulated time in us (default: bar 20, disc its run.end_time)")
    p.add_argument("--chunk-us", type=float, default=0.5,
                   help="simulated time per timed chunk in us, the phases' resolution (default 0.5)")
    p.add_argument("--safety", type=float, default=0.7, help="step = safety x stable step (default 0.7)")
    p.add_argument("--repeat", type=int, default=1, help="timed runs per case, medians kept (default 1)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's)")
    p.add_argument("--json", type=Path, default=None, help="write every number to this JSON file")
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error("--repeat must be >= 1")
    if args.chunk_us <= 0 or args.size <= 0:
        p.error("--chunk-us and --size must be > 0")
    return args


def set_threads(threads: int | None) -> int:
    """numba threads (NUMBA_NUM_THREADS raised first where it caps the request); the count in use."""
    if threads is not None:
        if threads > int(os.environ.get("NUMBA_NUM_THREADS", "0") or 0) and threads > (os.cpu_count() or 1):
            os.environ["NUMBA_NUM_THREADS"] = str(threads)
    import numba

    if threads is not None:
        numba.set_num_threads(threads)
    return numba.get_num_threads()


def peak_rss_mb() -> float:
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


# -- the bar ----------------------------------------------------------------------------------
def write_bar_mesh(path: Path, element_size: float) -> Path:
    """The bar meshed by gmsh at `element_size` (m), written as a gmsh 2.2 ascii file holding its
    tets only (one physical volume, "bar"): what both crackle and Akantu read."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("bar")
        volume = gmsh.model.occ.addBox(0.0, 0.0, 0.0, *BAR_SIZE)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [volume], name="bar")
        gmsh.option.setNumber("Mesh.MeshSizeMin", element_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", element_size)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def bar_rock(insertion: str):
    from crackle.fdem.laws import GuoMunjizaLaw
    from crackle.materials import Material

    law = GuoMunjizaLaw(BAR_TENSILE_STRENGTH, BAR_COHESION, BAR_FRICTION_ANGLE, BAR_FRACTURE_ENERGY,
                        insertion=insertion)
    return Material(BAR_DENSITY, BAR_YOUNGS, BAR_POISSON, law, name="rock (paper 001, Gf = 10 J/m^2)")


def bar_velocity(points: np.ndarray) -> np.ndarray:
    """The initial velocity field: v_x = strain rate x (x - x_mid), nothing across."""
    v = np.zeros_like(points)
    v[:, 0] = BAR_STRAIN_RATE * (points[:, 0] - 0.5 * BAR_SIZE[0])
    return v


def bar_simulation(mesh_file: Path, insertion: str, file_order: bool = False):
    """The bar's FdemSimulation from the mesh file (no supports, tools or surface contact: the
    failed faces' paired contact only, as Akantu's cohesive elements)."""
    from crackle.fdem.model import build_fdem_model
    from crackle.fdem.simulation import FdemSimulation
    from crackle.geometry.meshes import locality_order, read_mesh

    mesh = read_mesh(mesh_file)
    if not file_order:
        mesh = locality_order(mesh)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # process-zone resolution advice: the anchor's mesh as it is
        model = build_fdem_model(mesh, bar_rock(insertion), initial_velocity=bar_velocity(mesh.points))
    return FdemSimulation(model)


# -- the disc ---------------------------------------------------------------------------------
def disc_simulation(insertion: str, quick: bool):
    """The brazilian-disc example's FdemSimulation and its run.end_time."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario("brazilian-disc", [f"material.interface.insertion={insertion}"], quick)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim, control = build_simulation(scenario, base)
    return sim, control.end_time


# -- the run ----------------------------------------------------------------------------------
@dataclass
class Chunk:
    """One timed call of advance and the state after it."""

    t_end: float  # s
    wall: float  # s
    driver_steps: int
    compiled_steps: int
    tied: bool  # no face has reached its strength (extrinsic: every face tied; intrinsic: none damaged)
    reached: int  # faces that reached their strength (inserted / damaged)
    broken: int


def faces_reached(sim) -> int:
    """Faces past their strength: extrinsic ones inserted (their law row extrinsic, no longer
    tied), intrinsic ones damaged; pre-cracks not counted."""
    from crackle.fdem.extrinsic import TIED
    from crackle.fdem.laws.row import LAW_EXTRINSIC
    from crackle.fdem.topology import PRECRACK

    ifs, ties = sim.model.ifs, sim.model.ties
    reached = ifs.damage > 0.0
    if len(ties.load):  # some faces extrinsic
        extrinsic = ifs.law_table[ifs.law, LAW_EXTRINSIC] > 0
        reached |= extrinsic & (ties.tied != TIED)
    return int(np.count_nonzero(reached & (ifs.state != PRECRACK)))


def run_through_fracture(sim, dt: float, end_time: float, chunk_time: float, max_chunks: int | None = None):
    """Advance `sim` from its start to end_time in chunks of about chunk_time; the chunks."""
    steps_per_chunk = max(1, round(chunk_time / dt))
    total = max(1, round(end_time / dt))
    chunks = []
    while sim.steps < total and (max_chunks is None or len(chunks) < max_chunks):
        n = min(steps_per_chunk, total - sim.steps)
        first, was_tied = sim.steps, sim.tied_phase
        t0 = time.perf_counter()
        sim.advance(n, dt)
        wall = time.perf_counter() - t0
        # Compiled steps: one per driver step while tied, sim.substeps each after.
        tied_steps = n if sim.tied_phase else (round(sim.tied_until / dt) - first if was_tied else 0)
        compiled = tied_steps + (n - tied_steps) * sim.model.tied_substeps
        reached = faces_reached(sim)
        chunks.append(Chunk(sim.time, wall, n, compiled, reached == 0, reached, sim.broken))
    return chunks


def classify(chunks: list[Chunk]) -> list[str]:
    """Each chunk's phase (see the module docstring)."""
    last_rise = max((i for i in range(len(chunks)) if chunks[i].broken > (chunks[i - 1].broken if i else 0)),
                    default=None)
    phases = []
    for i, c in enumerate(chunks):
        if c.tied:
            phases.append("tied")
        elif c.broken == 0:
            phases.append("inserting")
        elif i <= last_rise:
            phases.append("failing")
        else:
            phases.append("contact")
    return phases


def phase_table(chunks: list[Chunk], n_tets: int) -> dict:
    """Per phase: wall time, simulated time and steps, and the rates they give."""
    phases = classify(chunks)
    starts = [0.0] + [c.t_end for c in chunks[:-1]]
    table = {}
    for name in PHASES:
        mine = [(start, c) for start, c, p in zip(starts, chunks, phases) if p == name]
        wall = sum(c.wall for _, c in mine)
        compiled = sum(c.compiled_steps for _, c in mine)
        simulated = sum(c.t_end - start for start, c in mine)
        table[name] = {
            "start_us": 1e6 * mine[0][0] if mine else None,
            "end_us": 1e6 * mine[-1][1].t_end if mine else None,
            "simulated_us": 1e6 * simulated,
            "wall_s": wall,
            "wall_s_per_us": wall / (1e6 * simulated) if simulated > 0 else None,
            "driver_steps": sum(c.driver_steps for _, c in mine),
            "compiled_steps": compiled,
            "step_ns": 1e9 * simulated / compiled if compiled else None,
            "ms_per_compiled_step": 1e3 * wall / compiled if compiled else None,
            "tet_steps_per_s": n_tets * compiled / wall if wall > 0 else None,
        }
    return table


def failure_times(sim) -> tuple[float | None, float | None]:
    """s: the first and the last failure of the run (None: none failed)."""
    from crackle.fdem.topology import INTACT, PRECRACK

    ifs = sim.model.ifs
    failed = (ifs.state != INTACT) & (ifs.state != PRECRACK)
    if not failed.any():
        return None, None
    times = ifs.fail_time[failed]
    return float(times.min()), float(times.max())


def end_state(sim, dt: float) -> dict:
    """What the run ended with: faces reached and failed, fragments and energies (J)."""
    first, last = failure_times(sim)
    energies = sim.sample(dt / sim.substeps)
    return {
        "time_us": 1e6 * sim.time,
        "faces_reached": faces_reached(sim),
        "broken": sim.broken,
        "fragments": sim.fragments().count,
        "tied_until_us": None if sim.tied_until is None else 1e6 * sim.tied_until,
        "first_failure_us": None if first is None else 1e6 * first,
        "last_failure_us": None if last is None else 1e6 * last,
        "energies": {k.removeprefix("energy."): float(v) for k, v in energies.items() if k.startswith("energy.")},
    }


def build_case(case: str, insertion: str, args, mesh_file: Path | None):
    """The case's simulation and its end time (s)."""
    if case == "bar":
        sim = bar_simulation(mesh_file, insertion, args.file_order)
        end = 20e-6
    else:
        sim, end = disc_simulation(insertion, args.quick)
    return sim, (1e-6 * args.until_us if args.until_us is not None else end)


def median_phases(tables: list[dict]) -> dict:
    """Phase tables of repeated runs: the timed numbers their medians, the steps the first run's
    (the same in every run of a deterministic code)."""
    phases = {}
    for name in PHASES:
        rows = [t[name] for t in tables]
        median = dict(rows[0])
        for key in ("wall_s", "wall_s_per_us", "ms_per_compiled_step", "tet_steps_per_s"):
            values = [r[key] for r in rows if r[key] is not None]
            median[key] = statistics.median(values) if values else None
        phases[name] = median
    return phases


def time_case(case: str, insertion: str, args, mesh_file: Path | None) -> dict:
    """Warm-up, then `args.repeat` timed runs from fresh builds; medians per phase."""
    sim, end = build_case(case, insertion, args, mesh_file)
    dt = args.safety * sim.stable_dt
    run_through_fracture(sim, dt, end, 1e-6 * args.chunk_us, max_chunks=2)  # compile / load the cache
    runs = []
    for _ in range(args.repeat):
        t_build = time.perf_counter()
        sim, end = build_case(case, insertion, args, mesh_file)
        build_s = time.perf_counter() - t_build
        chunks = run_through_fracture(sim, dt, end, 1e-6 * args.chunk_us)
        runs.append({"build_s": build_s, "chunks": chunks, "phases": phase_table(chunks, sim.model.n_tets),
                     "wall_s": sum(c.wall for c in chunks)})
    phases = median_phases([r["phases"] for r in runs])
    return {
        "case": case,
        "insertion": insertion,
        "tets": sim.model.n_tets,
        "interfaces": sim.model.n_interfaces,
        "dt_ns": 1e9 * dt,
        "compiled_dt_ns": 1e9 * dt / sim.model.tied_substeps,
        "tied_substeps": sim.model.tied_substeps,
        "end_us": 1e6 * end,
        "wall_s": statistics.median(r["wall_s"] for r in runs),
        "wall_s_runs": [r["wall_s"] for r in runs],
        "build_s": statistics.median(r["build_s"] for r in runs),
        "phases": phases,
        "end": end_state(sim, dt),
        "chunks": [asdict(c) for c in runs[-1]["chunks"]],
    }


def _fmt(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def print_phases(phases: dict, indent: str = "  ") -> None:
    print(f"{indent}{'phase':10s} {'from-to (us)':>14s} {'wall (s)':>9s} {'s per us':>9s} {'driver':>7s} "
          f"{'compiled':>9s} {'step (ns)':>10s} {'ms/step':>8s} {'M tet-steps/s':>14s}")
    for name, p in phases.items():
        span = f"{p['start_us']:.4g}-{p['end_us']:.4g}" if p["start_us"] is not None else "-"
        tps = None if p["tet_steps_per_s"] is None else p["tet_steps_per_s"] / 1e6
        print(f"{indent}{name:10s} {span:>14s} {p['wall_s']:9.3f} {_fmt(p['wall_s_per_us'], '9.3f')} "
              f"{p['driver_steps']:7d} {p['compiled_steps']:9d} {_fmt(p['step_ns'], '10.4g')} "
              f"{_fmt(p['ms_per_compiled_step'], '8.3f')} {_fmt(tps, '14.3f')}")


def print_result(r: dict) -> None:
    e = r["end"]
    print(f"\n{r['case']} {r['insertion']}: {r['tets']:,} tets, {r['interfaces']:,} interfaces, driver step "
          f"{r['dt_ns']:.4g} ns ({r['tied_substeps']} compiled steps of {r['compiled_dt_ns']:.4g} ns after the tied "
          f"phase), to {r['end_us']:.3g} us: {r['wall_s']:.2f} s of stepping (median of {len(r['wall_s_runs'])})")
    print_phases(r["phases"])
    print(f"  end: {e['faces_reached']:,} faces reached their strength, {e['broken']:,} failed, {e['fragments']} "
          f"fragments; tied until {_fmt(e['tied_until_us'], '.4g')} us, failures {_fmt(e['first_failure_us'], '.4g')}-"
          f"{_fmt(e['last_failure_us'], '.4g')} us; energies (J): "
          + ", ".join(f"{k} {v:.4g}" for k, v in e["energies"].items()))


def main(argv=None) -> int:
    args = parse_args(argv)
    threads = set_threads(args.threads)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        mesh_file = None
        if "bar" in args.case:
            mesh_file = write_bar_mesh(Path(tmp) / "bar.msh", 1e-3 * args.size)
        for case in args.case:
            for insertion in args.insertion:
                results.append(time_case(case, insertion, args, mesh_file))
                print_result(results[-1])
    rss = peak_rss_mb()
    print(f"\npeak RSS {rss:.1f} MB, {threads} threads")
    if args.json is not None:
        args.json.write_text(json.dumps({"results": results, "threads": threads, "peak_rss_mb": rss,
                                         "args": {k: str(v) for k, v in vars(args).items()}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

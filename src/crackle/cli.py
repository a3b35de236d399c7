"""Command line: crackle run | sweep | calibrate | examples | keys | fpz."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _cmd_run(args) -> int:
    from .api import run_scenario
    from .scenario import ScenarioError
    from .solver import DiskFullError, StoppedAtOnce, UnstableRunError

    try:
        result = run_scenario(args.scenario, args.out, args.set, args.quick, resume=args.resume,
                              report=lambda text: print(text, flush=True))
    except ScenarioError as err:
        print(f"crackle: error: {err}", file=sys.stderr)
        return 2
    except (UnstableRunError, DiskFullError, StoppedAtOnce) as err:  # a run that ended early, outputs kept
        print(f"crackle: {err}", file=sys.stderr)
        return {UnstableRunError: 3, DiskFullError: 1, StoppedAtOnce: 130}[type(err)]
    except KeyboardInterrupt:
        # During the run the driver handles Ctrl-C itself (status "interrupted", outputs kept);
        # this is one during reading, meshing or set-up.
        print("crackle: interrupted during set-up, before the first step: no results written", file=sys.stderr)
        return 130
    s = result.summary
    # No tools: no force.
    force = f"peak force {s['peak_force']:.4g} N ({s['peak_force_tool']}), " if s["peak_force"] > 0 else ""
    print(
        f"{s['scenario']}: {s['status']} after {s['steps']} steps ({s['wall_time']:.1f} s), "
        f"t = {s['end_time']:.4g} s, broken {s['broken']}, {force}energy error {s['energy_error']:.2%}"
    )
    if s.get("plastic_zone_length") is not None:
        print(f"  plastic zone while the fracture grows: {s['plastic_zone_length'] * 1e3:.1f} mm")
    if s.get("message"):
        print(f"  {s['message']}")
    print(f"  outputs in {result.out_dir}")
    return 130 if s["status"] == "interrupted" else 0


def _counts_at_least_one(args, names) -> bool:
    """Whether each of the count options given is at least 1 (a message for the first that is not)."""
    for name in names:
        value = getattr(args, name)
        if value is not None and value < 1:
            print(f"crackle: error: --{name.replace('_', '-')} must be at least 1", file=sys.stderr)
            return False
    return True


def _runs_of_many(command: str, out, call):
    """(call(), 0) for a command that runs many runs in their folders (sweep, validate); (None,
    exit code) when it refused its input (2, the message printed) or was interrupted (130, saying
    what is kept: the finished runs, and the interrupted ones' checkpoints)."""
    from .scenario import ScenarioError

    try:
        return call(), 0
    except ScenarioError as err:
        print(f"crackle: error: {err}", file=sys.stderr)
        return None, 2
    except KeyboardInterrupt:
        print(f"\ncrackle: {command} interrupted: the finished runs are kept in {out}; the same command finishes the "
              "others", file=sys.stderr)
        return None, 130


def _cmd_sweep(args) -> int:
    from .sweep import make_plan, run_sweep
    from .sweep.runner import COMPLETED

    if not _counts_at_least_one(args, ("workers", "threads_per_run", "seeds")):
        return 2
    out = args.out or f"crackle-out/sweep-{Path(args.sweep).stem}"
    result, code = _runs_of_many(
        "sweep", out, lambda: run_sweep(make_plan(args.sweep, args.vary, args.set, args.zip, args.quick, args.seeds),
                                        out, args.scheduler, args.workers, args.threads_per_run, args.plot,
                                        report=lambda text: print(text, flush=True)))
    if result is None:
        return code
    statuses = [row["status"] for row in result.rows]
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in dict.fromkeys(statuses))
    print(f"sweep: {len(statuses)} runs ({counts}); {result.ran} run now")
    print(f"  table in {result.out_dir / 'sweep.csv'} (and sweep.parquet), plots in {result.out_dir / 'plots'}")
    for line in result.notes:
        print(f"  {line}")
    return 0 if all(s in COMPLETED for s in statuses) else 1


def _cmd_validate(args) -> int:
    from .validation import exit_code, select, validate
    from .validation.runner import document_runs, write_document

    if not _counts_at_least_one(args, ("jobs", "threads_per_run")):
        return 2
    try:
        cases = select(args.papers, args.tier, args.cases)
        # The document's own numbers: the runs its markers name, of these papers at this tier.
        also = () if not args.document or args.cases else tuple(
            run for run in document_runs(Path(args.document).read_text())
            if (not args.papers or run.paper in args.papers) and run.quick == (args.tier == "quick"))
    except (OSError, ValueError) as err:
        print(f"crackle: error: {err}", file=sys.stderr)
        return 2
    out = Path(args.out or f"crackle-out/validate-{args.tier}")
    results, code = _runs_of_many("validate", out, lambda: validate(
        cases, out, args.scheduler, args.jobs, args.threads_per_run, report=lambda text: print(text, flush=True),
        also=also))
    if results is None:
        return code
    if args.document:
        try:
            changes = write_document(args.document, results, out)
        except (OSError, ValueError) as err:
            print(f"crackle: error: --document: {err}", file=sys.stderr)
            return 2
        print(f"validate: {args.document}: " + (f"{len(changes)} numbers changed" if changes else "every number as before"))
        for change in changes:
            print(f"  {change}")
    for r in results:
        if r.status in ("outside", "failed"):
            print(f"  {r.case.name}: {r.status} ({r.value if r.value is not None else r.message}; band "
                  f"{r.case.band[0]:g}-{r.case.band[1]:g} {r.case.unit})", flush=True)
    statuses = [r.status for r in results]
    print(f"validate: {len(results)} cases: " + ", ".join(f"{statuses.count(s)} {s}" for s in dict.fromkeys(statuses)))
    print(f"  report in {out / 'report.md'}")
    return exit_code(results)


def _cmd_calibrate(args) -> int:
    from .scenario import ScenarioError
    from .sweep.calibrate import CalibrationFailed, calibrate

    if not _counts_at_least_one(args, ("workers", "threads_per_run", "population", "generations")):
        return 2
    try:
        result = calibrate(
            args.scenario, args.target, args.fit, args.start, args.set, args.quick, args.tool,
            args.out or f"crackle-out/calibrate-{Path(args.scenario).stem}", args.population, args.generations,
            args.tol, args.seed, args.scheduler, args.workers, args.threads_per_run,
            report=lambda text: print(text, flush=True),
        )
    except ScenarioError as err:
        print(f"crackle: error: {err}", file=sys.stderr)
        return 2
    except CalibrationFailed as err:
        print(f"crackle: calibrate: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("\ncrackle: calibration interrupted: the candidates' runs so far are in their folders; it is not "
              "resumed (run it again to start over)", file=sys.stderr)
        return 130
    values = ", ".join(f"{key} = {value:.6g}" for key, value in result.fitted.items())
    print(f"calibrate: {values}; distance {result.distance:.4g} after {result.runs} runs")
    plot = ", calibration.png" if (result.out_dir / "calibration.png").is_file() else ""
    print(f"  calibration.json, calibration.csv{plot} in {result.out_dir}; fitted run in {result.fitted_folder}")
    return 0


def _cmd_examples(args) -> int:
    from .scenario import list_examples

    for name, text in list_examples().items():
        print(f"{name:24s} {text}")
    return 0


def _cmd_keys(args) -> int:
    from .keys import key_reference, reference_document
    from .methods import METHODS

    if args.method is None:
        print(reference_document(), end="")
    elif args.method not in METHODS:
        print(f"crackle: error: unknown method {args.method!r}; choose one of {', '.join(METHODS)}", file=sys.stderr)
        return 2
    else:
        print(key_reference(args.method), end="")
    return 0


def _cmd_fpz(args) -> int:
    from .materials import process_zone

    for name in ("E", "Gf", "ft"):
        value = getattr(args, name)
        if not (0 < value < float("inf")):  # also refuses nan
            print(f"crackle: error: --{name} must be a positive finite number, not {value}", file=sys.stderr)
            return 2
    # The scenario's ranges: a solid's modulus from 1e5 Pa, a strength from 1 kPa (a value in GPa or MPa slipped in).
    for name, least, meant in (("E", 1e5, "GPa, write {v:g}e9"), ("ft", 1e3, "MPa, write {v:g}e6")):
        value = getattr(args, name)
        if value < least:
            print(f"crackle: error: --{name} {value:g} Pa is below {least:g} Pa, less than any solid's: if that is "
                  + meant.format(v=value), file=sys.stderr)
            return 2
    pz = process_zone(args.E, args.Gf, args.ft)
    if args.json:
        print(json.dumps(pz.as_dict()))
    else:
        print(f"plastic zone, long crack  (3 pi E Gf / 32 ft^2): {pz.plastic_zone_long * 1e3:.3f} mm")
        print(f"plastic zone, short crack (3 E Gf / 4 ft^2):     {pz.plastic_zone_short * 1e3:.3f} mm")
        print(f"advised element size (<= long / 3):             {pz.advised_element_size * 1e3:.3f} mm")
    return 0


def _dask_options(p, workers: str, workers_help: str) -> None:
    """The options of a command whose runs go to Dask (sweep, calibrate, validate)."""
    p.add_argument(workers, type=int, help=workers_help)
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (tcp://HOST:PORT); default: a "
                   "local cluster on this machine")
    p.add_argument("--threads-per-run", type=int, help="numba threads per run (default: the cores shared among the "
                   "workers)")


def main(argv=None) -> int:
    from . import __version__

    parser = argparse.ArgumentParser(prog="crackle", description="Dynamic fracture of brittle solids and shells.")
    parser.add_argument("--version", action="version", version=f"crackle {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run a scenario file or a shipped example")
    p.add_argument("scenario", help="a .toml scenario or the name of a shipped example")
    p.add_argument("--out", help="output folder (default crackle-out/NAME)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario value, e.g. run.end_time=1e-3")
    p.add_argument("--quick", action="store_true", help="the example's quick form: coarser, shorter")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR (its checkpoint) to run.end_time; "
                   "give the same scenario, --quick and --set as that run")
    p.set_defaults(func=_cmd_run)
    p = sub.add_parser("sweep", help="a family of runs on Dask: every combination of --vary values, one table",
                       description="Run a scenario for every combination (or, with --zip, every position) of the "
                       "--vary values, each in its own folder under --out, on a Dask cluster; then sweep.csv, "
                       "sweep.parquet and plots/sweep_KEY.png. Rerun the same command to finish an interrupted sweep.")
    p.add_argument("sweep", help="a scenario (file or shipped example), a sweep file, or a shipped sweep "
                   "(brazilian-angles, walnut-layouts, mesh-ladder, tube-shots, tension-size-effect, "
                   "layered-longmaxi)")
    p.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a key and its values, e.g. --vary loading.angle=0,30,60,90 (repeat for more keys)")
    p.add_argument("--zip", action="store_true", help="the i-th values of every key together (not every combination)")
    p.add_argument("--seeds", type=int, metavar="N", help="every run with run.seed = 0 .. N-1 (random material "
                   "properties drawn anew); sweep_seeds.csv: each summary scalar's mean and standard deviation over the seeds")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an override every run gets")
    p.add_argument("--quick", action="store_true", help="every run in its example's quick form")
    p.add_argument("--out", help="the sweep's folder (default crackle-out/sweep-NAME)")
    _dask_options(p, "--workers", "local workers (default: one per core, at most one per run)")
    p.add_argument("--plot", action="append", default=[], metavar="SCALAR",
                   help="a summary scalar to plot against each varied key, beside peak_force, broken, energy_error")
    p.set_defaults(func=_cmd_sweep)
    p = sub.add_parser("calibrate", help="fit scenario values to measured curves and values (runs on Dask)",
                       description="Fit the --fit keys within their bounds so that the runs meet every --target: "
                       "a tool's load-displacement curve, a summary value of the run, or one of another scenario "
                       "run with the same values (scipy's differential evolution, each generation's runs in "
                       "parallel on Dask). Distance: sqrt(mean d^2) over the targets; a curve's d is the RMS "
                       "force difference at its displacements over its largest force, a value's the relative "
                       "difference.")
    p.add_argument("scenario", help="a .toml scenario or the name of a shipped example")
    p.add_argument("--target", action="append", required=True,
                   help="a CSV with columns displacement (m) and force (N) (the --tool curve); KEY=VALUE, a "
                   "summary.json value of the run (e.g. peak_stress=70e6); or SCENARIO:KEY=VALUE, one of another "
                   "scenario run with the same values, --set and --quick (e.g. dem-brazilian:brazilian_strength=6e6); "
                   "repeat for several")
    p.add_argument("--fit", action="append", default=[], metavar="KEY=LO:HI", required=True,
                   help="a key to fit and its bounds, e.g. --fit material.interface.tensile_strength=1e6:6e6")
    p.add_argument("--start", action="append", default=[], metavar="KEY=VALUE",
                   help="a fitted key's start value (default: the middle of its bounds)")
    p.add_argument("--tool", help="the tool whose curve is fitted (default: the first in the history)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an override every run gets")
    p.add_argument("--quick", action="store_true", help="every run in its example's quick form")
    p.add_argument("--population", type=int, default=8, help="candidates per generation and fitted key (default 8)")
    p.add_argument("--generations", type=int, default=20, help="at most this many generations (default 20)")
    p.add_argument("--tol", type=float, default=0.01, help="stop when the population's distances agree to this "
                   "fraction of their mean (default 0.01)")
    p.add_argument("--seed", type=int, default=0, help="the search's random seed (default 0)")
    p.add_argument("--out", help="output folder (default crackle-out/calibrate-NAME)")
    _dask_options(p, "--workers", "local workers (default: one per core)")
    p.set_defaults(func=_cmd_calibrate)
    p = sub.add_parser("validate", help="run the papers' benchmark cases and check them against their bands",
                       description="Run the benchmark cases of the chosen papers at the chosen tier (each case: a "
                       "run, the number read from it, the paper's value and the band crackle's value must fall in, "
                       "with its source), on Dask as crackle sweep; write report.md and report.json. Exit 1 when a "
                       "case is outside its band or its run failed. Rerun the same command to finish an "
                       "interrupted validation.")
    p.add_argument("papers", nargs="*", metavar="PAPER", help="000, 001, 002, 003, 004 or closed-form (default: all)")
    p.add_argument("--tier", default="quick", help="quick (the examples' quick forms, the default), full (the "
                   "full forms) or paper (the papers' own meshes and samples)")
    p.add_argument("--cases", nargs="+", metavar="NAME", help="only these cases (any tier)")
    p.add_argument("--out", help="the report's folder (default crackle-out/validate-TIER)")
    _dask_options(p, "--jobs", "local workers (default: one per core, at most one per run; 1: the runs one after "
                  "the other in this process, no cluster)")
    p.add_argument("--document", metavar="MARKDOWN", help="also run the runs this document's <!--q:RUN:...--> "
                   "markers name (of these papers, at this tier; none with --cases), and write their numbers there, "
                   "each line stamped with its runs' commits, and the cases' values and commits into its "
                   "<!--validate:begin--> ... <!--validate:end--> block (docs/validation.md); numbers and cases "
                   "not run keep their last values")
    p.set_defaults(func=_cmd_validate)
    p = sub.add_parser("examples", help="list the shipped examples")
    p.set_defaults(func=_cmd_examples)
    p = sub.add_parser("keys", help="every scenario key: unit, default, range (docs/keys.md)")
    p.add_argument("method", nargs="?", help="only this method's keys (default: all)")
    p.set_defaults(func=_cmd_keys)
    p = sub.add_parser("fpz", help="process-zone lengths and the advised element size")
    p.add_argument("--E", type=float, required=True, help="Young's modulus (Pa)")
    p.add_argument("--Gf", type=float, required=True, help="fracture energy (J/m^2)")
    p.add_argument("--ft", type=float, required=True, help="tensile strength (Pa)")
    p.add_argument("--json", action="store_true", help="print one JSON object (lengths in m)")
    p.set_defaults(func=_cmd_fpz)
    args = parser.parse_args(argv)
    from .io.progress import guarded_standard_streams
    from .solver.driver import request_stop

    # A closed pipe or terminal stops a run as Ctrl-C does (summary, checkpoint, lock released), no traceback.
    with guarded_standard_streams(lambda what: request_stop(f"as its {what}")):
        return args.func(args)


if __name__ == "__main__":
    sys.exit(main())

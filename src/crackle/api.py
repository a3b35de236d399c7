"""Python entry points: build a scenario into a simulation (by its method) and run it."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import tempfile
import threading
from pathlib import Path

from .budget import ModelTooLarge
from .io.lock import FolderBusy, OutputLock
from .methods import get_method
from .scenario import RunSpec, ScenarioBase, ScenarioError, load_scenario
from .solver import (
    CheckpointError,
    RunControl,
    RunResult,
    StopConditions,
    check_one_step_travel,
    choose_time_step,
    steps_to,
    load_cell_steps,
    load_checkpoint,
    run,
)
from .solver.checkpoint import RESUMABLE_KEYS, scenario_changes


def run_control(run: RunSpec) -> RunControl:
    """The driver's settings from a scenario's [run]: the keys that have a RunControl field of
    their name (the others, damping, gravity, seed ..., are the method's), and [run.stop]."""
    driver_keys = {f.name for f in dataclasses.fields(RunControl)} & set(RunSpec.model_fields) - {"stop"}
    return RunControl(**{key: getattr(run, key) for key in driver_keys}, stop=StopConditions(**dict(run.stop)))


def build_simulation(scenario: ScenarioBase, base: Path | None = None):
    """The simulation of a validated scenario (built by its method) and the run control; a step
    larger than the stable one is refused here, before any output."""
    try:
        sim = get_method(scenario.method).build_simulation(scenario, base)
    except ModelTooLarge as err:
        raise ScenarioError(str(err)) from None
    control = run_control(scenario.run)
    try:
        dt = choose_time_step(sim, control)
        check_one_step_travel(sim, dt)
        load_cell_steps(control, dt, sim.wave_transit)
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    if control.end_time < dt:
        raise ScenarioError(f"run.end_time = {control.end_time:.3g} s is shorter than one step ({dt:.3g} s): the run would "
                            f"step past it; set run.end_time at least {dt:.3g} s")
    return sim, control


def run_scenario(source, out_dir=None, overrides: list[str] | dict | None = None, quick: bool = False, progress=None,
                 resume=None, report=None, plots: bool = True) -> RunResult:
    """Validate, build and run a scenario file or shipped example; returns the result.

    `resume`: the output folder of an earlier run of the same scenario (same file, --quick and
    --set, except the end time and what is written); continues it from its checkpoint to this
    scenario's run.end_time, in that folder. `report` (a callable taking a line of text) gets the
    set-up lines, advice and cost estimate before the first step (nothing when None). `plots`:
    False leaves out plots/ (a calibration's candidates: seconds each)."""
    scenario, base = load_scenario(source, overrides, quick)
    if resume is not None:
        out = Path(resume)
        if out_dir is not None and Path(out_dir).resolve() != out.resolve():
            raise ScenarioError(f"--out {out_dir} with --resume {resume}: a resumed run continues in its own folder; drop --out")
        if not out.is_dir():
            raise ScenarioError(f"--resume {resume}: no such folder; give the output folder of the run to continue")
    else:
        out = Path(out_dir) if out_dir is not None else Path("crackle-out") / scenario.name
    check_output_folder(out)
    try:
        with OutputLock(out) as lock:
            if lock.taken_over is not None and report is not None:
                report(f"  note: took over the lock of a run that is gone (pid {lock.taken_over.get('pid')}, "
                       f"started {lock.taken_over.get('started')})")
            return _run_locked(scenario, base, out, resume, progress, report, plots)
    except FolderBusy as err:
        raise ScenarioError(f"--out: {err}") from None


# Seconds of set-up (meshing, packing, neighbour search) after which a run says it is still at it,
# so that a large model is not silent for minutes before its first line.
SETUP_NOTE_AFTER = 10.0


@contextlib.contextmanager
def _said_if_slow(seconds: float, report, text: str):
    """`report(text)` once if the block lasts longer than `seconds` (nothing without a report)."""
    timer = threading.Timer(seconds, report, (text,)) if report is not None else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        yield
    finally:
        if timer is not None:
            timer.cancel()


# Keys a refused resume lists where the scenario differs (a different example changes hundreds).
RESUME_CHANGES_LISTED = 5


def _run_locked(scenario: ScenarioBase, base, out: Path, resume, progress, report, plots) -> RunResult:
    """run_scenario's work once the output folder is this run's."""
    record = scenario.model_dump(mode="json")
    if resume is not None:
        try:
            checkpoint = load_checkpoint(out)
        except CheckpointError as err:
            raise ScenarioError(str(err)) from None
        changes = scenario_changes(checkpoint.scenario, record)
        if changes:
            # The first few: a different example or --quick changes hundreds of keys.
            listed = "; ".join(changes[:RESUME_CHANGES_LISTED]) + (
                f"; and {len(changes) - RESUME_CHANGES_LISTED} more" if len(changes) > RESUME_CHANGES_LISTED else "")
            raise ScenarioError(
                f"--resume {resume}: the scenario differs from the run being resumed: {listed}. Give the "
                f"same file, --quick and --set as that run (only {', '.join(RESUMABLE_KEYS)} may change)"
            )
        _check_resumable(out, checkpoint, record)
        sim, control = checkpoint.sim, run_control(scenario.run)
        if steps_to(scenario.run.end_time, checkpoint.dt) <= sim.steps:
            raise ScenarioError(
                f"--resume {resume}: the run is already at t = {sim.time:.6g} s, run.end_time = {scenario.run.end_time:.6g} s; "
                f"set a later end, e.g. --set run.end_time={2 * sim.time:.3g}"
            )
    else:
        check_outputs_are_crackles(out)
        with _said_if_slow(SETUP_NOTE_AFTER, report, f"{scenario.name}: still setting up the model (meshing, packing, "
                           "neighbours: a large one takes minutes; Ctrl-C stops it)"):
            sim, control = build_simulation(scenario, base)
        checkpoint = None
    control.progress = progress
    control.plots = plots
    if report is not None:
        control.report = report
    return run(sim, control, out, scenario_name=scenario.name, scenario=record, resume=checkpoint)


def _check_resumable(out: Path, checkpoint, record: dict) -> None:
    """Refuse a resume that would lose or rewrite what the folder holds: its history gone, or a
    run that ended by its stop condition resumed with the same condition (it would stop again at
    once and only rewrite the summary)."""
    if not (out / "history.csv").is_file():
        raise ScenarioError(f"--resume {out}: history.csv is missing there, so the resumed run's history would "
                            "start at the checkpoint; rerun from the start (without --resume)")
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return  # a run killed before its summary: resumable
    stop = record["run"]["stop"] or {}
    if summary.get("status") == "stopped" and checkpoint.scenario.get("run", {}).get("stop") == stop:
        message = summary.get("message", "")
        # Past the condition that stopped it: a tool's travel twice as far, or a deeper force drop.
        if "moved" in message and stop.get("tool_displacement"):
            way = f"run.stop.tool_displacement={2 * stop['tool_displacement']:.3g}"
        else:
            way = f"run.stop.force_drop={0.5 * stop['force_drop']:.3g}"
        raise ScenarioError(
            f"--resume {out}: that run ended by its stop condition ({message}) and would stop again at once; "
            f"change run.stop to go on past it (e.g. --set {way})"
        )


def check_outputs_are_crackles(out: Path) -> None:
    """Refuse a fresh run into a folder whose files bear the names of crackle's outputs but that no
    crackle run wrote (a run writes status.json with its first row, and its history.csv's header
    starts with time and holds energy.kinetic): a run would remove or overwrite a user's own
    history.csv, summary.json, plots/*.png or fields/*.vtu there."""
    from .solver.driver import OUTPUT_FILES, OUTPUT_GLOBS

    theirs = [name for name in OUTPUT_FILES if (out / name).is_file()]
    theirs += [str(path.relative_to(out)) for pattern in OUTPUT_GLOBS for path in sorted(out.glob(pattern))]
    if not theirs or (out / "status.json").is_file():
        return
    try:
        with open(out / "history.csv", encoding="utf-8", errors="replace") as f:
            header = f.readline(100_000)
    except OSError:
        header = ""
    if not (header.startswith("time,") and ",energy.kinetic," in header):
        listed = ", ".join(theirs[:5]) + (f" and {len(theirs) - 5} more" if len(theirs) > 5 else "")
        raise ScenarioError(f"--out {out}: it holds {listed} that no crackle run wrote (no status.json beside "
                            "them), which this run would overwrite; choose another --out or move them")


def check_output_folder(out: Path) -> None:
    """Refuse, before any work, an output folder that is a file, lies under a file, or cannot be
    written (itself, or the nearest existing folder it would be made in)."""
    nearest = out
    while not nearest.exists() and nearest != nearest.parent:
        nearest = nearest.parent
    if nearest.exists() and not nearest.is_dir():
        where = "is a file" if nearest == out else f"lies under {nearest}, a file"
        raise ScenarioError(f"--out {out}: {where}; give a folder")
    try:
        # A probe that leaves nothing behind (os.access says yes to root on read-only mounts).
        with tempfile.TemporaryFile(dir=nearest):
            pass
    except OSError as err:
        raise ScenarioError(f"--out {out}: cannot write in {nearest} ({err.strerror}); choose a folder you can write to") from None

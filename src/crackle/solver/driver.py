"""The explicit run driver shared by every method (`run`, re-exported by crackle.solver).

A method supplies an object of the Simulation protocol (solver.simulation); its compiled step
calls the shared pieces (solver.integrator, loading.tools). The driver chooses the step, runs compiled chunks between outputs, applies the stop conditions,
audits energy, and writes every output of the contract as it goes: a run that goes unstable or
is interrupted keeps everything written so far.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import math
import signal
import sys
import threading
import time as wallclock
from dataclasses import dataclass, field
from typing import Callable
from pathlib import Path

import numpy as np

from .. import __version__
from ..loading.arrays import LOAD_CELL_RING, STARTS_INSIDE
from .checkpoint import CHECKPOINT_FILE, Checkpoint, save_checkpoint
from ..analysis.energy import EXTERNAL, UNSTABLE_CREATED, created_fraction, energy_error, imbalance_growth
from .simulation import Simulation
from ..io._units import duration_text, time_unit
from ..io import (EventWriter, FieldWriter, HistoryWriter, Progress, RunHistory, read_history_csv, write_standard_plots,
                  write_summary)
from ..analysis.columns import tool_magnitude
from ..io.outputs import NO_ROOM
from ..io.plots import RUN_PLOTS


# |energy_error| above which the summary and the screen warn, once a run has taken
# AUDIT_MIN_STEPS steps: the audit is second-order in the step, and a run of a few steps (a tool's
# ramp just begun) holds energies so small that its rounding terms are tens of per cent of them.
ENERGY_WARNING = 0.05
AUDIT_MIN_STEPS = 20


class UnstableRunError(RuntimeError):
    """The run blew up (non-finite or runaway energy); outputs up to that point are kept."""


class StoppedAtOnce(RuntimeError):
    """A second Ctrl-C stopped the run at once (while it stepped, or while the summary and plots
    were written): what was written is kept."""


class DiskFullError(RuntimeError):
    """The output folder's disk (or quota) filled up during the run: it stopped like an
    interrupt, with what could be written kept and the last checkpoint resumable."""


def _no_room(err: OSError, out: Path) -> tuple[str, str]:
    """What ran out, in words (the disk or quota, or the size a file may have: ulimit -f), and
    what makes room."""
    where = err.filename or out
    if err.errno == errno.EFBIG:
        return f"{where} reached the largest file this process may write (ulimit -f)", "raise the file size limit"
    return f"the disk is full ({where})", "free some space"


@dataclass
class StopConditions:
    """Stop before end_time when a tool has moved `tool_displacement` metres (tool `tool`, or
    any tool when None), or when, after at least one failure, the largest tool force has stayed
    below `force_drop` times its peak for `force_drop_hold` seconds (default 5 % of end_time, so
    that contact chatter before the break does not end the run, and at most half the time the
    peak came at, so that an end time meant as "until it breaks" (10 s) still stops there; on the
    shipped tests half the peak's time is 3-8x their 5 %, so they stop where they did)."""

    tool_displacement: float | None = None
    tool: str | None = None
    force_drop: float | None = None
    force_drop_hold: float | None = None


def _silent(text: str) -> None:
    pass


@dataclass
class RunControl:
    end_time: float
    dt: float | None = None  # None: safety * stable step
    safety: float = 0.7
    history_samples: int = 400  # rows in history.csv over end_time
    field_frames: int = 10  # VTU snapshots over end_time (0: none)
    load_cell_window: float | None = None  # s; None: LOAD_CELL_TRANSITS element wave transits
    stop: StopConditions = field(default_factory=StopConditions)
    plots: bool = True
    checkpoint: bool = True  # leave checkpoint.pkl for --resume
    checkpoint_every: float = 600.0  # s of wall time between checkpoints during the run (besides the last)
    report: Callable[[str], None] = _silent  # where set-up lines, warnings and the cost estimate go
    progress: bool | None = None  # None: only on a terminal


# Default load-cell window, in element wave transits (sim.wave_transit): the chatter of a tool's
# penalty contact has a period of about one transit (a bar hitting a wall reads 0 to 3 x its true
# force from step to step); averaged over 4 transits the peak reads within 10 % of the true force.
LOAD_CELL_TRANSITS = 4.0


def _free_tools_summary(tools, names) -> dict:
    """summary.json `free_tools` (only when a tool has a mass): per free tool its mass (kg), launch
    speed and its velocity and speed at the end (m/s: a projectile's residual velocity)."""
    free = {}
    for j, name in enumerate(names):
        if tools.mass[j] > 0.0:
            v = tools.velocity[j]
            free[name] = {"mass": float(tools.mass[j]), "launch_speed": float(abs(tools.speeds[j, 0])),
                          "velocity": v.tolist(), "speed": float(np.linalg.norm(v))}
    return {"free_tools": free} if free else {}


def load_cell_steps(control: RunControl, dt: float, wave_transit: float) -> int:
    """The load cell's averaging window in steps of dt: run.load_cell_window, or by default
    LOAD_CELL_TRANSITS element wave transits (at most the LOAD_CELL_RING steps the cell holds)."""
    if control.load_cell_window is None:
        return min(max(1, round(LOAD_CELL_TRANSITS * wave_transit / dt)), LOAD_CELL_RING)
    steps = max(1, round(control.load_cell_window / dt))
    if steps > LOAD_CELL_RING:
        raise ValueError(
            f"run.load_cell_window = {control.load_cell_window:.3g} s is {steps} steps of {dt:.3g} s, more than "
            f"the {LOAD_CELL_RING} the load cell holds; set it at most {LOAD_CELL_RING * dt:.3g} s"
        )
    return steps


def steps_to(end_time: float, dt: float) -> int:
    """Steps of dt a run to end_time takes (the last one reaches or passes it)."""
    return max(1, int(math.ceil(end_time / dt - 1e-9)))


# The most of an element a tool, a body or the specimen may cross in one step: farther, contact
# cannot catch it (a sphere at 3e5 m/s passed through a plate in one step, nothing broken). A 300 m/s
# impact crosses about 0.04 of an element a step.
TRAVEL_LIMIT = 0.5


# The fastest tool, body or point a scenario may set (m/s): above the fastest impacts a fracture
# code is used for (space debris hits at 7-10 km/s); faster is a unit slip (km/h, mm/s).
SPEED_LIMIT = 1e4


def check_one_step_travel(sim, dt: float) -> None:
    """ValueError when the fastest tool, body or point moves faster than SPEED_LIMIT, or would
    cross more than TRAVEL_LIMIT of an element (sim.element_length) in one step of dt."""
    speed, what = sim.fastest_motion()
    if speed > SPEED_LIMIT:
        raise ValueError(
            f"{what} moves at {speed:.4g} m/s, faster than any impact crackle is made for ({SPEED_LIMIT:g} m/s); speeds "
            f"are in m/s (km/h meant? write {speed / 3.6:.4g}; mm/s? {speed:g}e-3)")
    length = getattr(sim, "element_length", None)
    if not length:
        return
    if speed * dt > TRAVEL_LIMIT * length:
        raise ValueError(
            f"{what} moves at {speed:.4g} m/s: {speed * dt:.3g} m in one step of {dt:.3g} s, more than "
            f"{TRAVEL_LIMIT:g} of an element ({length:.3g} m), so contact cannot catch it; lower the speed "
            f"(below {TRAVEL_LIMIT * length / dt:.3g} m/s at this step) or check its unit"
        )


def choose_time_step(sim, control: RunControl) -> float:
    """The step to use: by default safety x the simulation's stable step. A given run.dt is
    refused above safety x stable, or, where the method proves a bound at set-up (`sim.proven_dt`,
    s, and `sim.proven_dt_how`, a few words), above that bound: the margin below it is the
    user's choice, as in the DEM codes. A step above the stable one but within the bound gets a
    warning (the stable step leaves room for stiffness that comes later, e.g. new contacts)."""
    stable_dt = sim.stable_dt
    limit = control.safety * stable_dt
    if control.dt is None:
        return limit
    proven = getattr(sim, "proven_dt", None)
    if proven is None:
        if control.dt > limit:
            raise ValueError(
                f"run.dt = {control.dt:.3e} s is larger than the stable step {limit:.3e} s "
                f"(safety {control.safety} x {stable_dt:.3e} s, an estimate of the method's stable step); "
                f"remove run.dt or set it at most {limit:.3e}"
            )
        return control.dt
    if control.dt > proven:
        raise ValueError(
            f"run.dt = {control.dt:.3e} s is larger than the step crackle can prove stable, {proven:.3e} s "
            f"({sim.proven_dt_how}); set run.dt at most {proven:.3e} s, or remove it for the default "
            f"{limit:.3e} s (safety {control.safety} x {stable_dt:.3e} s, which leaves room for stiffness that comes later)"
        )
    if control.dt > stable_dt:
        note = (f"run.dt = {control.dt:.3e} s is within the step proven stable at set-up ({proven:.3e} s) but above "
                f"the stable step with room for what comes later ({stable_dt:.3e} s): new contacts can make the run "
                "unstable, which then stops with a message and keeps its outputs")
        if note not in sim.warnings:
            sim.warnings.append(note)
    return control.dt


@dataclass
class RunResult:
    out_dir: Path
    summary: dict
    history: RunHistory


def run(sim: Simulation, control: RunControl, out_dir: str | Path, scenario_name: str = "",
        scenario: dict | None = None, resume: Checkpoint | None = None) -> RunResult:
    """Run `sim` to control.end_time, writing the outputs into out_dir, and leave a checkpoint
    there (control.checkpoint). `scenario` (the validated scenario as a dict) goes into the
    checkpoint; `resume`, a checkpoint whose `sim` is `sim`, continues that run in out_dir: its
    outputs up to the checkpoint are kept and the new rows follow them.

    Rows fall on a grid of steps fixed by end_time and history_samples (and the field frames),
    from step 0: a resumed run writes the rows an uninterrupted one would. A second Ctrl-C
    stops the run at once (while it steps, or while the summary and plots are written) and raises
    StoppedAtOnce saying what is kept."""
    out = Path(out_dir)
    started = wallclock.time()
    try:
        # Signals are taken over for the whole run, its summary and plots included: a hang-up
        # while they are written lets them finish.
        with _InterruptRequest() as interrupt:
            return _run(sim, control, out, scenario_name, scenario, resume, interrupt)
    except KeyboardInterrupt:
        resumable = (out / CHECKPOINT_FILE).is_file()
        # A second Ctrl-C while the plots are drawn comes after this run's summary was written.
        summary = out / "summary.json"
        summarised = summary.is_file() and summary.stat().st_mtime >= started
        raise StoppedAtOnce(
            f"stopped at once by Ctrl-C at t = {sim.time:.4e} s: what was written by then ("
            + ("summary.json, " if summarised else "") + f"history.csv, events.csv) is kept in {out}"
            + ("" if summarised else ", without a summary")
            + (f"; --resume {out} continues from the last checkpoint" if resumable else "")
        ) from None


def _run(sim: Simulation, control: RunControl, out: Path, scenario_name: str, scenario: dict | None,
         resume: Checkpoint | None, interrupt: _InterruptRequest) -> RunResult:
    out.mkdir(parents=True, exist_ok=True)
    if resume is None:
        clear_outputs(out)
        dt = choose_time_step(sim, control)
        sim.load_cell.set_window(load_cell_steps(control, dt, sim.wave_transit))
        state = _DriverState(dt)
    else:  # the window of the load cell comes with the simulation
        state = _DriverState(resume.dt, resume.energy_scale, resume.low_since, resume.events, off_grid=resume.off_grid)
    rows = _RowGrid.of(control, state.dt)
    resumed_from = sim.time if resume is not None else None
    started = wallclock.perf_counter()
    with contextlib.ExitStack() as stack:
        progress = stack.enter_context(Progress(control.end_time, enabled=control.progress, log=control.report,
                                                status_path=out / "status.json"))
        say = functools.partial(progress.note, fallback=control.report)
        say(f"{scenario_name or sim.method}: {sim.describe()}; {rows.total - sim.steps:,} steps of {state.dt:.3g} s to "
            f"t = {control.end_time:.4g} s" + (f" from {sim.time:.4g} s" if resume is not None else ""))
        for warning in sim.warnings:
            say(f"  warning: {warning}")
        progress.stage("compiling kernels")  # the first sample and step compile them (or load them from the cache)
        try:
            outputs = _Outputs.open(stack, sim, out, state, rows, resumed_from)
        except OSError as err:  # the first row or field frame: nothing to resume from yet
            if err.errno not in NO_ROOM:
                raise
            progress.finish("disk full", sim.time, sim.steps, sim.broken)
            again = "rerun" if resume is None else f"continue with --resume {out}"
            what, fix = _no_room(err, out)
            raise DiskFullError(f"stopped: {what} before the first step; {fix} and {again} (what was written is "
                                f"in {out})") from None
        if rows.next_stop(sim.steps, outputs.fields) > sim.steps + 1:
            # One step alone compiles the kernels before the timed probe; it never skips a row (a
            # row's state does not depend on how its steps were split).
            sim.advance(1, state.dt)
        progress.stage("")
        try:
            _advance_rows(sim, control, out, scenario, state, rows, outputs, progress, interrupt, say, started)
        except UnstableRunError as err:
            state.status, state.message = "unstable", str(err) + sim.where_unstable()
        except OSError as err:
            if err.errno not in NO_ROOM:
                raise
            what, state.fix = _no_room(err, out)
            state.status, state.message = "disk full", f"{what} at t = {sim.time:.4e} s"
        _close_run(sim, control, out, scenario, state, rows, outputs)
        progress.finish(state.status, sim.time, sim.steps, sim.broken)
    if state.status == "disk full":
        # Nothing more is written (the summary and plots need room too); the history and events
        # keep their complete lines, which a resumed run reads up to its checkpoint.
        resumable = (out / CHECKPOINT_FILE).is_file()
        raise DiskFullError(
            f"stopped: {state.message}. What was written is kept in {out}" + (
                f"; {state.fix} and continue with --resume {out} (the same scenario, --quick and --set)"
                if resumable else f"; no checkpoint was written, so {state.fix} and rerun")
        )
    hist = outputs.table
    summary = _summary(sim, control, state, scenario_name, hist, wallclock.perf_counter() - started, resumed_from)
    write_summary(out / "summary.json", summary)
    if control.plots:
        write_standard_plots(out, hist, out / "events.csv", sim.bounds())
        sim.extra_plots(out, hist)
    if state.status == "unstable":
        raise UnstableRunError(state.message + f" (outputs so far are in {out})")
    return RunResult(out, summary, hist)


@dataclass
class _DriverState:
    """What the driver carries from row to row, and what a checkpoint keeps of it."""

    dt: float
    scale: float = 1.0  # the largest external work seen (J): the runaway-energy check's scale
    low_since: float | None = None  # since when the tool force stayed low after a failure (the force-drop clock)
    events: int = 0  # rows of events.csv written
    written_until: int = 0  # the steps of the last history row written (or kept, resuming)
    off_grid: bool = False  # the last row is off the grid (a Ctrl-C within a row stopped there)
    status: str = "completed"
    message: str = ""
    fix: str = ""  # what makes room, when the disk (or a file's size limit) stopped the run

    def checkpoint(self, sim, scenario: dict | None) -> Checkpoint:
        return Checkpoint(sim, self.dt, self.scale, self.low_since, self.events, scenario or {}, self.off_grid)


# The most steps between two history rows (and stop checks, progress updates, Ctrl-C): the
# shipped examples' rows come every 50-700 steps.
MAX_STEPS_PER_ROW = 1000


@dataclass
class _RowGrid:
    """The steps with a row, fixed by end_time, history_samples and field_frames from step 0: a
    resumed run writes the rows an uninterrupted one would."""

    total: int  # steps to end_time
    every: int  # steps between history rows
    field_every: int  # steps between field frames (0: none)

    @classmethod
    def of(cls, control: RunControl, dt: float) -> "_RowGrid":
        total = steps_to(control.end_time, dt)
        # At most MAX_STEPS_PER_ROW: an end time meant as "until it breaks" (10 s) still gets rows,
        # stop checks and progress where the fracture happens.
        every = max(1, min(total // max(1, control.history_samples), MAX_STEPS_PER_ROW))
        return cls(total, every, max(1, total // control.field_frames) if control.field_frames > 0 else 0)

    def next_stop(self, step: int, fields) -> int:
        """The next step with a row (the grid of rows, the field frames, the end)."""
        stop = min(self.total, _next_multiple(step, self.every))
        return min(stop, _next_multiple(step, self.field_every)) if fields is not None else stop


@dataclass
class _Outputs:
    """The files a run writes as it goes: history.csv, events.csv, the field frames."""

    history: HistoryWriter
    table: RunHistory  # the same rows as arrays, for the summary and the plots
    events: EventWriter
    fields: FieldWriter | None

    @classmethod
    def open(cls, stack: contextlib.ExitStack, sim, out: Path, state: _DriverState, rows: _RowGrid,
             resumed_from: float | None) -> "_Outputs":
        """Open them (a resumed run continues the files of the run it resumes, rows up to its
        time); a new run writes its first row and frame, and its energy scale."""
        first = {"time": sim.time, **sim.sample(state.dt)}
        # A row off the grid where a Ctrl-C stopped the run is dropped: the resumed history is the
        # uninterrupted run's, row for row.
        kept = resumed_from if resumed_from is None or not state.off_grid else math.nextafter(resumed_from, -math.inf)
        history = stack.enter_context(HistoryWriter(out / "history.csv", list(first), keep_until=kept))
        # A resumed run's rows before its checkpoint are in the file alone: read once.
        table = RunHistory(sim.history_units(first), None if kept is None else read_history_csv(history.path))
        events = stack.enter_context(EventWriter(out / "events.csv", keep_rows=None if resumed_from is None else state.events,
                                                       materials=sim.several_materials))
        outputs = cls(history, table, events, FieldWriter(out, keep_until=resumed_from) if rows.field_every else None)
        state.written_until, state.off_grid = sim.steps, False
        if resumed_from is None:
            history.append(first)
            table.append(first)
            if outputs.fields is not None:
                _write_fields(outputs.fields, sim)
            state.scale = max(1.0, abs(first.get("energy.external", 0.0)))
        return outputs

    def write_row(self, sim, state: _DriverState, rows: _RowGrid) -> dict:
        """The history row of the current state, its new failures and (on the grid) its frame."""
        row = {"time": sim.time, **sim.sample(state.dt)}
        self.history.append(row)
        self.table.append(row)
        state.written_until = sim.steps
        t, xyz, modes, ids = sim.new_events()
        if len(ids):
            self.events.append_many(t, xyz, modes, ids, sim.failure_labels(ids))
            state.events += len(ids)
        if self.fields is not None and sim.steps % rows.field_every == 0:
            _write_fields(self.fields, sim)
        return row


def _advance_rows(sim, control: RunControl, out: Path, scenario, state: _DriverState, rows: _RowGrid,
                  outputs: _Outputs, progress, interrupt, say, started: float) -> None:
    """Step from row to row to the end, checking each row (UnstableRunError), until a stop rule,
    an interrupt or the end; checkpoints every control.checkpoint_every seconds of wall time."""
    probe = _CostProbe(sim.steps)
    tool_names = sim.tool_names()
    last_checkpoint = wallclock.perf_counter()
    while sim.steps < rows.total:
        stop = rows.next_stop(sim.steps, outputs.fields)
        while sim.steps < stop:
            sim.advance(probe.piece(stop - sim.steps), state.dt)
            estimate = probe.after_piece(sim.steps, rows, started, outputs.fields)
            if estimate:
                say(estimate)
            if sim.steps < stop:
                progress.update(sim.time, sim.steps, sim.broken)
                if interrupt.requested:  # within a long row: stop here, with a row off the grid
                    state.off_grid = True
                    break
        if not sim.state_is_finite():
            raise UnstableRunError(
                f"the run went unstable before t = {sim.time:.4e} s (non-finite positions or "
                f"velocities); {_advice(sim, 'reduce run.dt or run.safety, or check loads and penalties')}"
            )
        row = outputs.write_row(sim, state, rows)
        progress.update(sim.time, sim.steps, sim.broken)
        if state.off_grid:  # the stop rules and the energy scale keep to the grid's rows
            state.status, state.message = "interrupted", f"interrupted {interrupt.why} at t = {sim.time:.4e} s"
            return
        _check_energy(sim, row, state)
        reason = _stop_rule(sim, control, row, tool_names, state)
        if reason:
            state.status, state.message = "stopped", reason
            return
        if interrupt.requested:
            state.status, state.message = "interrupted", f"interrupted {interrupt.why} at t = {sim.time:.4e} s"
            return
        if control.checkpoint and wallclock.perf_counter() - last_checkpoint >= control.checkpoint_every:
            # After this row's driver state (energy scale, force-drop clock) is updated: a run
            # killed later resumes from here (its later rows are dropped then).
            save_checkpoint(out, state.checkpoint(sim, scenario))
            last_checkpoint = wallclock.perf_counter()


def _check_energy(sim, row: dict, state: _DriverState) -> None:
    """UnstableRunError when a row holds non-finite values, energy the work put in does not
    explain, or energy grown without work; else the row's external work joins the scale."""
    if not all(math.isfinite(v) for v in row.values()):
        raise UnstableRunError(
            f"the run went unstable at t = {sim.time:.4e} s (non-finite values); "
            f"{_advice(sim, 'reduce run.dt or run.safety, or check loads and penalties')}"
        )
    # Not in the first steps: a moving tool's work is booked a step after the motion it causes,
    # so a run's first rows hold more energy than was put in.
    created = created_fraction(row) if EXTERNAL in row and sim.steps >= 100 else 0.0
    if created > UNSTABLE_CREATED:
        raise UnstableRunError(
            f"the run went unstable at t = {sim.time:.4e} s (the model holds {created:.0%} more "
            f"energy than the work put in); {_advice(sim, 'reduce run.safety, or run.target_dt with mass scaling')}"
        )
    state.scale = max(state.scale, abs(row.get("energy.external", 0.0)))
    energy_terms = [v for k, v in row.items() if k.startswith("energy.")]
    if energy_terms and sum(abs(v) for v in energy_terms) > 1e6 * state.scale + 1e-3:
        raise UnstableRunError(
            f"the run went unstable at t = {sim.time:.4e} s (energy grew without work "
            f"put in); {_advice(sim, 'reduce run.dt or run.safety')}"
        )


def _stop_rule(sim, control: RunControl, row: dict, tool_names: list[str], state: _DriverState) -> str:
    """Why the run stops at this row ("" to go on); keeps the force-drop clock: it starts when,
    after a failure, the largest tool force falls below force_drop x its peak over every step
    (what the load cell keeps, not only the rows), and stops when the force rises again."""
    force = max((_tool_force(row, name) for name in tool_names), default=0.0)
    peaks, times = sim.load_cell.peaks()
    peak_force = float(np.max(peaks, initial=0.0))
    peak_time = float(times[np.argmax(peaks)]) if len(peaks) else 0.0
    if force >= (control.stop.force_drop or 0.0) * peak_force or sim.broken == 0:
        state.low_since = None
    elif state.low_since is None:
        state.low_since = sim.time
    return _stop_reason(control, row, tool_names, peak_force, peak_time, state.low_since, sim.time)


def _close_run(sim, control: RunControl, out: Path, scenario, state: _DriverState, rows: _RowGrid,
               outputs: _Outputs) -> None:
    """The last field frame and the last checkpoint of a run that ended, stopped or was
    interrupted (an unstable one leaves none: its state is not worth resuming)."""
    if outputs.fields is not None and state.status not in ("unstable", "disk full") and sim.steps % rows.field_every:
        _write_fields(outputs.fields, sim)
    # A full disk keeps the last checkpoint unless the history holds the current state's row (a
    # checkpoint past the last row written would leave a gap in the resumed history).
    if state.status == "unstable" or not control.checkpoint:
        return
    if state.status == "disk full" and state.written_until != sim.steps:
        return
    try:
        save_checkpoint(out, state.checkpoint(sim, scenario))
    except OSError as err:
        if err.errno not in NO_ROOM:
            raise
        what, state.fix = _no_room(err, out)
        state.status = "disk full"
        state.message = (state.message or f"{what} at t = {sim.time:.4e} s") + (
            "; the checkpoint could not be updated (an earlier one, if any, is whole)")


def _summary(sim, control: RunControl, state: _DriverState, scenario_name: str, hist: dict, wall_time: float,
             resumed_from: float | None) -> dict:
    """summary.json: the driver's part (status, steps, the load cell's peaks, the energy audit),
    then the method's; the warnings only the end of the run can tell are reported."""
    tool_names = sim.tool_names()
    peaks, peak_times = sim.load_cell.peaks()
    peak = int(np.argmax(peaks)) if len(peaks) and peaks.max() > 0.0 else None
    summary = {
        "method": sim.method,
        "scenario": scenario_name,
        "status": state.status,
        "message": state.message,
        "steps": sim.steps,
        "dt": state.dt,
        "stable_dt": sim.stable_dt,
        "end_time": sim.time,
        "wall_time": wall_time,
        "broken": sim.broken,
        "peak_force": float(peaks[peak]) if peak is not None else 0.0,
        "peak_force_tool": tool_names[peak] if peak is not None else None,
        "peak_force_time": float(peak_times[peak]) if peak is not None else None,
        "peak_forces": {name: float(f) for name, f in zip(tool_names, peaks)},
        "load_cell_window": sim.load_cell.window * state.dt,
        "energy_error": energy_error(hist),
        "history_units": hist.units,
        "crackle_version": __version__,
        **({"resumed_from": resumed_from} if resumed_from is not None else {}),
        **_free_tools_summary(sim.load_cell.tools, tool_names),
        **sim.summary(),
    }
    for warning in summary.get("warnings", [])[len(sim.warnings):]:  # those only the end of the run can tell
        control.report(f"  warning: {warning}")
    if abs(summary["energy_error"]) > ENERGY_WARNING and sim.steps >= AUDIT_MIN_STEPS:
        growth = imbalance_growth(hist)
        scale, unit = time_unit(sim.time)
        where = f": {growth.describe(scale, unit)}" if growth is not None else ""
        warning = (
            f"the energy balance is off by {summary['energy_error']:.1%} of the largest energy (more than "
            f"{ENERGY_WARNING:.0%}): results may not be trustworthy; "
            f"{_advice(sim, 'reduce run.safety or check the contact penalties')} (plots/energies.png shows when the "
            f"imbalance grew{where})"
        )
        summary["warnings"] = [*summary.get("warnings", []), warning]
        control.report(f"  warning: {warning}")
    return summary


# Wall time (s) of the first steps after compilation that the cost estimate is measured over, and
# the estimated run time above which it is printed.
PROBE_SECONDS = 0.5
ESTIMATE_ABOVE = 60.0
# Wall time (s) of the pieces a row is stepped in: Ctrl-C, a closed terminal and the progress
# line are answered within about this, however long a row takes (a row of 1,000 steps of a big
# model takes minutes).
PIECE_SECONDS = 1.0


class _CostProbe:
    """The pieces a row is stepped in, and the cost estimate: timed over the first steps after
    compiling, taken in pieces of 1, 2, 4 ... steps until PROBE_SECONDS have passed, so that a big
    model says what it costs within seconds, not after its first row; then pieces of about
    PIECE_SECONDS (a row's state does not depend on how its steps were split)."""

    def __init__(self, steps: int):
        self.since = (wallclock.perf_counter(), steps)  # wall time and steps when the timing began
        self.size = 1
        self.done = False

    def piece(self, left: int) -> int:
        """Steps to take next, of the `left` to the next row."""
        return min(left, self.size)

    def after_piece(self, steps: int, rows: _RowGrid, started: float, fields) -> str:
        """'  estimated wall time ...' once, when PROBE_SECONDS have passed and the whole run
        would take longer than ESTIMATE_ABOVE; else ""."""
        if self.done:
            return ""
        self.size *= 2
        now = wallclock.perf_counter()
        if now - self.since[0] <= PROBE_SECONDS:
            return ""
        self.done = True
        per_step = (now - self.since[0]) / max(1, steps - self.since[1])
        self.size = max(1, int(PIECE_SECONDS / per_step))
        total = now - started + per_step * (rows.total - steps)
        if total < ESTIMATE_ABOVE:
            return ""
        text = f"  estimated wall time {duration_text(total)} ({per_step * 1e3:.3g} ms per step)"
        if fields is not None and fields.steps:
            frames = len(fields.steps) + (rows.total - steps) // rows.field_every + 1
            text += f"; fields ~{frames * fields.last_frame_bytes / 1e6:,.0f} MB ({frames} frames)"
        return text


def _advice(sim, usual: str) -> str:
    """What to do about energy from nowhere: `usual` (the step, the penalties), unless the set-up
    noted points starting inside a tool, whose penalty throws them out with energy never put in."""
    inside = next((w for w in sim.warnings if STARTS_INSIDE in w), None)
    if inside is None:
        return usual
    return (f"{inside.split(':')[0]} started with points inside it (the set-up note), whose penalty throws them out "
            "with energy never put in: set seat = true on it, or place it on the surface (touch = true)")


def _next_multiple(step: int, every: int) -> int:
    """The first multiple of `every` after `step`."""
    return (step // every + 1) * every


def _tool_force(row: dict, name: str) -> float:
    return float(tool_magnitude(row, name, "f"))


def _stop_reason(control: RunControl, row, tool_names, peak_force, peak_time, low_since, now) -> str:
    stop = control.stop
    if stop.tool_displacement is not None:
        names = [stop.tool] if stop.tool else tool_names
        for name in names:
            u = float(tool_magnitude(row, name, "u"))
            if u >= stop.tool_displacement:
                return f"tool {name} moved {u:.4g} m"
    if stop.force_drop is not None and low_since is not None:
        hold = stop.force_drop_hold if stop.force_drop_hold is not None else \
            min(0.05 * control.end_time, 0.5 * peak_time)
        if now - low_since >= hold:
            return f"tool force stayed below {stop.force_drop:.0%} of its peak {peak_force:.4g} N for {now - low_since:.3g} s"
    return ""


class _InterruptRequest:
    """Ctrl-C (or a polite kill, SIGTERM, e.g. a batch system's time limit, or SIGHUP, its terminal
    closed) during a run asks it to stop after the piece in progress, so that the history, the
    events, the summary and the checkpoint end at the same consistent state; a second Ctrl-C
    interrupts at once (a SIGTERM or SIGHUP while it stops does not: a terminal closed after a
    Ctrl-C must not lose the summary). `request_stop` asks the same when the run's output stream is lost (a pipe
    closed: `crackle run ... | head`)."""

    active: _InterruptRequest | None = None  # the run's, while one runs in this process
    pending: str | None = None  # request_stop's reason, for runs that start after it (the stream stays lost)
    SIGNALS = {signal.SIGINT: "by the user", signal.SIGTERM: "by SIGTERM",
               **({signal.SIGHUP: "as its terminal closed (SIGHUP)"} if hasattr(signal, "SIGHUP") else {})}

    def __init__(self):
        self.requested = False
        self.why = "by the user"
        self.ctrl_c = 0  # Ctrl-Cs received
        self._previous = None

    def _handler(self, signum, frame):
        # Only a second Ctrl-C stops at once: a hang-up or SIGTERM while stopping lets the stop under
        # way keep its summary and checkpoint (Python runs signals that arrive within one compiled
        # piece lowest number first: SIGHUP before the SIGINT that came earlier).
        if signum == signal.SIGINT:
            self.ctrl_c += 1
            if self.ctrl_c > 1:
                raise KeyboardInterrupt
        if self.requested:
            return
        self.ask(self.SIGNALS.get(signum, "by a signal"))
        print(f"\ncrackle: stopping ({self.why}) with the summary and checkpoint within about a second (Ctrl-C again "
              "to stop at once)", file=sys.stderr, flush=True)

    def ask(self, why: str) -> None:
        if not self.requested:
            self.requested, self.why = True, why

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = {sig: signal.signal(sig, self._handler) for sig in self.SIGNALS}
        _InterruptRequest.active = self
        if _InterruptRequest.pending:
            self.ask(_InterruptRequest.pending)
        return self

    def __exit__(self, *exc):
        _InterruptRequest.active = None
        for sig, handler in (self._previous or {}).items():
            signal.signal(sig, handler)


def request_stop(why: str | None) -> None:
    """Ask the run in progress in this process to stop after its chunk, as Ctrl-C does, and every
    run that starts later after its first; None withdraws the request for the runs to come."""
    _InterruptRequest.pending = why
    if why is not None and _InterruptRequest.active is not None:
        _InterruptRequest.active.ask(why)


# What a run writes into its output folder (and a rerun into the same folder removes first): the
# figures are every one a run of any method draws (io.plots.RUN_PLOTS).
OUTPUT_FILES = ("summary.json", "status.json", "history.csv", "events.csv", "fields.pvd", CHECKPOINT_FILE) + tuple(
    f"plots/{name}.png" for name in RUN_PLOTS)
OUTPUT_GLOBS = ("fields/step_*.vtu",)


def clear_outputs(out: Path) -> None:
    """Remove an earlier run's outputs from `out` (only crackle's own files), so that ParaView
    and readers never mix two runs."""
    for name in OUTPUT_FILES:
        (out / name).unlink(missing_ok=True)
    for pattern in OUTPUT_GLOBS:
        for path in out.glob(pattern):
            path.unlink()


def _write_fields(writer: FieldWriter, sim) -> None:
    f = sim.fields()
    writer.write_blocks(sim.time, f["points"], f["blocks"], point_data=f["point_data"],
                        component_names=f.get("component_names"))

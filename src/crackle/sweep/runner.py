"""Running a sweep's runs on Dask: a local cluster by default, any scheduler by its address.

Each run is an ordinary `crackle run` in its own folder (outputs of the output contract); a run
whose folder holds a finished summary.json is not run again, so an interrupted sweep continues
where it stopped, and a run interrupted mid-way continues from its last checkpoint (`crackle run
--resume`; from the start when the checkpoint is of other settings). A run that fails (a value its scenario refuses, an unstable run, an error) is
a row with its status and message; the others go on."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from ..scenario import ScenarioError
from ..solver.checkpoint import CHECKPOINT_FILE
from .plan import SweepPlan, SweepRun
from .table import write_envelopes, write_seed_statistics, write_table

MANIFEST = "sweep.json"
# A run folder whose summary has one of these is finished (interrupted runs are run again).
FINISHED = ("completed", "stopped", "unstable")
COMPLETED = ("completed", "stopped")  # finished with results to use


@dataclass
class SweepResult:
    out_dir: Path
    rows: list[dict]  # one per run, in the plan's order
    ran: int  # runs made by this call (the rest were finished before)
    notes: list[str] = field(default_factory=list)  # to print: the means and deviations over seeds (--seeds), envelopes


# The sweeps interrupted while this process ran their runs (by sweep id): their runs not started
# yet are not started; the one in progress stops at its next piece, as a run stops on Ctrl-C.
_INTERRUPTED_SWEEPS: set[str] = set()
NOT_STARTED = "not started: the sweep was interrupted"


def interrupt_sweep_runs(sweep_id: str) -> None:
    """On a worker: stop the sweep's run in progress (and any of its runs starting now) as Ctrl-C
    stops a run, with its summary, plots and checkpoint; start none of its others."""
    from ..solver.driver import request_stop

    _INTERRUPTED_SWEEPS.add(sweep_id)
    request_stop("as its sweep was interrupted")


def run_one(scenario: str, folder: str, overrides: dict, quick: bool, threads: int, plots: bool = True,
            sweep_id: str = "") -> dict:
    """One run, on a worker: `crackle run` with these overrides, `threads` numba threads (and
    its plots unless `plots` is False). Returns {"status", "message"}; never raises, so one run's
    failure stays its own."""
    import numba

    from ..api import run_scenario
    from ..solver import UnstableRunError
    from ..solver.driver import request_stop

    if sweep_id in _INTERRUPTED_SWEEPS:
        return {"status": "interrupted", "message": NOT_STARTED}
    if _INTERRUPTED_SWEEPS:  # an earlier sweep's stop, on a worker that outlived it: not this sweep's
        _INTERRUPTED_SWEEPS.clear()
        request_stop(None)
    caller_threads = numba.get_num_threads()  # given back after the run (a run on the caller's thread)
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        try:
            if not (Path(folder) / CHECKPOINT_FILE).is_file():
                raise ScenarioError("no checkpoint")
            result = run_scenario(scenario, None, overrides, quick, progress=False, plots=plots, resume=folder)
        except ScenarioError:  # nothing to resume (or a checkpoint of other settings): from the start
            result = run_scenario(scenario, folder, overrides, quick, progress=False, plots=plots)
    except ScenarioError as err:
        return {"status": "invalid", "message": str(err)}
    except UnstableRunError as err:
        return {"status": "unstable", "message": str(err)}
    except Exception as err:  # noqa: BLE001 - any error is this run's row, not the sweep's end
        return {"status": "failed", "message": f"{type(err).__name__}: {err}"}
    finally:
        numba.set_num_threads(caller_threads)
    return {"status": result.summary["status"], "message": result.summary.get("message", "")}


def outcome_of(future) -> dict:
    """A task's {"status", "message"}, or a failed one when its worker died (memory, a crash)."""
    try:
        return future.result()
    except Exception as err:  # noqa: BLE001 - one task's end, not the sweep's
        return {"status": "failed", "message": f"{type(err).__name__}: {err}"}


def finished_summary(folder: Path) -> dict | None:
    """The summary of a finished run in `folder`, or None."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return summary if summary.get("status") in FINISHED else None


def check_runs(plan: SweepPlan, runs: list[SweepRun]) -> dict[int, str]:
    """Validate every run's scenario before any is started: {index: message} of those refused.
    When every run is refused the sweep cannot do anything: ScenarioError (exit 2)."""
    from ..scenario import load_scenario

    refused = {}
    for run in runs:
        try:
            load_scenario(plan.scenario, {**plan.fixed, **run.varied}, plan.quick)
        except ScenarioError as err:
            refused[run.index] = str(err)
    if refused and len(refused) == len(runs):
        first = runs[0]
        raise ScenarioError(f"every run of the sweep is refused; the first ({first.folder}): {refused[first.index]}")
    return refused


def run_sweep(plan: SweepPlan, out_dir: str | Path, scheduler: str | None = None, workers: int | None = None,
              threads_per_run: int | None = None, plots: list[str] = (), report=print) -> SweepResult:
    """Run the plan's runs not finished yet in out_dir, then write the table and the plots."""
    from ..api import check_output_folder

    out = Path(out_dir)
    runs = plan.runs()
    check_output_folder(out)
    refused = check_runs(plan, runs)  # before anything is written
    _claim_folder(out, plan)
    todo = [r for r in runs if r.index not in refused and finished_summary(out / r.folder) is None]
    report(f"sweep of {len(runs)} runs in {out}: {len(runs) - len(todo) - len(refused)} finished before, "
           f"{len(refused)} refused, {len(todo)} to run")
    outcome: dict[int, dict] = {i: {"status": "invalid", "message": msg} for i, msg in refused.items()}
    if todo:
        outcome.update(_run_on_dask(plan, out, todo, scheduler, workers, threads_per_run, report))
    rows = []
    for run in runs:
        summary = finished_summary(out / run.folder)
        row = {"run": run.folder, **run.varied}
        if summary is not None:
            row.update(status=summary["status"], message=summary.get("message", ""), summary=summary)
        else:
            got = outcome.get(run.index, {"status": "missing", "message": "no finished summary.json"})
            row.update(status=got["status"], message=got["message"], summary={})
        rows.append(row)
    unknown = write_table(out, list(plan.vary), rows, plots, plan.scenario)
    notes = write_seed_statistics(out, list(plan.vary), rows, list(plots))
    notes += write_envelopes(out, rows, plan.scenario)
    if unknown:
        raise ScenarioError(f"--plot {'; '.join(unknown)}: no such scalar in the runs' summaries; the table and the "
                            "other plots are written, and rerunning with the right name reuses the finished runs")
    return SweepResult(out, rows, len(todo), notes)


def _claim_folder(out: Path, plan: SweepPlan) -> None:
    """Write the plan into out/sweep.json, refusing a folder that holds another sweep."""
    manifest = out / MANIFEST
    record = plan.as_record()
    if manifest.is_file():
        try:
            before = json.loads(manifest.read_text())
        except ValueError:
            before = None
        if before != json.loads(json.dumps(record)):
            raise ScenarioError(
                f"--out {out}: it holds another sweep ({MANIFEST} differs: scenario, --vary, --set, --zip or "
                "--quick changed); give a new --out, or the same arguments to continue that sweep"
            )
    out.mkdir(parents=True, exist_ok=True)
    manifest.write_text(json.dumps(record, indent=2) + "\n")


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int | None, threads_per_run: int | None, n_runs: int, report):
    """A Dask client and the numba threads per run: a local cluster of `workers` processes (default
    one per core, at most one per run) sharing the cores, or the scheduler at its address."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ScenarioError("crackle sweep and calibrate need Dask: pip install 'crackle[sweep]'") from None
    cores = os.cpu_count() or 1
    if scheduler is None:
        workers = workers or max(1, min(n_runs, cores // (threads_per_run or 1)))
        threads = threads_per_run or max(1, cores // workers)
        cluster = _quiet_cluster(LocalCluster, workers)
        client = Client(cluster)
        where = f"a local cluster of {workers} workers"
    else:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as err:
            raise ScenarioError(f"--scheduler {scheduler}: cannot reach it ({err}); start dask-scheduler there "
                                "or give its address as tcp://HOST:PORT") from None
        cluster, threads, where = None, threads_per_run or 1, scheduler
    report(f"  on {where}, {threads} numba thread(s) per run")
    try:
        yield client, threads
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _quiet_cluster(LocalCluster, workers: int):
    """A local cluster whose worker processes ignore Ctrl-C (they inherit SIGINT ignored): the
    sweep's own process stops them and says so in one line, instead of each worker printing its
    traceback."""
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)


def _run_on_dask(plan, out, todo, scheduler, workers, threads_per_run, report) -> dict[int, dict]:
    outcome = {}
    with dask_client(scheduler, workers, threads_per_run, len(todo), report) as (client, threads):
        tasks = {r.index: (plan.scenario, out / r.folder, {**plan.fixed, **r.varied}, plan.quick) for r in todo}
        folders = {r.index: r.folder for r in todo}
        with _RunsProgress(len(todo)) as progress:
            def done(index, result):
                outcome[index] = result
                progress.advance(f"{folders[index]}: {result['status']}")

            run_tasks(client, tasks, threads, done)
    return outcome


# Seconds between the sweep's looks at its runs (and at a Ctrl-C).
POLL_SECONDS = 0.2


def run_tasks(client, tasks: dict, threads: int, done) -> None:
    """Run `tasks` ({key: (scenario, folder, overrides, quick)}) with run_one on the client's
    workers, calling done(key, {"status", "message"}) as each ends. A Ctrl-C stops the runs in
    progress as Ctrl-C stops a run (each within about a second, with its summary, plots and
    checkpoint, its folder's lock released), starts none of the others, then raises
    KeyboardInterrupt; a second one stops at once."""
    from distributed import as_completed

    sweep_id = uuid.uuid4().hex
    futures = {client.submit(run_one, scenario, str(Path(folder).resolve()), overrides, quick, threads,
                             sweep_id=sweep_id, pure=False): key
               for key, (scenario, folder, overrides, quick) in tasks.items()}
    waiting = dict(futures)

    def gather():
        # Polled, not waited on: a Ctrl-C the kernel hands to one of Dask's threads reaches
        # Python's handler only when the main thread wakes (it waited for the next run to end).
        finished = as_completed(list(waiting))
        while not finished.is_empty():
            for future in finished.next_batch(block=False):
                result = outcome_of(future)
                del waiting[future]
                if result["message"] != NOT_STARTED:
                    done(futures[future], result)
            time.sleep(POLL_SECONDS)

    try:
        gather()
    except KeyboardInterrupt:
        print("\ncrackle: stopping the runs in progress with their summaries and checkpoints (Ctrl-C again to "
              "stop at once)", file=sys.stderr, flush=True)
        client.run(interrupt_sweep_runs, sweep_id)
        gather()
        raise


class _RunsProgress:
    """A bar over the runs on a terminal; a line per finished run otherwise."""

    def __init__(self, total: int):
        self.total, self.done, self.bar = total, 0, None

    def __enter__(self):
        if sys.stdout.isatty():
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

            self.bar = Progress(BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
            self.task = self.bar.add_task("runs", total=self.total)
            self.bar.start()
        return self

    def advance(self, text: str) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.console.print(text, highlight=False, markup=False)
            self.bar.advance(self.task)
        else:
            print(f"  [{self.done}/{self.total}] {text}", flush=True)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()

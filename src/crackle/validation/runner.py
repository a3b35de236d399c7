"""`crackle validate`: run the chosen cases (on Dask, as `crackle sweep`), read their numbers,
write the report and say whether every case is inside its band.

Each distinct run (scenario, tier, overrides) runs once (on a Dask cluster; with --jobs 1 and no
scheduler, one after the other in the calling process), in its own folder under the output
folder (named by the scenario and a hash of its settings, with run.json saying which); a folder
holding a finished run of the same settings is read, not run again, so an interrupted validation
continues where it stopped.

A case's status: "pass" (inside its band), "not reproduced" (inside its band, the case saying
why crackle does not reach the paper), "outside" (outside its band: crackle has drifted), or
"failed" (its run did not finish: refused, unstable, an error). Exit 1 when any is outside or
failed.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from .cases import PAPERS, Case, Run, read_number
from .figures import case_figure

PASS, NOT_REPRODUCED, OUTSIDE, FAILED = "pass", "not reproduced", "outside", "failed"
REPORT = "report.md"


@dataclass
class CaseResult:
    case: Case
    value: float | None
    status: str
    run: str  # the run's folder, relative to the output folder
    wall_time: float | None  # s, the run's
    message: str = ""
    commit: str = ""  # what the run ran at, and when (run.json)
    date: str = ""


def validate(cases: list[Case], out_dir: str | Path, scheduler: str | None = None, jobs: int | None = None,
             threads_per_run: int | None = None, report=print, also: tuple[Run, ...] = ()) -> list[CaseResult]:
    """Run the cases' runs (and the runs `also` names) not finished yet in out_dir, read every
    case, write report.md and report.json there; the results in the cases' order."""
    from ..sweep.runner import finished_summary

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs: dict[str, Run] = {}
    for run in [case.run for case in cases] + list(also):
        runs.setdefault(run.folder(), run)
    todo = {name: run for name, run in runs.items() if not _finished_here(out / name, run)}
    report(f"validate: {len(cases)} cases" + (f" and {len(also)} more runs" if also else "")
           + f" in {len(runs)} runs in {out}: {len(runs) - len(todo)} finished before, {len(todo)} to run")
    if not todo:
        outcome = {}
    elif scheduler is None and jobs == 1:
        outcome = _run_here(out, todo, threads_per_run, report)
    else:
        outcome = _run_on_dask(out, todo, scheduler, jobs, threads_per_run, report)
    results = []
    for case in cases:
        name = case.run.folder()
        summary = finished_summary(out / name)
        if summary is None or summary.get("status") not in ("completed", "stopped"):
            got = outcome.get(name, {"message": "no finished summary.json"})
            message = got.get("message") or (summary or {}).get("message", "")
            results.append(CaseResult(case, None, FAILED, name, None, message))
            continue
        value = case.value(summary, out / name)
        if value is None:
            results.append(CaseResult(case, None, FAILED, name, summary.get("wall_time"),
                                      f"the run has no number {case.read!r}"))
            continue
        low, high = case.band
        inside = low <= value <= high
        status = OUTSIDE if not inside else (NOT_REPRODUCED if case.reason else PASS)
        record = _run_record(out / name)
        results.append(CaseResult(case, value, status, name, summary.get("wall_time"),
                                  commit=record.get("commit", ""), date=record.get("date", "")))
    write_report(out, results)
    return results


def _run_record(folder: Path) -> dict:
    """run.json: the run's settings, and the commit and date it ran at."""
    try:
        return json.loads((folder / "run.json").read_text())
    except (OSError, ValueError):
        return {}


def _finished_here(folder: Path, run: Run) -> bool:
    from ..sweep.runner import finished_summary

    return _run_record(folder).get("settings") == run.settings() and finished_summary(folder) is not None


def _claim(out: Path, name: str, run: Run) -> Path:
    """The run's folder, with run.json saying its settings and the commit and date it runs at."""
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    where = provenance()
    (folder / "run.json").write_text(json.dumps({"settings": run.settings(), "commit": where["commit"],
                                                 "date": where["date"]}, indent=2) + "\n")
    return folder


def _run_here(out: Path, runs: dict[str, Run], threads_per_run, report) -> dict[str, dict]:
    """One job and no scheduler: the runs one after the other in this process (no cluster to start)."""
    from ..sweep.runner import run_one

    threads = threads_per_run or os.cpu_count() or 1
    report(f"  in this process, {threads} numba thread(s) per run")
    outcome = {}
    for name, run in runs.items():
        folder = _claim(out, name, run)
        outcome[name] = run_one(run.scenario, str(folder.resolve()), dict(run.overrides), run.quick, threads)
        report(f"  {name}: {outcome[name]['status']}")
    return outcome


def _run_on_dask(out: Path, runs: dict[str, Run], scheduler, jobs, threads_per_run, report) -> dict[str, dict]:
    from ..sweep.runner import dask_client, run_tasks

    outcome = {}
    with dask_client(scheduler, jobs, threads_per_run, len(runs), report) as (client, threads):
        tasks = {name: (run.scenario, _claim(out, name, run), dict(run.overrides), run.quick) for name, run in runs.items()}

        def done(name, result):
            outcome[name] = result
            report(f"  {name}: {result['status']}")

        run_tasks(client, tasks, threads, done)
    return outcome


def exit_code(results: list[CaseResult]) -> int:
    return 1 if any(r.status in (OUTSIDE, FAILED) for r in results) else 0


def _format(value: float | None, case: Case) -> str:
    """4 significant digits, more where the band is narrower than that shows."""
    if value is None:
        return "none"
    low, high = case.band
    span = (high - low) / max(abs(high), abs(low), 1e-300)
    digits = 4 if span >= 1e-3 else min(15, 3 + math.ceil(-math.log10(max(span, 1e-15))))
    return f"{value:.{digits}g}"


def provenance() -> dict:
    """The commit and machine a validation ran on."""
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True,
                                check=True).stdout.strip()
        # Uncommitted changes of the package's code (documents and tests do not change a result).
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "."], cwd=here.parent,
                               capture_output=True, text=True, check=True).stdout.strip()
        commit += "-dirty" if dirty else ""  # git describe's mark: uncommitted changes
    except (OSError, subprocess.CalledProcessError):
        from .. import __version__

        commit = f"crackle {__version__} (not a git checkout)"
    from llvmlite.binding import get_host_cpu_name

    # numba compiles for the host's generation (get_host_cpu_name): results differ in the last bits across them.
    cpu = f"{cpu_model() or platform.machine()} ({get_host_cpu_name()})"
    return {"commit": commit, "machine": f"{cpu}, {os.cpu_count()} cores, {platform.system()}",
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def cpu_model() -> str:
    """The processor's model name (/proc/cpuinfo), or what the platform says ("" when nothing)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
        return ""
    except OSError:
        return platform.processor()


def write_report(out: Path, results: list[CaseResult]) -> None:
    """report.md (a table per paper) and report.json."""
    where = provenance()
    lines = ["# crackle validate", "", f"Commit {where['commit']}; {where['machine']}; {where['date']}.", "",
             "A case passes inside its band; 'not reproduced' is inside its band with the reason crackle does not "
             "reach the paper; 'outside' means crackle has drifted from its band.", ""]
    for paper, title in PAPERS.items():
        rows = [r for r in results if r.case.paper == paper]
        if not rows:
            continue
        lines += [f"## {title}", "", "| case | quantity | paper | crackle | band | status | run (wall time) |",
                  "|---|---|---|---|---|---|---|"]
        for r in rows:
            c = r.case
            unit = f" {c.unit}" if c.unit else ""
            wall = f" ({r.wall_time:.0f} s)" if r.wall_time is not None else ""
            status = r.status + (f": {r.message}" if r.message else "")
            lines.append(f"| {c.name} | {c.quantity} | {c.paper_value} | {_format(r.value, c)}{unit} | "
                         f"{_format(c.band[0], c)} to {_format(c.band[1], c)}{unit} | {status} | "
                         f"[{r.run}]({r.run}/){wall} |")
        lines.append("")
        for r in rows:
            lines.append(f"- **{r.case.name}**: band: {r.case.band_source}."
                         + (f" Not reproduced: {r.case.reason}." if r.case.reason else ""))
        lines.append("")
        for r in rows:
            figure = case_figure(r.case, out / r.run, r.value, out / "figures" / f"{r.case.name}.png")
            if figure is not None:
                lines += [f"![{r.case.name}: {r.case.quantity}](figures/{figure.name})", ""]
    (out / REPORT).write_text("\n".join(lines))
    (out / "report.json").write_text(json.dumps({
        **where,
        "cases": [{"name": r.case.name, "paper": r.case.paper, "tier": r.case.tier, "value": r.value,
                   "unit": r.case.unit, "band": list(r.case.band), "status": r.status, "run": r.run,
                   "wall_time": r.wall_time, "message": r.message} for r in results]}, indent=2) + "\n")


# A document's generated parts (docs/validation.md), written by `crackle validate --document`:
# - its validate block, between BEGIN and END: a table per paper of every declared case, each row
#   with the value and commit of the case's last run (cases not run this time keep theirs), and, in
#   a comment, the same rows and each run's commit and date as JSON, for the next update and the tests;
# - numbers anywhere in its text between MARKERs, `<!--q:RUN:NUMBER:FORMAT-->value<!--/q-->`: RUN a
#   name of cases.RUNS, NUMBER a number of that run (cases.read_number), FORMAT a Python format
#   spec, optionally followed by `|` and a suffix written after the number (` deg`); a missing value
#   reads "none";
# - on each line holding markers, one STAMP, `<!--q-stamp-->...<!--/q-->`: the commits and dates of
#   the runs those markers name.
BEGIN, END = "<!--validate:begin-->", "<!--validate:end-->"
DATA = re.compile(r"<!--validate-data (?P<json>.*?)-->", re.S)
MARKER = re.compile(r"<!--q:(?P<run>[\w.-]+):(?P<number>[\w.*/+-]+):(?P<format>[^>]*?)-->(?P<text>.*?)<!--/q-->")
STAMP = re.compile(r"<!--q-stamp-->(?P<text>.*?)<!--/q-->")


def document_data(text: str) -> dict:
    """What a document's validate block records: {"cases": {name: {"value", "status", "commit",
    "date"}}, "runs": {run name: {"commit", "date"}}}."""
    found = DATA.search(text)
    data = json.loads(found["json"]) if found else {}
    return {"cases": data.get("cases", {}), "runs": data.get("runs", {})}


def document_runs(text: str) -> list[Run]:
    """The runs a document's markers name (ValueError for a name cases.RUNS does not have)."""
    from .cases import RUNS

    names = list(dict.fromkeys(m["run"] for m in MARKER.finditer(text)))
    unknown = [n for n in names if n not in RUNS]
    if unknown:
        raise ValueError(f"markers name runs crackle does not declare: {', '.join(unknown)} (validation/cases.py RUNS)")
    return [RUNS[n] for n in names]


def stamp_text(names: list[str], runs: dict[str, dict]) -> str:
    """The stamp of a line whose markers name these runs: their commits and dates."""
    made = [runs.get(n) for n in names]
    if any(m is None for m in made):
        return "not run by crackle validate yet"
    groups: dict[str, list[str]] = {}
    for m in made:
        groups.setdefault(m["commit"], []).append(m["date"])
    said = [f"commit {commit}, {max(dates)}" for commit, dates in groups.items()]
    return ("run at " if len(made) == 1 else "runs at ") + "; ".join(said)


def write_document(path: str | Path, results: list[CaseResult], out_dir: str | Path) -> list[str]:
    """Rewrite the generated parts of the document at `path` with this validation's results (the
    validate block) and the runs finished in out_dir (the markers naming them, and every line's
    stamp); ValueError when it has no block. The changed numbers, as "run:number: old -> new"."""
    from ..sweep.runner import finished_summary
    from .cases import CASES, RUNS

    path, out = Path(path), Path(out_dir)
    text = path.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{path}: no {BEGIN} ... {END} block to write the cases into")
    data = document_data(text)
    rows, runs = data["cases"], data["runs"]
    for r in results:
        rows[r.case.name] = {"value": r.value, "status": r.status, "commit": r.commit or "unknown",
                             "date": r.date[:10]}
    summaries = {}
    for run in document_runs(text):
        summary = finished_summary(out / run.folder())
        if summary is not None and summary.get("status") in ("completed", "stopped"):
            summaries[run.name] = summary
            record = _run_record(out / run.folder())
            runs[run.name] = {"commit": record.get("commit", "unknown"), "date": record.get("date", "")[:10]}
    changes = []

    def number(m):
        if m["run"] not in summaries:
            return m[0]
        value = read_number(m["number"], summaries[m["run"]], out / RUNS[m["run"]].folder())
        spec, _, suffix = m["format"].partition("|")
        if value is not None and value.is_integer() and not any(c in spec for c in "efg%"):
            value = int(value)  # a count (summary.json's numbers are read as floats): "10", "1,179"
        new = "none" if value is None else format(value, spec) + suffix
        if new != m["text"]:
            changes.append(f"{m['run']}:{m['number']}: {m['text']} -> {new}")
        return f"<!--q:{m['run']}:{m['number']}:{m['format']}-->{new}<!--/q-->"

    def stamped(line: str) -> str:
        line = MARKER.sub(number, line)
        names = list(dict.fromkeys(m["run"] for m in MARKER.finditer(line)))
        return STAMP.sub(lambda _: f"<!--q-stamp-->{stamp_text(names, runs)}<!--/q-->", line) if names else line

    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    head, tail = ("\n".join(stamped(line) for line in part.split("\n")) for part in (head, tail))
    rows = {c.name: rows[c.name] for c in CASES if c.name in rows}
    runs = {n: runs[n] for n in RUNS if n in runs}
    block = ["", f"<!--validate-data {json.dumps({'cases': rows, 'runs': runs})}-->", ""]
    for paper, title in PAPERS.items():
        cases = [c for c in CASES if c.paper == paper]
        if not cases:
            continue
        block += [f"**{title}**", "", "| case | tier | quantity | paper | crackle (commit and date of its run) | band | "
                  "status |", "|---|---|---|---|---|---|---|"]
        for c in cases:
            row = rows.get(c.name)
            unit = f" {c.unit}" if c.unit else ""
            got = (f"{_format(row['value'], c)}{unit} ({row['commit']} {row['date']})"
                   if row and row["value"] is not None else "not run yet" if not row else f"none ({row['commit']})")
            status = row["status"] if row else ""
            block.append(f"| {c.name} | {c.tier} | {c.quantity} | {c.paper_value} | {got} | "
                         f"{_format(c.band[0], c)} to {_format(c.band[1], c)}{unit} | {status} |")
        block.append("")
    path.write_text(head + BEGIN + "\n".join(block) + END + tail)
    return changes

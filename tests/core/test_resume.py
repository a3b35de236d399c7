"""Checkpoint and restart (crackle run --resume DIR): a resumed run's history, events and
results are bit-identical to an uninterrupted run's, for an interrupted run (Ctrl-C) and for a
finished one continued to a later end time; a resume that would not be the same run is refused."""

from __future__ import annotations

import json
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from crackle.cli import main
from crackle.io import read_history_csv, read_pvd

LATTICE = str(Path(__file__).parents[1] / "data" / "lattice-platen.toml")
# Results that must match; wall time, status and message describe the session, not the physics.
SAME = ("steps", "end_time", "broken", "peak_force", "peak_force_time", "peak_forces", "energy_error", "fragments")


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _same_files(a: Path, b: Path, rows_after: float = -1.0, keys=SAME) -> None:
    """history.csv rows later than `rows_after`, the whole events.csv and the summary's `keys`
    identical, bit for bit."""
    ha, hb = read_history_csv(a / "history.csv"), read_history_csv(b / "history.csv")
    assert list(ha) == list(hb)
    ka, kb = ha["time"] > rows_after, hb["time"] > rows_after
    assert ka.sum() == kb.sum() > 0
    for name in ha:
        assert np.array_equal(ha[name][ka], hb[name][kb], equal_nan=True), name
    assert (a / "events.csv").read_bytes() == (b / "events.csv").read_bytes()
    sa, sb = _summary(a), _summary(b)
    for key in keys:
        assert sa.get(key) == sb.get(key), key


@pytest.mark.slow
def test_interrupted_run_resumed_is_bit_identical(tmp_path):
    """Ctrl-C a fracturing impact with surface contact, resume it to the same end: every row of
    history.csv, events.csv and the results equal those of the run never interrupted; the
    snapshots continue the series (with the one the interrupted run wrote when it stopped)."""
    args = ["sphere-impact-fast", "--quick", "--set", "run.end_time=5e-5", "--set", "run.history_samples=300",
            "--set", "run.field_frames=3"]
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main(["run", *args, "--out", str(whole)]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "crackle.cli", "run", *args, "--out", str(cut)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not ((cut / "history.csv").exists() and len((cut / "history.csv").read_text().splitlines()) > 100):
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    stopped_at = _summary(cut)["end_time"]
    assert 0.0 < stopped_at < _summary(whole)["end_time"]

    assert main(["run", *args, "--resume", str(cut)]) == 0
    _same_files(whole, cut)
    assert _summary(cut)["resumed_from"] == stopped_at and _summary(cut)["status"] == "completed"
    frames = read_pvd(cut / "fields.pvd")
    assert sorted({t for t, _ in read_pvd(whole / "fields.pvd")} | {stopped_at}) == [t for t, _ in frames]
    assert all(path.exists() for _, path in frames)


def test_ctrl_c_within_a_long_row_stops_there_and_resumes_bit_identical(tmp_path, monkeypatch):
    """A row is stepped in pieces of about PIECE_SECONDS of wall time (here made one step each):
    a Ctrl-C within a row stops the run at the next piece, not at the row (the lattice's rows come
    every 130 steps; the Ctrl-C at step 50). The interrupted run's history, events and summary end
    at that step; resumed, its history, events and results are the uninterrupted run's, row for
    row (the row off the grid is dropped)."""
    from crackle.io.progress import Progress
    from crackle.solver import driver

    args = ["run", LATTICE, "--set", "run.history_samples=2", "--set", "run.field_frames=0"]
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main([*args, "--out", str(whole)]) == 0
    monkeypatch.setattr(driver, "PROBE_SECONDS", 0.0)
    monkeypatch.setattr(driver, "PIECE_SECONDS", 1e-12)  # pieces of one step
    update = Progress.update

    def ctrl_c_at_step_50(self, time_, steps, broken):
        if steps == 50:
            driver._InterruptRequest.active.ask("by the user")
        update(self, time_, steps, broken)

    monkeypatch.setattr(Progress, "update", ctrl_c_at_step_50)
    assert main([*args, "--out", str(cut)]) == 130
    summary = _summary(cut)
    assert summary["status"] == "interrupted" and summary["steps"] == 50, summary
    history = read_history_csv(cut / "history.csv")
    assert history["time"][-1] == summary["end_time"] and len(history["time"]) == 2  # step 0 and step 50
    monkeypatch.undo()
    assert main([*args, "--resume", str(cut)]) == 0
    _same_files(whole, cut)
    assert _summary(cut)["resumed_from"] == summary["end_time"]


def test_finished_run_continued_to_a_later_end(tmp_path):
    """The lattice run to half its end time, then resumed to the end: the rows after the half
    (on the grid of the full run) equal the uninterrupted run's; the earlier rows are the first
    run's own."""
    whole, half = tmp_path / "whole", tmp_path / "half"
    assert main(["run", LATTICE, "--out", str(whole)]) == 0
    end = _summary(whole)["end_time"]
    assert main(["run", LATTICE, "--out", str(half), "--set", f"run.end_time={end / 2!r}"]) == 0
    assert _summary(half)["broken"] < _summary(whole)["broken"]  # the failures come after the half
    assert main(["run", LATTICE, "--resume", str(half)]) == 0
    _same_files(whole, half, rows_after=end / 2)


def test_extrinsic_run_continued_from_its_half_is_bit_identical(tmp_path):
    """The quick sphere impact with extrinsic faces (clusters of tied copies moving on their
    leaders within a step, the tied phase ending at the first insertion) run to half its end
    time, then resumed to the end: the rows after the half, the events and the results equal
    the uninterrupted run's (the checkpoint holds every copy's state and the clusters', and the
    face strengths drawn at set-up, here from a random field)."""
    args = ["sphere-impact-slow", "--quick", "--set", "material.interface.insertion=extrinsic", "--set",
            "run.field_frames=0", "--set",
            'material.random.tensile_strength={distribution="weibull", modulus=8, correlation_length=0.01}']
    whole, half = tmp_path / "whole", tmp_path / "half"
    assert main(["run", *args, "--out", str(whole)]) == 0
    end = _summary(whole)["end_time"]
    assert main(["run", *args, "--out", str(half), "--set", f"run.end_time={end / 2!r}"]) == 0
    assert main(["run", *args, "--resume", str(half)]) == 0
    assert _summary(whole)["broken"] > 0 and _summary(whole)["insertion_energy"] > 0.0
    # energy_error divides by the largest energy its rows saw: the half run sampled its first half
    # on a finer grid (its own end time's), so only the rows after the half are compared.
    _same_files(whole, half, rows_after=end / 2, keys=tuple(k for k in SAME if k != "energy_error"))


def test_resume_refusals(tmp_path, capsys):
    """Exit 2 with one message: no checkpoint; a changed model; an end time already reached; a
    checkpoint written by other sources."""
    out = tmp_path / "run"
    assert main(["run", LATTICE, "--out", str(out)]) == 0
    capsys.readouterr()
    cases = [
        ([LATTICE, "--resume", str(tmp_path)], "no checkpoint.pkl"),
        ([LATTICE, "--resume", str(out), "--set", "material.youngs_modulus=30e9", "--set", "run.end_time=1e-4"],
         "material.youngs_modulus = 30000000000.0 (the checkpoint's run had 26000000000.0)"),
        ([LATTICE, "--resume", str(out)], "the run is already at t = 4.01"),
        ([LATTICE, "--resume", str(out), "--out", str(tmp_path / "elsewhere")], "drop --out"),
    ]
    history = (out / "history.csv").read_bytes()
    # A checkpoint written by other sources (a development install edited since).
    other = tmp_path / "other-code"
    other.mkdir()
    checkpoint = pickle.loads((out / "checkpoint.pkl").read_bytes())
    checkpoint.code = "0" * 16
    (other / "checkpoint.pkl").write_bytes(pickle.dumps(checkpoint))
    cases.append(([LATTICE, "--resume", str(other), "--set", "run.end_time=1e-4"], "before its sources changed"))
    for argv, expected in cases:
        assert main(["run", *argv]) == 2
        err = capsys.readouterr().err
        assert expected in err and len(err.strip().splitlines()) == 1, err
    assert (out / "history.csv").read_bytes() == history  # a refused resume touches nothing


def test_checkpoint_can_be_switched_off(tmp_path):
    out = tmp_path / "run"
    assert main(["run", LATTICE, "--out", str(out), "--set", "run.checkpoint=false"]) == 0
    assert not (out / "checkpoint.pkl").exists()


def test_killed_run_resumes_from_its_last_periodic_checkpoint(tmp_path):
    """SIGKILL (no chance to clean up) after checkpoints every row: the resume drops the rows
    written after the last checkpoint and continues bit-identically to the uninterrupted run."""
    args = ["run", LATTICE, "--set", "run.history_samples=1200", "--set", "run.end_time=6e-4"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    assert main([*args, "--out", str(whole)]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "crackle.cli", *args, "--out", str(killed),
                             "--set", "run.checkpoint_every=1e-9"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 120
    while time.time() < deadline and not ((killed / "history.csv").exists() and len((killed / "history.csv").read_text().splitlines()) > 60):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert not (killed / "summary.json").exists() and (killed / "checkpoint.pkl").exists()
    assert main([*args, "--resume", str(killed)]) == 0
    _same_files(whole, killed)


def test_periodic_checkpoint_carries_the_stop_clock(tmp_path, monkeypatch):
    """A copy of the run folder taken at the periodic checkpoint of the row where the force-drop
    clock starts (what a kill right after it leaves), resumed, stops at the same step with the
    same rows: the checkpoint holds the driver state of the row it follows."""
    import shutil

    import crackle.solver.driver as solver

    args = ["run", LATTICE, "--set", "run.end_time=6e-4", "--set", "run.history_samples=1200",
            "--set", "run.stop.force_drop=0.5", "--set", "run.stop.force_drop_hold=2e-5"]
    whole, snapshot = tmp_path / "whole", tmp_path / "snapshot"
    assert main([*args, "--out", str(whole)]) == 0
    assert _summary(whole)["status"] == "stopped"
    save = solver.save_checkpoint

    def save_and_copy(out, checkpoint):
        path = save(out, checkpoint)
        if checkpoint.low_since is not None and checkpoint.low_since == checkpoint.sim.time and not snapshot.exists():
            shutil.copytree(out, snapshot)
        return path

    monkeypatch.setattr(solver, "save_checkpoint", save_and_copy)
    assert main([*args, "--out", str(tmp_path / "run"), "--set", "run.checkpoint_every=1e-9"]) == 0
    monkeypatch.undo()
    assert not (snapshot / "summary.json").exists()
    assert main([*args, "--resume", str(snapshot)]) == 0
    _same_files(whole, snapshot)


@pytest.mark.parametrize("which", ["row before a field frame", "row before a failure"])
def test_killed_after_a_checkpoint_resumes_exactly(tmp_path, monkeypatch, which):
    """The checkpoint of one row kept while the run goes on to its end (what a kill long after
    that checkpoint leaves): the resume drops the later history rows and events and writes every
    row again. The rows chosen are the hard ones: one step before a field-frame row (the resume
    must not step over it), and one whose next step breaks a spring (that failure carries the
    row's own time, so only the count of events written tells it apart)."""
    import shutil

    import crackle.solver.driver as solver
    from crackle.io import read_events_csv
    from crackle.solver import steps_to

    end = 6e-4
    args = ["run", LATTICE, "--set", f"run.end_time={end!r}", "--set", "run.history_samples=1296",
            "--set", "run.field_frames=4"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    assert main([*args, "--out", str(whole)]) == 0
    failure_times = set(read_events_csv(whole / "events.csv")["time"].tolist())
    kept = tmp_path / "kept.pkl"
    save = solver.save_checkpoint

    def chosen(checkpoint) -> bool:
        if which == "row before a field frame":
            return (checkpoint.sim.steps + 1) % (steps_to(end, checkpoint.dt) // 4) == 0
        return checkpoint.sim.time in failure_times

    def save_and_keep(out, checkpoint):
        path = save(out, checkpoint)
        if chosen(checkpoint) and not kept.exists():
            shutil.copy(path, kept)
        return path

    monkeypatch.setattr(solver, "save_checkpoint", save_and_keep)
    assert main([*args, "--out", str(killed), "--set", "run.checkpoint_every=1e-9"]) == 0
    monkeypatch.undo()
    shutil.copy(kept, killed / "checkpoint.pkl")
    (killed / "summary.json").unlink()
    assert main([*args, "--resume", str(killed)]) == 0
    _same_files(whole, killed)

"""Checkpoints: the complete state of a run at a history row (every run.checkpoint_every seconds
of wall time, and at its end), so that `crackle run --resume DIR` continues an interrupted,
killed or finished run to a later end time.

The checkpoint holds the method's Simulation object as it is (every array of its model, tools,
load cell, contact lists and failure records: nothing to forget when a method adds state), the
driver's own state, and the validated scenario it was built from. It is a pickle: load only
checkpoints you wrote (like any restart file, it can run code when read).
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__

CHECKPOINT_FILE = "checkpoint.pkl"
# Bumped when what a checkpoint holds changes; an older one is refused with a message.
CHECKPOINT_FORMAT = 6


@functools.cache
def code_fingerprint() -> str:
    """A hash of crackle's own Python sources. The pickled Simulation holds the state layout of
    the code that wrote it: under other code a resume could fail half-way or, worse, run on with
    state the new code reads differently, so a checkpoint resumes only under the same sources (a
    version number does not change with every edit of a development install)."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]

# Scenario keys a resumed run may change: how far it goes and what it writes, never the model.
RESUMABLE_KEYS = ("run.end_time", "run.history_samples", "run.field_frames", "run.stop", "run.checkpoint",
                  "run.checkpoint_every", "description", "quick")


class CheckpointError(ValueError):
    """A checkpoint that cannot be resumed; the message says why and what to do."""


@dataclass
class Checkpoint:
    sim: object  # the method's Simulation, after its last step
    dt: float  # the step the run used (a resumed run keeps it)
    energy_scale: float  # the driver's largest external work seen (for the instability check)
    low_since: float | None  # the driver's force-drop clock
    events: int  # rows of events.csv written (the failures reported so far)
    scenario: dict  # the validated scenario (model_dump), for the resume check
    off_grid: bool = False  # taken within a row (a Ctrl-C there): its history row is dropped on resume
    crackle_version: str = __version__
    format: int = CHECKPOINT_FORMAT
    code: str = field(default_factory=code_fingerprint)  # the sources that wrote it


def save_checkpoint(out_dir: Path, checkpoint: Checkpoint) -> Path:
    """Write the checkpoint next to the run's outputs (write, then rename: a run killed while
    writing leaves the previous checkpoint whole)."""
    path = Path(out_dir) / CHECKPOINT_FILE
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            pickle.dump(checkpoint, f, protocol=pickle.HIGHEST_PROTOCOL)
    except BaseException:  # e.g. a full disk: no half file left beside the previous checkpoint
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
    return path


def load_checkpoint(run_dir: Path) -> Checkpoint:
    path = Path(run_dir) / CHECKPOINT_FILE
    if not path.is_file():
        raise CheckpointError(
            f"--resume {run_dir}: no {CHECKPOINT_FILE} there; give the output folder of a run that completed, "
            "stopped or was interrupted (an unstable run, or one with run.checkpoint = false, leaves none)"
        )
    try:
        with open(path, "rb") as f:
            checkpoint = pickle.load(f)
    except Exception as err:  # a torn or foreign file: say so rather than show the unpickler's error
        raise CheckpointError(f"--resume {run_dir}: {CHECKPOINT_FILE} cannot be read ({err}); rerun from the start") from None
    if not isinstance(checkpoint, Checkpoint) or checkpoint.format != CHECKPOINT_FORMAT:
        raise CheckpointError(
            f"--resume {run_dir}: {CHECKPOINT_FILE} was written by another crackle version "
            f"({getattr(checkpoint, 'crackle_version', 'unknown')}); rerun from the start"
        )
    if checkpoint.code != code_fingerprint():
        raise CheckpointError(
            f"--resume {run_dir}: {CHECKPOINT_FILE} was written by crackle {checkpoint.crackle_version} before its "
            "sources changed (the saved state may not fit the code now); rerun from the start, or resume with "
            "the code that wrote it"
        )
    return checkpoint


def scenario_changes(saved: dict, now: dict) -> list[str]:
    """The keys (dotted) where `now` differs from `saved` other than RESUMABLE_KEYS, each with
    both values."""
    a, b = _flatten(saved), _flatten(now)
    changed = []
    for key in sorted(set(a) | set(b)):
        if any(key == k or key.startswith(k + ".") for k in RESUMABLE_KEYS):
            continue
        if a.get(key) != b.get(key):
            changed.append(f"{key} = {b.get(key)!r} (the checkpoint's run had {a.get(key)!r})")
    return changed


def _flatten(value, prefix: str = "") -> dict:
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    if isinstance(value, list):
        out = {}
        for i, v in enumerate(value):
            out.update(_flatten(v, f"{prefix}{i}."))
        return out
    return {prefix[:-1]: value}

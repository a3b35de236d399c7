"""Tabular run outputs: history.csv, events.csv and summary.json.

Floats are written with ``repr`` (the shortest string that reads back to the
same double), so two runs can be compared bit for bit from their files alone.
Every row is flushed as soon as it is written: a run that crashes keeps all
the rows it produced.
"""

from __future__ import annotations

import csv
import errno
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

EVENT_COLUMNS = ("time", "x", "y", "z", "mode", "id")
# events.csv's last column in a model of several materials: the material a failure happened in,
# or the pair ("A-B") it parted.
MATERIAL_COLUMN = "material"
FAILURE_MODES = ("tension", "shear", "mixed")
class RunHistory(Mapping):
    """A run's history as arrays: {column: float64 array} in history.csv's column order, each
    column with the unit it was registered with (`units`). The driver appends each row as it
    writes it to history.csv, so that the summary and the plots read the numbers, not the file
    back (the values are the file's bit for bit: it writes each with repr)."""

    def __init__(self, units: Mapping[str, str], kept: Mapping[str, np.ndarray] | None = None):
        """`kept`: the rows a resumed run keeps (read from its history.csv once)."""
        self.units = dict(units)
        self._index = {name: i for i, name in enumerate(self.units)}
        self._rows: list[np.ndarray] = []
        if kept is not None and len(kept) and len(next(iter(kept.values()))):
            self._rows = list(np.column_stack([np.asarray(kept[name], float) for name in self.units]))
        self._table: np.ndarray | None = None

    def append(self, row: Mapping[str, Any]) -> None:
        """One row (a missing column is nan, as history.csv writes it)."""
        values = np.full(len(self._index), np.nan)
        for name, value in row.items():
            values[self._index[name]] = float(value)
        self._rows.append(values)
        self._table = None

    def _columns(self) -> np.ndarray:
        if self._table is None:
            self._table = np.array(self._rows, dtype=np.float64).reshape(-1, len(self._index))
        return self._table

    def __getitem__(self, name: str) -> np.ndarray:
        return self._columns()[:, self._index[name]].copy()

    def __iter__(self):
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)


def format_number(value: Any) -> str:
    """Exact text for one CSV value: integers as integers, floats via repr."""
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    # float() of any numpy float is exact; repr(float) round-trips exactly,
    # keeps the sign of -0.0 and writes nan/inf as 'nan'/'inf'.
    return repr(float(value))


def _check_names(names: Sequence[str]) -> list[str]:
    names = [str(n) for n in names]
    for name in names:
        if not name or any(c in name for c in ',"\r\n'):
            raise ValueError(f"invalid CSV column name {name!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate column names in {names}")
    return names


# Write errors that mean no room (a full disk or quota, a file past ulimit -f): a run stops on
# them as on an interrupt, its outputs kept (solver.driver), rather than in a traceback.
NO_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class _CsvFile:
    """A CSV file written row by row (self._file), closed at the end of its with-block."""

    _file = None

    def close(self) -> None:
        if self._file is not None and not self._file.closed:
            try:
                self._file.close()
            except OSError as err:  # the rest of a line a full disk cut: a reader drops a torn last line
                if err.errno not in NO_ROOM:
                    raise

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class HistoryWriter(_CsvFile):
    """Writes ``history.csv``: ``time`` first, then one column per series.

    ``append`` takes a dict (missing columns are written as nan, unknown
    keys raise KeyError so that typos show up at the first row) or a
    sequence of values in column order.

    ``keep_until``: continue an existing file (a resumed run): its rows up to
    that time are kept, later ones dropped; its columns must be ``columns``.
    """

    def __init__(self, path: str | os.PathLike, columns: Sequence[str], keep_until: float | None = None):
        self.columns = _check_names(columns)
        if not self.columns or self.columns[0] != "time":
            raise ValueError("history columns must start with 'time'")
        self.path = Path(path)
        self._index = {name: i for i, name in enumerate(self.columns)}
        kept = [] if keep_until is None else [
            line for line in _existing_rows(self.path, self.columns) if float(line.split(",", 1)[0]) <= keep_until
        ]
        self._file = _open_csv(self.path, self.columns, kept)

    def _write_line(self, fields: Sequence[str]) -> None:
        self._file.write(",".join(fields) + "\n")
        self._file.flush()

    def append(self, row: Mapping[str, Any] | Sequence[Any]) -> None:
        if isinstance(row, Mapping):
            unknown = [k for k in row if k not in self._index]
            if unknown:
                raise KeyError(f"unknown history columns {unknown}")
            values = ["nan"] * len(self.columns)
            for key, value in row.items():
                values[self._index[key]] = format_number(value)
        else:
            row = list(row)
            if len(row) != len(self.columns):
                raise ValueError(
                    f"history row has {len(row)} values, expected {len(self.columns)}"
                )
            values = [format_number(v) for v in row]
        self._write_line(values)



class EventWriter(_CsvFile):
    """Writes ``events.csv``: one row per failure, ``time,x,y,z,mode,id`` (and ``material`` in a
    model of several materials)."""

    def __init__(self, path: str | os.PathLike, keep_rows: int | None = None, materials: bool = False):
        """`keep_rows`: continue an existing file (a resumed run) after its first keep_rows rows
        (the failures reported before the checkpoint; a failure in the step after it has that
        step's start time, so a time cannot tell it apart). `materials`: rows carry the material
        (or pair) of each failure."""
        self.path = Path(path)
        self.columns = EVENT_COLUMNS + ((MATERIAL_COLUMN,) if materials else ())
        kept = [] if keep_rows is None else _existing_rows(self.path, self.columns)[:keep_rows]
        self._file = _open_csv(self.path, self.columns, kept)

    def append_many(self, times, xyz, modes, ids, materials: Sequence[str] | None = None) -> None:
        """Append k events. ``modes`` may also be one string for all of them; ``materials`` (one
        label per event) when the file has the material column."""
        times = np.atleast_1d(np.asarray(times))
        xyz = np.asarray(xyz).reshape(-1, 3)
        k = len(times)
        if isinstance(modes, str):
            modes = [modes] * k
        modes = [str(m) for m in np.ravel(np.asarray(modes, dtype=object))]
        ids = np.atleast_1d(np.asarray(ids))
        if not (len(xyz) == len(modes) == len(ids) == k):
            raise ValueError(
                f"event arrays differ in length: times {k}, xyz {len(xyz)}, "
                f"modes {len(modes)}, ids {len(ids)}"
            )
        if (materials is not None) != (MATERIAL_COLUMN in self.columns) or (materials is not None and len(materials) != k):
            raise ValueError(f"events.csv's columns are {','.join(self.columns)}: give one material per event exactly "
                             "when it has the material column")
        bad = sorted(set(modes) - set(FAILURE_MODES))
        if bad:
            raise ValueError(f"unknown failure modes {bad}; expected {FAILURE_MODES}")
        if k == 0:
            return
        if not np.issubdtype(ids.dtype, np.integer):
            raise TypeError(f"event ids must be integers, got dtype {ids.dtype}")
        lines = [
            ",".join(
                (format_number(t), format_number(p[0]), format_number(p[1]),
                 format_number(p[2]), m, str(int(i)))
            )
            for t, p, m, i in zip(times, xyz, modes, ids)
        ]
        if materials is not None:
            lines = [f"{line},{material}" for line, material in zip(lines, materials)]
        self._file.write("\n".join(lines) + "\n")
        self._file.flush()



def _complete_lines(path: Path) -> tuple[list[str], list[str]]:
    """Header fields and data lines.

    Writers end every row with a newline, so text after the last newline is
    a row torn by a crash mid-write and is dropped.
    """
    with open(path, encoding="utf-8", newline="") as f:
        header = f.readline().rstrip("\r\n").split(",")
        lines = f.read().split("\n")[:-1]
    return header, [ln.rstrip("\r") for ln in lines if ln.strip()]


def _open_csv(path: Path, columns: Sequence[str], kept: list[str]):
    """A CSV open for appending rows, its header and the `kept` lines (a resumed run's) written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    file = open(path, "w", encoding="utf-8", newline="")
    file.write("".join(line + "\n" for line in [",".join(columns), *kept]))
    file.flush()
    return file


def _existing_rows(path: Path, columns: Sequence[str]) -> list[str]:
    """The complete data lines of an existing CSV; refuses a file with other columns (it belongs
    to another kind of run)."""
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: nothing to continue")
    header, lines = _complete_lines(path)
    if header != list(columns):
        raise ValueError(f"{path} has other columns than this run writes; it belongs to another run")
    return lines


def read_history_csv(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read ``history.csv`` into ``{column: float64 array}`` (column order kept)."""
    header, lines = _complete_lines(Path(path))
    if not lines:
        return {name: np.zeros(0) for name in header}
    # numpy's parser converts decimal strings to the correctly rounded double,
    # so the values are bit-identical to what was written.
    table = np.loadtxt(lines, delimiter=",", dtype=np.float64, ndmin=2)
    return {name: table[:, i].copy() for i, name in enumerate(header)}


def read_events_csv(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read ``events.csv`` into arrays: time, x, y, z (float), mode (str), id (int), and material
    (str) where the file has it."""
    header, lines = _complete_lines(Path(path))
    rows = list(csv.reader(lines))
    floats = np.array([[float(v) for v in r[:4]] for r in rows], dtype=np.float64)
    floats = floats.reshape(-1, 4)
    events = {
        "time": floats[:, 0].copy(),
        "x": floats[:, 1].copy(),
        "y": floats[:, 2].copy(),
        "z": floats[:, 3].copy(),
        "mode": np.array([r[4] for r in rows], dtype=str),
        "id": np.array([int(r[5]) for r in rows], dtype=np.int64),
    }
    if MATERIAL_COLUMN in header:
        events[MATERIAL_COLUMN] = np.array([r[6] for r in rows], dtype=str)
    return events


def to_json_compatible(value: Any) -> Any:
    """Convert numpy types, tuples and paths to plain JSON types; NaN/inf -> None."""
    if isinstance(value, Mapping):
        return {str(k): to_json_compatible(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return to_json_compatible(value.tolist())
    if isinstance(value, (list, tuple)):
        return [to_json_compatible(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return [to_json_compatible(v) for v in sorted(value)]
    if isinstance(value, np.generic):
        return to_json_compatible(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"cannot write {type(value).__name__} to JSON: {value!r}")


def write_summary(path: str | os.PathLike, summary: Mapping[str, Any]) -> None:
    """Write ``summary.json`` (indent=2, sorted keys, strict JSON)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(
        to_json_compatible(summary), indent=2, sort_keys=True, allow_nan=False
    )
    # Write then rename, so a reader never sees a half-written summary.
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text + "\n", encoding="utf-8")
    os.replace(tmp, path)

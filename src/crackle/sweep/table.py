"""A sweep's table (sweep.csv, sweep.parquet), its comparison plots (plots/sweep_KEY.png) and, over
triaxial runs, the strength envelopes (envelope.json, plots/strength_envelope.png).

Columns: the varied keys, then `run` (its folder), `status`, `message`, then every scalar of
the runs' summary.json (a nested object's scalars as `object.field`, e.g. `dt_limit.dt`; lists
are left out: they stay in each run's summary)."""

from __future__ import annotations

import csv
import difflib
import json
import math
import re
from pathlib import Path

import numpy as np

DEFAULT_PLOTTED = ("peak_force", "broken", "energy_error")


def summary_scalars(summary: dict) -> dict:
    """The scalars of a summary, nested objects' as `object.field`, in sorted order."""
    out = {}
    for key in sorted(summary):
        value = summary[key]
        if isinstance(value, dict):
            for sub in sorted(value):
                if _is_scalar(value[sub]):
                    out[f"{key}.{sub}"] = value[sub]
        elif _is_scalar(value):
            out[key] = value
    return out


def _is_scalar(value) -> bool:
    return value is None or isinstance(value, (bool, int, float, str))


def table_rows(varied_keys: list[str], rows: list[dict]) -> tuple[list[str], list[dict]]:
    """The table's columns and rows from the runner's rows (varied values, run, status,
    message, summary)."""
    first = list(varied_keys) + ["run", "status", "message"]
    records, columns = [], list(first)
    for row in rows:
        record = {key: row[key] for key in first}
        for key, value in summary_scalars(row["summary"]).items():
            if key in ("status", "message"):
                continue
            record[key] = value
            if key not in columns:
                columns.append(key)
        records.append(record)
    return columns, records


# Units of the summary scalars a sweep plots (axis labels); a scalar not listed is labelled by its name.
SUMMARY_UNITS = {
    "peak_force": "N", "peak_force_time": "s", "peak_stress": "Pa", "brazilian_strength": "Pa",
    "nominal_strength": "Pa", "platen_modulus": "Pa", "energy_error": "-", "broken": "count", "steps": "count",
    "wall_time": "s", "dt": "s", "stable_dt": "s", "end_time": "s", "splitting_angle": "degrees",
    "tensile_strength_ratio": "-", "loaded_area": "m^2", "plastic_zone_length": "m", "max_temperature": "K",
    "max_plastic_strain": "-", "particles": "count", "bonds": "count", "load_cell_window": "s",
}


def write_table(out: Path, varied_keys: list[str], rows: list[dict], plotted: list[str] = (),
                scenario: str | None = None) -> list[str]:
    """sweep.csv, sweep.parquet and plots/sweep_KEY.png (titled with `scenario`, the sweep's
    example name or file, whose schema gives the varied keys' units); returns the `plotted` names
    that are no column of the table (a misspelt --plot), each with the nearest column where one is
    close."""
    columns, records = table_rows(varied_keys, rows)
    with open(out / "sweep.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, columns, restval="")
        writer.writeheader()
        for record in records:
            writer.writerow({k: _csv_value(v) for k, v in record.items()})
    _write_parquet(out / "sweep.parquet", columns, records)
    known = [name for name in plotted if name in columns]
    for key in varied_keys:
        plot_against(out / "plots" / f"sweep_{_file_part(key)}.png", key, varied_keys, records,
                     list(DEFAULT_PLOTTED) + [name for name in known if name not in DEFAULT_PLOTTED], scenario)
    finished = any(record.get("status") in ("completed", "stopped") for record in records)
    unknown = [name for name in plotted if name not in columns] if finished else []
    return [name + "".join(f" (did you mean {close}?)" for close in difflib.get_close_matches(name, columns, n=1))
            for name in unknown]


def write_seed_statistics(out: Path, varied_keys: list[str], rows: list[dict], shown: list[str] = ()) -> list[str]:
    """sweep_seeds.csv, when the sweep varies run.seed: per combination of the other varied keys,
    every numeric summary scalar's mean, standard deviation (n - 1), CV and number of finished
    runs over the seeds. Returns one line per combination for the `shown` scalars (and
    DEFAULT_PLOTTED) to print."""
    from .plan import SEED_KEY

    if SEED_KEY not in varied_keys:
        return []
    others = [key for key in varied_keys if key != SEED_KEY]
    columns, records = table_rows(varied_keys, rows)
    groups: dict[tuple, list[dict]] = {}
    for record in records:
        if record.get("status") in ("completed", "stopped"):
            groups.setdefault(tuple(repr(record[key]) for key in others), []).append(record)
    numeric = [c for c in columns if c not in (*varied_keys, "run", "status", "message")
               and any(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in records)]
    table, lines = [], []
    for group in groups.values():
        head = {key: group[0][key] for key in others}
        described = []
        for name in numeric:
            values = [float(r[name]) for r in group if isinstance(r.get(name), (int, float)) and r.get(name) is not None
                      and math.isfinite(float(r[name]))]
            if not values:
                continue
            mean = sum(values) / len(values)
            sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1)) if len(values) > 1 else float("nan")
            cv = sd / abs(mean) if mean else float("nan")
            table.append({**head, "quantity": name, "mean": mean, "sd": sd, "cv": cv, "runs": len(values)})
            if name in (*DEFAULT_PLOTTED, *shown):
                described.append(f"{name} {mean:.4g} +- {sd:.3g} (CV {cv:.1%})")
        where = ", ".join(f"{key.split('.')[-1]}={_csv_value(v)}" for key, v in head.items())
        lines.append(f"over {len(group)} seeds{' at ' + where if where else ''}: " + "; ".join(described))
    with open(out / "sweep_seeds.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, [*others, "quantity", "mean", "sd", "cv", "runs"])
        writer.writeheader()
        for record in table:
            writer.writerow({k: _csv_value(v) for k, v in record.items()})
    return lines


ENVELOPE_FILE = "envelope.json"


def write_envelopes(out: Path, rows: list[dict], scenario: str | None = None) -> list[str]:
    """When two or more finished runs at different confinements report confining_pressure and
    peak_stress (triaxial tests: sigma_3 and sigma_1): the Mohr-Coulomb and Hoek-Brown envelopes
    fitted to them (analysis.envelope) in envelope.json, drawn with the peaks in
    plots/strength_envelope.png. Returns a line per envelope to print (none without them)."""
    from ..analysis.envelope import hoek_brown, hoek_brown_sigma_1, mohr_coulomb, mohr_coulomb_sigma_1
    from ..io.plots import _new_figure, _save, axis_label

    peaks = [(float(r["summary"]["confining_pressure"]), float(r["summary"]["peak_stress"])) for r in rows
             if r.get("status") in ("completed", "stopped")
             and _number(r["summary"].get("confining_pressure")) is not None
             and _number(r["summary"].get("peak_stress")) is not None]
    if len({s3 for s3, _ in peaks}) < 2:
        return []
    s3, s1 = (np.array(v) for v in zip(*sorted(peaks)))
    coulomb, hoek = mohr_coulomb(s3, s1), hoek_brown(s3, s1)
    (out / ENVELOPE_FILE).write_text(json.dumps({
        "sigma_3": s3.tolist(), "sigma_1": s1.tolist(), "mohr_coulomb": coulomb, "hoek_brown": hoek}, indent=2) + "\n")
    fig = _new_figure(figsize=(5.0, 4.0))
    ax = fig.subplots()
    ax.plot(s3 / 1e6, s1 / 1e6, "ko", label="peaks")
    span = np.linspace(0.0, float(s3.max()) * 1.05, 50)
    lines = []
    if coulomb is not None:
        ax.plot(span / 1e6, mohr_coulomb_sigma_1(coulomb, span) / 1e6, "-",
                label=f"Mohr-Coulomb: c {coulomb['cohesion'] / 1e6:.3g} MPa, phi {coulomb['friction_angle']:.3g} deg")
        lines.append(f"Mohr-Coulomb: UCS {coulomb['ucs'] / 1e6:.4g} MPa, cohesion {coulomb['cohesion'] / 1e6:.4g} MPa, "
                     f"friction angle {coulomb['friction_angle']:.3g} deg (R^2 {coulomb['r2']:.3f})")
    if hoek is not None:
        ax.plot(span / 1e6, hoek_brown_sigma_1(hoek, span) / 1e6, "--",
                label=f"Hoek-Brown: sigma_ci {hoek['sigma_ci'] / 1e6:.3g} MPa, m_i {hoek['m_i']:.3g}")
        lines.append(f"Hoek-Brown: sigma_ci {hoek['sigma_ci'] / 1e6:.4g} MPa, m_i {hoek['m_i']:.3g} "
                     f"(R^2 {hoek['r2']:.3f})")
    ax.set_xlabel(axis_label("confining pressure sigma_3", "MPa"))
    ax.set_ylabel(axis_label("peak stress sigma_1", "MPa"))
    ax.set_title(f"{Path(scenario).stem if scenario else 'sweep'}: strength envelope", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    _save(fig, out / "plots" / "strength_envelope.png")
    return lines


def _csv_value(value):
    if isinstance(value, list):
        return "[" + ", ".join(str(v) for v in value) + "]"
    return "" if value is None else value


def _write_parquet(path: Path, columns: list[str], records: list[dict]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = {}
    for column in columns:
        values = [r.get(column) for r in records]
        try:
            arrays[column] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed kinds (a number in one run, text in another)
            arrays[column] = pa.array([None if v is None else str(v) for v in values])
    pq.write_table(pa.table(arrays), path)


def _file_part(key: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]", "_", key)


def plot_against(path: Path, key: str, varied_keys: list[str], records: list[dict], names: list[str],
                 scenario: str | None = None) -> None:
    """Each named scalar against `key`, a line per combination of the other varied keys' values
    (failed runs left out). Values that are not numbers are placed in order, labelled."""
    from ..io.plots import _new_figure, _save, axis_label
    from ..keys import key_unit

    names = [n for n in names if any(_number(r.get(n)) is not None for r in records)]
    if not names:
        return
    others = [k for k in varied_keys if k != key]
    numeric = all(_number(r[key]) is not None for r in records)
    labels = [] if numeric else list(dict.fromkeys(str(r[key]) for r in records))

    def x_of(value):
        return float(value) if numeric else labels.index(str(value))

    fig = _new_figure(figsize=(5.0, 2.6 * len(names)))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault(tuple(str(r[k]) for k in others), []).append(r)
    for ax, name in zip(axes, names):
        for group, members in groups.items():
            points = sorted((x_of(r[key]), _number(r.get(name))) for r in members if _number(r.get(name)) is not None)
            if points:
                label = ", ".join(f"{k.split('.')[-1]}={v}" for k, v in zip(others, group)) or None
                ax.plot([p[0] for p in points], [p[1] for p in points], "o-", label=label)
        ax.set_ylabel(axis_label(name, SUMMARY_UNITS.get(name)))
        ax.grid(alpha=0.3)
        if others and ax is axes[0]:
            ax.legend(fontsize=7)
    if labels:
        axes[-1].set_xticks(range(len(labels)), labels, rotation=30, fontsize=7)
    axes[-1].set_xlabel(axis_label(key, key_unit(scenario, key) if scenario and numeric else None))
    name = Path(scenario).stem if scenario else "sweep"
    axes[0].set_title(f"{name}: {', '.join(names)} against {key.split('.')[-1]}", fontsize=9)
    _save(fig, path)


def _number(value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)

"""`crackle calibrate`: fit scenario values so that simulated results match measured ones: a
tool's load-displacement curve, summary values (a UCS, a Brazilian strength), or both, of the
calibrated scenario and of others run with the same values (the usual DEM calibration: bond
strengths fitted to a UCS and a tensile strength at once).

A curve target's distance: the target's points (u_i, F_i); the run's curve of the same tool
(force magnitude against displacement magnitude, io.plots.tool_curves) read at each u_i by
linear interpolation (beyond the run's last displacement, its last force);

    d = sqrt(mean_i (F_run(u_i) - F_i)^2) / max_i |F_i|

A value target's (a summary.json key, dotted into dicts, and its measured value v): d = (s - v) / |v|.
A candidate's distance is sqrt(mean over the targets of d^2) (0 when every target is met; a run
that failed or lacks the key counts FAILED_DISTANCE). The search is scipy's
differential evolution within the given bounds, the start values in its first population, each
generation's candidates run in parallel on Dask (updating="deferred"): no gradient, so a
curve that jumps as elements fail does not mislead it. Deterministic for a given seed.

Fracture runs are noisy in their parameters (which element fails first changes the curve by a
few per cent), so the best candidate is a noisy estimate. The fitted values are the minimum of
a quadratic fitted, by least squares, to the squared distances of the better half of the
candidates (for a curve that responds linearly to the parameters near the fit, the squared
distance is exactly quadratic in them), confirmed by one more run; the best candidate where that
quadratic has no minimum within the candidates' range."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scenario import ScenarioError, split_override
from .plan import absolute_source
from .runner import COMPLETED, dask_client, outcome_of, run_one

FAILED_DISTANCE = 10.0  # a run that did not finish: far from any curve (a curve's own scale is 1)
# A fit that misses its targets by more than this (relative) is of no use: a target in other units
# (kN for N, mm for m) or bounds that exclude the answer. The calibration says so and exits 1.
USEFUL_MISFIT = 0.5


class CalibrationFailed(RuntimeError):
    """Every candidate run failed, or the best fit misses the targets beyond any use; the
    outputs (calibration.json, calibration.csv) are written first."""


@dataclass(frozen=True)
class Target:
    """One thing a candidate's runs should give: a tool's curve (`curve`: displacement and force
    arrays) or a summary value (`key`, `value`), of the calibrated scenario (`scenario` None) or of
    another one run with the same values, overrides and --quick."""

    text: str  # as given on the command line
    scenario: str | None = None
    key: str | None = None
    value: float = 0.0
    curve: tuple | None = None


def parse_target(text: str) -> Target:
    """A CSV file of a curve; KEY=VALUE, a summary value of the calibrated scenario's run;
    SCENARIO:KEY=VALUE, one of another scenario's (a shipped example or a .toml)."""
    path = Path(text)
    if path.suffix.lower() == ".csv" or path.is_file():
        return Target(text, curve=read_target(path))
    where, sep, raw = text.rpartition("=")
    scenario, _, key = where.rpartition(":")
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not sep or not key.strip() or not math.isfinite(value) or value == 0.0:
        raise ScenarioError(f"--target {text!r}: give a CSV of displacement and force, KEY=VALUE (a summary value "
                            "of the run, non-zero, e.g. peak_stress=70e6) or SCENARIO:KEY=VALUE (another scenario's, "
                            "e.g. dem-brazilian:brazilian_strength=6e6)")
    return Target(text, absolute_source(scenario) if scenario else None, key.strip(), value)


def summary_value(summary: dict, key: str) -> float | None:
    """summary.json's value at a dotted key (into dicts and lists), or None when there is no number."""
    value = summary
    for part in key.split("."):
        if isinstance(value, dict) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            return None
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


@dataclass
class CalibrationResult:
    out_dir: Path
    fitted: dict[str, float]
    distance: float
    runs: int
    fitted_folder: Path  # the run of the fitted values


def read_target(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, force) of a measured curve: a CSV with a header, its columns named
    `displacement` (m) and `force` (N) (or just two columns, in that order)."""
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"--target {path}: no such file; give a CSV of displacement (m) and force (N)")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ScenarioError(f"--target {path}: empty; give a header (displacement,force) and the curve's points")
    header = [h.strip().lower() for h in rows[0]]
    named = [next((i for i, h in enumerate(header) if h.startswith(name)), None) for name in ("displacement", "force")]
    if None in named:
        if len(header) != 2:
            raise ScenarioError(f"--target {path}: name the columns 'displacement' and 'force' in its header")
        named = [0, 1]
    try:
        data = np.array([[float(row[named[0]]), float(row[named[1]])] for row in rows[1:] if row], dtype=float)
    except (ValueError, IndexError):
        raise ScenarioError(f"--target {path}: every row needs a number in the displacement and force columns") from None
    if len(data) < 3 or not np.all(np.isfinite(data)):
        raise ScenarioError(f"--target {path}: give at least 3 points, all finite numbers")
    if np.any(np.diff(data[:, 0]) < 0.0):
        raise ScenarioError(f"--target {path}: displacement must not decrease from row to row")
    if not np.any(data[:, 1] != 0.0):
        raise ScenarioError(f"--target {path}: the force is zero throughout; nothing to fit")
    return data[:, 0], data[:, 1]


def curve_distance(target_u, target_f, run_u, run_f) -> float:
    """The RMS force difference at the target's displacements over its largest force."""
    u, first = np.unique(np.asarray(run_u, float), return_index=True)  # sorted, one force per displacement
    if len(u) < 2:
        return FAILED_DISTANCE
    f = np.asarray(run_f, float)[first]
    misfit = np.interp(target_u, u, f) - target_f
    return float(np.sqrt(np.mean(misfit**2)) / np.max(np.abs(target_f)))


def parse_fit(texts: list[str]) -> dict[str, tuple[float, float]]:
    bounds = {}
    for text in texts:
        key, _, raw = text.partition("=")
        lo, sep, hi = raw.partition(":")
        try:
            lo_hi = (float(lo), float(hi))
        except ValueError:
            lo_hi = None
        if not key.strip() or not sep or lo_hi is None or not all(map(math.isfinite, lo_hi)) or lo_hi[0] >= lo_hi[1]:
            raise ScenarioError(f"--fit {text!r}: write key=lo:hi with lo < hi, e.g. --fit material.tensile_strength=1e6:6e6")
        bounds[key.strip()] = lo_hi
    if not bounds:
        raise ScenarioError("nothing to fit: give --fit key=lo:hi")
    return bounds


def quadratic_minimum(points: np.ndarray, distances: np.ndarray, bounds: np.ndarray) -> np.ndarray | None:
    """The minimum of a quadratic in the parameters (scaled to their bounds) fitted by least
    squares to the squared distances of the better half of the candidates (at least twice the
    quadratic's coefficients); None when there are too few, the fit has no minimum, or it lies
    outside the range those candidates span."""
    n = points.shape[1]
    coefficients = (n + 1) * (n + 2) // 2
    finite = distances < FAILED_DISTANCE
    points, distances = points[finite], distances[finite]
    keep = np.argsort(distances, kind="stable")[: max(2 * coefficients, len(distances) // 2)]
    if len(keep) < 2 * coefficients:
        return None
    lo, span = bounds[:, 0], bounds[:, 1] - bounds[:, 0]
    x = (points[keep] - lo) / span
    pairs = [(i, j) for i in range(n) for j in range(i, n)]
    design = np.column_stack([np.ones(len(x)), x, *[x[:, i] * x[:, j] for i, j in pairs]])
    c, *_ = np.linalg.lstsq(design, distances[keep] ** 2, rcond=None)
    hessian = np.zeros((n, n))
    for (i, j), value in zip(pairs, c[1 + n:]):
        hessian[i, j] += value
        hessian[j, i] += value  # d2/dxi2 of c xi^2 is 2c: the diagonal gets it twice
    if np.any(np.linalg.eigvalsh(hessian) <= 0.0):
        return None
    best = np.linalg.solve(hessian, -c[1:1 + n])
    if np.any(best < x.min(axis=0)) or np.any(best > x.max(axis=0)):
        return None
    return lo + best * span


def run_curve(folder: str | Path, tool: str | None) -> tuple[np.ndarray, np.ndarray] | str:
    """A finished run's (displacement, force) of `tool` (default: the first in its history), or
    the message why there is none."""
    from ..io import read_history_csv
    from ..io.plots import tool_curves

    curves = tool_curves(read_history_csv(Path(folder) / "history.csv"))
    name = tool or next(iter(curves), None)
    if name not in curves:
        return f"--tool {name}: no such tool in the history ({', '.join(curves)})"
    u, f, _ = curves[name]
    return u, f


def evaluate(scenario: str, folder: str, overrides: dict, quick: bool, threads: int, tool: str | None,
             targets: list[Target]) -> dict:
    """One candidate on a worker: a run of each scenario the targets name (the calibrated one in
    `folder`, another in `folder`-NAME, see target_folder), then the distance: sqrt(mean d^2) over
    the targets, and each value target's value (`values`)."""
    runs, outcomes = {}, []
    for source in dict.fromkeys(t.scenario or scenario for t in targets):
        run_folder = target_folder(folder, source, scenario)
        outcomes.append(run_one(source, run_folder, overrides, quick, threads, plots=False))
        if outcomes[-1]["status"] not in COMPLETED:
            return {**outcomes[-1], "distance": FAILED_DISTANCE}
        runs[source] = run_folder
    misfits, values = [], {}
    for target in targets:
        run_folder = runs[target.scenario or scenario]
        if target.curve is not None:
            curve = run_curve(run_folder, tool)
            if isinstance(curve, str):
                return {"status": "invalid", "message": curve, "distance": FAILED_DISTANCE}
            misfits.append(curve_distance(*target.curve, *curve))
            continue
        summary = json.loads((Path(run_folder) / "summary.json").read_text())
        value = summary_value(summary, target.key)
        if value is None:
            return {"status": "invalid", "message": f"--target {target.text}: the run's summary.json has no number "
                    f"{target.key}", "distance": FAILED_DISTANCE}
        values[target.text] = value
        misfits.append((value - target.value) / abs(target.value))
    distance = float(np.sqrt(np.mean(np.square(misfits))))
    return {**outcomes[0], "distance": min(distance, FAILED_DISTANCE), "values": values,
            "misfits": {target.text: float(d) for target, d in zip(targets, misfits)}}


def target_folder(folder: str, source: str, scenario: str) -> str:
    """Where a candidate runs `source`: its folder for the calibrated scenario, folder-NAME for
    another one (NAME: the example's name or the file's stem)."""
    return folder if source == scenario else f"{folder}-{Path(source).stem}"


def calibrate(scenario: str, target: str | Path | list, fit: list[str], start: list[str] = (), fixed: list[str] = (),
              quick: bool = False, tool: str | None = None, out_dir: str | Path = "crackle-out/calibration",
              population: int = 8, generations: int = 20, tol: float = 0.01, seed: int = 0,
              scheduler: str | None = None, workers: int | None = None, threads_per_run: int | None = None,
              report=print) -> CalibrationResult:
    from scipy.optimize import differential_evolution

    from ..scenario import load_scenario

    targets = [parse_target(str(text)) for text in ([target] if isinstance(target, (str, Path)) else target)]
    if not targets:
        raise ScenarioError("nothing to fit to: give --target (a curve CSV, KEY=VALUE or SCENARIO:KEY=VALUE)")
    bounds = parse_fit(fit)
    keys = list(bounds)
    fixed_overrides = dict(split_override(text) for text in fixed)
    x0 = [0.5 * (lo + hi) for lo, hi in bounds.values()]
    for text in start:
        key, value = split_override(text)
        if key not in bounds:
            raise ScenarioError(f"--start {key}: not a fitted key ({', '.join(keys)}); give it a --fit range too")
        lo, hi = bounds[key]
        if not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise ScenarioError(f"--start {text!r}: give a number within its --fit range [{lo:g}, {hi:g}]")
        x0[keys.index(key)] = float(value)
    for key in keys:
        if key in fixed_overrides:
            raise ScenarioError(f"{key}: both fitted and set; drop the --set")
    scenario = absolute_source(scenario)
    # The bounds' ends must make valid scenarios (a refused value would stall the search).
    for source in dict.fromkeys(t.scenario or scenario for t in targets):
        for corner in (dict(zip(keys, (b[0] for b in bounds.values()))), dict(zip(keys, (b[1] for b in bounds.values())))):
            loaded, _ = load_scenario(source, {**fixed_overrides, **corner}, quick)
            if tool is not None and source == scenario:
                names = [t.name for t in loaded.all_tools()] + [name for _, name in loaded.support_grips()]
                if tool not in names:
                    raise ScenarioError(f"--tool {tool}: no such tool in {Path(scenario).stem} ({', '.join(names) or 'no tools'})")

    out = Path(out_dir)
    (out / "candidates").mkdir(parents=True, exist_ok=True)
    candidates: list[dict] = []

    with dask_client(scheduler, workers, threads_per_run, population * len(keys), report) as (client, threads):

        def run_generation(_func, xs):
            xs = [np.asarray(x, float) for x in xs]
            first = len(candidates)
            futures = []
            for k, x in enumerate(xs):
                values = {key: float(v) for key, v in zip(keys, x)}
                folder = str((out / "candidates" / f"{first + k:04d}").resolve())
                candidates.append({"candidate": first + k, **values, "folder": folder})
                futures.append(client.submit(evaluate, scenario, folder, {**fixed_overrides, **values}, quick, threads,
                                             tool, targets, pure=False))
            results = [{"distance": FAILED_DISTANCE, **outcome_of(future)} for future in futures]
            for k, result in enumerate(results):
                candidates[first + k].update(distance=result["distance"], status=result["status"],
                                             message=result.get("message", ""), misfits=result.get("misfits", {}),
                                             **result.get("values", {}))
            best = min(c["distance"] for c in candidates)
            report(f"  {len(candidates)} runs, best distance so far {best:.4g}")
            return [r["distance"] for r in results]

        fit_result = differential_evolution(
            lambda x: 0.0,  # never called: run_generation evaluates every candidate
            list(bounds.values()), x0=x0, workers=run_generation, updating="deferred", polish=False,
            popsize=population, maxiter=generations, tol=tol, seed=seed, init="latinhypercube",
        )
        points = np.array([[c[key] for key in keys] for c in candidates])
        surface = quadratic_minimum(points, np.array([c["distance"] for c in candidates]), np.array(list(bounds.values())))
        if surface is not None:
            run_generation(None, [surface])
    best = min(candidates, key=lambda c: (c["distance"], c["candidate"]))
    fitted = candidates[-1] if surface is not None else best
    _write_outputs(out, keys, candidates, fitted, best, surface is not None, x0, targets, tool, bounds, fit_result)
    finished = [c for c in candidates if c["status"] in COMPLETED]
    if not finished:
        reasons = list(dict.fromkeys(c["message"] for c in candidates if c["message"]))
        raise CalibrationFailed(f"every one of the {len(candidates)} runs failed ({'; '.join(reasons[:2]) or 'no message'}); "
                                f"calibration.csv in {out} lists them")
    if fitted["distance"] > USEFUL_MISFIT:
        raise CalibrationFailed(
            f"the best fit misses the targets by {fitted['distance']:.3g} (relative, more than {USEFUL_MISFIT:g}): a "
            "target in other units than the run's (N and m; kN or mm?) or --fit bounds that leave the answer out; "
            f"calibration.json in {out} has each target's misfit"
        )
    return CalibrationResult(out, {key: fitted[key] for key in keys}, fitted["distance"], len(candidates),
                             Path(fitted["folder"]))


def _write_outputs(out, keys, candidates, fitted, best, by_surface, x0, targets, tool, bounds, fit_result) -> None:
    value_targets = [t.text for t in targets if t.curve is None]
    columns = ["candidate", *keys, "distance", *value_targets, "status", "message", "folder"]
    with open(out / "calibration.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(candidates)
    record = {
        "fitted": {key: fitted[key] for key in keys},
        "distance": fitted["distance"],
        "fitted_run": fitted["folder"],
        "fitted_by": "the minimum of a quadratic fitted to the better half's squared distances, run once"
                     if by_surface else "the best candidate (no quadratic minimum within the candidates' range)",
        "best_candidate": {**{key: best[key] for key in keys}, "distance": best["distance"], "run": best["folder"]},
        "start": dict(zip(keys, x0)),
        "bounds": {key: list(b) for key, b in bounds.items()},
        "runs": len(candidates),
        "generations": int(fit_result.nit),
        "converged": bool(fit_result.success),
        "relative_misfit": fitted["distance"],
        "misfit_per_target": fitted.get("misfits", {}),
        "usable": bool(fitted.get("status") in COMPLETED and fitted["distance"] <= USEFUL_MISFIT),
        "optimizer_message": str(fit_result.message),
        "targets": [t.text for t in targets],
        "fitted_values": {text: fitted.get(text) for text in value_targets},
        "distance_definition": "sqrt(mean over the targets of d^2); a curve's d = sqrt(mean((F_run(u_i) - F_i)^2)) / "
                               "max|F_i| at the target's displacements u_i, a value's d = (run's - target's) / |target's|",
    }
    (out / "calibration.json").write_text(json.dumps(record, indent=2) + "\n")
    curve = next((t.curve for t in targets if t.curve is not None), None)
    if curve is not None:
        _plot_overlay(out / "calibration.png", *curve, candidates[0], fitted, tool, keys)


def _plot_overlay(path, target_u, target_f, start, fitted, tool, keys) -> None:
    from ..io.plots import _new_figure, _save, axis_label

    fig = _new_figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    ax.plot(np.asarray(target_u) * 1e3, np.asarray(target_f) * 1e-3, "k.", label="target")
    for label, candidate, style in (("start", start, "--"), ("fitted", fitted, "-")):
        if candidate.get("status") not in COMPLETED:
            continue
        curve = run_curve(candidate["folder"], tool)
        if not isinstance(curve, str):
            u, f = curve
            values = ", ".join(f"{k.split('.')[-1]}={candidate[k]:.4g}" for k in keys)
            ax.plot(u * 1e3, f * 1e-3, style, label=f"{label}: {values} (distance {candidate['distance']:.3g})")
    ax.set_xlabel(axis_label("displacement", "mm"))
    ax.set_ylabel(axis_label("force", "kN"))
    ax.set_title("Calibration: load-displacement")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(fig, path)

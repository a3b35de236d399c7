"""The report's figures: a case's curve from its run's history, in the case's unit, with the band
crackle's value must fall in shaded and the paper's value dashed, where the paper gives one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outputs import read_history_csv
from ..io.plots import _new_figure, _save, axis_label, tool_curves


def _load(history: dict) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Each tool's force (N) against its displacement (mm)."""
    return [(tool, disp * 1e3, force) for tool, (disp, force, _) in tool_curves(history).items()]


def _stress_strain(history: dict) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Platen stress (MPa) against platen strain (%)."""
    if "platen.stress" not in history or "platen.strain" not in history:
        return []
    return [("platens", np.asarray(history["platen.strain"]) * 100.0, np.asarray(history["platen.stress"]) * 1e-6)]


# A case's `curve`: the history's curves in the case's unit (N, MPa) and the axes' names and units.
CURVES = {
    "load": (_load, ("displacement", "mm"), ("force", "N")),
    "stress_strain": (_stress_strain, ("platen strain", "%"), ("platen stress", "MPa")),
}


def case_figure(case, folder: Path, value: float | None, path: Path) -> Path | None:
    """figures/CASE.png: the case's curves, its band, crackle's value and the paper's; None when the
    case has no curve or its run no history."""
    if case.curve is None or not (Path(folder) / "history.csv").is_file():
        return None
    read, (x_name, x_unit), (y_name, y_unit) = CURVES[case.curve]
    curves = read(read_history_csv(Path(folder) / "history.csv"))
    if not curves:
        return None
    fig = _new_figure(figsize=(6, 4.2))
    ax = fig.add_subplot()
    for label, x, y in curves:
        ax.plot(x, y, label=label)
    ax.axhspan(*case.band, color="0.85", label=f"band {case.band[0]:g}-{case.band[1]:g} {case.unit}")
    if value is not None:
        ax.axhline(value, color="C3", lw=0.8, label=f"crackle {value:.4g} {case.unit}")
    if case.paper_number is not None:
        ax.axhline(case.paper_number, color="k", ls="--", label=f"paper {case.paper_value}")
    ax.set_xlabel(axis_label(x_name, x_unit))
    ax.set_ylabel(axis_label(y_name, y_unit))
    ax.set_title(f"{case.name}: {case.quantity}", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return _save(fig, path)

"""Standard plots of a run: load-displacement, energy history, crack pattern.

Figures are built on matplotlib's Agg canvas directly (no pyplot), so they
never open a window, never touch the global backend and are freed with the
Figure object. Inputs are in SI units; plots show kN, mm and µs/ms.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..analysis.energy import ENERGY_NOISE, imbalance, imbalance_growth
from ._units import time_unit
from ..analysis.columns import tool_magnitude
from .outputs import read_events_csv, read_history_csv

_TOOL_COLUMN = re.compile(r"^tool\.(.+)\.([fu][xyz])$")  # analysis.columns.tool_column_names' force and travel
EDGE_LOAD_FORCE, EDGE_LOAD_DISPLACEMENT = "edge_load.force", "edge_load.displacement"  # a shell's edge loads
_MODE_MARKERS = {"tension": "o", "shear": "^", "mixed": "s"}


def _columns(table) -> dict[str, np.ndarray]:
    """Accept a dict of arrays, a CSV path, a DataFrame or a structured array."""
    if table is None:
        return {}
    if isinstance(table, (str, os.PathLike)):
        return read_history_csv(table)
    if isinstance(table, Mapping):
        return {str(k): np.asarray(v) for k, v in table.items()}
    if hasattr(table, "columns"):  # pandas DataFrame
        return {str(c): np.asarray(table[c]) for c in table.columns}
    names = getattr(getattr(table, "dtype", None), "names", None)
    if names:  # numpy structured array
        return {n: np.asarray(table[n]) for n in names}
    raise TypeError(f"cannot read columns from {type(table).__name__}")


def _new_figure(**kwargs):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(layout="constrained", **kwargs)
    FigureCanvasAgg(fig)
    return fig


def axis_label(quantity: str, unit: str | None) -> str:
    """Every axis of crackle's figures: 'quantity [unit]' ('quantity' alone when it has no unit)."""
    return f"{quantity} [{unit}]" if unit else quantity


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    fig.clear()  # drop artists now rather than at garbage collection
    return path


def _labelled_and_saved(fig, ax, path, x: tuple[str, str], y: tuple[str, str], title: str) -> Path:
    """The axes labelled (x and y: quantity and unit), titled and gridded; the figure saved."""
    ax.set_xlabel(axis_label(*x))
    ax.set_ylabel(axis_label(*y))
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def tool_names(history) -> list[str]:
    """Tools that have at least one force and one displacement column."""
    found: dict[str, set[str]] = {}
    for name in _columns(history):
        m = _TOOL_COLUMN.match(name)
        if m:
            found.setdefault(m.group(1), set()).add(m.group(2))
    return [
        tool for tool, comps in found.items()
        if comps & {"fx", "fy", "fz"} and comps & {"ux", "uy", "uz"}
    ]


def tool_curves(history) -> dict[str, tuple[np.ndarray, np.ndarray, bool]]:
    """Each tool's (displacement magnitude, force magnitude, fixed) over the history. A tool that
    never moves (a support plate) gets the travel of the moving tools (the largest of their
    displacements), where its reaction belongs. A shell's edge loads (edge_load.force,
    edge_load.displacement) are one more curve, "edge loads"."""
    cols = _columns(history)
    tools = tool_names(cols)
    disp = {tool: tool_magnitude(cols, tool, "u") for tool in tools}
    moving = [d for d in disp.values() if np.any(d != 0.0)]
    travel = np.max(moving, axis=0) if moving else None
    out = {}
    for tool in tools:
        force = tool_magnitude(cols, tool, "f")
        fixed = travel is not None and not np.any(disp[tool] != 0.0)
        out[tool] = (travel if fixed else disp[tool], force, fixed)
    if EDGE_LOAD_FORCE in cols and EDGE_LOAD_DISPLACEMENT in cols:
        out["edge loads"] = (np.asarray(cols[EDGE_LOAD_DISPLACEMENT], float), np.asarray(cols[EDGE_LOAD_FORCE], float),
                             False)
    return out


def plot_load_displacement(history, path) -> Path:
    """Force magnitude (kN) against displacement magnitude (mm), one curve per tool (tool_curves:
    a fixed tool against the moving tools' travel, dashed)."""
    fig = _new_figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    curves = tool_curves(history)
    for tool, (disp, force, fixed) in curves.items():
        ax.plot(disp * 1e3, force * 1e-3, "--" if fixed else "-", label=f"{tool} (fixed)" if fixed else tool)
    tools = list(curves)
    if tools:
        ax.legend(title="load")
    else:
        ax.text(0.5, 0.5, "no tool data", transform=ax.transAxes, ha="center")
    return _labelled_and_saved(fig, ax, path, ("displacement", "mm"), ("force", "kN"), "Load-displacement")


def plot_stress_strain(history, path, stress: str = "platen.stress", strain: str = "platen.strain") -> Path:
    """Platen stress (MPa) against platen strain (%), as a rock-mechanics UCS curve: both
    positive in compression."""
    cols = _columns(history)
    fig = _new_figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    if stress in cols and strain in cols:
        ax.plot(np.asarray(cols[strain], float) * 100.0, np.asarray(cols[stress], float) * 1e-6)
    else:
        ax.text(0.5, 0.5, "no platen data", transform=ax.transAxes, ha="center")
    return _labelled_and_saved(fig, ax, path, ("platen strain", "%"), ("platen stress", "MPa"), "Stress-strain")


def plot_energies(history, path) -> Path:
    """Every ``energy.*`` column against time, plus the imbalance (dashed); below, the imbalance
    as a share of the largest energy, the span where it grew shaded and the term it grew with
    named (analysis.energy.imbalance_growth).

    imbalance = external - sum of all other energy terms; it should stay
    near zero in a well-resolved run.
    """
    cols = _columns(history)
    energy_names = [n for n in cols if n.startswith("energy.")]
    fig = _new_figure(figsize=(7, 6))
    ax, share_ax = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    time = np.asarray(cols.get("time", np.zeros(0)), float)
    scale, unit = time_unit(np.nanmax(np.abs(time)) if time.size else 0.0)
    if energy_names and time.size:
        for name in energy_names:
            ax.plot(time * scale, np.asarray(cols[name], float), label=name[7:])
        if "energy.external" in cols:
            terms = {n: np.asarray(cols[n], float) for n in energy_names}
            gap = imbalance(terms)
            ax.plot(time * scale, gap, "k--", label="imbalance")
            # energy_error's scale: the largest external work or sum of the other terms.
            largest = max(float(np.max(np.abs(terms["energy.external"]))),
                          float(np.max(np.abs(terms["energy.external"] - gap))), ENERGY_NOISE)
            share_ax.plot(time * scale, 100.0 * gap / largest, "k-")
            growth = imbalance_growth({"time": time, **terms})
            if growth is not None:
                label = "grew here" + (f" with {growth.term[7:]}" if growth.term is not None else "")
                share_ax.axvspan(growth.start * scale, growth.end * scale, color="tab:red", alpha=0.15, label=label)
                share_ax.legend(fontsize="small")
        ax.legend(fontsize="small", ncol=2)
    else:
        ax.text(0.5, 0.5, "no energy data", transform=ax.transAxes, ha="center")
    share_ax.set_xlabel(axis_label("time", unit))
    ax.set_ylabel(axis_label("energy", "J"))
    share_ax.set_ylabel(axis_label("imbalance / largest energy", "%"))
    ax.set_title("Energy history")
    ax.grid(True, alpha=0.3)
    share_ax.grid(True, alpha=0.3)
    return _save(fig, path)


def _events(events) -> dict[str, np.ndarray]:
    """Event arrays time, x, y, z, mode from a dict, a table or events.csv."""
    if isinstance(events, (str, os.PathLike)):
        cols = read_events_csv(events)
    else:
        cols = _columns(events)
    time = np.asarray(cols.get("time", []), float).ravel()
    out = {"time": time}
    for axis in ("x", "y", "z"):
        out[axis] = np.asarray(cols.get(axis, np.zeros(len(time))), float).ravel()
    out["mode"] = np.asarray(cols.get("mode", ["unknown"] * len(time)), dtype=str).ravel()
    return out


# Colours of the crack pattern's lines by their label.
_PATH_COLOURS = {"pre-crack": "black", "grown": "tab:red"}
# Failures above which the crack pattern shows slices (SLICE_FRACTION of the depth) instead of
# whole projections.
SLICE_ABOVE = 2000
SLICE_FRACTION = 0.1


def plot_crack_pattern(events, bounds, path, paths=()) -> Path:
    """Failure points in three projections (xy, xz, yz), coloured by time.

    ``events`` holds arrays ``time, x, y, z, mode`` (a dict, or the path of
    events.csv); ``bounds`` is ``(lo, hi)`` of the specimen, drawn as a
    rectangle in each view (or None). Coordinates are shown in mm. Above
    SLICE_ABOVE failures (a collapsed DEM sample: projections would be solid
    colour) each view shows a slice through the specimen's middle, SLICE_FRACTION
    of its depth thick, with smaller marks. ``paths``: (label, (k, 3) points)
    drawn as lines (a shell's pre-cracks, the paths its tips ran), m.
    """
    from matplotlib.colors import Normalize
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    ev = _events(events)
    n = len(ev["time"])
    xyz_mm = np.stack([ev["x"], ev["y"], ev["z"]], axis=1) * 1e3
    scale, unit = time_unit(np.nanmax(np.abs(ev["time"])) if n else 0.0)
    t = ev["time"] * scale
    norm = Normalize(vmin=np.nanmin(t), vmax=np.nanmax(t)) if n else Normalize(0, 1)
    if n and norm.vmin == norm.vmax:
        norm = Normalize(norm.vmin - 0.5, norm.vmax + 0.5)

    fig = _new_figure(figsize=(14, 4.8))
    axes = fig.subplots(1, 3)
    scatter = None
    sliced = n > SLICE_ABOVE and bounds is not None
    for ax, (i, j) in zip(axes, [(0, 1), (0, 2), (1, 2)]):
        shown = np.ones(n, dtype=bool)
        title = f"{'xyz'[i]}{'xyz'[j]} projection"
        if sliced:
            k = 3 - i - j  # the axis across the view
            lo_k, hi_k = bounds[0][k] * 1e3, bounds[1][k] * 1e3
            middle, half = 0.5 * (lo_k + hi_k), 0.5 * SLICE_FRACTION * (hi_k - lo_k)
            shown = np.abs(xyz_mm[:, k] - middle) <= half
            title = (f"{'xyz'[i]}{'xyz'[j]} slice, |{'xyz'[k]} - {middle:.3g}| <= {half:.2g} mm "
                     f"({np.count_nonzero(shown):,} of {n:,})")
        if bounds is not None:
            lo = np.asarray(bounds[0], float) * 1e3
            hi = np.asarray(bounds[1], float) * 1e3
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j],
                                   fill=False, edgecolor="0.3", linewidth=1.2))
        for mode in np.unique(ev["mode"]):
            sel = (ev["mode"] == mode) & shown
            scatter = ax.scatter(xyz_mm[sel, i], xyz_mm[sel, j], c=t[sel], norm=norm,
                                 cmap="viridis", marker=_MODE_MARKERS.get(mode, "x"),
                                 s=4 if sliced else 14, linewidths=0.3 if mode in _MODE_MARKERS else 1.0)
        for label, points in paths:
            points = np.asarray(points, float) * 1e3
            ax.plot(points[:, i], points[:, j], "-", color=_PATH_COLOURS.get(label, "tab:red"), linewidth=1.5,
                    label=label if ax is axes[0] else None)
        if n == 0:
            ax.text(0.5, 0.5 if not paths else 0.92, "no failures" if not paths else "no growth",
                    transform=ax.transAxes, ha="center", va="center", color="0.4")
        ax.autoscale_view()
        ax.margins(0.05)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(axis_label("xyz"[i], "mm"))
        ax.set_ylabel(axis_label("xyz"[j], "mm"))
        ax.set_title(title, fontsize=9 if sliced else None)
    if scatter is not None:
        fig.colorbar(scatter, ax=list(axes), label=f"failure time [{unit}]", shrink=0.9)
        handles = [Line2D([], [], linestyle="", marker=_MODE_MARKERS.get(m, "x"),
                          color="0.3", label=m) for m in np.unique(ev["mode"])]
        fig.legend(handles=handles, title="failure mode", loc="outside lower center",
                   ncol=len(handles), fontsize="small")
    if paths:
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside upper right", fontsize="small")
    fig.suptitle(f"Crack pattern ({n:,} failures)")
    return _save(fig, path)


def plot_fragment_sizes(masses, path) -> Path:
    """Cumulative fragment-size distribution: share of the total mass in fragments of at most a
    given mass, on log axes (one point per fragment)."""
    m = np.sort(np.asarray(masses, dtype=float))
    fig = _new_figure(figsize=(6, 4.5))
    ax = fig.add_subplot(111)
    if len(m):
        ax.step(m * 1e3, np.cumsum(m) / m.sum(), where="post", color="tab:red")
        ax.plot(m * 1e3, np.cumsum(m) / m.sum(), ".", color="tab:red")
        ax.set_xscale("log")
    ax.set_xlabel(axis_label("fragment mass", "g"))
    ax.set_ylabel(axis_label("mass fraction in fragments this size or smaller", "-"))
    ax.set_title(f"Fragment sizes ({len(m)} fragments)")
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def plot_time_steps(element_dt, bulk_dt, limit: dict, path) -> Path:
    """Histogram of the stable step each element allows, beside what its bulk stiffness alone
    would allow: the gap is what interface and contact penalties cost. `limit` is summary.json's
    dt_limit (the step, what sets it, where)."""
    scale, unit = time_unit(float(np.median(bulk_dt)))
    fig = _new_figure(figsize=(6.5, 4.5))
    ax = fig.add_subplot(111)
    values = [np.asarray(element_dt) * scale, np.asarray(bulk_dt) * scale]
    lo, hi = min(v.min() for v in values), max(v.max() for v in values)
    bins = np.geomspace(lo, hi * 1.0001, 50) if hi > lo else 10
    ax.hist(values[0], bins=bins, alpha=0.7, color="tab:red", label="element (bulk + interfaces + contact)")
    ax.hist(values[1], bins=bins, alpha=0.5, color="tab:blue", label="bulk tet alone")
    ax.axvline(limit["dt"] * scale, color="k", ls="--", label=f"run's stable step ({limit['estimate']})")
    ax.axvline(limit["bound_dt"] * scale, color="k", ls=":", label=f"element bound ({limit['kind']}, element {limit['element']})")
    if hi > lo:
        ax.set_xscale("log")
    ax.set_xlabel(axis_label("stable time step", unit))
    ax.set_ylabel(axis_label("elements", "count"))
    ax.set_title(f"Time step: stable {limit['dt'] * scale:.3g} {unit}, median element {limit['median_dt'] * scale:.3g} {unit}")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def plot_crack_growth(length_history, speed_history, path) -> Path:
    """Main-crack length (area / wall) against time, and its growth speed per interval."""
    lh = np.asarray(length_history, dtype=float).reshape(-1, 2)
    sh = np.asarray(speed_history, dtype=float).reshape(-1, 2)
    fig = _new_figure(figsize=(6, 6))
    ax1 = fig.add_subplot(211)
    ax1.step(lh[:, 0] * 1e3, lh[:, 1] * 1e3, where="post", color="tab:red")
    ax1.set_ylabel(axis_label("main crack length", "mm"))
    ax1.set_title("Crack growth")
    ax1.grid(True, alpha=0.3)
    ax2 = fig.add_subplot(212, sharex=ax1)
    if len(sh):
        ax2.plot(sh[:, 0] * 1e3, sh[:, 1], color="tab:blue")
    ax2.set_xlabel(axis_label("time", "ms"))
    ax2.set_ylabel(axis_label("growth speed", "m/s"))
    ax2.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_j_history(history, path, reference: float | None = None) -> Path | None:
    """J and G (J/m^2) of each crack tip (history columns j.tipK, g.tipK: the domain J-integral
    and the virtual crack extension) against time, with the closed-form reference where the
    scenario gives one (a dashed line); None when the history has no J column."""
    cols = _columns(history)
    names = sorted(k for k in cols if k.startswith("j.tip"))
    if not names or len(cols["time"]) == 0:
        return None
    scale, unit = time_unit(float(np.max(cols["time"])))
    t = cols["time"] * scale
    fig = _new_figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    for name in names:
        tip = name[5:]
        line, = ax.plot(t, cols[name], label=f"J, tip {tip}")
        if f"g.tip{tip}" in cols:
            ax.plot(t, cols[f"g.tip{tip}"], ":", color=line.get_color(), label=f"G, tip {tip}")
    if reference is not None:
        ax.axhline(reference, color="0.3", linestyle="--", label="closed form")
    ax.legend(fontsize=7)
    return _labelled_and_saved(fig, ax, path, ("time", unit), ("J, G", "J/m^2"), "Energy release at the crack tips")


# Every figure a run writes into its plots/ folder, by file name (without .png), and where it comes
# from: the three standard ones, then those a method draws in its extra_plots (through
# run_plot_path). One list, so that a rerun into a folder removes the figures of an earlier run,
# whichever method drew them.
RUN_PLOTS = {
    "load_displacement": "standard: tool force against displacement (when the run has tools or edge loads)",
    "energies": "standard: the energy audit's terms over time",
    "crack_pattern": "standard: the failures' positions (the shell redraws it with its crack paths)",
    "fragment_sizes": "fdem: fragment masses",
    "time_step": "fdem: the per-element stable steps and the step used",
    "crack_growth": "fdem: the main crack's length and speed (with [analysis.cracks])",
    "stress_strain": "platen stress against strain (a compression or triaxial test between platens)",
    "j_history": "shell: J and G at each crack tip",
}


def run_plot_path(out_dir, name: str) -> Path:
    """out_dir/plots/NAME.png for a figure of RUN_PLOTS (a name not listed is a programming error:
    a rerun would leave it behind)."""
    if name not in RUN_PLOTS:
        raise KeyError(f"plot {name!r} is not in io.plots.RUN_PLOTS; add it there")
    return Path(out_dir) / "plots" / f"{name}.png"


def write_standard_plots(out_dir, history, events, bounds) -> list[Path]:
    """Write ``plots/{load_displacement,energies,crack_pattern}.png``.

    Load-displacement is skipped when the history has neither tool nor edge-load columns.
    Returns the paths written.
    """
    cols = _columns(history)
    paths = []
    if tool_names(cols) or EDGE_LOAD_FORCE in cols:
        paths.append(plot_load_displacement(cols, run_plot_path(out_dir, "load_displacement")))
    paths.append(plot_energies(cols, run_plot_path(out_dir, "energies")))
    paths.append(plot_crack_pattern(events, bounds, run_plot_path(out_dir, "crack_pattern")))
    return paths

"""The compression test between platens, which the FDEM and DEM set-ups recognise from their
tools: the platen stress and strain in the history, the peak stress and the curve's modulus in
the summary, and, with a confining pressure on the specimen's side (a triaxial test), that
pressure at the peak and the deviator stress there."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..analysis.strength import platen_modulus
from ..analysis.columns import tool_vector
from ..io.plots import plot_stress_strain, run_plot_path
from .simulation import Probe


@dataclass(frozen=True)
class Platen:
    """The first moving tool: its force on the sample along its travel over the loaded area is
    the history's `platen.stress`; the platens' approach (its travel towards the opposite platen
    less the opposite one's travel towards it, whether that one moves or not) over the sample's
    extent along it is `platen.strain` (both positive in compression, as a UCS curve is read)."""

    name: str
    direction: np.ndarray  # unit, the tool's travel
    length: float  # m, the sample's extent along it
    opposite: str | None = None  # the tool facing it across the sample, if any

    def stress_strain(self, row: dict, loaded_area: float) -> tuple[float, float]:
        """(stress, strain) of a history row with the tools' force and travel columns."""
        force = tool_vector(row, self.name, "f")  # on the sample
        approach = tool_vector(row, self.name, "u")
        if self.opposite is not None:
            approach = approach - tool_vector(row, self.opposite, "u")
        return float(force @ self.direction) / loaded_area, float(approach @ self.direction) / self.length


def facing_tool(tools, lead, direction) -> str | None:
    """The tool facing `lead` across the sample (travelling against it, moving or not): the
    platen whose travel makes the platens' approach with lead's."""
    facing = [t for t in tools if t is not lead and t.shape != "support" and float(_unit(t.direction) @ direction) < -0.9]
    return facing[0].name if facing else None


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


class PlatenProbe(Probe):
    """platen.stress and platen.strain in the history; in the summary the peak stress (the
    largest tool peak over the loaded area) and the modulus of the curve (20-50 % of the peak);
    plots/stress_strain.png. With a `confinement` (the pressure on the sample's side, a function of
    time: FDEM's pressure history, the DEM membrane's mean over the sides), the summary's
    confining_pressure is its value when the peak came and
    deviator_at_peak = peak_stress - confining_pressure (sigma_1 - sigma_3, compression
    positive)."""

    def __init__(self, platen: Platen, loaded_area: float, confinement: Callable[[float], float] | None = None):
        self.platen = platen
        self.loaded_area = loaded_area
        self.confinement = confinement
        self.curve: dict[float, tuple[float, float]] = {}  # time -> (strain, stress)

    units = {"platen.stress": "Pa", "platen.strain": "1"}

    def columns(self, sim, row: dict) -> dict[str, float]:
        stress, strain = self.platen.stress_strain(row, self.loaded_area)
        self.curve[sim.time] = (strain, stress)
        return {"platen.stress": stress, "platen.strain": strain}

    def summary(self, sim) -> dict:
        peaks, times = sim.load_cell.peaks()
        peak_stress = float(np.max(peaks, initial=0.0)) / self.loaded_area
        # JSON has no NaN: None until the curve has rows between 20 and 50 % of its peak.
        curve = np.array([self.curve[t] for t in sorted(self.curve)]).reshape(-1, 2)
        out = {"loaded_area": self.loaded_area, "peak_stress": peak_stress,
               "platen_modulus": platen_modulus(curve[:, 0], curve[:, 1])}
        if self.confinement is not None:
            at_peak = float(times[np.argmax(peaks)]) if len(peaks) else 0.0
            confining = float(self.confinement(at_peak))
            out.update(confining_pressure=confining, deviator_at_peak=peak_stress - confining)
        return out

    def plots(self, sim, out_dir) -> None:
        plot_stress_strain(out_dir / "history.csv", run_plot_path(out_dir, "stress_strain"))

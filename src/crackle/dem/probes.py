"""DEM's measurements (solver.simulation.Probe), each set up when the scenario asks for it: the
platen's stress-strain curve and modulus, a disc's Brazilian strength, where cracking starts
along a flaw (a direct tension test's strengths: solver.simulation.PeakForceProbe)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analysis.brazilian import brazilian_strength
from ..analysis.flaw import initiation_along_flaw
from ..analysis.strength import platen_modulus
from ..io.plots import plot_stress_strain, run_plot_path
from ..solver.simulation import Probe


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
        force = np.array([row[f"tool.{self.name}.f{c}"] for c in "xyz"])  # on the sample
        approach = np.array([row[f"tool.{self.name}.u{c}"] for c in "xyz"])
        if self.opposite is not None:
            approach = approach - np.array([row[f"tool.{self.opposite}.u{c}"] for c in "xyz"])
        return float(force @ self.direction) / loaded_area, float(approach @ self.direction) / self.length


class PlatenProbe(Probe):
    """platen.stress and platen.strain in the history, the modulus of their curve (20-50 % of
    the peak) in the summary, plots/stress_strain.png."""

    def __init__(self, platen: Platen, loaded_area: float):
        self.platen = platen
        self.loaded_area = loaded_area
        self.curve: dict[float, tuple[float, float]] = {}  # time -> (strain, stress)

    def columns(self, sim, row: dict) -> dict[str, float]:
        stress, strain = self.platen.stress_strain(row, self.loaded_area)
        self.curve[sim.time] = (strain, stress)
        return {"platen.stress": stress, "platen.strain": strain}

    def summary(self, sim) -> dict:
        # JSON has no NaN: None until the curve has rows between 20 and 50 % of its peak.
        curve = np.array([self.curve[t] for t in sorted(self.curve)]).reshape(-1, 2)
        return {"platen_modulus": platen_modulus(curve[:, 0], curve[:, 1])}

    def plots(self, sim, out_dir) -> None:
        plot_stress_strain(out_dir / "history.csv", run_plot_path(out_dir, "stress_strain"))


class BrazilianProbe(Probe):
    """A disc's Brazilian strength: the elastic relation's tensile stress across the loaded
    diameter at the peak force."""

    def __init__(self, diameter: float, thickness: float):
        self.diameter, self.thickness = diameter, thickness

    def summary(self, sim) -> dict:
        peak = float(np.max(sim.load_cell.peaks()[0], initial=0.0))
        return {"brazilian_strength": brazilian_strength(peak, self.diameter, self.thickness)}


class FlawProbe(Probe):
    """Where along the scenario's [flaw] the bonds began to fail (analysis.flaw)."""

    def __init__(self, flaw):
        self.flaw = flaw

    def summary(self, sim) -> dict:
        if not sim.broken:
            return {}
        failed = np.flatnonzero(sim.failed_bonds())
        s = sim.inter
        along, across = self.flaw.axes()
        return {"flaw_initiation": initiation_along_flaw(0.5 * (sim.x0[s.a[failed]] + sim.x0[s.b[failed]]),
                                                         s.fail_time[failed], self.flaw.center, along, across,
                                                         self.flaw.length)}


class MembraneProbe(Probe):
    """The pressures on the sample's faces (dem.membrane): `pressure.K` (Pa) per [[pressures]]
    entry in the history; with a platen, the triaxial test's results in the summary:
    `confining_pressure` (Pa, the area-weighted mean pressure on the faces parallel to the
    platen's travel at the time of the peak tool force, the one peak_stress reads),
    `deviator_at_peak` (peak_stress less it)."""

    def __init__(self, platen: Platen | None):
        self.platen = platen

    def columns(self, sim, row: dict) -> dict[str, float]:
        return {f"pressure.{k}": float(p) for k, p in enumerate(sim.membrane.pressures(sim.time))}

    def summary(self, sim) -> dict:
        membrane = sim.membrane
        out = {"membrane_rasters": membrane.rasters}
        if self.platen is None or not sim.loaded_area:
            return out
        peaks, times = sim.load_cell.peaks()
        j = int(np.argmax(peaks))  # the tool whose peak summary.json's peak_stress reads
        weight = np.array([sum(f.area for f in faces if abs(float(f.inward @ self.platen.direction)) < 1e-9)
                           for faces in membrane.faces])
        if not weight.any():
            return out
        confining = float(weight @ membrane.pressures(float(times[j]))) / float(weight.sum())
        peak = float(peaks[j]) / sim.loaded_area
        return {**out, "confining_pressure": confining, "deviator_at_peak": peak - confining}

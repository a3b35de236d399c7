"""DEM's measurements (solver.simulation.Probe), each set up when the scenario asks for it: a
disc's Brazilian strength, where cracking starts along a flaw (a direct tension test's strengths:
solver.simulation.PeakForceProbe; the platens' curve: solver.platen.PlatenProbe)."""

from __future__ import annotations

import numpy as np

from ..analysis.brazilian import brazilian_strength
from ..analysis.flaw import initiation_along_flaw
from ..solver.simulation import Probe


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
    entry in the history, `membrane_rasters` (how many times the exposure was drawn) in the
    summary; a triaxial test's confinement at the peak is the platens' probe's
    (solver.platen.PlatenProbe, from Membrane.confinement)."""

    def columns(self, sim, row: dict) -> dict[str, float]:
        return {f"pressure.{k}": float(p) for k, p in enumerate(sim.membrane.pressures(sim.time))}

    def summary(self, sim) -> dict:
        return {"membrane_rasters": sim.membrane.rasters}

"""DEM's measurements (solver.simulation.Probe), each set up when the scenario asks for it: a
disc's Brazilian strength, where cracking starts along a flaw (a direct tension test's strengths:
solver.simulation.PeakForceProbe; the platens' curve: solver.platen.PlatenProbe)."""

from __future__ import annotations

import numpy as np

from ..analysis.flaw import initiation_along_flaw
from ..solver.failures import MODE_NAMES
from ..solver.simulation import Probe


class BrazilianProbe(Probe):
    """A disc's Brazilian strength and splitting angle (analysis.strength.BrazilianTest, as FDEM's)
    from the tools' peak forces and where and how the bonds failed (at their reference midpoints)."""

    def __init__(self, test):
        self.test = test

    def summary(self, sim) -> dict:
        failed = np.flatnonzero(sim.failed_bonds())
        s = sim.inter
        xyz = 0.5 * (sim.x0[s.a[failed]] + sim.x0[s.b[failed]])
        events = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
                  "mode": np.array([MODE_NAMES[k] for k in s.fail_mode[failed]])}
        return self.test.summary(sim.load_cell.peaks()[0], events)


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

    units = {"pressure.*": "Pa"}

    def columns(self, sim, row: dict) -> dict[str, float]:
        return {f"pressure.{k}": float(p) for k, p in enumerate(sim.membrane.pressures(sim.time))}

    def summary(self, sim) -> dict:
        return {"membrane_rasters": sim.membrane.rasters}

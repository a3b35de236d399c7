"""FDEM's measurements (solver.simulation.Probe), each set up when the scenario asks for it:
the fracture tip and plastic zone along a plane ([analysis.fracture_plane]), the crack count and
main-crack speed ([analysis.cracks]), the nominal strength of a Brazilian disc (a direct tension
test's is solver.simulation.PeakForceProbe's)."""

from __future__ import annotations

import numpy as np

from ..analysis import (CrackAnalysis, CrackSettings, FracturePlane, analyse_cracks, loading_index_of,
                        propagating_plastic_zone, tip_and_plastic_zone)
from ..analysis.energy_jumps import JUMP_SPEED, energy_jumps
from ..io.plots import plot_crack_growth, run_plot_path
from ..solver.failures import MODE_NAMES
from ..solver.simulation import Probe
from .topology import INTACT, PRECRACK

# The ring rule's length moved by -25 % and +50 %: how much the crack count leans on it.
CRACK_SCALE_FACTORS = (0.75, 1.0, 1.5)


def failed_interfaces(model) -> np.ndarray:
    """Ids of the interfaces failed in the run (not the pre-cracks)."""
    return np.flatnonzero((model.ifs.state != INTACT) & (model.ifs.state != PRECRACK))


class FractureTipProbe(Probe):
    """The fracture tip and plastic zone along a plane, per history row (fracture.tip,
    fracture.plastic_zone), and the propagating plastic zone's length in the summary."""

    def __init__(self, plane: FracturePlane):
        self.plane = plane
        self.tips: list[float] = []
        self.zones: list[float] = []

    units = {"fracture.tip": "m", "fracture.plastic_zone": "m"}

    def columns(self, sim, row: dict) -> dict[str, float]:
        m = sim.model
        ifs = m.ifs
        tip, zone = tip_and_plastic_zone(self.plane, m.iface_centroids(m.nodes.x), ifs.damage, ifs.state != INTACT)
        self.tips.append(tip)
        self.zones.append(zone)
        return {"fracture.tip": tip, "fracture.plastic_zone": zone}

    def summary(self, sim) -> dict:
        if not self.tips:
            return {}
        zones = np.asarray(self.zones)
        values = {
            "plastic_zone_length": propagating_plastic_zone(self.tips, zones),
            "plastic_zone_max": float(zones.max()),
            "fracture_tip_final": float(self.tips[-1]),
        }
        return {k: (v if np.isfinite(v) else None) for k, v in values.items()}  # JSON has no inf/nan


class CrackProbe(Probe):
    """Crack networks, the paper-004 count and the main crack's speed (analysis.cracks), the
    count's sensitivity to its ring scale, the bursts of the damage dissipation (the paper's
    Fig. 12 measure, from each row's energy.damage) and the tools' loading index."""

    def __init__(self, settings: CrackSettings):
        self.settings = settings
        self.dissipation: list[tuple[float, float]] = []  # (time, energy.damage) per history row
        self._analysed: tuple[int, CrackAnalysis] | None = None  # (failures analysed, analysis)

    def columns(self, sim, row: dict) -> dict[str, float]:
        self.dissipation.append((sim.time, row["energy.damage"]))
        return {}

    def cracks(self, sim, scale: float | None = None) -> CrackAnalysis:
        """The analysis of the failures so far at the settings' scale (kept until new failures:
        the summary and the plots both ask for it) or at `scale` (m)."""
        m = sim.model
        failed = failed_interfaces(m)
        c = self.settings

        def analyse(r):
            top_point = m.x0[np.argmax(m.x0 @ np.asarray(c.top, float))]
            return analyse_cracks(m.iface_centroids(ids=failed), m.ifs.area[failed], m.ifs.fail_time[failed], r, c.wall,
                                  top_point, faces=m.corner_point[m.ifs.na[failed]])

        if scale is not None:
            return analyse(scale)
        if self._analysed is None or self._analysed[0] != len(failed):
            self._analysed = (len(failed), analyse(c.scale))
        return self._analysed[1]

    def summary(self, sim) -> dict:
        m = sim.model
        directions = np.array([t.direction for t in m.tool_specs], float).T
        scale = self.settings.scale
        threshold = (min(mat.interface.fracture_energy for mat in m.materials) * self.settings.wall
                     * JUMP_SPEED * m.materials[0].rayleigh_speed)
        jumps = energy_jumps(*np.array(self.dissipation).reshape(-1, 2).T, threshold)
        return {
            **self.cracks(sim).as_summary(),
            "cracks_at_scales": [[factor * scale, self.cracks(sim, factor * scale).cracks] for factor in CRACK_SCALE_FACTORS],
            "energy_jumps": len(jumps),
            "energy_jump_times": [start for start, _, _ in jumps],
            "energy_jump_threshold": threshold,
            "loading_index": loading_index_of(directions) if directions.size else None,
        }

    def plots(self, sim, out_dir) -> None:
        cracks = self.cracks(sim)
        if len(cracks.length_history):
            plot_crack_growth(cracks.length_history, cracks.speed_history, run_plot_path(out_dir, "crack_growth"))


class BrazilianProbe(Probe):
    """A Brazilian disc's nominal strength (analysis.strength.BrazilianTest) from the tools' peak
    forces and where and how the interfaces failed."""

    def __init__(self, test):
        self.test = test

    def summary(self, sim) -> dict:
        peaks = sim.load_cell.peaks()[0]
        m = sim.model
        failed = failed_interfaces(m)
        xyz = m.iface_centroids(ids=failed)
        events = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
                  "mode": np.array([MODE_NAMES[k] for k in m.ifs.fail_mode[failed]])}
        return self.test.summary(peaks, events)

"""The lattice behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

import numpy as np

from ..solver.simulation import SimulationBase
from .kernels import advance


class LatticeSimulation(SimulationBase):
    method = "lattice"

    def __init__(self, setup, nodes, springs, tools, break_strain, stable_dt, wave_transit):
        self._start_clock_and_tools(tools, setup.tool_names, setup.warnings)
        self.nodes = self.body = nodes
        self.springs = springs
        self.x0 = nodes.x.copy()
        self.break_strain = float(break_strain)
        self.stable_dt = self.proven_dt = stable_dt
        self.proven_dt_how = "a Gershgorin bound over each node's springs and tools"
        self.wave_transit = wave_transit
        self.gravity = np.asarray(setup.scenario.run.gravity, float)
        self.damping = float(setup.scenario.run.damping)

    def advance(self, n_steps: int, dt: float) -> None:
        advance(n_steps, self.steps, dt, self.nodes, self.springs, self.tools, self.break_strain, self.gravity,
                self.damping)
        self.steps += n_steps
        self.time = self.steps * dt

    def failure_state(self):
        s = self.springs
        return ~s.intact, s.fail_time, s.fail_mode

    def failure_positions(self, ids) -> np.ndarray:
        return 0.5 * (self.x0[self.springs.a[ids]] + self.x0[self.springs.b[ids]])

    def _spring_energy(self, x) -> float:
        s = self.springs
        stretch = np.linalg.norm(x[s.b] - x[s.a], axis=1) - s.rest
        return float(np.sum(np.where(s.intact, 0.5 * s.k * stretch**2, 0.0)))

    def own_energies(self, dt: float) -> dict[str, float]:
        # Potentials at the mid-step positions pair with the half-step velocities.
        return {"elastic": self._spring_energy(self.nodes.x - 0.5 * dt * self.nodes.v),
                "damage": float(np.sum(self.springs.e_damage))}

    def fields(self) -> dict:
        s = self.springs
        return {
            "points": self.nodes.x,
            "point_data": {"displacement": self.nodes.x - self.x0, "velocity": self.nodes.v},
            "blocks": [("line", np.stack([s.a, s.b], axis=1), {"intact": s.intact.astype(np.int64)})],
        }

    def describe(self) -> str:
        return f"{len(self.nodes.x):,} nodes, {len(self.springs.a):,} springs"

    def own_summary(self) -> dict:
        return {"nodes": len(self.nodes.x), "springs": len(self.springs.a)}

"""The lattice behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

import numpy as np

from ..solver.failures import FailureRecorder
from ..solver.simulation import SimulationBase
from .kernels import advance


class LatticeSimulation(SimulationBase):
    method = "lattice"

    def __init__(self, nodes, springs, tools, tool_names, break_strain, stable_dt, wave_transit, gravity, damping):
        self._start_clock_and_tools(tools, tool_names)
        self.nodes, self.springs = nodes, springs
        self.body = nodes
        self.break_strain = float(break_strain)
        self.stable_dt = stable_dt
        self.proven_dt = stable_dt
        self.proven_dt_how = "a Gershgorin bound over each node's springs and tools"
        self.wave_transit = wave_transit
        self.gravity = gravity
        self.damping = float(damping)
        self.x0 = nodes.x.copy()
        self._failures = FailureRecorder(len(springs.a))

    def advance(self, n_steps: int, dt: float) -> None:
        advance(n_steps, self.steps, dt, self.nodes, self.springs, self.tools, self.break_strain, self.gravity,
                self.damping)
        self.steps += n_steps
        self.time = self.steps * dt

    @property
    def broken(self) -> int:
        return int(np.count_nonzero(~self.springs.intact))

    def _spring_energy(self, x) -> float:
        s = self.springs
        stretch = np.linalg.norm(x[s.b] - x[s.a], axis=1) - s.rest
        return float(np.sum(np.where(s.intact, 0.5 * s.k * stretch**2, 0.0)))

    def own_energies(self, dt: float) -> dict[str, float]:
        # Potentials at the mid-step positions pair with the half-step velocities.
        return {"elastic": self._spring_energy(self.nodes.x - 0.5 * dt * self.nodes.v),
                "damage": float(np.sum(self.springs.e_damage))}

    def new_events(self):
        s = self.springs
        return self._failures.new(~s.intact, s.fail_time, s.fail_mode,
                                  lambda ids: 0.5 * (self.x0[s.a[ids]] + self.x0[s.b[ids]]))

    def fields(self) -> dict:
        s = self.springs
        return {
            "points": self.nodes.x,
            "point_data": {"displacement": self.nodes.x - self.x0, "velocity": self.nodes.v},
            "blocks": [("line", np.stack([s.a, s.b], axis=1), {"intact": s.intact.astype(np.int64)})],
        }

    def describe(self) -> str:
        return f"{len(self.nodes.x):,} nodes, {len(self.springs.a):,} springs"

    def bounds(self):
        return self.x0.min(axis=0), self.x0.max(axis=0)

    def summary(self) -> dict:
        return {"nodes": len(self.nodes.x), "springs": len(self.springs.a), "warnings": list(self.warnings)}

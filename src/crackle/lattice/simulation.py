"""The lattice behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

import numpy as np

from ..loading.loadcell import LoadCell, ToolSprings
from ..solver.failures import FailureRecorder
from .kernels import advance


class LatticeSimulation:
    method = "lattice"

    def __init__(self, nodes, springs, tools, tool_names, radius, break_strain, stable_dt, wave_transit, gravity,
                 damping):
        self.nodes, self.springs, self.tools = nodes, springs, tools
        self._tool_names = list(tool_names)
        self.radius = float(radius)
        self.break_strain = float(break_strain)
        self.stable_dt = stable_dt
        self.proven_dt = stable_dt
        self.proven_dt_how = "a Gershgorin bound over each node's springs and tools"
        self.wave_transit = wave_transit
        self.gravity = gravity
        self.damping = float(damping)
        self.time = 0.0
        self.steps = 0
        self.x0 = nodes.x.copy()
        self._radius = np.array([self.radius])
        self._springs = ToolSprings(tools, tool_names)
        self.load_cell = LoadCell(tools)
        self._failures = FailureRecorder(len(springs.a))
        self.warnings: list[str] = []

    def advance(self, n_steps: int, dt: float) -> None:
        advance(n_steps, self.steps, dt, self.nodes, self.springs, self.tools, self.radius, self.break_strain,
                self.gravity, self.damping)
        self.steps += n_steps
        self.time = self.steps * dt

    def state_is_finite(self) -> bool:
        return bool(np.isfinite(self.nodes.x).all() and np.isfinite(self.nodes.v).all())

    @property
    def broken(self) -> int:
        return int(np.count_nonzero(~self.springs.intact))

    def _tool_springs(self, dt: float | None = None) -> ToolSprings:
        """The tool springs now, or with the step dt at mid-step (the energy audit's)."""
        n = self.nodes
        mid = {} if dt is None else {"v": n.v, "time": self.time, "dt": dt}
        return self._springs.measure(n.x, self._radius, n.area, n.tool, n.tool_offset, n.friction, **mid)

    def _spring_energy(self, x) -> float:
        s = self.springs
        stretch = np.linalg.norm(x[s.b] - x[s.a], axis=1) - s.rest
        return float(np.sum(np.where(s.intact, 0.5 * s.k * stretch**2, 0.0)))

    def energies(self, dt: float) -> dict[str, float]:
        n = self.nodes
        # Potentials at the mid-step positions pair with the half-step velocities.
        x_mid = n.x - 0.5 * dt * n.v
        return {
            "energy.kinetic": float(0.5 * np.sum(n.mass * np.einsum("ij,ij->i", n.v, n.v))),
            "energy.elastic": self._spring_energy(x_mid),
            "energy.contact": float(np.sum(self._tool_springs(dt).energy)),
            "energy.damage": float(np.sum(self.springs.e_damage)),
            "energy.friction": float(np.sum(n.d_friction)),
            "energy.damping": float(np.sum(n.w_damping)),
            "energy.external": float(np.sum(n.w_external)) + self._springs.free_work(),
        }

    def sample(self, dt: float) -> dict[str, float]:
        energies = self.energies(dt)
        return {**self._springs.columns(self.load_cell, self._tool_springs), **energies, "broken": self.broken}

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

    def tool_names(self) -> list[str]:
        return list(self._tool_names)

    def bounds(self):
        return self.x0.min(axis=0), self.x0.max(axis=0)

    def summary(self) -> dict:
        return {"nodes": len(self.nodes.x), "springs": len(self.springs.a), "warnings": list(self.warnings)}

    def extra_plots(self, out_dir) -> None:
        pass

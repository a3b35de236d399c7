"""The shell behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..loading.loadcell import LoadCell, ToolSprings
from ..solver.failures import FailureRecorder
from .jintegral import j_integral
from .kernels import advance
from .model import Shell


@dataclass
class CrackTip:
    position: np.ndarray  # m, reference configuration
    direction: np.ndarray  # unit vector the crack runs along at the tip


class ShellSimulation:
    method = "shell"

    def __init__(self, shell: Shell, tools, tool_names, load_factor, tips, rings, stable_dt, wave_transit, gravity,
                 damping):
        self.shell, self.tools, self.load_factor = shell, tools, load_factor
        self._tool_names = list(tool_names)
        self.tips, self.rings = list(tips), [tuple(map(float, r)) for r in rings]
        self.stable_dt = float(stable_dt)
        self.wave_transit = float(wave_transit)
        self.gravity = np.asarray(gravity, dtype=float)
        self.damping = float(damping)
        self.j_reference: float | None = None
        self.time = 0.0
        self.steps = 0
        self._springs = ToolSprings(tools, tool_names)
        self.load_cell = LoadCell(tools)
        self._failures = FailureRecorder(0)  # no crack growth yet: nothing fails
        self.warnings: list[str] = []

    @property
    def nodes(self):
        return self.shell.nodes

    def advance(self, n_steps: int, dt: float) -> None:
        s = self.shell
        advance(n_steps, self.steps, dt, s.nodes, s.faces, s.edges, self.tools, self.load_factor, self.gravity,
                self.damping)
        self.steps += n_steps
        self.time = self.steps * dt

    def state_is_finite(self) -> bool:
        n = self.nodes
        return bool(np.isfinite(n.x).all() and np.isfinite(n.v).all())

    @property
    def broken(self) -> int:
        return 0

    def _tool_springs(self) -> ToolSprings:
        n = self.nodes
        return self._springs.measure(n.x, n.radius, n.area, n.tool, n.tool_offset, n.friction)

    def energies(self, dt: float) -> dict[str, float]:
        n = self.nodes
        # Potentials at the mid-step positions pair with the half-step velocities.
        membrane, bending = self.shell.strain_energies(n.x - 0.5 * dt * n.v)
        return {
            "energy.kinetic": float(0.5 * np.sum(n.mass * np.einsum("ij,ij->i", n.v, n.v))),
            "energy.membrane": membrane,
            "energy.bending": bending,
            "energy.contact": float(np.sum(self._tool_springs().energy)),
            "energy.friction": float(np.sum(n.d_friction)),
            "energy.damping": float(np.sum(n.w_damping)),
            "energy.external": float(np.sum(n.w_external)),
        }

    def j_values(self) -> np.ndarray:
        """J (J/m^2) at each tip (rows) over each ring (columns), at the current positions."""
        return np.array([[j_integral(self.shell, self.nodes.x, tip.position, tip.direction, *ring)
                          for ring in self.rings] for tip in self.tips]).reshape(len(self.tips), len(self.rings))

    def sample(self, dt: float) -> dict[str, float]:
        row = {**self._springs.columns(self.load_cell, self._tool_springs), **self.energies(dt), "broken": 0}
        for k, values in enumerate(self.j_values()):
            row[f"j.tip{k}"] = float(np.mean(values))
        return row

    def new_events(self):
        return self._failures.new(np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0, dtype=np.int8),
                                  lambda ids: np.zeros((len(ids), 3)))

    def fields(self) -> dict:
        n, mesh = self.nodes, self.shell.mesh
        return {
            "points": n.x,
            "point_data": {"displacement": n.x - mesh.X, "velocity": n.v},
            "blocks": [("triangle", mesh.tri, {"thickness": mesh.thickness.copy()})],
        }

    def describe(self) -> str:
        return f"{len(self.shell.mesh.tri):,} triangles, {len(self.shell.mesh.X):,} vertices, {len(self.tips)} crack tips"

    def tool_names(self) -> list[str]:
        return list(self._tool_names)

    def bounds(self):
        X = self.shell.mesh.X
        return X.min(axis=0), X.max(axis=0)

    def summary(self) -> dict:
        j = self.j_values()
        out = {
            "triangles": len(self.shell.mesh.tri),
            "nodes": len(self.shell.mesh.X),
            "elements": len(self.shell.mesh.tri),
            "element_size": self.shell.mesh.element_size(),
            "crack_tips": [tip.position.tolist() for tip in self.tips],
            "j_rings": [list(r) for r in self.rings],
            "j_tips": j.tolist(),
            "j_integral": float(np.mean(j[0])) if len(self.tips) else None,
            "warnings": list(self.warnings),
        }
        if self.j_reference is not None:
            out["j_reference"] = self.j_reference
            out["j_ratio"] = out["j_integral"] / self.j_reference if out["j_integral"] is not None else None
        return out

    def extra_plots(self, out_dir) -> None:
        pass

"""The shell behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.fields import STRESS_COMPONENTS
from ..io.plots import EDGE_LOAD_DISPLACEMENT, EDGE_LOAD_FORCE, plot_crack_pattern, plot_j_history, run_plot_path
from ..solver.failures import MODE_NAMES, failure_mode
from ..solver.simulation import SimulationBase
from .growth import GROWTH_CHECK, Advance, GrowthLaw, align_ahead, cut_edge, edge_between, edge_stresses, step_ahead
from .jintegral import (KINK_CRITERIA, VirtualExtension, bending_density, branch_pairs, j_integral, stress_intensity,
                        vertex_normal)
from .kernels import advance
from .mesh import altitudes
from .model import Shell


# A J read while the sheet moves is not the static one: an oscillation about equilibrium moves J
# by about sqrt(kinetic / strain energy) of it (the undamped centre-crack plate: +-5 % at 1e-3),
# so below 1e-4 the motion's share is ~1 %.
STATIC_KINETIC = 1e-4


def static_warning(kinetic_to_strain: float) -> list[str]:
    """The warning for a J read while the sheet still moved (kinetic energy above STATIC_KINETIC
    of the strain energy), or none."""
    if not kinetic_to_strain > STATIC_KINETIC:
        return []
    return [f"J and G were read while the sheet still moved (kinetic energy {kinetic_to_strain:.2g} of the strain "
            f"energy, above {STATIC_KINETIC:g}): they are not the static values a closed form or Gc compares with "
            "(off by about the square root of that ratio); run longer, ramp the load more slowly or damp "
            "(run.damping) before reading them"]


@dataclass
class CrackTip:
    vertex: int  # the tip's vertex (not split: the crack ends there)
    direction: np.ndarray  # unit vector the crack runs along at the tip
    extension: float = 0.0  # m grown since the start
    pending: float = 0.0  # m run (speed x time) since the last cut, not yet an edge
    active: bool = True  # False once the crack reached a boundary
    aim: np.ndarray | None = None  # unit vector the kink criterion last chose (the cut follows the mesh's nearest edge)


class ShellSimulation(SimulationBase):
    method = "shell"
    HISTORY_UNITS = {EDGE_LOAD_FORCE: "N", EDGE_LOAD_DISPLACEMENT: "m", "j.tip*": "J/m^2", "g.tip*": "J/m^2",
                     "crack.tip*": "m"}

    def __init__(self, shell: Shell, tools, tool_names, load_factor, pressures, tips, rings, stable_dt, wave_transit,
                 gravity, damping, growth: GrowthLaw | None = None):
        self._start_clock_and_tools(tools, tool_names)
        self.shell, self.load_factor, self.pressures = shell, load_factor, pressures
        self.tips, self.rings = list(tips), [tuple(map(float, r)) for r in rings]
        self._history_tips = len(self.tips)  # the history's columns are fixed: a nucleated tip is in the summary
        self.nucleations: list[dict] = []  # cracks started at a free edge (fracture.strength)
        self.stable_dt = float(stable_dt)
        self.wave_transit = float(wave_transit)
        self.gravity = np.asarray(gravity, dtype=float)
        self.damping = float(damping)
        self.j_reference: float | None = None  # a closed form of the case (fracture.reference)
        self.j_bracket: list[float] | None = None  # the range of several estimates, where there are
        self.growth = growth
        self.advances: list[Advance] = []  # every cut, in order
        self.pre_cracks: list[np.ndarray] = []  # the [[cracks]] as cut, reference positions (set-up)
        self._tip_starts = [shell.mesh.X[tip.vertex].copy() for tip in self.tips]
        self._reported = 0  # advances already in events.csv
        self.fracture_energy = 0.0  # J: what the cuts and the moves at the tip changed at once (_replace_shell)
        self._thinnest = float(np.min(altitudes(shell.mesh.X, shell.mesh.tri)))  # the step's length: moves keep to it
        self._extensions: dict = {}  # (tip vertex, direction, ring) -> VirtualExtension of the current shell
        # {material: {property: statistics}} of the properties drawn per site ([material.random];
        # their values: growth.sites, functions of the reference position), or None (set-up).
        self.random_properties: dict | None = None

    def __getstate__(self):
        # the virtual extensions are rebuilt on demand: a checkpoint need not carry them
        return {**self.__dict__, "_extensions": {}}

    @property
    def nodes(self):
        return self.shell.nodes

    body = nodes

    def advance(self, n_steps: int, dt: float) -> None:
        if self.growth is None:
            self._advance_on_grid(n_steps, dt, None, self._compiled_steps)
        else:
            self._advance_on_grid(n_steps, dt, GROWTH_CHECK, self._compiled_steps, after=self._nucleate_and_grow)

    def _compiled_steps(self, n: int, dt: float) -> None:
        s = self.shell
        advance(n, self.steps, dt, s.nodes, s.faces, s.edges, self.tools, self.load_factor, self.pressures, self.gravity,
                self.damping)

    def _nucleate_and_grow(self, dt: float) -> None:
        self._nucleate(dt)
        self._grow(dt)

    def _nucleate(self, dt: float) -> None:
        """Start a crack at the free-edge vertex whose stress along the edge is the largest, if it
        reached the strength (growth.edge_stresses): the vertex opens, the edge inward (turned
        onto the edge's normal first) is cut, its far end a new tip. One per check: the new
        crack relieves its neighbours before the next."""
        if not np.isfinite(self.growth.strength):
            return
        vertices, stress, inward = edge_stresses(self.shell, self.nodes.x)
        if self.growth.sites is not None and "strength" in self.growth.sites.fields:
            # Each vertex's own strength (drawn at its reference position): the most overstressed starts.
            if not len(vertices):
                return
            ratio = stress / self.growth.vertex_strength(self.shell.mesh, vertices)
            k = int(np.argmax(ratio))
            if ratio[k] < 1.0:
                return
        elif not len(vertices) or stress.max() < self.growth.strength:
            return
        else:
            k = int(np.argmax(stress))
        mouth, heading = int(vertices[k]), inward[k]
        self._replace_shell(align_ahead(self.shell, mouth, heading, self._thinnest), dt)
        ahead = step_ahead(self.shell, mouth, heading)
        if ahead is None:
            return
        tip_vertex = ahead[0]
        through = self._cut(mouth, tip_vertex, dt)
        X = self.shell.mesh.X
        direction = X[tip_vertex] - X[mouth]
        length = float(np.linalg.norm(direction))
        self.tips.append(CrackTip(tip_vertex, direction / length, extension=length, active=not through, aim=heading))
        self._tip_starts.append(X[mouth].copy())
        self.advances.append(Advance(self.time, X[tip_vertex].copy(), len(self.tips) - 1, failure_mode(0.0)))
        self.nucleations.append({"time": self.time, "position": X[mouth].tolist(), "stress": float(stress[k])})

    def _grow(self, dt: float) -> None:
        """Griffith's check and the speed law at each running tip; cut the edges it has passed."""
        for k, tip in enumerate(self.tips):
            if not tip.active:
                continue
            j = float(np.mean(self._tip_g(tip) if self.growth.criterion == "g" else self._tip_j(tip)))
            drawn = self.growth.random_toughness
            if drawn:
                # Gc drawn per edge: the speed from the Gc of the edge ahead along the heading.
                heading, mode = self._heading(tip, j)
                ahead = step_ahead(self.shell, tip.vertex, heading)
                speed = self.growth.speed(j, None if ahead is None else self._edge_gc(tip.vertex, ahead[0]))
            else:
                speed = self.growth.speed(j)
            if speed == 0.0:
                continue
            tip.pending += speed * GROWTH_CHECK * dt
            if not drawn:
                heading, mode = self._heading(tip, j)
            while tip.active:
                ahead = step_ahead(self.shell, tip.vertex, heading)
                if ahead is None:
                    tip.active = False
                    break
                if tip.pending < ahead[1]:
                    break
                self._replace_shell(align_ahead(self.shell, tip.vertex, heading, self._thinnest), dt)
                vertex, _ = step_ahead(self.shell, tip.vertex, heading)
                if drawn and not j >= self._edge_gc(tip.vertex, vertex):
                    # The edge to cut (the next one, or the one the move turned) is tougher than J: the tip stops there.
                    tip.pending = 0.0
                    break
                through = self._cut(tip.vertex, vertex, dt)
                direction = self.shell.mesh.X[vertex] - self.shell.mesh.X[tip.vertex]
                length = float(np.linalg.norm(direction))  # the move may have shortened it
                tip.pending -= length
                tip.extension += length
                tip.vertex, tip.direction, tip.aim = vertex, direction / length, heading
                self.advances.append(Advance(self.time, self.shell.mesh.X[vertex].copy(), k, mode))
                tip.active = not through

    def _heading(self, tip: CrackTip, j: float) -> tuple[np.ndarray, int]:
        """The direction the tip grows in: its direction turned by the growth law's kink criterion
        (maximum tangential stress or energy release rate) for its K_I, K_II and K_III
        (jintegral.stress_intensity), in the surface's tangent plane; right after a kink, where
        no crack-face pair measures the new branch's mixity (jintegral.branch_pairs), the
        direction the criterion chose last (a cut follows the mesh's edge nearest to it, up to
        ~20 deg off where the mesh cannot be turned: aiming on keeps such a step from steering
        the path). Also the failure mode of that mixity (the shear modes' share, (K_II^2 +
        K_III^2) / K^2)."""
        k1, k2, k3 = stress_intensity(self.shell, self.nodes.x, tip.vertex, tip.direction, j)
        normal = vertex_normal(self.shell.mesh, tip.vertex)
        mode = failure_mode((k2 * k2 + k3 * k3) / (k1 * k1 + k2 * k2 + k3 * k3))
        if tip.aim is not None and not branch_pairs(self.shell.mesh, tip.vertex, tip.direction):
            aim = tip.aim - (tip.aim @ normal) * normal
            return aim / np.linalg.norm(aim), mode
        angle = KINK_CRITERIA[self.growth.kink](k1, k2, k3)
        side = np.cross(normal, tip.direction)
        return np.cos(angle) * tip.direction + np.sin(angle) * side, mode

    def _edge_gc(self, a: int, b: int) -> float:
        """Gc (J/m^2) of the edge (a, b) of the current mesh (drawn: growth.GrowthLaw.edge_toughness)."""
        mesh = self.shell.mesh
        return float(self.growth.edge_toughness(mesh, edge_between(mesh, a, b))[0])

    def _cut(self, a: int, b: int, dt: float) -> bool:
        """Cut the edge (a, b); True when that opened b (the crack reached a boundary)."""
        new, opened = cut_edge(self.shell, a, b)
        self._replace_shell(new, dt)
        return b in opened

    def _replace_shell(self, new: Shell | None, dt: float) -> None:
        """Continue with `new` (None: keep the shell) and book what the change did at once in
        `energy.damage` (the shell's fracture dissipation): the strain energy (a new free edge's condensed bending, a moved
        vertex's triangles) and the kinetic energy (a moved vertex's mass and interpolated
        velocity, the cut edge's mid-edge rotation)."""
        if new is None:
            return
        before = self._jump_energy(dt)
        self.shell = new
        self._extensions = {}  # they belong to the shell before the cut
        self.fracture_energy += before - self._jump_energy(dt)

    def _jump_energy(self, dt: float) -> float:
        n, e = self.nodes, self.shell.edges
        return sum(self.shell.strain_energies(n.x - 0.5 * dt * n.v, e.xi - 0.5 * dt * e.xi_rate)) + self.kinetic_energy()

    @property
    def broken(self) -> int:
        """Edges cut by crack growth."""
        return len(self.advances)

    def kinetic_energy(self) -> float:
        """Of the vertices and of the mid-edge rotations."""
        n, e = self.nodes, self.shell.edges
        return float(0.5 * np.sum(n.mass * np.einsum("ij,ij->i", n.v, n.v)) + 0.5 * np.sum(e.xi_inertia * e.xi_rate**2))

    def own_energies(self, dt: float) -> dict[str, float]:
        n = self.nodes
        e = self.shell.edges
        # Potentials at the mid-step positions (and rotations) pair with the half-step rates.
        membrane, bending = self.shell.strain_energies(n.x - 0.5 * dt * n.v, e.xi - 0.5 * dt * e.xi_rate)
        return {"membrane": membrane, "bending": bending, "damping": float(np.sum(e.xi_damping)),
                "damage": self.fracture_energy}

    def kinetic_to_strain(self) -> float:
        """Kinetic over strain energy now (inf with no strain energy): how static the sheet is."""
        n, e = self.nodes, self.shell.edges
        kinetic = self.kinetic_energy()
        strain = sum(self.shell.strain_energies(n.x, e.xi))
        return kinetic / strain if strain > 0.0 else (0.0 if kinetic == 0.0 else float("inf"))

    def _tip_j(self, tip: CrackTip) -> list[float]:
        X, external = self.shell.mesh.X, self.external_forces()
        return [j_integral(self.shell, self.nodes.x, X[tip.vertex], tip.direction, *ring, external=external,
                           extension=self._extension(tip, ring))
                for ring in self.rings]

    def j_values(self) -> np.ndarray:
        """J (J/m^2) at each tip (rows) over each ring (columns), at the current positions."""
        return np.array([self._tip_j(tip) for tip in self.tips]).reshape(len(self.tips), len(self.rings))

    def external_forces(self) -> np.ndarray:
        """(n, 3) N: the pressures' and edge loads' nodal forces now (the pressures as the last
        step's face pass left them)."""
        n, faces, tri = self.nodes, self.shell.faces, self.shell.mesh.tri
        lf = self.load_factor
        forces = np.interp(self.time, lf.times[:lf.n], lf.values[:lf.n]) * n.load
        loaded = faces.pressure >= 0
        for c in range(3):
            np.add.at(forces, tri[loaded, c], faces.pressure_force[loaded])
        return forces

    def edge_load_columns(self) -> dict[str, float]:
        """The edge loads as one load-displacement pair (none without edge loads): edge_load.force,
        the magnitude of all the applied edge forces summed (N), and edge_load.displacement, the
        loaded vertices' displacement along their loads weighted by those (m), so that force x
        displacement rate is the edge loads' power. A plate pulled by both ends reads the sum of
        both ends' forces against half its elongation."""
        load = self.nodes.load
        total = float(np.sum(np.linalg.norm(load, axis=1)))
        if total == 0.0:
            return {}
        lf = self.load_factor
        factor = float(np.interp(self.time, lf.times[:lf.n], lf.values[:lf.n]))
        return {EDGE_LOAD_FORCE: factor * total,
                EDGE_LOAD_DISPLACEMENT: float(np.sum(load * (self.nodes.x - self.shell.mesh.X))) / total}

    def _tip_g(self, tip: CrackTip) -> list[float]:
        external = self.external_forces()
        return [self._extension(tip, ring).release_rate(self.shell, self.nodes.x, external) for ring in self.rings]

    def _extension(self, tip: CrackTip, ring, direction: np.ndarray | None = None) -> VirtualExtension:
        """The tip's virtual crack extension over `ring` along `direction` (default the crack's),
        built once per shell, tip and direction."""
        direction = tip.direction if direction is None else direction
        key = (tip.vertex, tuple(direction), ring)
        if key not in self._extensions:
            self._extensions[key] = VirtualExtension(self.shell, self.shell.mesh.X[tip.vertex], direction, *ring)
        return self._extensions[key]

    def _across(self, tip: CrackTip) -> np.ndarray:
        """The unit vector m = n x d in the surface's tangent plane at the tip, across the crack."""
        m = np.cross(vertex_normal(self.shell.mesh, tip.vertex), tip.direction)
        return m / np.linalg.norm(m)

    def configurational_forces(self) -> np.ndarray:
        """(tips, 2) J/m^2: each tip's configurational force in the surface, the mean over the
        rings of G by virtual extension along the crack (= J) and across it (along m = n x d:
        positive where the tip is driven towards m, the way a kink by a positive angle turns)."""
        external = self.external_forces()
        out = np.zeros((len(self.tips), 2))
        for k, tip in enumerate(self.tips):
            for c, direction in enumerate((tip.direction, self._across(tip))):
                out[k, c] = np.mean([self._extension(tip, ring, direction).release_rate(self.shell, self.nodes.x, external)
                                     for ring in self.rings])
        return out

    def g_values(self) -> np.ndarray:
        """G (J/m^2) by virtual crack extension at each tip (rows) over each ring (columns), at the
        current positions: bending and pressure included (jintegral.energy_release_rate)."""
        return np.array([self._tip_g(tip) for tip in self.tips]).reshape(len(self.tips), len(self.rings))

    def history_columns(self, dt: float) -> dict[str, float]:
        """The edge loads', and J, G and the extension of each tip of the set-up."""
        row = self.edge_load_columns()
        for k, tip in enumerate(self.tips[:self._history_tips]):
            row[f"j.tip{k}"] = float(np.mean(self._tip_j(tip)))
            row[f"g.tip{k}"] = float(np.mean(self._tip_g(tip)))
            row[f"crack.tip{k}"] = tip.extension
        return row

    def new_events(self):
        """Each cut (a tip moving one edge) once: its time, the new tip's reference position,
        the mode of the tip's mixity, the tip's number as the id."""
        new = self.advances[self._reported:]
        self._reported = len(self.advances)
        return (np.array([a.time for a in new]), np.array([a.position for a in new]).reshape(-1, 3),
                [MODE_NAMES[a.mode] for a in new], np.array([a.tip for a in new], dtype=np.int64))

    def fields(self) -> dict:
        """The mid-surface's triangles with, per triangle, the membrane strain and force and the
        bending moment (global xx yy zz xy yz xz) and the bending energy per area; the crack
        faces as lines (cell_kind 1: both faces of every cut edge, pre-cracks and grown) with the
        crack's opening there, the distance between the two faces' midpoints (m); per vertex
        the displacement, velocity. With [material.random]: per triangle `toughness`, the mean of
        its three edges' Gc, and per vertex `strength`, the nucleation strength at it."""
        n, mesh = self.nodes, self.shell.mesh
        strain, force = self.shell.membrane_state(n.x)
        pairs = mesh.crack_faces()
        middle = 0.5 * (n.x[mesh.edge[pairs, 0]] + n.x[mesh.edge[pairs, 1]])  # (p, 2, 3)
        opening = np.linalg.norm(middle[:, 0] - middle[:, 1], axis=1)
        drawn_faces, drawn_points = self._drawn_values()
        blocks = [("triangle", mesh.tri, {"thickness": mesh.thickness.copy(), "region": mesh.region.copy(),
                                          "membrane_strain": strain, "membrane_force": force,
                                          "bending_moment": self.shell.bending_moment_state(n.x),
                                          "bending_energy": bending_density(self.shell, n.x), **drawn_faces})]
        if len(pairs):
            blocks.append(("line", mesh.edge[pairs.ravel()], {"crack_opening": np.repeat(opening, 2)}))
        return {
            "points": n.x,
            "point_data": {"displacement": n.x - mesh.X, "velocity": n.v, **drawn_points},
            "component_names": {"membrane_strain": STRESS_COMPONENTS, "membrane_force": STRESS_COMPONENTS,
                                "bending_moment": STRESS_COMPONENTS},
            "blocks": blocks,
        }

    def _drawn_values(self) -> tuple[dict, dict]:
        """The drawn properties on the current mesh: ({"toughness": per triangle, the mean of its
        edges' Gc}, {"strength": per vertex}), each where some material draws it."""
        growth, mesh = self.growth, self.shell.mesh
        if growth is None or growth.sites is None:
            return {}, {}
        faces, points = {}, {}
        if growth.random_toughness:
            faces["toughness"] = growth.edge_toughness(mesh, np.arange(len(mesh.edge)))[mesh.face_edge].mean(axis=1)
        if "strength" in growth.sites.fields:
            points["strength"] = growth.vertex_strength(mesh, np.arange(len(mesh.X)))
        return faces, points

    def describe(self) -> str:
        return f"{len(self.shell.mesh.tri):,} triangles, {len(self.shell.mesh.X):,} vertices, {len(self.tips)} crack tips"

    def bounds(self):
        X = self.shell.mesh.X
        return X.min(axis=0), X.max(axis=0)

    def own_summary(self) -> dict:
        j, g = self.j_values(), self.g_values()
        out = {
            "triangles": len(self.shell.mesh.tri),
            "nodes": len(self.shell.mesh.X),
            "elements": len(self.shell.mesh.tri),
            "element_size": self.shell.mesh.element_size(),
            "crack_tips": [self.shell.mesh.X[tip.vertex].tolist() for tip in self.tips],
            "crack_extension": [tip.extension for tip in self.tips],
            "j_rings": [list(r) for r in self.rings],
            "j_tips": j.tolist(),
            "j_integral": float(np.mean(j[0])) if len(self.tips) else None,
            "g_tips": g.tolist(),
            "energy_release_rate": float(np.mean(g[0])) if len(self.tips) else None,
            "random_properties": self.random_properties,
        }
        if self.tips:
            out["configurational_force"] = self.configurational_forces().tolist()
            ratio = self.kinetic_to_strain()
            out["kinetic_to_strain"] = ratio
            out["j_static"] = not ratio > STATIC_KINETIC
        if self.growth is not None and np.isfinite(self.growth.strength):
            out["nucleations"] = list(self.nucleations)
        if self.growth is not None:
            thickness = float(np.median(self.shell.mesh.thickness))
            out["griffith_energy"] = self.growth.toughness * thickness * sum(tip.extension for tip in self.tips)
            out["growth_start_time"] = self.advances[0].time if self.advances else None
        if self.j_bracket is not None:
            out["j_bracket"] = list(self.j_bracket)
        if self.j_reference is not None:
            out["j_reference"] = self.j_reference
            out["j_ratio"] = out["j_integral"] / self.j_reference if out["j_integral"] is not None else None
            out["g_ratio"] = (out["energy_release_rate"] / self.j_reference
                              if out["energy_release_rate"] is not None else None)
        return out

    def late_warnings(self, summary: dict) -> list[str]:
        return static_warning(summary["kinetic_to_strain"]) if self.tips else []

    def extra_plots(self, out_dir, history) -> None:
        """plots/crack_pattern.png redrawn with the pre-cracks and the paths the tips ran;
        plots/j_history.png: each tip's J and G over the run and the closed form."""
        out = Path(out_dir)
        grown = [np.array([start] + [a.position for a in self.advances if a.tip == k])
                 for k, start in enumerate(self._tip_starts)]
        plot_crack_pattern(out / "events.csv", self.bounds(), run_plot_path(out, "crack_pattern"),
                           paths=[("pre-crack", p) for p in self.pre_cracks] + [("grown", p) for p in grown if len(p) > 1])
        if self.tips:
            plot_j_history(history, run_plot_path(out, "j_history"), self.j_reference)

"""The meshfree (EFG) particles behind the driver's Simulation protocol (solver.simulation)."""

from __future__ import annotations

import math

import numpy as np

from ..analysis.fragments import find_fragments
from ..analysis.perforation import measure_perforation
from ..io.fields import STRESS_COMPONENTS
from ..loading.tools import TOOL_SPHERE, TOOL_SURFACE
from ..solver.failures import MODE_TENSION
from ..solver.simulation import SimulationBase
from .fracture import FRACTURE_CHECK
from .kernels import PairContact, advance, strain_energies
from .material import MODEL, THERMO


# A compiled step above this fraction of the estimated stable step after a fracture rebuild is
# sub-stepped (_follow_stable_step): the estimate (Gershgorin's bound times its set-up ratio to
# Lanczos) is not exact, so a tenth is kept; below it the set-up's safety margin is left to absorb
# the change, as it absorbs new contacts.
SUBSTEP_ABOVE = 0.9

# Particles nearest the impact axis whose local spacing a graded plate's perforation is measured in.
PERFORATION_SPACING_SAMPLE = 30


class MeshfreeSimulation(SimulationBase):
    method = "meshfree"

    def __init__(self, particles, links, columns, law, tools, tool_names, support_radius, stable_dt, wave_transit, gravity,
                 damping, plate, breaking, pressed, pressures, contact=None, body_start=None, material_names=None):
        self._start_clock_and_tools(tools, tool_names)
        self.particles, self.links, self.law = particles, links, law
        self.body = particles
        # The lines through the wall and each particle's Gauss points on them (thickness.py).
        self.columns = columns
        self.support_radius = float(support_radius)
        self.stable_dt = float(stable_dt)
        self.wave_transit = float(wave_transit)
        self.gravity = np.asarray(gravity, dtype=float)
        self.damping = float(damping)
        self.plate = plate
        # Link breaking (fracture.LinkBreaking), or None without a fracture stress.
        self.breaking = breaking
        # The wall faces the pressures load (kernels.PressedFaces; build.pressure_arrays, empty
        # without) and the pressures' histories (loading.arrays.HistoryTable).
        self.pressed, self.pressures = pressed, pressures
        # The particle contact (contact.ParticleContact) between bodies and across cracks, or None.
        self.contact = contact
        # The first particle of each body (the specimen's 0, then build.MeshfreeBody's) and the end.
        self.body_start = np.array([0, len(particles.x)] if body_start is None else body_start, dtype=np.int64)
        # The name of each row of the law table (particles.material): the specimen's materials
        # ([material] or [materials.NAME] in order), then the bodies'.
        self.material_names = list(material_names or [f"material{i}" for i in range(len(law))])
        # The specimen's materials (the rows before the bodies'): several ones count failures each.
        self.specimen_materials = len(self.material_names) - (len(self.body_start) - 2)
        self._no_pairs = PairContact(np.zeros(len(particles.x) + 1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                     np.zeros(0), np.zeros(0), np.zeros((0, 3)))
        # One failure per particle (the particle where a crack plane was put).
        # The properties drawn per particle ([material.random], fracture.draw_thresholds): {property:
        # values on the specimen's particles}, and their statistics per material (summary.json); the
        # thresholds they set are the link breaking's (LinkBreaking.fracture_stress, failure_strain).
        self.drawn, self.random_properties = {}, None
        # Compiled steps per driver step: 1, until link breaking lowers the estimated stable step
        # to within SUBSTEP_ABOVE of the step in use (_follow_stable_step); the velocity span of
        # the next compiled step where the step changed.
        self.substeps = 1
        self._first_kick = -1.0
        # Energy present at t = 0 (an initial velocity) counts as work put in.
        self._initial_energy = self.kinetic_energy()

    def advance(self, n_steps: int, dt: float) -> None:
        # Fracture checks and the contact pairs' refresh at the step numbers that are multiples of FRACTURE_CHECK.
        self._advance_on_grid(n_steps, dt, None if self.breaking is None and self.contact is None else FRACTURE_CHECK,
                              self._compiled_steps, before=None if self.contact is None else self._refresh_contact,
                              after=None if self.breaking is None else self._check_fracture)

    def _compiled_steps(self, n: int, dt: float) -> None:
        pairs = self._no_pairs if self.contact is None else self.contact.pairs
        k = self.substeps
        advance(n * k, self.steps * k, dt / k, self.particles, self.links, self.columns, self.law, self.tools,
                self.pressed, self.pressures, pairs, self.gravity, self.damping, self._first_kick)
        self._first_kick = -1.0

    def sample(self, dt: float) -> dict[str, float]:
        # The energies pair the half-step velocities with the mid-step positions of the step
        # actually taken (sub-steps once link breaking stiffened the model).
        return super().sample(dt / self.substeps)

    def _refresh_contact(self, dt: float) -> None:
        self.contact.refresh(self.particles.x, self.particles.v, dt, FRACTURE_CHECK,
                             None if self.breaking is None else self.breaking.blocked)

    def _check_fracture(self, dt: float) -> None:
        if self.breaking.check(self, dt / self.substeps):
            self._follow_stable_step(dt)
            if self.contact is not None:
                self.contact.stale = True

    def _follow_stable_step(self, dt: float) -> None:
        """Sub-step where a rebuild lowered the estimated stable step (fracture.LinkBreaking
        .stable_estimate) to within SUBSTEP_ABOVE of the step in use: k compiled steps of dt / k
        per driver step, k the least that restores the set-up's margin (dt / stable_dt, the
        run's safety) on the new estimate, never fewer than before. Decided at the fracture
        checks' fixed step numbers, so a run stays the same whatever its split into calls, its
        thread count or a resume; the driver's step, rows and times do not change. The first
        short step's velocity update spans the mean of the two steps (kernels.advance)."""
        estimate = self.breaking.stable_estimate
        if estimate is None or dt / self.substeps <= SUBSTEP_ABOVE * estimate:
            return
        k = max(self.substeps + 1, math.ceil(self.stable_dt / estimate))
        self._first_kick = 0.5 * (dt / self.substeps + dt / k)
        note = (f"link breaking at t = {self.time:.4g} s lowered the estimated stable step to {estimate:.3g} s, "
                f"{estimate / self.stable_dt:.2f} x the set-up's: each step of {dt:.3g} s is now {k} sub-steps "
                "(history.csv: dt)")
        self.substeps = k
        self.warnings.append(note)

    @property
    def broken(self) -> int:
        """Links removed by fracture (pairs {I, J} of distinct particles)."""
        return 0 if self.breaking is None else self.breaking.broken_links

    def strain_energies(self, x, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """Per particle, the elastic and the stabilisation energy (J) at positions x; with `rows`,
        of those particles only (in that order)."""
        p, s = self.particles, self.links
        which = np.arange(len(x)) if rows is None else np.asarray(rows, dtype=np.int64)
        elastic = np.zeros(len(x))
        stab = np.zeros(len(x))
        strain_energies(which, np.ascontiguousarray(x), p.volume, p.plastic, p.thermal, p.stab_k, s, self.columns,
                        self.law, p.material, elastic, stab)
        return (elastic, stab) if rows is None else (elastic[which], stab[which])

    def own_energies(self, dt: float) -> dict[str, float]:
        p = self.particles
        # Potentials at the mid-step positions pair with the half-step velocities.
        x_mid = p.x - 0.5 * dt * p.v
        elastic, stab = self.strain_energies(x_mid)
        thermal = {}
        if self.thermo:
            # The stored energy the temperature changes released at fixed strain (thermal
            # expansion against the stress, the moduli's softening): mechanical work that left
            # the elastic store, booked as its own term.
            thermal = {"thermal": float(np.sum(p.volume * self.per_particle(p.thermal[:, 1])))}
        return {
            "elastic": float(np.sum(elastic)),
            "stabilisation": float(np.sum(stab)),
            "plastic": float(np.sum(p.w_plastic)),
            "contact": 0.0 if self.contact is None else self.contact.energy(x_mid),  # between bodies, across cracks
            "damage": 0.0 if self.breaking is None else self.breaking.damage,
            **thermal,
        }

    def failure_state(self):
        """Particle failures (a crack plane through the particle, mode tension)."""
        n = len(self.particles.x)
        b = self.breaking
        if b is None:
            return np.zeros(n, dtype=bool), np.zeros(n), np.zeros(n, dtype=np.int8)
        return b.failed, b.fail_time, np.where(b.failed, MODE_TENSION, 0).astype(np.int8)

    def failure_positions(self, ids) -> np.ndarray:
        return self.particles.X[ids]

    def cauchy_stress(self) -> np.ndarray:
        """Per particle, the Cauchy stress sigma = F S F^T / det F from the last step (n, 6), in the
        order xx yy zz xy yz xz, Pa."""
        p = self.particles
        F = p.deformation.reshape(-1, 3, 3)
        s = p.stress
        S = np.stack([s[:, [0, 3, 5]], s[:, [3, 1, 4]], s[:, [5, 4, 2]]], axis=1)
        sigma = np.einsum("nab,nbc,ndc->nad", F, S, F) / np.linalg.det(F)[:, None, None]
        return np.stack([sigma[:, 0, 0], sigma[:, 1, 1], sigma[:, 2, 2], sigma[:, 0, 1], sigma[:, 1, 2],
                         sigma[:, 0, 2]], axis=1)

    def fields(self) -> dict:
        """The particles as points (vertex cells) with their displacement (of the nodal
        parameters), velocity, Cauchy stress, equivalent plastic strain and the fracture state:
        `failed` (1 where a crack plane passes through the particle), `crack_normal` (its normal
        in the current configuration, F^-T N normalised; 0 elsewhere: glyphs show the crack) and
        `detached` (1: a free particle, all its links removed), `material` (its row of the law
        table: summary.json's material_names); with the thermo law the `temperature` (K; nan on
        particles of a J2 material); each property drawn per particle ([material.random]) by its
        name (nan on the particles of other bodies, which do not fracture)."""
        p = self.particles
        n = len(p.x)
        b = self.breaking
        failed = np.zeros(n) if b is None else b.failed.astype(float)
        detached = np.zeros(n) if b is None else b.detached.astype(float)
        normal = np.zeros((n, 3))
        if b is not None and b.failed.any():
            ids = np.flatnonzero(b.failed)
            F = p.deformation[ids].reshape(-1, 3, 3)
            current = np.linalg.solve(np.transpose(F, (0, 2, 1)), b.normal[ids][:, :, None])[:, :, 0]
            normal[ids] = current / np.linalg.norm(current, axis=1)[:, None]
        return {
            "points": p.x,
            "point_data": {"displacement": p.x - p.X, "velocity": p.v, "stress": self.cauchy_stress(),
                           "plastic_strain": self.per_particle(p.eq_plastic), "failed": failed, "crack_normal": normal,
                           "detached": detached, "material": p.material.copy(), **self._temperature(),
                           **self._drawn_values()},
            "component_names": {"stress": STRESS_COMPONENTS},
            "blocks": [("vertex", np.arange(n, dtype=np.int64)[:, None], {})],
        }

    def _drawn_values(self) -> dict:
        """Each property drawn per particle, on every particle (nan past the specimen's)."""
        out = {}
        for name, values in sorted(self.drawn.items()):
            column = np.full(len(self.particles.x), np.nan)
            column[:len(values)] = values
            out[name] = column
        return out

    @property
    def thermo(self) -> bool:
        """The thermo-visco-plastic law (material.py): particles carry a temperature."""
        return bool(np.any(self.law[:, MODEL] == THERMO))

    def _temperature(self) -> dict:
        """The VTU's `temperature` (K) for the thermo law, nan on the particles of a J2 material
        (no temperature); nothing without a thermo material."""
        if not self.thermo:
            return {}
        return {"temperature": np.where(self._thermo_particles(), self.per_particle(self.particles.thermal[:, 0]),
                                        np.nan)}

    def _thermo_particles(self) -> np.ndarray:
        """Per particle, whether its law is the thermo law."""
        return self.law[self.particles.material, MODEL] == THERMO

    @staticmethod
    def per_particle(values: np.ndarray) -> np.ndarray:
        """The mean over each particle's two Gauss points of a state (rows 2 I, 2 I + 1)."""
        return 0.5 * (values[0::2] + values[1::2])

    def describe(self) -> str:
        n = len(self.particles.x)
        return f"{n:,} particles, {len(self.links.neighbour) / n:.0f} links each"

    def bounds(self):
        return self.particles.X.min(axis=0), self.particles.X.max(axis=0)

    def own_summary(self) -> dict:
        p = self.particles
        n = len(p.x)
        return {
            "particles": n,
            "links": int(len(self.links.neighbour) - n),  # without each particle's link to itself
            "broken_links": int(self.broken),
            "precrack_links": 0 if self.breaking is None else self.breaking.precut_pairs,
            "failed_particles": 0 if self.breaking is None else int(self.breaking.failed.sum()),
            "detached_particles": 0 if self.breaking is None else int(self.breaking.detached.sum()),
            "layers": int(self.plate.layers),
            "support_radius": self.support_radius,
            "max_plastic_strain": float(np.max(self.per_particle(p.eq_plastic), initial=0.0)),
            **({"max_temperature": float(np.max(self.per_particle(p.thermal[:, 0])[self._thermo_particles()]))}
               if self.thermo else {}),
            **self.perforation(),
            **self.bodies(),
            "random_properties": self.random_properties,
            "material_names": self.material_names,
        }

    @property
    def several_materials(self) -> bool:
        """Several materials in the specimen (the bodies' rows do not count: they do not fail)."""
        return self.specimen_materials > 1

    def failure_materials(self, ids):
        """A particle's failure is in its own material, on both sides."""
        material = self.particles.material[ids]
        return material, material

    def pieces(self) -> np.ndarray:
        """Per particle, the piece it belongs to (particles joined by links that fracture has not
        removed), 0 the heaviest (analysis.fragments)."""
        p, b = self.particles, self.breaking
        n = len(p.x)
        if b is None:
            return np.zeros(n, dtype=np.int64)
        intact = (b.row != self.links.neighbour) & ~np.isin(b.key, b.blocked)
        pairs = np.stack([b.row[intact], self.links.neighbour[intact]], axis=1)
        return find_fragments(n, pairs, p.mass, p.v).labels

    def perforation(self) -> dict:
        """The hole's diameter and the petals (analysis.perforation) of a plate that can fracture,
        struck along its normal by a sphere or surface tool (a projectile; the first such: its
        path is the impact axis) or by a second body (its centre of mass); nothing for other
        set-ups."""
        plate, t = self.plate, self.tools
        if plate.thickness_axis is None or self.breaking is None:
            return {}
        normal = np.eye(3)[plate.thickness_axis]
        # A surface strikes when it moves (a projectile); a fixed one is a die or a support.
        moving = [t.mass[j] > 0.0 or np.any(t.speeds[j, :t.n[j]] != 0.0) for j in range(len(t.kind))]
        strikers = [j for j in range(len(t.kind)) if abs(t.direction[j] @ normal) > 0.9 and
                    (t.kind[j] == TOOL_SPHERE or (t.kind[j] == TOOL_SURFACE and moving[j]))]
        p, b = self.particles, self.breaking
        if len(self.body_start) > 2:
            lo, hi = self.body_start[1], self.body_start[2]
            axis_point = p.mass[lo:hi] @ p.x[lo:hi] / np.sum(p.mass[lo:hi])
        elif strikers:
            j = strikers[0]  # a sphere's centre, a surface's area centroid (loading.arrays)
            axis_point = t.geom[j, :3] if t.kind[j] == TOOL_SPHERE else t.geom[j, 5:8]
        else:
            return {}
        own = slice(0, self.body_start[1])
        if plate.local_spacing is None:
            spacing = float(np.max(np.delete(plate.spacing, plate.thickness_axis)))
        else:  # a graded plate: the median edge around the particles nearest the impact axis
            off_axis = p.X[own] - axis_point
            off_axis -= np.outer(off_axis @ normal, normal)
            nearest = np.argsort(np.einsum("ij,ij->i", off_axis, off_axis), kind="stable")[:PERFORATION_SPACING_SAMPLE]
            spacing = float(np.median(plate.local_spacing[nearest, 1]))
        found = measure_perforation(p.X[own], p.x[own], self.pieces()[own], b.failed[own], b.normal[own],
                                    axis_point, normal, spacing)
        return found.summary()

    def bodies(self) -> dict:
        """The bodies after the specimen (build.MeshfreeBody): each one's particles, mass (kg) and
        the velocity of its centre of mass (m/s); and the contact's pair-list builds."""
        p, first = self.particles, self.body_start
        if len(first) <= 2:
            return {}
        rows = []
        for lo, hi in zip(first[1:-1], first[2:]):
            m = float(np.sum(p.mass[lo:hi]))
            v = p.mass[lo:hi] @ p.v[lo:hi] / m
            rows.append({"particles": int(hi - lo), "mass": m, "velocity": v.tolist(),
                         "speed": float(np.linalg.norm(v))})
        return {"bodies": rows, "contact_list_builds": self.contact.builds}

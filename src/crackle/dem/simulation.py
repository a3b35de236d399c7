"""The bonded-particle DEM behind the driver's Simulation protocol (solver.simulation); its measurements are in probes.py."""

from __future__ import annotations

import math

import numpy as np

from ..io.fields import STRESS_COMPONENTS
from ..solver.simulation import SimulationBase
from .kernels import BONDED, GONE, TRANSFER_FORCE, TRANSFER_LEVER_A, TRANSFER_LEVER_B, advance
from .membrane import no_membrane
from .model import with_contacts


# Steps between two checks of whether the contact list must be rebuilt: a fixed grid of steps, so
# that a run's state does not depend on how its steps are split into advance calls.
CONTACT_CHECK = 20


class DemSimulation(SimulationBase):
    method = "dem"

    def __init__(self, particles, inter, n_bonds, law, tools, tool_names, stable_dt, gravity, damping,
                 skin, loaded_area=None):
        self._start_clock_and_tools(tools, tool_names)
        self.particles, self.inter, self.n_bonds, self.law = particles, inter, n_bonds, law
        self.body = particles
        self.stable_dt = stable_dt
        self.proven_dt = stable_dt  # the bound at set-up; build_dem_simulation sets it
        self.proven_dt_how = ("a Gershgorin bound over each particle's bonds, contacts and tools, translation and "
                              "spin: docs/user-guide-dem.md")
        radius = particles.radius
        self.element_length = float(2.0 * np.mean(radius))
        self.wave_transit = float(2.0 * np.mean(radius) / math.sqrt(law.bond_modulus / np.mean(particles.mass / (
            4.0 / 3.0 * math.pi * radius**3))))
        self.gravity = np.asarray(gravity, float)
        self.damping = float(damping)
        self.skin = float(skin)
        self.loaded_area = loaded_area  # m^2, normal to the platens: peak_stress = peak force / it
        # m^3, the region the packing fills (set-up sets the specimen's; else the particles' box)
        self.sample_volume = float(np.prod(np.ptp(particles.x, axis=0) + 2.0 * np.mean(particles.radius)))
        self.x0 = particles.x.copy()
        # Bond strengths drawn per bond ([material.random]): {property: values}, and their statistics
        self.drawn, self.random_properties = {}, None
        self._x_listed = particles.x.copy()  # positions when the contact list was last built
        self._dropped_friction = 0.0  # friction of contacts no longer listed (J)
        # [[pressures]]: the membrane on the loaded faces (dem.membrane), set by set_membrane
        self.membrane = None
        self._membrane_args = no_membrane(len(radius))
        self._relist()
        # Energy present at t = 0 (initial velocities; an initial stress: start_stored) counts as work put in.
        self._initial_stored = None
        self._initial_energy = self.kinetic_energy()

    def start_stored(self) -> None:
        """The bonds have been preloaded ([initial_stress], dem.prestress): their energy at t = 0
        counts as work put in, as the kinetic energy of initial velocities does."""
        self._initial_stored = self.interaction_energy(0.0)
        self._initial_energy = self.kinetic_energy() + self._initial_stored

    # -- stepping ----------------------------------------------------------------------------
    def advance(self, n_steps: int, dt: float) -> None:
        self._advance_on_grid(n_steps, dt, CONTACT_CHECK, self._compiled_steps, before=self._check_contacts)

    def _compiled_steps(self, n: int, dt: float) -> None:
        advance(n, self.steps, dt, self.particles, self.inter, self.tools, self.gravity, self.damping,
                *self._membrane_args)

    def set_membrane(self, membrane) -> None:
        """Pressures on faces of the sample (a dem.membrane.Membrane), from the next step on."""
        self.membrane = membrane
        self._membrane_args = (membrane.area, membrane.moment, membrane.x_raster, membrane.histories)

    def _check_contacts(self, dt: float) -> None:
        if self._contacts_may_change(dt):
            self._relist()
        if self.membrane is not None:
            self.membrane.update(self.particles.x)

    def _contacts_may_change(self, dt: float) -> bool:
        """Whether a pair not listed could touch before the next check: some particle has moved,
        or could move within the next CONTACT_CHECK steps (at twice its speed), half the skin."""
        p = self.particles
        moved = float(np.sqrt(np.max(np.sum((p.x - self._x_listed) ** 2, axis=1))))
        speed = float(np.sqrt(np.max(np.sum(p.v**2, axis=1))))
        return moved + 2.0 * speed * CONTACT_CHECK * dt > 0.5 * self.skin

    def _relist(self) -> None:
        self._dropped_friction += float(np.sum(self.inter.e_friction[self.n_bonds:]))
        self.inter = with_contacts(self.particles, self.law, self.inter, self.n_bonds, self.skin)
        self.inter.e_friction[self.n_bonds:] = 0.0
        self._x_listed = self.particles.x.copy()

    def state_is_finite(self) -> bool:
        return super().state_is_finite() and bool(np.isfinite(self.particles.spin).all())

    # -- results -------------------------------------------------------------------------------
    def failed_bonds(self) -> np.ndarray:
        """Which bonds have failed (a joint never does)."""
        return np.isfinite(self.inter.fail_time[: self.n_bonds])

    def failure_state(self):
        n = self.n_bonds
        return self.failed_bonds(), self.inter.fail_time[:n], self.inter.fail_mode[:n]

    def failure_positions(self, ids) -> np.ndarray:
        return 0.5 * (self.x0[self.inter.a[ids]] + self.x0[self.inter.b[ids]])

    def broken_by_mode(self) -> dict[str, int]:
        from ..solver.failures import MODE_NAMES

        modes = self.inter.fail_mode[: self.n_bonds][self.failed_bonds()]
        return {MODE_NAMES[m]: int(np.count_nonzero(modes == m)) for m in np.unique(modes)}

    def interaction_energy(self, dt: float) -> float:
        """Elastic energy of the live interactions at the mid-step positions x - v dt/2 (which
        pair with the half-step velocities): kn un^2 / 2 (compression only once not bonded) and
        |Fs|^2 / (2 kt) with the shear force carried half a step on."""
        p, s = self.particles, self.inter
        live = s.state != GONE
        a, b = s.a[live], s.b[live]
        x_mid = p.x - 0.5 * dt * p.v
        d = x_mid[b] - x_mid[a]
        dist = np.linalg.norm(d, axis=1)
        n = d / dist[:, None]
        un = s.d0[live] - dist
        ra, rb = p.radius[a], p.radius[b]
        la = (dist * ra / (ra + rb))[:, None]
        lb = dist[:, None] - la
        rel = p.v[b] - p.v[a] - np.cross(lb * p.spin[b] + la * p.spin[a], n)
        # A joint: along its flaw's normal, its incremental un carried half a step on, dilatancy.
        joint = s.joint[live]
        at_joint = joint >= 0
        jn = s.joint_normal[joint[at_joint]]
        n[at_joint] = jn
        un[at_joint] = (s.joint_un[joint[at_joint]] - 0.5 * dt * np.sum(rel[at_joint] * jn, axis=1)
                        + s.joint_tan_psi[joint[at_joint]] * s.joint_slip[joint[at_joint]])
        bonded = s.state[live] == BONDED
        acting = bonded | (un >= 0.0)
        kn, kt = s.kn[live], s.kt[live]
        rel -= np.sum(rel * n, axis=1)[:, None] * n
        shear = s.shear[live] - 0.5 * dt * kt[:, None] * rel
        normal = np.where(acting, 0.5 * kn * un**2, 0.0)
        tangential = np.where(acting, 0.5 * np.sum(shear**2, axis=1) / kt, 0.0)
        return float(np.sum(normal) + np.sum(tangential))

    def kinetic_energy(self) -> float:
        """Of translation and spin."""
        p = self.particles
        return float(0.5 * np.sum(p.mass * np.sum(p.v**2, axis=1)) + 0.5 * np.sum(p.inertia * np.sum(p.spin**2, axis=1)))

    def own_energies(self, dt: float) -> dict[str, float]:
        return {
            "elastic": self.interaction_energy(dt),
            "damage": float(np.sum(self.inter.e_damage)),
            # Friction of the listed pairs and of those dropped from the list (particles' own on the tools: shared).
            "friction": float(np.sum(self.inter.e_friction) + self._dropped_friction),
        }

    def particle_stress(self) -> np.ndarray:
        """Per particle, the stress tensor (1 / Vp) sum_c x_c (x) f_c (x_c from the centre to the
        contact point, f_c the force on the particle there), symmetrised, (n, 6) in the order xx
        yy zz xy yz xz. Pa, tension positive as crackle's other stresses: paper 003 eqs 7-8 with
        the sign of geomechanics (compression positive) turned. The membrane's forces (pressures on
        the faces, dem.membrane) count as contacts where each cell's force meets the sphere; the
        tools' do not."""
        p, s = self.particles, self.inter
        n = len(p.radius)
        live = s.state != GONE
        a, b = s.a[live], s.b[live]
        d = p.x[b] - p.x[a]
        dist = np.linalg.norm(d, axis=1)
        unit = d / dist[:, None]
        f_b = s.transfer[live, TRANSFER_FORCE:TRANSFER_FORCE + 3]
        la = s.transfer[live, TRANSFER_LEVER_A][:, None]
        lb = s.transfer[live, TRANSFER_LEVER_B][:, None]
        sigma = np.zeros((n, 3, 3))
        # On a: branch +la n, force -f_b; on b: branch -lb n, force +f_b. Both give -l n (x) f_b.
        np.add.at(sigma, a, -np.einsum("ki,kj->kij", la * unit, f_b))
        np.add.at(sigma, b, -np.einsum("ki,kj->kij", lb * unit, f_b))
        if self.membrane is not None:
            # The membrane's cells: d (x) f, d from the centre to where each cell's force acts.
            sigma += np.einsum("k,knij->nij", self.membrane.pressures(self.time), self.membrane.first)
        volume = 4.0 / 3.0 * math.pi * p.radius**3
        sigma /= volume[:, None, None]
        sym = 0.5 * (sigma + sigma.transpose(0, 2, 1))
        return np.stack([sym[:, 0, 0], sym[:, 1, 1], sym[:, 2, 2], sym[:, 0, 1], sym[:, 1, 2], sym[:, 0, 2]], axis=1)

    def homogenised_stress(self, cell: float | None = None, lower=None, upper=None, stress=None):
        """The particle stresses averaged on a grid of cubic cells (paper 003 appendix A, in 3D):
        per cell, the sum of Vp sigma_p of the particles whose centre lies in it over the cell's
        volume. `cell` (m): the cell size, default the mean particle diameter; one cell holding
        the whole sample gives the Love-Weber stress of the assembly. Returns (lower corner (3,),
        cell, stress (nx, ny, nz, 6) in the order xx yy zz xy yz xz, Pa, tension positive)."""
        p = self.particles
        cell = 2.0 * float(np.mean(p.radius)) if cell is None else float(cell)
        lo = (p.x - p.radius[:, None]).min(axis=0) if lower is None else np.asarray(lower, float)
        hi = (p.x + p.radius[:, None]).max(axis=0) if upper is None else np.asarray(upper, float)
        shape = np.maximum(1, np.ceil((hi - lo) / cell - 1e-9).astype(int))
        index = np.clip(np.floor((p.x - lo) / cell).astype(int), 0, shape - 1)
        flat = np.ravel_multi_index(index.T, shape)
        stress = self.particle_stress() if stress is None else stress  # given: particle_stress() of this state
        moment = stress * (4.0 / 3.0 * math.pi * p.radius**3)[:, None]
        grid = np.zeros((int(np.prod(shape)), 6))
        np.add.at(grid, flat, moment)
        return lo, cell, grid.reshape(*shape, 6) / cell**3

    def love_weber_stress(self) -> np.ndarray:
        """The assembly's stress (xx yy zz xy yz xz, Pa): the particles' internal moments over the
        sample's volume (the packing region), from the bonds and contacts between particles."""
        p = self.particles
        moment = self.particle_stress() * (4.0 / 3.0 * math.pi * p.radius**3)[:, None]
        return moment.sum(axis=0) / self.sample_volume

    def fields(self) -> dict:
        """The particles (points) with their bonds (lines, cell_kind 0), and the homogenised
        stress on its grid of cells one mean diameter wide (hexahedra, cell_kind 1; their corner
        points carry radius 0 and zero particle fields)."""
        p, s = self.particles, self.inter
        n = self.n_bonds
        stress = self.particle_stress()
        lo, cell, grid = self.homogenised_stress(stress=stress)
        corners, hexes = _grid_cells(lo, cell, grid.shape[:3])
        n_particles = len(p.x)
        hexes += n_particles

        def padded(values):
            values = np.asarray(values)
            return np.concatenate([values, np.zeros((len(corners), *values.shape[1:]), values.dtype)])

        normal, shear = self.bond_forces()
        return {
            "points": np.concatenate([p.x, corners]),
            "point_data": {
                "displacement": padded(p.x - self.x0), "velocity": padded(p.v), "spin": padded(p.spin),
                "radius": padded(p.radius), "stress": padded(stress), "material": padded(self.particle_material()),
                "id": np.concatenate([np.arange(n_particles), np.full(len(corners), -1)]),
            },
            "component_names": {"stress": STRESS_COMPONENTS, "homogenised_stress": STRESS_COMPONENTS},
            "blocks": [("line", np.stack([s.a[:n], s.b[:n]], axis=1),
                        {"intact": (s.state[:n] == BONDED).astype(np.int64), "state": s.state[:n].astype(np.int64),
                         "normal_force": normal, "shear_force": shear, **self.drawn}),
                       ("hexahedron", hexes, {"homogenised_stress": grid.reshape(-1, 6)})],
        }

    def particle_material(self) -> np.ndarray:
        """Each particle's material (its index in [materials]; 0 with one [material])."""
        return np.asarray(getattr(self.law, "group", np.zeros(len(self.particles.radius), dtype=np.int64)), np.int64)

    def failure_materials(self, ids):
        """The materials of the two particles of bonds `ids`."""
        group = self.particle_material()
        return group[self.inter.a[ids]], group[self.inter.b[ids]]

    def bond_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Per bond (the first n_bonds interactions), the force it carried in the last step: its
        normal component along the line of centres, tension positive, and the magnitude of the rest
        (N; 0 once the pair has parted). Coloured on the bond lines: the force chains a DEM user looks for."""
        p, s = self.particles, self.inter
        n = self.n_bonds
        d = p.x[s.b[:n]] - p.x[s.a[:n]]
        unit = d / np.linalg.norm(d, axis=1)[:, None]
        on_b = s.transfer[:n, TRANSFER_FORCE:TRANSFER_FORCE + 3]
        force = np.where((s.state[:n] == GONE)[:, None], 0.0, on_b)
        along = np.einsum("ij,ij->i", force, unit)
        # A stretched bond pulls b back towards a: a force on b against the unit vector is tension.
        return -along, np.linalg.norm(force - along[:, None] * unit, axis=1)

    def describe(self) -> str:
        return f"{len(self.particles.radius):,} particles, {self.n_bonds:,} bonds"

    def bounds(self):
        r = self.particles.radius[:, None]
        return (self.x0 - r).min(axis=0), (self.x0 + r).max(axis=0)

    def own_summary(self) -> dict:
        n = len(self.particles.radius)
        return {
            "particles": n,
            "bonds": self.n_bonds,
            "bonds_per_particle": 2.0 * self.n_bonds / n,
            "broken_by_mode": self.broken_by_mode(),
            "love_weber_stress": [float(v) for v in self.love_weber_stress()],
            "random_properties": self.random_properties,
            # [initial_stress]: the energy the preloaded bonds held at t = 0 (J), counted in the
            # audit's input
            "initial_stored_energy": self._initial_stored,
        }


def _grid_cells(lower, cell: float, shape) -> tuple[np.ndarray, np.ndarray]:
    """The corner points and the hexahedra (VTK order) of a grid of `shape` cubic cells from
    `lower`, the cells in C order of their (i, j, k) index as homogenised_stress gives them."""
    nx, ny, nz = (int(v) for v in shape)
    i, j, k = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    corners = np.asarray(lower, float) + cell * np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)
    node = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nx + 1, ny + 1, nz + 1)
    base = node[:nx, :ny, :nz]
    dx, dy, dz = (ny + 1) * (nz + 1), nz + 1, 1
    offsets = [0, dx, dx + dy, dy, dz, dx + dz, dx + dy + dz, dy + dz]
    hexes = base.reshape(-1, 1) + np.array(offsets)
    return corners, hexes.astype(np.int64)

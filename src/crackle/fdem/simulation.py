"""FDEM behind the driver's Simulation protocol (solver.simulation); its measurements are in probes.py."""

from __future__ import annotations

import numpy as np

from ..analysis import Fragments, find_fragments
from ..io.plots import plot_fragment_sizes, plot_time_steps, run_plot_path
from ..io.fields import STRESS_COMPONENTS
from ..solver.simulation import SimulationBase
from .contact import build_contact, contact_energy, empty_contact, find_candidates
from .kernels import advance, interface_energy, tet_energy_and_stress
from .topology import INTACT, PRECRACK
from .model import FdemModel


# Longest run of steps between two checks of the contact surface: new fracture faces take part in
# surface contact at most this many steps after they fail.
CONTACT_REFRESH_STEPS = 100
# Extrinsic insertion energy, as a fraction of the external work, above which the summary warns.
INSERTION_WARNING = 0.1


class FdemSimulation(SimulationBase):
    """Steps an FdemModel and reports histories, events and fields."""

    method = "fdem"
    HISTORY_UNITS = {"fragments": "1"}

    def __init__(self, model: FdemModel):
        self._start_clock_and_tools(model.tools, [t.name for t in model.tool_specs], model.warnings)
        self.model = model
        self.body = model.nodes
        self.material_names = [mat.name for mat in model.materials]
        self._tet_energy = np.zeros(model.n_tets)
        self._stress = np.zeros((model.n_tets, 6))
        self._cohesive = np.zeros(model.n_interfaces)
        self._contact = np.zeros(model.n_interfaces)
        self.contact = empty_contact(4 * model.n_tets, model.contact_penalty)
        self._contact_ref = None  # positions at the last broad phase
        self._contact_failed = -1
        self._next_refresh = 0  # step of the next contact refresh
        self.rebuilds = 0
        # The tied phase (fdem.time_step): while every extrinsic face is tied, one compiled step
        # per driver step of model.tied_substeps x the stable step; from the first insertion on,
        # that many compiled steps of the stable step each. tied_until: the time it ended.
        self.tied_phase = model.tied_substeps > 1
        self.tied_until: float | None = None
        self._first_kick = -1.0  # the velocity span of the next compiled step, where the step changed
        self._fragments: Fragments | None = None
        self._fragments_failed = -1
        # Energy present at t = 0 (initial velocities, an initial stress) counts as work put in.
        self._initial_stored = self.initial_stored_energy()
        self._initial_energy = self.kinetic_energy() + self._initial_stored

    def initial_stored_energy(self) -> float:
        """J: the energy the tets and interfaces (intact, and pre-cracks pressed) hold at t = 0
        under an initial stress (kernels.tet_energy_and_stress, fdem.prestress); 0 without one."""
        m = self.model
        if not len(m.tets.s0):
            return 0.0
        tet_energy_and_stress(m.x0, m.tets, self._tet_energy, self._stress)
        interface_energy(m.x0, m.ifs, self._cohesive, self._contact)
        return float(np.sum(self._tet_energy)) + float(np.sum(self._cohesive)) + float(np.sum(self._contact))

    # -- stepping ---------------------------------------------------------------------------
    @property
    def stable_dt(self) -> float:
        """The driver's step: the tied phase's where there is one (see advance)."""
        return self.model.stable_dt * self.model.tied_substeps

    @property
    def substeps(self) -> int:
        """Compiled steps per driver step now."""
        return 1 if self.tied_phase else self.model.tied_substeps

    @property
    def wave_transit(self) -> float:
        return self.model.wave_transit

    @property
    def element_length(self) -> float:
        return self.model.element_size

    def advance(self, n_steps: int, dt: float) -> None:
        """n_steps compiled steps, split where the contact candidate lists are refreshed. The
        refreshes follow their own schedule in steps, not the driver's chunks, so the state after
        a step does not depend on how often the history is sampled (nor on a resume)."""
        m = self.model
        end = self.steps + n_steps
        while self.steps < end:
            n = end - self.steps
            if m.contact_enabled:
                if self.steps >= self._next_refresh:
                    self._refresh_contact()
                    self._next_refresh = self.steps + self._refresh_interval(dt)
                n = min(n, self._next_refresh - self.steps)
            if self.tied_phase:
                # Stops after a step that inserted a face: the next ones need the stable step.
                done, inserted = advance(n, self.steps, dt, m.nodes, m.tets, m.ifs, self.contact, m.tools, m.pressures,
                                         m.controls, m.ties, -1.0, True)
                self.steps += int(done)
                if inserted:
                    self._end_tied_phase(dt)
                continue
            k = self.substeps
            advance(n * k, self.steps * k, dt / k, m.nodes, m.tets, m.ifs, self.contact, m.tools, m.pressures,
                    m.controls, m.ties, self._first_kick, False)
            self._first_kick = -1.0
            self.steps += n
        # Exact time of the step count, not an accumulated sum of dt.
        self.time = self.steps * dt

    def _end_tied_phase(self, dt: float) -> None:
        """From the first insertion on, sub-step: the velocity update of the first short step spans
        the mean of the two steps (kernels.advance)."""
        self.tied_phase = False
        self.tied_until = self.steps * dt
        self._first_kick = 0.5 * (dt + dt / self.substeps)

    def sample(self, dt: float) -> dict[str, float]:
        # The energies pair the half-step velocities with the mid-step positions of the step
        # actually taken (sub-steps after the tied phase).
        return super().sample(dt / self.substeps)

    def _refresh_interval(self, dt: float) -> int:
        """Steps to the next contact refresh: no node may move more than half the skin between two
        broad phases (the fastest node, allowing it to double its speed, sets it), and new fracture
        faces join the surface within CONTACT_REFRESH_STEPS."""
        m = self.model
        vmax = float(np.sqrt(np.max(np.einsum("ij,ij->i", m.nodes.v, m.nodes.v)))) if len(m.nodes.v) else 0.0
        if vmax == 0.0:
            return CONTACT_REFRESH_STEPS
        return min(CONTACT_REFRESH_STEPS, max(1, int(0.25 * m.contact_skin / (2.0 * vmax * dt))))

    def _refresh_contact(self) -> None:
        """Rebuild the surface after new failures, and the candidates once surface nodes moved
        half the skin since the last broad phase."""
        m = self.model
        failed = int(np.count_nonzero(m.ifs.state != INTACT))
        if self._contact_ref is None or failed != self._contact_failed:
            self.contact = build_contact(m, self.contact)
            self._contact_failed = failed
        else:
            d = m.nodes.x[self.contact.slot_node] - self._contact_ref
            if len(d) == 0 or np.max(np.einsum("ij,ij->i", d, d)) < (0.5 * m.contact_skin) ** 2:
                return
        self.contact = find_candidates(m.nodes.x, self.contact, m.contact_skin)
        self._contact_ref = m.nodes.x[self.contact.slot_node]
        self.rebuilds += 1

    # -- diagnostics --------------------------------------------------------------------------
    def describe(self) -> str:
        return f"{self.model.n_tets:,} tets, {self.model.n_interfaces:,} interfaces"

    def describe_point(self, g: int) -> str:
        """Node g's tet (as the user numbers it), its density over the material's (mass scaling),
        its principal stretches, its faces (failed, intact, outer) and the tool it touches."""
        m = self.model
        tet = g // 4
        material = m.materials[int(m.tet_material[tet])]
        density = 4.0 * m.nodes.mass[g] / m.tets.vol[tet]
        x0 = m.x0[4 * tet:4 * tet + 4]
        x = m.nodes.x[4 * tet:4 * tet + 4]
        stretch = np.linalg.svd((x[1:] - x[0]).T @ np.linalg.inv((x0[1:] - x0[0]).T), compute_uv=False)
        faces = m.tets.face_iface[tet]
        inner = faces[faces >= 0]
        failed = int(np.count_nonzero(m.ifs.state[inner] != INTACT))
        tool = int(m.nodes.tool[g])
        touching = f", touching tool '{m.tool_specs[tool].name}'" if tool >= 0 else ""
        return (f", corner of tet {m.mesh.label(tet)} (density {density / material.density:.3g}x the material's, principal "
                f"stretches {stretch.min():.3g}-{stretch.max():.3g}; faces: {failed} failed, {len(inner) - failed} intact, "
                f"{len(faces) - len(inner)} outer{touching})")

    def failure_state(self):
        """The faces that failed (a pre-crack is not a failure)."""
        ifs = self.model.ifs
        return (ifs.state != INTACT) & (ifs.state != PRECRACK), ifs.fail_time, ifs.fail_mode

    def failure_positions(self, ids) -> np.ndarray:
        return self.model.iface_centroids(ids=ids)

    def own_energies(self, dt: float) -> dict[str, float]:
        m = self.model
        nodes = m.nodes
        # Potentials at the mid-step positions pair with the half-step velocities of the
        # central-difference scheme: the discrete energy balance then holds to second order.
        x_mid = nodes.x - 0.5 * dt * nodes.v
        tet_energy_and_stress(x_mid, m.tets, self._tet_energy, self._stress)
        interface_energy(x_mid, m.ifs, self._cohesive, self._contact)
        return {
            "elastic": float(np.sum(self._tet_energy)),
            "cohesive": float(np.sum(self._cohesive)),
            # Failed interfaces' paired contact and the crack-surface contact (the tools': shared).
            "contact": float(np.sum(self._contact)) + contact_energy(self.contact),
            "damage": float(np.sum(m.ifs.e_damage)),
            "friction": float(np.sum(m.ifs.e_friction) + np.sum(self.contact.d_friction)),
        }

    def history_columns(self, dt: float) -> dict[str, float]:
        return {"fragments": self.fragments().count}

    def fragments(self) -> Fragments:
        """Pieces of tets still joined by intact interfaces (recomputed after new failures)."""
        m = self.model
        failed = int(np.count_nonzero(m.ifs.state != INTACT))
        if self._fragments is None or failed != self._fragments_failed:
            intact = m.ifs.state == INTACT
            links = np.stack([m.ifs.na[intact, 0] // 4, m.ifs.nb[intact, 0] // 4], axis=1)
            tet_mass = m.nodes.mass.reshape(-1, 4).sum(axis=1)
            tet_velocity = m.nodes.v.reshape(-1, 4, 3).mean(axis=1)
            self._fragments = find_fragments(m.n_tets, links, tet_mass, tet_velocity)
            self._fragments_failed = failed
        return self._fragments

    def fields(self) -> dict:
        """Arrays for a ParaView snapshot on the exploded mesh."""
        m = self.model
        n = m.nodes
        tet_energy_and_stress(n.x, m.tets, self._tet_energy, self._stress)
        n_tets = m.n_tets
        tet_damage = np.zeros(n_tets)
        has_if = m.tets.face_iface >= 0
        dmg = np.where(has_if, m.ifs.damage[np.where(has_if, m.tets.face_iface, 0)], 0.0)
        tet_damage[:] = dmg.max(axis=1)
        return {
            "points": n.x,
            "point_data": {"displacement": n.x - m.x0, "velocity": n.v},
            "blocks": [
                ("tetra", np.arange(4 * n_tets).reshape(-1, 4),
                 {"stress": self._stress.copy(), "damage": tet_damage, "fragment": self.fragments().labels,
                  "material": np.asarray(m.tet_material, dtype=np.int64),
                  "element": m.mesh.labels if m.mesh.labels is not None else np.arange(1, n_tets + 1)}),
                ("triangle", m.ifs.na, {"damage": m.ifs.damage.copy(), "state": m.ifs.state.astype(np.int64),
                                        **self._drawn_face_values()}),
            ],
            "component_names": {"stress": STRESS_COMPONENTS},
        }

    def bounds(self):
        return self.model.mesh.bounds()

    def failure_materials(self, ids):
        """The tets' materials on the two sides of faces `ids` (an exploded node's tet: node // 4)."""
        m = self.model
        return m.tet_material[m.ifs.na[ids, 0] // 4], m.tet_material[m.ifs.nb[ids, 0] // 4]

    def _drawn_face_values(self) -> dict:
        """Each property some material draws per face, on every face (the faces' law rows)."""
        m = self.model
        rows = m.ifs.law_table[m.ifs.law]
        columns = {name: type(mat.interface).RANDOM[name] for mat in m.materials for name in mat.random}
        return {name: rows[:, column].copy() for name, column in sorted(columns.items())}

    def extra_plots(self, out_dir, history) -> None:
        plot_fragment_sizes(self.fragments().masses, run_plot_path(out_dir, "fragment_sizes"))
        step = self.model.time_step
        plot_time_steps(step.element_dt, step.bulk_dt, step.as_summary(), run_plot_path(out_dir, "time_step"))
        super().extra_plots(out_dir, history)

    def _process_zones(self) -> list[dict]:
        """Paper 004 eqs 4-5 (paper 001 eqs 10-11) per material, with the minimal discretisation
        of the process zone by this mesh, 2 l_lower / h (paper 004 Table 2)."""
        return [
            {
                "material": mat.name,
                "lower": mat.process_zone.plastic_zone_long,
                "upper": mat.process_zone.plastic_zone_short,
                "minimal_discretisation": 2.0 * mat.process_zone.plastic_zone_long / self.model.element_size,
            }
            for mat in self.model.materials
        ]

    def own_summary(self) -> dict:
        m = self.model
        insertion = float(np.sum(m.ifs.e_inserted)) if len(m.ties.load) else None
        # Velocities change without new failures: refresh the fragment velocities for the record.
        self._fragments = None
        frags = self.fragments()
        return {
            "fragments": frags.count,
            "largest_fragment_mass_fraction": frags.largest_mass_fraction,
            "fragment_masses": frags.masses[:20].tolist(),
            "fragment_speeds": np.linalg.norm(frags.velocities[:20], axis=1).tolist(),
            "largest_fragment_velocity": frags.velocities[0].tolist(),
            "contact_rebuilds": self.rebuilds,
            "process_zones": self._process_zones(),
            "random_properties": m.random_properties or None,
            "elements": m.n_tets,
            "interfaces": m.n_interfaces,
            "nodes": 4 * m.n_tets,
            "element_size": m.element_size,
            "dt_limit": m.time_step.as_summary(m.mesh.label),
            # Extrinsic runs: the step while every face was tied, in stable steps, and when the
            # first insertion ended that phase (None: it did not).
            "tied_phase": {"substeps": m.tied_substeps, "until": self.tied_until} if m.tied_substeps > 1 else None,
            # Extrinsic faces: the energy their preload put into the law's springs at insertion,
            # booked as negative dissipation (fdem.extrinsic); none without extrinsic laws.
            "insertion_energy": insertion,
            # [initial_stress]: the energy the tets and interfaces held at t = 0 (J), counted in
            # energy.external as put in; None without one.
            "initial_stored_energy": self._initial_stored if len(m.tets.s0) else None,
            "added_mass": m.mass_scaling.added_mass,
            "mass_scaling": m.mass_scaling.as_summary(m.mesh.label),
        }

    def late_warnings(self, summary: dict) -> list[str]:
        """The preload of faces inserted against a soft penalty can return to the body as motion
        (fdem.extrinsic): where it rivals the work done on the specimen, the run is not the
        quasi-static or energy-conserving one it looks like."""
        insertion = summary["insertion_energy"]
        external = self.external_work()
        if insertion is None or not external or insertion <= INSERTION_WARNING * abs(external):
            return []
        return [
            f"the extrinsic faces' insertion preload holds {insertion:.3g} J, {insertion / abs(external):.0%} of the "
            f"external work (more than {INSERTION_WARNING:.0%}): the interface penalty is soft against the "
            "tractions at insertion and that energy can return as motion; raise the interface stiffness "
            "or use intrinsic insertion"
        ]

"""Fracture by link breaking (paper 000 section 3.3): when the maximum principal Cauchy stress at
a particle exceeds the fracture stress (`fracture_factor` x `tensile_strength`, 3 x in the
paper), or its equivalent plastic strain reaches `failure_plastic_strain` (a ductile criterion,
as Abaqus's ductile damage initiation at a constant strain: off by default), the particle
fails, once: a crack plane passes through it with its normal along the maximum principal
direction. The links that cross the crack are removed, in both directions, and the
shape-function gradients (the MLS at the quadrature points of each affected particle's cell, and
the stabilisation's values and stiffness at the particle) are rebuilt without them: the crack hides each side
from the other's interpolation (a visibility rule).

The crack cuts through the wall, as in the paper's shells: with 2-3 particles through the
thickness a crack parallel to the wall would strip a whole layer of its neighbours through the
thickness (first measured on plate-impact: most failures there had a normal near the wall's
normal, and 45 of 56 failed particles ended detached). So the crack normal is the principal
direction less its component through the wall (for a principal direction through the wall, the
largest in-plane principal direction of the second Piola-Kirchhoff stress).

Which links cross: the crack of a failed particle c is the disc of radius `crack_radius` (the
largest grid step, or c's local spacing in a graded set, so that the discs of adjacent failed
particles overlap into one surface)
centred on X_c in the plane with normal N_c, in material coordinates (N_c = F^T n, n the
principal direction in the current configuration). A link (I, J) crosses it when I and J lie
on different sides of the plane and the segment X_I X_J meets the plane within the disc. A
particle on the plane (c itself among them) counts as on the side the normal points away from,
so c keeps its links on that side and loses those to the side N_c points to.

A quadrature point on a crack face sees particles on one side only: with the default dilation
(2.5) they lie on two planes parallel to the crack, too few for the quadratic basis, so such a
point falls back to the linear basis (shape.cell_gradients; linear fields are still exact). A
particle whose cell is left with a singular moment matrix even so (too few visible neighbours
for the linear basis) is detached: all its links are removed, it carries
no stress and no pressure and moves as a free particle (mass, tools, supports and gravity still
act on it), and
its neighbours are rebuilt without it (which may detach more, repeated until none is left).

Random strengths ([material.random]): the fracture stress and the failure strain are thresholds
per particle (`draw_thresholds`: the tensile strength and the failure plastic strain drawn at each
particle's reference position from `run.seed`, materials.random_properties); at uniform strength
every particle's threshold is the one value, so the criterion compares the same numbers as with
a scalar and a uniform run stays bit-identical.

The stored energy that the removal releases (the jump of the elastic plus stabilisation energy
at the rebuild, at the mid-step positions the audit uses) is booked as damage. Checks run on a
fixed grid of step numbers (FRACTURE_CHECK), so the state does not depend on how a run is split
into advance calls; the rebuild is sequential numpy and per-point compiled loops: the same
whatever the thread count.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..materials.random_properties import draw, statistics
from ..solver.stability import STEP_MARGIN
from .kernels import gauss_strains, rest_terms, stabilisation_stiffness
from .material import thermal_strain
from .shape import MAX_CONDITION, cell_gradients, csr_positions, nodal_values
from .step import gershgorin_bounds, refresh_gershgorin_bounds
from .thickness import line_mates, single_point

# A rebuilt moment matrix (a face centre or a particle next to a crack, with the quadratic or the
# linear basis) whose condition number exceeds this counts as singular: on a tube run the set-up
# ones reached 2.5e6, and rebuilt ones of 2e8-3e9 gave gradients 6 x the largest at set-up,
# whose stiffness blew the step up (the run went unstable within 30 steps). Kept at MAX_CONDITION,
# the set-up's bound, where that is lower.
REBUILD_CONDITION = min(1e8, MAX_CONDITION)
# A rebuilt particle whose gradients sum (sum_J |grad N_J|) to more than this times the largest
# sum at set-up counts as singular too: a face centre across a crack from the particles it still
# sees extrapolates, well conditioned but with large values; on the tube run such rows reached
# 8 x the set-up's largest and blew the step up (the step is set from the set-up's stiffness).
GRADIENT_GROWTH = 2.0

# Steps between fracture checks: the criterion is evaluated and links removed at the step
# numbers that are multiples of it. The lag it allows is ~1.8 spacing / c at the default step
# (0.7 x the Lanczos step, ~0.6 spacing / c on a regular grid; 10 steps of the former Gershgorin
# step, 3.5 x smaller, gave the same lag).
FRACTURE_CHECK = 3
# A particle this close to a crack plane (relative to the support radius) is on it.
_ON_PLANE = 1e-9

# What [material.random] may draw per particle: the properties of the material (meshfree/setup.py
# MeshfreeMaterial) whose values set a particle's thresholds, the fracture stress (fracture_factor
# x tensile_strength) and the failure plastic strain.
RANDOM_PARTICLE_PROPERTIES = ("tensile_strength", "failure_plastic_strain")


def draw_thresholds(X: np.ndarray, random: dict, means: dict, seed: int, material: str) -> tuple[dict, dict]:
    """The properties `random` ({name: RandomProperty}, names from RANDOM_PARTICLE_PROPERTIES)
    drawn per particle at the reference positions X (m, the specimen's particles), each with the
    material's value `means[name]` as its mean, from the run's `seed` and the `material`'s name:
    ({name: values}, {name: statistics for summary.json})."""
    drawn, stats_of = {}, {}
    for name, spec in random.items():
        values = draw(spec, float(means[name]), X, seed, material, name)
        drawn[name], stats_of[name] = values, statistics(spec, X, values)
    return drawn, stats_of


class LinkBreaking:
    """The crack state of a MeshfreeSimulation and the check that extends it."""

    def __init__(self, X, volume, cells, radius, terms, stab_scale, fracture_stress, crack_radius, links,
                 wall_frame, tool_k=0.0, step_ratio=1.0, failure_strain=np.inf, fracturing=None):
        n = len(X)
        # The particles [0, fracturing) can fail: the specimen's (a projectile after them does not,
        # build.MeshfreeBody); the tree holds them only, so no rebuild reaches another body.
        self.fracturing = n if fracturing is None else int(fracturing)
        # Per particle: two unit tangents of the wall and its normal (particles.WallParticles).
        self.wall_frame = wall_frame
        self.X, self.volume, self.cells = X, volume, cells
        # The support radius and the crack discs' radius: numbers, or one per particle (a graded set);
        # the stabilisation's alpha E: a number, or one per fracturing particle (several materials).
        self.radius, self.terms = radius, terms
        self.stab_scale = float(stab_scale) if np.ndim(stab_scale) == 0 else _per_particle(stab_scale, n,
                                                                                             self.fracturing, 0.0)
        # Per particle: the maximum principal stress that fails it (Pa) and the equivalent plastic
        # strain that fails it, given as one value for all or one per fracturing particle (drawn:
        # draw_thresholds); inf on the particles that cannot fail (another body's).
        self.fracture_stress = _per_particle(fracture_stress, n, self.fracturing)
        self.failure_strain = _per_particle(failure_strain, n, self.fracturing)
        crack_radius = np.asarray(crack_radius, dtype=float)  # a number or one per fracturing particle
        self.crack_radius = np.zeros(n)
        self.crack_radius[:self.fracturing] = crack_radius
        self.tree = cKDTree(X[:self.fracturing])
        self.failed = np.zeros(n, dtype=bool)
        self.detached = np.zeros(n, dtype=bool)
        self.fail_time = np.zeros(n)
        self.normal = np.zeros((n, 3))  # material crack normal of each failed particle
        self.blocked = np.zeros(0, dtype=np.int64)  # sorted keys I * n + J of the removed links
        self.damage = 0.0  # J, stored energy released by the removals
        self.broken_links = 0  # removed pairs {I, J}, I != J, that were linked
        self.precut = np.zeros(0, dtype=np.int64)  # sorted keys of the links the pre-cracks removed
        self.precut_pairs = 0  # pairs {I, J} of linked particles the pre-cracks separated
        self.stable_estimate = None  # s, the stable step after the last rebuild (_check_step)
        self._bounds = None  # Gershgorin's per-particle bounds (_check_step), once computed
        # The stable-step check after rebuilds (_check_step): the tool penalties (N/m per
        # particle) and the set-up ratio of the Lanczos omega_max^2 to Gershgorin's bound.
        self.tool_k, self.step_ratio = tool_k, float(step_ratio)
        self.row = np.repeat(np.arange(n, dtype=np.int64), np.diff(links.start))
        self.key = self.row * np.int64(n) + links.neighbour  # increasing (CSR rows sorted)
        self.reach = _longest_link(X, self.row, links.neighbour)
        self.gradient_limit = GRADIENT_GROWTH * float(np.max(_gradient_sums(self.row, links.grad, n)))

    # -- the criterion ---------------------------------------------------------------------------
    def newly_failed(self, cauchy: np.ndarray, deformation: np.ndarray, pk2: np.ndarray,
                     eq_plastic: np.ndarray | None = None):
        """Particles (ids, increasing) whose maximum principal stress exceeds the fracture stress,
        or whose equivalent plastic strain `eq_plastic` reaches the failure strain, and that have
        not failed yet, with their material crack normals: the maximum principal
        direction pulled back to the material, less its component through the wall (the crack
        cuts through the wall; where the direction is through the wall, the largest in-plane
        principal direction of the second Piola-Kirchhoff stress `pk2`)."""
        s = cauchy
        # Gershgorin's bound on the largest eigenvalue spares the eigen-solve where it cannot pass.
        off = np.abs(s[:, 3:])
        bound = np.max(s[:, :3] + np.stack([off[:, 0] + off[:, 2], off[:, 0] + off[:, 1], off[:, 1] + off[:, 2]],
                                           axis=1), axis=1)
        strained = np.zeros(len(s), dtype=bool) if eq_plastic is None else eq_plastic >= self.failure_strain
        near = np.flatnonzero(((bound > self.fracture_stress) | strained) & ~self.failed & ~self.detached)
        near = near[near < self.fracturing]
        s = s[near]
        sigma = np.stack([s[:, [0, 3, 5]], s[:, [3, 1, 4]], s[:, [5, 4, 2]]], axis=1)
        values, vectors = np.linalg.eigh(sigma)
        over = (values[:, 2] > self.fracture_stress[near]) | strained[near]
        ids = near[over]
        n_current = vectors[over, :, 2]
        F = deformation[ids].reshape(-1, 3, 3)
        N = np.einsum("kab,ka->kb", F, n_current)  # F^T n: the normal pulled back to the material
        N /= np.linalg.norm(N, axis=1)[:, None]
        # A solid (no wall_frame) keeps the principal direction: nothing to remove.
        wall = np.zeros((len(ids), 3)) if self.wall_frame is None else self.wall_frame[ids, 2]
        N -= np.einsum("ka,ka->k", N, wall)[:, None] * wall
        through = np.flatnonzero(np.linalg.norm(N, axis=1) < 1e-6)
        if len(through):
            S = pk2[ids[through]]
            S = np.stack([S[:, [0, 3, 5]], S[:, [3, 1, 4]], S[:, [5, 4, 2]]], axis=1)
            tangents = self.wall_frame[ids[through], :2]  # (k, 2, 3)
            in_wall = np.einsum("kpa,kab,kqb->kpq", tangents, S, tangents)
            v = np.linalg.eigh(in_wall)[1][:, :, 1]
            N[through] = v[:, 0, None] * tangents[:, 0] + v[:, 1, None] * tangents[:, 1]
        N /= np.linalg.norm(N, axis=1)[:, None]
        # A fixed sign (largest component positive): which side a particle on the plane keeps.
        big = np.argmax(np.abs(N), axis=1)
        N *= np.sign(N[np.arange(len(ids)), big])[:, None]
        return ids, N

    # -- the crossing rule -----------------------------------------------------------------------
    def crossing_links(self, c: int, normal: np.ndarray, start, neighbour) -> np.ndarray:
        """Positions of the links (I, J) that cross the crack disc of particle c."""
        X = self.X
        crack_radius = self.crack_radius[c]
        near = np.sort(np.asarray(self.tree.query_ball_point(X[c], crack_radius + self.reach), dtype=np.int64))
        counts = start[near + 1] - start[near]
        pos = np.repeat(start[near] - np.cumsum(np.r_[0, counts[:-1]]), counts) + np.arange(counts.sum())
        I, J = self.row[pos], neighbour[pos]
        dI = (X[I] - X[c]) @ normal
        dJ = (X[J] - X[c]) @ normal
        tol = _ON_PLANE * float(np.max(self.radius))
        across = (dI > tol) != (dJ > tol)
        t = np.where(across, dI / np.where(across, dI - dJ, 1.0), 0.0)
        t = np.clip(t, 0.0, 1.0)
        hit = X[I] + t[:, None] * (X[J] - X[I]) - X[c]
        inside = np.einsum("ij,ij->i", hit, hit) <= (crack_radius * (1.0 + 1e-9)) ** 2
        return pos[across & inside]

    def precut_links(self, crack, scale: float, neighbour) -> np.ndarray:
        """Positions of the links (I, J) that cross a pre-crack (loading.Precrack): I and J on
        different sides of its plane (a particle on the plane, within `tol`, counts as on the side
        the normal points away from, as for a failed particle's crack) and the segment meets the
        plane inside its box (widened by tol)."""
        X = self.X
        normal = np.asarray(crack.normal, dtype=float)
        normal = normal / np.linalg.norm(normal)
        tol = crack.tol if crack.tol is not None else 1e-6 * scale
        I, J = self.row, neighbour
        dI = (X[I] - np.asarray(crack.point)) @ normal
        dJ = (X[J] - np.asarray(crack.point)) @ normal
        across = (dI > tol) != (dJ > tol)
        t = np.clip(np.where(across, dI / np.where(across, dI - dJ, 1.0), 0.0), 0.0, 1.0)
        hit = X[I] + t[:, None] * (X[J] - X[I])
        inside = np.all((hit >= np.asarray(crack.box_min) - tol) & (hit <= np.asarray(crack.box_max) + tol), axis=1)
        return np.flatnonzero(across & inside & (I < self.fracturing))

    def cut(self, sim, precracks, scale: float) -> None:
        """Remove the links that cross the pre-cracks (a notch or a slit present from the start)
        and rebuild the particles that lost some: the same visibility rule as a grown crack,
        but no particle fails and no energy is released (nothing is strained yet). Raises
        ValueError when a pre-crack cuts no link."""
        links, n = sim.links, len(self.X)
        keys = []
        for i, crack in enumerate(precracks):
            hit = self.key[self.precut_links(crack, scale, links.neighbour)]
            if len(hit) == 0:
                raise ValueError(f"precracks.{i}: its plane cuts no link between particles inside its box; check "
                                 "point, normal, box_min and box_max against the specimen")
            keys.append(hit)
        if not keys:
            return
        new = np.concatenate(keys)
        new = np.concatenate([new, (new % n) * n + new // n])
        self.precut = np.unique(new)
        self._block(self.precut)
        self.precut_pairs = self._pairs(self.precut)
        self._rebuild(sim, np.unique(self.row[self._link_positions(self.precut)]))

    # -- the check -------------------------------------------------------------------------------
    def check(self, sim, dt: float) -> bool:
        """At a check step: fail the particles over the criterion, remove the links across their
        cracks, rebuild the affected particles and book the released energy. True if links
        changed."""
        if not (np.isfinite(self.fracture_stress).any() or np.isfinite(self.failure_strain).any()):  # pre-cracks only
            return False
        cauchy = sim.cauchy_stress()
        # Blown up (non-finite stresses; numpy's eigen-solve raised on one such state of a tube run):
        # left to the driver, which stops the run as unstable and keeps its outputs.
        if not np.isfinite(cauchy).all():
            return False
        ids, normals = self.newly_failed(cauchy, sim.particles.deformation, sim.particles.stress,
                                         sim.per_particle(sim.particles.eq_plastic))
        if len(ids) == 0:
            return False
        self.fail(sim, ids, normals, dt)
        return True

    def fail(self, sim, ids, normals, dt: float) -> None:
        """Fail the particles `ids` (increasing) with the material crack normals `normals`:
        remove the links across their cracks, rebuild and book the released energy. Only the
        rebuilt particles change (their gradients, values, stiffness, plastic strain), so only
        their strains and energies are compared, before and after: the cost follows the crack,
        not the model (benchmarks/meshfree_fracture_rebuild.py)."""
        p, links = sim.particles, sim.links
        n = len(self.X)
        x_mid = p.x - 0.5 * dt * p.v
        self.failed[ids] = True
        self.fail_time[ids] = sim.time
        self.normal[ids] = normals
        new = [self.key[self.crossing_links(c, N, links.start, links.neighbour)] for c, N in zip(ids, normals)]
        new = np.concatenate(new)
        new = np.concatenate([new, (new % n) * n + new // n])  # both directions
        self._block(new)
        # Each particle's strains and energy as the rebuild first reaches it (before it changes):
        # those of the rebuilt particles and of the others on their lines through the wall, whose
        # Gauss points their F reaches (thickness.py).
        seen = np.zeros(n, dtype=bool)
        touched, strain_before, energy_before = [np.zeros(0, dtype=np.int64)], [np.zeros((0, 2, 6))], [np.zeros(2)]

        def record(rows):
            rows = line_mates(sim.columns, rows)
            fresh = rows[~seen[rows]]
            seen[fresh] = True
            touched.append(fresh)
            strain_before.append(self._gauss_strains(sim, p.x, fresh))
            energy_before.append(np.sum(sim.strain_energies(x_mid, fresh), axis=0))

        was_detached = self.detached.copy()
        self._rebuild(sim, np.unique(self.row[self._link_positions(new)]), record)
        # A free particle's F is I: one point a cell on its line through the wall.
        single_point(sim.columns, np.flatnonzero(self.detached & ~was_detached))
        rows = np.concatenate(touched)
        # The rebuilt approximation changes F at the rebuilt particles although nothing moved:
        # that change is no deformation, so their elastic strain carries over (the plastic strain,
        # an eigenstrain for an elastic law, takes up the difference). Otherwise a yielded
        # particle's trial stress jumps and one radial return dissipates work no step did.
        before = np.concatenate(strain_before)
        after = self._gauss_strains(sim, p.x, rows)
        changed = np.any(after != before, axis=(1, 2)) & ~self.detached[rows]
        plastic = p.plastic.reshape(n, 2, 6)
        plastic[rows[changed]] += after[changed] - before[changed]
        # A free particle carries no stress: its plastic strain takes up its thermal strain (thermo
        # law; F = I without links; 0.0 - theta keeps +0 where theta = 0, as before).
        free = np.repeat(self.detached, 2)
        p.plastic[free] = 0.0
        p.plastic[free, :3] = 0.0 - _thermal_strains(p.thermal[:, 0], np.repeat(p.material, 2), free, sim.law)[:, None]
        p.stress[self.detached] = 0.0
        released = float(np.sum(np.concatenate(energy_before)) - np.sum(sim.strain_energies(x_mid, rows)))
        self.damage += released
        self._check_step(sim, dt, rows)
        self.broken_links = self._pairs(np.setdiff1d(self.blocked, self.precut, assume_unique=True))

    def _link_positions(self, keys) -> np.ndarray:
        """The positions of those of the link keys I * n + J `keys` that are links (a reversed
        key (J, I) need not be one: a particle's links are the supports of its cell's points)."""
        if len(self.key) == 0 or len(keys) == 0:
            return np.zeros(0, dtype=np.int64)
        at = np.minimum(np.searchsorted(self.key, keys), len(self.key) - 1)
        return at[self.key[at] == keys]

    def _pairs(self, keys) -> int:
        """The number of pairs {I, J} of distinct particles among the links with keys `keys`."""
        keys = self.key[self._link_positions(keys)]
        n = len(self.X)
        a, b = keys // n, keys % n
        keep = a != b
        return len(np.unique(np.minimum(a[keep], b[keep]) * n + np.maximum(a[keep], b[keep])))

    def _check_step(self, sim, dt: float, rows) -> None:
        """The stable step of the rebuilt links into `stable_estimate` (s): one-sided gradients at
        crack faces can be stiffer, and the simulation sub-steps where it fell below its step
        (MeshfreeSimulation._follow_stable_step). The estimate is Gershgorin's bound (cheap,
        numpy) times its set-up ratio to the Lanczos value (step.stable_step), the tools as at
        set-up: a Lanczos run per rebuild would cost ~100 force passes. The per-particle bounds
        are kept and refreshed where the rebuild of `rows` changed them, not recomputed."""
        if self.detached.all():
            return
        if self._bounds is None:
            self._bounds = gershgorin_bounds(sim.particles, sim.links, self.row, sim.law, self.tool_k)
        else:
            refresh_gershgorin_bounds(self._bounds, sim.particles, sim.links, sim.law, self.tool_k, np.sort(rows))
        self.stable_estimate = STEP_MARGIN * 2.0 / np.sqrt(self.step_ratio * float(np.max(self._bounds[2])))

    def _gauss_strains(self, sim, x, rows) -> np.ndarray:
        """Per particle of `rows`, the Green-Lagrange strains (xx yy zz xy yz xz) at its two Gauss
        points through the wall (len(rows), 2, 6) at positions x (kernels.gauss_strains)."""
        strain = np.empty((len(rows), 2, 6))
        gauss_strains(np.asarray(rows, dtype=np.int64), np.ascontiguousarray(x), sim.links, sim.columns, strain)
        return strain

    def _block(self, keys):
        self.blocked = np.union1d(self.blocked, keys)

    def _rebuild(self, sim, rows, record=None):
        """New gradients and stabilisation (values and stiffness) for the particles `rows` with the
        blocked links left out; detaches those left singular and rebuilds their neighbours in turn.
        `record(rows)` is called before each round changes its rows. Touches the links of the
        rebuilt and detached particles only (their positions through the CSR and its transpose)."""
        links, p, n = sim.links, sim.particles, len(self.X)
        rows = rows[~self.detached[rows]]
        changed = []
        while len(rows):
            if record is not None:
                record(rows)
            pos, _ = csr_positions(links.start, rows)
            links.grad[pos] = 0.0
            r, col, grad, condition, _, owner = cell_gradients(self.X, self.volume, self.cells, self.radius,
                                                               self.terms, rows, self.tree, self.blocked,
                                                               linear_fallback=True,
                                                               max_condition=REBUILD_CONDITION)
            at = np.searchsorted(self.key, r * n + col)
            if not np.array_equal(self.key[np.minimum(at, len(self.key) - 1)], r * n + col):
                raise RuntimeError("a rebuilt gradient has no link: the quadrature points' supports grew")
            links.grad[at] = grad
            self._stabilisation(links, p, rows, pos)
            rest_terms(rows, self.X, links)  # before the next round's record reads these rows' energies
            changed.append(pos)
            bad = ~np.isfinite(condition) | (condition > REBUILD_CONDITION)
            steep = np.flatnonzero(_gradient_sums(r, grad, n) > self.gradient_limit)
            lost = np.union1d(owner[bad], steep)
            if len(lost) == 0:
                break
            self.detached[lost] = True
            # Every link of a lost particle, and every link to one (the transpose's rows).
            own, _ = csr_positions(links.start, lost)
            back, first = csr_positions(links.back_start, lost)
            to_lost = np.searchsorted(self.key, links.back_row[back] * n + np.repeat(lost, np.diff(first)))
            touching = np.union1d(own, to_lost)
            keys = self.key[touching]
            self._block(np.concatenate([keys, (keys % n) * n + keys // n]))
            links.grad[own] = 0.0
            links.value[own] = 0.0
            rest_terms(lost, self.X, links)
            changed.append(own)
            p.stab_k[lost] = 0.0
            # Nor does a pressure push it: a free particle keeps no wall face (its F is I: the
            # reference face would push a tumbling fragment in a fixed direction).
            faces, _ = csr_positions(sim.pressed.start, lost)
            sim.pressed.area[faces] = 0.0
            rows = np.unique(self.row[touching])
            rows = rows[~self.detached[rows]]
        # The gather's copies, in the transposed order (kernels.Links), where they changed.
        if changed:
            pos = np.concatenate(changed)
            links.back_grad_value[links.to_back[pos]] = links.grad_value[pos]

    def _stabilisation(self, links, particles, rows, pos):
        """The values N_K(X_J) and the stiffness k_J of the particles `rows` (their links at the
        positions `pos`) over the links still there (build.nodal_stabilisation); k_J = 0 where
        even the linear basis is singular at X_J."""
        hidden = np.zeros(len(self.key), dtype=bool)
        hidden[pos] = self._is_blocked(self.key[pos])
        pos, value, condition = nodal_values(self.X, self.volume, self.radius, self.terms, links.start,
                                             links.neighbour, rows, hidden, REBUILD_CONDITION)
        links.value[pos] = value
        k = stabilisation_stiffness(self.X, self.volume, self.row[pos], links.neighbour[pos], ~hidden[pos],
                                    self.radius, self.stab_scale)[rows]
        k[~np.isfinite(condition) | (condition > REBUILD_CONDITION)] = 0.0
        particles.stab_k[rows] = k

    def _is_blocked(self, keys) -> np.ndarray:
        if len(self.blocked) == 0:
            return np.zeros(len(keys), dtype=bool)
        return self.blocked[np.minimum(np.searchsorted(self.blocked, keys), len(self.blocked) - 1)] == keys


def _per_particle(threshold, n: int, fracturing: int, beyond: float = np.inf) -> np.ndarray:
    """A threshold (a number, or one per fracturing particle) on all n particles: `beyond` (inf:
    never reached) past the fracturing ones."""
    out = np.full(n, beyond)
    out[:fracturing] = threshold
    return out


def _thermal_strains(temperature, row, which, law_table) -> np.ndarray:
    """material.thermal_strain at the Gauss points `which` (a mask) of their temperatures, each by
    its law's row (`row`: each point's row of `law_table`)."""
    ids = np.flatnonzero(which)
    out = np.zeros(len(ids))
    for r in np.unique(row[ids]):
        sel = row[ids] == r
        out[sel] = thermal_strain(temperature[ids[sel]], law_table[r])
    return out


def _gradient_sums(row, grad, n) -> np.ndarray:
    """Per particle, sum_J |grad N_J| over its links (row: each link's particle)."""
    return np.bincount(row, weights=np.linalg.norm(grad, axis=1), minlength=n)


def _longest_link(X, row, neighbour, block=1 << 20) -> float:
    """max |X_J - X_I| over the links (I = row, J = neighbour), in blocks of links: all the link
    vectors at once would add 32 bytes a link to the set-up's peak memory."""
    longest2 = 0.0
    for first in range(0, len(row), block):
        dX = X[neighbour[first:first + block]] - X[row[first:first + block]]
        longest2 = max(longest2, float(np.max(np.einsum("ij,ij->i", dX, dX))))
    return float(np.sqrt(longest2))

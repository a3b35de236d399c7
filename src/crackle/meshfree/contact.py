"""Penalty contact between particles that no link joins: between bodies (a deformable projectile
and its target, build.MeshfreeBody) and across the cracks of one body (the faces of a crack
closing again, a fragment or a petal folding back onto its plate).

Each particle is a sphere of radius r (half its body's in-plane spacing: a wall's particles then
touch their neighbours along the wall, so that no particle of another body slips between them)
for this purpose only. A pair (I, J) pushes apart when closer than its reach s: r_I + r_J between
bodies; for two particles of one body, the smaller of that and their distance in the reference
configuration (particles across a crack sit a spacing apart: they push only where the crack
closes past where they started, never at the start). Two particles of one body within its support
radius in the reference configuration are joined by links unless fracture removed them: only
such a removed link makes them a pair. The force is k (s - d) along the line of centres, its
energy k (s - d)^2 / 2 (`energy.contact`, with the tools' springs), k the two particles'
springs in series (each CONTACT_STIFFNESS x its body's Young's modulus x its contact diameter).
No friction between particles (yet).

The pairs are a Verlet list: all pairs closer than s + skin at the last build (skin = the
smallest radius), rebuilt when a particle may have moved skin / 2 since (checked between the
compiled calls with the largest speed, twice over). The kernel's pass gathers each particle's
force from its own rows, both rows of a pair computing the same numbers: the forces are equal
and opposite bit for bit (momentum is conserved to round-off) and do not depend on the thread
count. Build and check are sequential numpy: the same whatever the threads.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .kernels import PairContact

# A particle's spring over its body's Young's modulus times its contact diameter (N/m over Pa m):
# about the stiffness of the material between two neighbouring particles (E a for a spacing a).
# The tools' penalty (TOOL_PENALTY_FACTOR E / h times the contact area, h the wall's smallest
# step) is 40 x that on a 4 mm grid through a 2 mm wall: pressed by three or more such pairs at
# once a particle outran the step (+11 % energy on two crack faces closing at 20 m/s).
CONTACT_STIFFNESS = 1.0
# The stable step holds this many pairs at once on a particle (build.py).
STEP_PAIRS = 4
# The skin of the Verlet list over the smallest contact radius.
SKIN = 1.0
# Margin on the largest speed when deciding how far the particles may move before the next check.
SPEED_MARGIN = 2.0


class ParticleContact:
    """The contact pairs of a MeshfreeSimulation's particles and the rule that keeps them current."""

    def __init__(self, X, body, radius, spring, support_radius, self_contact: bool = True):
        """X: reference positions (n, 3); body: each particle's body (n,); radius: contact radius
        (n,) m; spring: each particle's penalty spring (n,) N/m; support_radius: per body, the
        distance within which its particles are linked (m); self_contact: pairs within a body too
        (without it, between bodies only)."""
        self.self_contact = bool(self_contact)
        # The pairs of one body whose link fracture removed, by key I n + J (I < J, sorted), with
        # the reach they got when first seen: no more than their distance then (a crack that
        # opens where the material is compressed must not start with an overlap: its spring
        # would hold energy no work put in).
        self._cut_keys = np.zeros(0, dtype=np.int64)
        self._cut_reach = np.zeros(0)
        # Set when links were removed: the next refresh rebuilds (and sees the new pairs at once).
        self.stale = False
        self.X, self.body = X, np.asarray(body, dtype=np.int64)
        self.radius = np.asarray(radius, dtype=float)
        self.spring = np.asarray(spring, dtype=float)
        self.support_radius = np.asarray(support_radius, dtype=float)
        self.skin = SKIN * float(self.radius.min())
        self.builds = 0
        n = len(X)
        self.pairs = PairContact(np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0),
                                 np.zeros(0), np.zeros((n, 3)))
        self._built_at = None  # positions at the last build

    def refresh(self, x, v, dt: float, steps: int, blocked=None) -> None:
        """Rebuild the pairs if a particle may come closer than the skin allows within the next
        `steps` steps of dt (`blocked`: the sorted keys I n + J of links fracture removed)."""
        if self._built_at is not None and not self.stale:
            moved = np.sqrt(np.max(np.einsum("ij,ij->i", x - self._built_at, x - self._built_at), initial=0.0))
            ahead = SPEED_MARGIN * steps * dt * np.sqrt(np.max(np.einsum("ij,ij->i", v, v), initial=0.0))
            if moved + ahead < 0.5 * self.skin:
                return
        self.build(x, blocked)

    def build(self, x, blocked=None) -> None:
        n = len(x)
        I, J, reach = self.candidates(x, blocked)
        stiffness = self.spring[I] * self.spring[J] / (self.spring[I] + self.spring[J])
        # Both rows of each pair, by particle then by the other.
        row, other = np.concatenate([I, J]), np.concatenate([J, I])
        order = np.lexsort((other, row))
        start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(row, minlength=n), out=start[1:])
        self.pairs = PairContact(start, other[order], np.concatenate([stiffness, stiffness])[order],
                                 np.concatenate([reach, reach])[order], self.pairs.force)
        self._built_at = x.copy()
        self.stale = False
        self.builds += 1

    def candidates(self, x, blocked=None):
        """The pairs (I < J) closer than their reach + the skin at positions x, that no link
        joins, and their reach."""
        r = self.radius
        pairs = cKDTree(x).query_pairs(2.0 * float(r.max()) + self.skin, output_type="ndarray")
        I, J = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
        reach = r[I] + r[J]
        d = x[I] - x[J]
        near = np.einsum("ij,ij->i", d, d) < (reach + self.skin) ** 2
        I, J, reach, d = I[near], J[near], reach[near], d[near]
        same = self.body[I] == self.body[J]
        if not self.self_contact:
            I, J, reach = I[~same], J[~same], reach[~same]
            return I, J, reach
        dX = self.X[I] - self.X[J]
        apart = np.sqrt(np.einsum("ij,ij->i", dX, dX))
        linked = same & (apart < self.support_radius[self.body[I]])
        cut = np.zeros(len(I), dtype=bool)
        if blocked is not None and len(blocked) and linked.any():
            key = I[linked] * np.int64(len(x)) + J[linked]
            at = np.minimum(np.searchsorted(blocked, key), len(blocked) - 1)
            cut[np.flatnonzero(linked)[blocked[at] == key]] = True
        reach = np.where(same, np.minimum(reach, apart), reach)
        if cut.any():
            reach[cut] = self._reach_of_cut(I[cut] * np.int64(len(x)) + J[cut], reach[cut],
                                            np.linalg.norm(d[cut], axis=1))
        keep = ~linked | cut
        return I[keep], J[keep], reach[keep]

    def _reach_of_cut(self, keys, reach, distance):
        """The reach of pairs whose link was cut (keys I n + J): the one given when first seen, else the smaller of `reach` and their `distance` now (recorded)."""
        at = np.minimum(np.searchsorted(self._cut_keys, keys), max(len(self._cut_keys) - 1, 0))
        seen = (self._cut_keys[at] == keys) if len(self._cut_keys) else np.zeros(len(keys), dtype=bool)
        out = np.minimum(reach, distance)
        out[seen] = self._cut_reach[at[seen]]
        if not seen.all():
            keys_all = np.concatenate([self._cut_keys, keys[~seen]])
            order = np.argsort(keys_all, kind="stable")
            self._cut_keys = keys_all[order]
            self._cut_reach = np.concatenate([self._cut_reach, out[~seen]])[order]
        return out

    def energy(self, x) -> float:
        """The pairs' stored energy k (s - d)^2 / 2 at positions x (J)."""
        p = self.pairs
        row = np.repeat(np.arange(len(x)), np.diff(p.start))
        d = np.linalg.norm(x[row] - x[p.other], axis=1)
        overlap = np.maximum(p.reach - d, 0.0)
        return float(0.25 * np.sum(p.stiffness * overlap**2))  # each pair is in two rows

    def overlaps_between_bodies(self, x) -> int:
        """Pairs of particles of different bodies closer than their reach at positions x."""
        I, J, reach = self.candidates(x)
        d = x[I] - x[J]
        return int(np.sum((self.body[I] != self.body[J]) & (np.einsum("ij,ij->i", d, d) < reach**2)))

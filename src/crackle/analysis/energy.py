"""The energy audit, shared by every method: external work (tools, pressures, gravity, initial
kinetic energy, and the energy an initial stress stores at t = 0) = kinetic + stored (elastic,
cohesive, contact) + dissipated (damage, friction, damping). Each method reports its terms as
`energy.*` history columns; this module is the one place that turns them into an imbalance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EXTERNAL = "energy.external"
CONTACT = "energy.contact"
# Energies below this (J) are rounding noise, not a state of the model: a run without loads sits
# at ~1e-27 J; a cube of rock 1 um on a side strained by 1e-4 already stores ~1e-16 J.
ENERGY_NOISE = 1e-18
PREFIX = "energy."
# A model holding more energy than was put in by this fraction of the largest energy has gone
# unstable, not drifted: sound runs stay within a few per cent (docs/validation.md).
UNSTABLE_CREATED = 0.25


# Every energy term's role, in the order history.csv gives them (energy.NAME): the one
# vocabulary of the five methods. Kinetic and stored energy come back; dissipated energy does not
# (fracture: `damage`, in every method); the input is the work put in. The audit itself is
# external - everything else, whatever the roles.
KINETIC, STORED, DISSIPATED, INPUT = "kinetic", "stored", "dissipated", "input"
ENERGY_ROLES = {
    "kinetic": KINETIC,
    "elastic": STORED,  # bulk strain energy (tets, bonds, springs, particles)
    "membrane": STORED,  # the shell's in-plane strain energy
    "bending": STORED,  # the shell's bending energy
    "cohesive": STORED,  # FDEM interfaces before they fail
    "stabilisation": STORED,  # the meshfree particles' stabilisation springs
    "contact": STORED,  # penalty springs: tools, crack faces, bodies
    "damage": DISSIPATED,  # fracture: interfaces, bonds, links, the shell's cuts
    "plastic": DISSIPATED,
    "thermal": DISSIPATED,  # the meshfree thermo law's release of stored energy by heating
    "friction": DISSIPATED,
    "damping": DISSIPATED,
    "external": INPUT,
}


def energy_order(terms) -> list[str]:
    """The names of `terms` (without the prefix) in ENERGY_ROLES's order; KeyError names a term
    outside the vocabulary (add it there, with its role)."""
    unknown = [name for name in terms if name not in ENERGY_ROLES]
    if unknown:
        raise KeyError(f"energy terms {unknown} are not in analysis.energy.ENERGY_ROLES; add them with their role")
    return [name for name in ENERGY_ROLES if name in terms]


def _accounted(terms):
    """The sum of every energy term but the external work."""
    return sum(v for k, v in terms.items() if k.startswith(PREFIX) and k != EXTERNAL)


def imbalance(terms):
    """external - the sum of every other energy term, from a mapping of `energy.*` values (a
    history row, or whole history columns: then per row)."""
    return terms[EXTERNAL] - _accounted(terms)


def relative_imbalance(terms) -> float:
    """imbalance / external work: for a single state with work put in."""
    return imbalance(terms) / terms[EXTERNAL]


def energy_error(history: dict[str, np.ndarray]) -> float:
    """Relative imbalance at the end of a history: imbalance / the largest energy seen (the
    external work or the sum of the other terms); 0 when nothing above rounding noise
    (ENERGY_NOISE) was ever seen (no loads, or stopped before the first step)."""
    if EXTERNAL not in history or not any(k.startswith(PREFIX) and k != EXTERNAL for k in history):
        return 0.0
    ext = history[EXTERNAL]
    rest = _accounted(history)
    scale = max(float(np.max(np.abs(ext))), float(np.max(np.abs(rest))))
    if scale < ENERGY_NOISE:
        return 0.0
    return float((ext[-1] - rest[-1]) / scale)


def created_fraction(row) -> float:
    """Energy the model holds beyond the work put in, as a fraction of the larger of the two,
    from one history row (0 at rounding-noise level). A run that goes unstable creates energy
    long before its values overflow. The contact springs' energy is left out: it is measured
    after the step while a tool's work for the penetration of that step is booked in the next,
    so in a contact's first steps it alone exceeds the work (a tool that reaches the specimen
    after a gap); an instability shows in the kinetic and elastic energy anyway."""
    external, accounted = row[EXTERNAL], _accounted(row) - row.get(CONTACT, 0.0)
    scale = max(abs(external), abs(accounted))
    return 0.0 if scale < ENERGY_NOISE else (accounted - external) / scale


# The imbalance's growth window: from the last row below the first fraction of its final value to
# the first row at or beyond the second.
GROWTH_FROM, GROWTH_TO = 0.1, 0.9


@dataclass(frozen=True)
class ImbalanceGrowth:
    """Where the imbalance grew: it went from GROWTH_FROM to GROWTH_TO of its final value between
    `start` and `end` (s), by `change` (J). `term` (energy.NAME) is the term it grew most nearly in
    proportion to over the run: imbalance - its first value ~ `ratio` x (term - its first value),
    with coefficient of determination `r2`; None with fewer than 3 rows or no term that moved."""

    start: float
    end: float
    change: float
    term: str | None
    ratio: float
    r2: float

    def describe(self, time_scale: float = 1e3, unit: str = "ms") -> str:
        text = (f"it went from {GROWTH_FROM:.0%} to {GROWTH_TO:.0%} of its final value between "
                f"{self.start * time_scale:.4g} and {self.end * time_scale:.4g} {unit}")
        if self.term is not None:
            text += (f", in proportion to {self.term} ({self.ratio:+.1%} of its change, "
                     f"R^2 {self.r2:.2f}; a pointer to the mechanism, not a proof)")
        return text


def imbalance_growth(history: dict[str, np.ndarray]) -> ImbalanceGrowth | None:
    """When the imbalance grew and which energy term it grew with, from the history's `time` and
    `energy.*` columns (None without them or without an imbalance). The term points at the
    mechanism without proving it: a force that is not the gradient of the energy booked for it
    shows in the term its motion also feeds (a walnut's crushed faces, pressed and sliding over
    turning faces: the friction, docs/validation.md)."""
    if "time" not in history or EXTERNAL not in history:
        return None
    time = np.asarray(history["time"], float)
    gap = np.asarray(imbalance(history), float)
    if len(gap) < 2 or abs(gap[-1]) < ENERGY_NOISE:
        return None
    share = gap / gap[-1]
    below = np.flatnonzero(share < GROWTH_FROM)
    first = int(below[-1]) if len(below) else 0
    reached = np.flatnonzero((share >= GROWTH_TO) & (np.arange(len(share)) > first))
    last = int(reached[0]) if len(reached) else len(share) - 1
    # The term it grew with over the whole run: a window alone cannot tell it from any term that
    # happens to grow steadily there.
    term, ratio, best = None, 0.0, -np.inf
    grown = gap - gap[0]
    spread = float(np.sum((grown - grown.mean()) ** 2))
    if len(gap) >= 3 and spread > 0.0:
        for name in history:
            if not name.startswith(PREFIX):
                continue
            values = np.asarray(history[name], float)
            moved = values - values[0]
            norm = float(moved @ moved)
            if norm == 0.0:
                continue
            c = float(moved @ grown) / norm
            r2 = 1.0 - float(np.sum((grown - c * moved) ** 2)) / spread
            if r2 > best:
                term, ratio, best = name, c, r2
    return ImbalanceGrowth(float(time[first]), float(time[last]), float(gap[last] - gap[first]), term, ratio,
                           best if term is not None else 0.0)

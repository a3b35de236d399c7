"""A perforated plate measured as an impact experiment reports it: the hole's diameter and the
number of petals (paper 000, section 4.2: four petals at every resolution).

The rules (one home, documented in docs/user-guide-meshfree.md):

- The impact axis is a line along the plate's normal (the impactor's path).
- The hole is the opening seen along the axis. The plate is the largest piece still linked
  together (a plug or a loose fragment is not the plate); each of its particles, projected onto
  the plate's plane at its current position, stands for a disc of half a spacing (its cell). Along
  each of RAYS rays from the axis, the hole's radius is where the ray first meets such a disc; the
  hole's diameter is twice the median over the rays (the smallest and largest are reported beside
  it); 0 where the plate still covers the axis.
- A petal is bounded by radial cracks. A radial crack is a run of failed particles whose material
  crack normal lies within 45 degrees of the hoop direction about the axis (the crack plane holds
  the radius and the normal); a ring of failed particles with radial normals is a plug's rim and
  opens no petal. The petals are the radial cracks that reach a circle `reach` beyond the hole's
  rim (reference positions): the failed particles within a spacing of that circle, split into
  runs where two neighbours along it are more than two spacings apart. The default reach is the
  hole's radius (a petal's crack at least as long as the hole is wide at its half; not less than
  PETAL_REACH spacings): a ragged rim, failures a spacing or two past the hole all round, is not
  petals. `petals_by_reach` gives the count at 1 to 4 spacings beside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RAYS = 36  # rays from the axis along which the hole's radius is measured (10 degrees apart)
HOOP_COSINE = np.cos(np.pi / 4)  # a radial crack's normal within 45 degrees of the hoop direction
PETAL_REACH = 2.0  # the least reach beyond the hole's rim, in particle spacings (the resolution)


@dataclass(frozen=True)
class Perforation:
    hole_diameter: float  # m, twice the median over the rays of the opening's radius
    hole_diameter_min: float  # m
    hole_diameter_max: float  # m
    petals: int  # radial cracks that cross the circle `reach` beyond the hole's rim
    petal_circle: float  # m, that circle's radius about the axis
    plug_particles: int  # particles no longer part of the plate (plug, fragments, free particles)
    # of those, the particles of the largest piece still linked together: a plug is one piece, a
    # hole whose material went as debris or single particles leaves none large
    largest_loose_piece: int
    # The rule's sensitivity: (reach in spacings, petals) for 1 to 4 spacings beyond the rim
    petals_by_reach: tuple = ()

    def summary(self) -> dict:
        return {"hole_diameter": self.hole_diameter, "hole_diameter_min": self.hole_diameter_min,
                "hole_diameter_max": self.hole_diameter_max, "petals": self.petals,
                "petal_circle_radius": self.petal_circle, "petals_by_reach": [list(r) for r in self.petals_by_reach],
                "plug_particles": self.plug_particles, "largest_loose_piece": self.largest_loose_piece}


def measure_perforation(X, x, piece, failed, crack_normal, axis_point, axis, spacing: float,
                        reach: float | None = None) -> Perforation:
    """The hole and the petals of a plate about the impact axis (the line through `axis_point`
    along the unit `axis`, the plate's normal): X and x the particles' reference and current
    positions (n, 3), `piece` (n,) each particle's piece (particles still linked together; 0 the
    plate's main piece, analysis.fragments), `failed` (n,)
    bool with `crack_normal` (n, 3) their material crack normals, `spacing` the in-plane particle
    spacing (m) and `reach` the distance beyond the hole's rim that a radial crack must reach
    (m; default the hole's radius, at least PETAL_REACH spacings)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    origin = np.asarray(axis_point, dtype=float)
    piece = np.asarray(piece)
    in_plate = piece == 0
    loose = np.bincount(piece[~in_plate]) if np.any(~in_plate) else np.zeros(1, dtype=np.int64)

    def polar(points):
        d = np.asarray(points, dtype=float) - origin
        u, v = d @ e1, d @ e2
        return np.hypot(u, v), np.arctan2(v, u)

    # The opening seen along the axis: along each ray from the axis, where it first meets a plate
    # particle's cell (a disc of half a spacing about its projection).
    r, theta = polar(np.asarray(x)[in_plate])
    half = 0.5 * spacing
    radius = np.full(RAYS, np.inf)
    for k, angle in enumerate(np.arange(RAYS) * (2.0 * np.pi / RAYS)):
        along, off = r * np.cos(theta - angle), r * np.sin(theta - angle)
        hit = (np.abs(off) <= half) & (along > -half)
        if hit.any():
            radius[k] = max(float(np.min(along[hit] - np.sqrt(half**2 - off[hit] ** 2))), 0.0)
    radius = radius[np.isfinite(radius)]  # a ray that meets no plate at all has no rim
    if len(radius) == 0:
        radius = np.zeros(1)
    hole = float(np.median(radius))

    # The radial cracks crossing the petal circle.
    R, Theta = polar(X)
    hoop = np.stack([-np.sin(Theta), np.cos(Theta)], axis=1)
    n_plane = np.stack([np.asarray(crack_normal) @ e1, np.asarray(crack_normal) @ e2], axis=1)
    radial = np.abs(np.einsum("ij,ij->i", hoop, n_plane)) >= HOOP_COSINE * np.linalg.norm(crack_normal, axis=1)
    radial &= np.asarray(failed)

    def petals_at(circle):
        on_circle = radial & (np.abs(R - circle) <= spacing)
        return _runs(np.sort(Theta[on_circle]), circle, 2.0 * spacing)

    reach = max(PETAL_REACH * spacing, hole) if reach is None else float(reach)
    by_reach = tuple((k, petals_at(hole + k * spacing)) for k in (1, 2, 3, 4))
    return Perforation(2.0 * hole, 2.0 * float(radius.min()), 2.0 * float(radius.max()), petals_at(hole + reach),
                       hole + reach, int(np.count_nonzero(~in_plate)), int(loose.max()), by_reach)


def _runs(angles: np.ndarray, circle: float, gap: float) -> int:
    """The runs of sorted angles (rad) on a circle of radius `circle` that are split where two
    neighbours are more than `gap` (m) apart along it, the circle closed."""
    if len(angles) == 0:
        return 0
    steps = np.diff(np.append(angles, angles[0] + 2.0 * np.pi)) * circle
    return max(int(np.count_nonzero(steps > gap)), 1)

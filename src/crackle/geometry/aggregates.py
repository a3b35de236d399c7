"""Random concrete mesostructure: non-overlapping spherical (or, along an axis, cylindrical)
aggregates of a Fuller grading placed in a box by take-and-place.

The classic generator of meso-scale concrete models (Walraven 1980; Wriggers and Moftah 2006,
Finite Elem. Anal. Des. 42: 623-636): the aggregates between `min_diameter` and `max_diameter`
take the share of the box that `volume_fraction` says, split over size classes by the Fuller
curve P(d) = (d / d_max)^n (the volume fraction of the aggregate passing a sieve of size d; what
passes `min_diameter` is the mortar's sand and is not modelled). The sizes are drawn first, then
placed largest first, each at uniformly random positions until one keeps `gap` from every
aggregate placed before it. With an axis the aggregates are circular cylinders through the whole
box (the 2D mesostructure of thin specimens) and every fraction is by area of the cross-section.

The box is periodic: an aggregate crossing a face comes back through the opposite one. The
aggregates are then spread evenly up to the faces (no wall effect, as in a core drilled or a disc
sawn from a larger casting), the box holds exactly the placed fraction, and any specimen inside
it, its bounding box or a larger one, holds that fraction on average, its aggregates cut by its
surface.

Deterministic: the same arguments give the same aggregates (numpy's PCG64 from `seed`), whatever
mesh or method later asks which points they hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# Size classes per doubling of the diameter: each class is filled to its Fuller share on its own,
# so the placed grading follows the curve class by class, not only on average.
CLASSES_PER_OCTAVE = 4
# Random positions an aggregate may try before the placement is declared jammed.
MAX_TRIES = 20_000
# More aggregates than a tet mesh resolving each with a few elements could hold.
MAX_AGGREGATES = 1_000_000
# Above this fraction random take-and-place does not get: for a Fuller grading over a factor 4 in
# size it jams near 0.45 in 3D and past 0.6 in 2D (measured), less for narrower gradings; denser
# packings need other algorithms.
MAX_FRACTION = 0.6


class AggregatePlacementError(ValueError):
    """The aggregates drawn for the fraction could not all be placed."""


@dataclass(frozen=True, eq=False)
class Aggregates:
    """Placed aggregates: spheres, or with `axis` (0, 1, 2) cylinders along that coordinate
    through the box."""

    centers: np.ndarray
    """m, (n, 3); a cylinder's coordinate along the axis is the box's mid-plane"""
    diameters: np.ndarray
    """m, (n,), largest first"""
    axis: int | None
    box_min: np.ndarray
    box_max: np.ndarray

    def _across(self) -> list[int]:
        """The coordinates the aggregates are round in (all three, or the two across the axis)."""
        return [k for k in range(3) if k != self.axis]

    def _periodic(self):
        """The centres in the box's frame, [0, L) across the aggregates, and L: what a periodic
        cKDTree takes."""
        across = self._across()
        size = (self.box_max - self.box_min)[across]
        return _wrap(self.centers[:, across] - self.box_min[across], size), size

    def contains(self, x) -> np.ndarray:
        """Which of the points x (m, (k, 3)) lie inside an aggregate (or its periodic image) and
        inside the box."""
        from scipy.spatial import cKDTree

        x = np.asarray(x, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(x), dtype=bool)
        if not len(x) or not len(self.diameters):
            return inside
        rows = np.flatnonzero(np.all((x >= self.box_min) & (x <= self.box_max), axis=1))
        centers, size = self._periodic()
        across = self._across()
        tree = cKDTree(_wrap(x[np.ix_(rows, across)] - self.box_min[across], size), boxsize=size)
        for hits in tree.query_ball_point(centers, 0.5 * self.diameters, return_sorted=False):
            inside[rows[hits]] = True
        return inside

    def measure(self) -> float:
        """m^3 of the spheres, or m^2 of the cylinders' cross-sections."""
        return float(np.sum(_measure(self.diameters, len(self._across()))))

    def fraction(self) -> float:
        """The share of the box (by volume; with an axis, of its cross-section by area) they fill."""
        extent = (self.box_max - self.box_min)[self._across()]
        return self.measure() / float(np.prod(extent))

    def closest_gap(self) -> float:
        """m, the smallest distance between two aggregates' surfaces (inf for fewer than two)."""
        from scipy.spatial import cKDTree

        if len(self.diameters) < 2:
            return math.inf
        c, size = self._periodic()
        r = 0.5 * self.diameters
        tree = cKDTree(c, boxsize=size)
        # The nearest centres give one pair's gap; any closer pair has its centres within that gap
        # plus two of the largest radii: search those, exactly.
        distance, other = tree.query(c, k=2)
        first = int(np.argmin(distance[:, 1]))
        bound = distance[first, 1] - r[first] - r[other[first, 1]]
        pairs = tree.query_pairs(bound + 2.0 * r.max(), output_type="ndarray")
        if not len(pairs):
            return float(bound)
        i, j = pairs[:, 0], pairs[:, 1]
        apart = c[i] - c[j]
        apart -= size * np.round(apart / size)  # the nearest image
        return float(min(bound, np.min(np.linalg.norm(apart, axis=1) - r[i] - r[j])))


def _wrap(v: np.ndarray, size: np.ndarray) -> np.ndarray:
    """v folded into [0, size) (np.mod rounds a tiny negative value up to size itself, which a
    periodic cKDTree refuses)."""
    v = np.mod(v, size)
    return np.where(v >= size, 0.0, v)


def _measure(d, dims: int):
    """Volume of spheres (dims 3) or area of discs (dims 2) of diameters d."""
    return math.pi / 6.0 * d ** 3 if dims == 3 else math.pi / 4.0 * d ** 2


def fuller_passing(d, max_diameter: float, exponent: float = 0.5):
    """The Fuller curve: the fraction of the aggregate passing a sieve of size d, (d / d_max)^n."""
    return (np.asarray(d, dtype=float) / max_diameter) ** exponent


def graded_fraction_passing(d, min_diameter: float, max_diameter: float, exponent: float = 0.5):
    """The share of the modelled aggregate (min_diameter to max_diameter) finer than d: the Fuller
    curve between the two sieves, rescaled to 0 at min_diameter and 1 at max_diameter."""
    if max_diameter == min_diameter:
        return np.where(np.asarray(d) >= max_diameter, 1.0, 0.0)
    low = fuller_passing(min_diameter, max_diameter, exponent)
    share = (fuller_passing(np.clip(d, min_diameter, max_diameter), max_diameter, exponent) - low) / (1.0 - low)
    return share


def _draw_in_class(rng, low: float, high: float, exponent: float, dims: int) -> float:
    """One diameter in [low, high] drawn by number so that the class's volume follows the Fuller
    curve: its volume density is proportional to d^(n-1), its number density to d^(n-1-dims)."""
    if high == low:
        return low
    e = exponent - dims
    u = rng.random()
    if abs(e) < 1e-12:
        return low * (high / low) ** u
    return (low ** e + u * (high ** e - low ** e)) ** (1.0 / e)


def draw_diameters(rng, target: float, min_diameter: float, max_diameter: float, exponent: float,
                   dims: int) -> np.ndarray:
    """Diameters whose volumes (areas for dims 2) sum to `target` within half the smallest one,
    split over size classes by the Fuller curve; largest first.

    Classes run from the largest down, each filled until its running total reaches the Fuller
    share through that class: a draw is kept while it brings the total nearer that share, so no
    class is off by more than about half an aggregate and the shortfalls do not add up."""
    octaves = math.log2(max_diameter / min_diameter) if max_diameter > min_diameter else 0.0
    n_classes = max(1, math.ceil(octaves * CLASSES_PER_OCTAVE))
    sieves = min_diameter * (max_diameter / min_diameter) ** (np.arange(n_classes + 1) / n_classes)
    coarser = 1.0 - graded_fraction_passing(sieves, min_diameter, max_diameter, exponent)  # retained share
    out, total = [], 0.0
    for k in range(n_classes - 1, -1, -1):
        through = target * coarser[k]  # the running total this class must bring
        while True:
            d = _draw_in_class(rng, sieves[k], sieves[k + 1], exponent, dims)
            size = _measure(d, dims)
            if total + 0.5 * size > through:
                break
            out.append(d)
            total += size
            if len(out) > MAX_AGGREGATES:
                raise AggregatePlacementError(
                    f"more than {MAX_AGGREGATES:,} aggregates would fill this fraction of the box: no mesh "
                    "resolves so many; give a larger min_diameter or a smaller box")
    return np.sort(np.asarray(out, dtype=float))[::-1]


def check_request(extent, min_diameter: float, max_diameter: float, volume_fraction: float, gap: float) -> None:
    """AggregatePlacementError for what take-and-place cannot do whatever the draw: sizes the wrong
    way round, a fraction past MAX_FRACTION, a box (`extent`: its sides across the aggregates, m)
    under twice the largest reach, where the nearest periodic image no longer decides the gap."""
    if min_diameter > max_diameter:
        raise AggregatePlacementError(f"min_diameter = {min_diameter:g} m is above max_diameter = {max_diameter:g} m")
    if not 0.0 < volume_fraction <= MAX_FRACTION:
        raise AggregatePlacementError(
            f"volume_fraction = {volume_fraction:g} is beyond random take-and-place (it jams below {MAX_FRACTION:g}; "
            f"about 0.45 in 3D): give a fraction above 0 and at most {MAX_FRACTION:g}")
    if min(extent) < 2.0 * (max_diameter + gap):
        raise AggregatePlacementError(
            f"the box is {min(extent):g} m across the aggregates at its narrowest, under twice max_diameter + gap "
            f"= {max_diameter + gap:g} m (an aggregate must not meet its own periodic image): give a larger box (it may "
            f"reach beyond the specimen) or a smaller max_diameter"
            + (", or an axis for cylinders through a thin specimen" if len(extent) == 3 else ""))


def place_aggregates(box_min, box_max, min_diameter: float, max_diameter: float, volume_fraction: float,
                     gap: float, seed: int = 0, exponent: float = 0.5, axis: int | None = None,
                     max_tries: int = MAX_TRIES) -> Aggregates:
    """Take-and-place: aggregates of a Fuller grading filling `volume_fraction` of the periodic
    box, no two surfaces closer than `gap` (across its faces too, through the periodic images);
    spheres, or with `axis` (0, 1 or 2) cylinders along that coordinate through the whole box.
    The centres lie in the box.

    AggregatePlacementError when an aggregate finds no free place in `max_tries` random positions
    (the fraction is past what random placement reaches for this grading and gap), or the request
    cannot be met whatever the draw (check_request)."""
    lo, hi = np.asarray(box_min, dtype=float), np.asarray(box_max, dtype=float)
    across = [k for k in range(3) if k != axis]
    dims = len(across)
    extent = (hi - lo)[across]
    check_request(extent, min_diameter, max_diameter, volume_fraction, gap)
    sizes_stream, places_stream = (np.random.Generator(np.random.PCG64(s))
                                   for s in np.random.SeedSequence(seed).spawn(2))
    target = volume_fraction * float(np.prod(extent))
    diameters = draw_diameters(sizes_stream, target, min_diameter, max_diameter, exponent, dims)
    centers = _take_and_place(places_stream, diameters, lo[across], hi[across], gap, max_tries, target)
    full = np.empty((len(diameters), 3))
    full[:, across] = centers
    if axis is not None:
        full[:, axis] = 0.5 * (lo[axis] + hi[axis])
    return Aggregates(full, diameters, axis, lo, hi)


def _take_and_place(rng, diameters: np.ndarray, lo: np.ndarray, hi: np.ndarray, gap: float, max_tries: int,
                    target: float) -> np.ndarray:
    """Centres for the diameters (largest first) at random free places in the periodic box, the
    candidates drawn from `rng` in blocks and tried in order by the compiled `_place_block` (the
    block size does not change which candidate an aggregate gets: the stream is read in one
    order)."""
    dims = len(lo)
    # Work in three coordinates: a 2D set is the plane z = 0 with one cell through it.
    lo3, hi3 = np.zeros(3), np.zeros(3)
    lo3[:dims], hi3[:dims] = lo, hi
    cell = float(diameters[0]) + gap if len(diameters) else 1.0
    # Whole cells across the box, each at least the largest reach wide.
    shape = np.maximum(1, np.floor((hi3 - lo3) / cell)).astype(np.int64)
    head = np.full(int(np.prod(shape)), -1, dtype=np.int64)  # per cell its last aggregate, -1: none
    next_in_cell = np.full(len(diameters), -1, dtype=np.int64)  # the aggregate placed before it in its cell
    centers = np.zeros((len(diameters), 3))
    radius = 0.5 * np.asarray(diameters, dtype=float)
    state = np.zeros(2, dtype=np.int64)  # the aggregate being placed, its tries so far
    block = np.zeros((4096, 3))
    while state[0] < len(diameters):
        block[:, :dims] = rng.random((len(block), dims))
        if not _place_block(block, centers, radius, lo3, hi3, gap, cell, shape, head, next_in_cell, state, max_tries):
            i = int(state[0])
            box = float(np.prod(hi - lo))
            placed = float(np.sum(_measure(diameters[:i], dims)))
            raise AggregatePlacementError(
                f"take-and-place jammed: aggregate {i + 1:,} of {len(diameters):,} (diameter {diameters[i]:.3g} m) "
                f"found no free place in {max_tries:,} random tries, with {placed / box:.3f} of the box filled "
                f"towards {target / box:.3f}: give a lower volume_fraction or gap, or a wider grading (a lower "
                f"min_diameter fills the spaces between the large ones)")
    return centers[:, :dims]


@njit(cache=True)
def _place_block(uniform, centers, radius, lo, hi, gap, cell, shape, head, next_in_cell, state, max_tries):
    """Try the candidates of `uniform` ((B, 3) in [0, 1), in order) for the aggregates from
    state[0] on: a candidate keeps `gap` from the nearest periodic image of every placed aggregate
    (those in its cell and the cells around it, wrapping round the box; a cell is at least the
    largest reach wide) or is dropped. False when an aggregate has used max_tries candidates;
    state holds where it got."""
    i, tries = state[0], state[1]
    n = radius.shape[0]
    size = hi - lo
    p = np.empty(3)
    home = np.empty(3, dtype=np.int64)
    first = np.empty(3, dtype=np.int64)
    count = np.empty(3, dtype=np.int64)
    for k in range(uniform.shape[0]):
        if i >= n:
            break
        r = radius[i]
        for c in range(3):
            p[c] = lo[c] + uniform[k, c] * size[c]  # the flat third coordinate of a 2D set stays lo
            home[c] = min(int(uniform[k, c] * shape[c]), shape[c] - 1)
            # The cells around, wrapping; all of them where there are fewer than three.
            first[c], count[c] = (home[c] - 1, 3) if shape[c] >= 3 else (0, shape[c])
        tries += 1
        fits = True
        for da in range(count[0]):
            a = (first[0] + da) % shape[0]
            for db in range(count[1]):
                b = (first[1] + db) % shape[1]
                for dc in range(count[2]):
                    j = head[(a * shape[1] + b) * shape[2] + (first[2] + dc) % shape[2]]
                    while j >= 0 and fits:
                        distance2 = 0.0
                        for c in range(3):
                            d = p[c] - centers[j, c]
                            if size[c] > 0.0:
                                d -= size[c] * np.round(d / size[c])  # the nearest image
                            distance2 += d * d
                        if math.sqrt(distance2) - radius[j] - r < gap:
                            fits = False
                        j = next_in_cell[j]
        if fits:
            centers[i, 0], centers[i, 1], centers[i, 2] = p[0], p[1], p[2]
            flat = (home[0] * shape[1] + home[1]) * shape[2] + home[2]
            next_in_cell[i] = head[flat]
            head[flat] = i
            i += 1
            tries = 0
        elif tries >= max_tries:
            state[0], state[1] = i, tries
            return False
    state[0], state[1] = i, tries
    return True

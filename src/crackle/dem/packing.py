"""Random dense packings of spheres filling a domain: the particles of the bonded-particle DEM.

The radii are uniformly distributed between Rmin and Rmax = radius_ratio Rmin (paper 003,
section 2.3: Dmax / Dmin = 1.86), and their number follows from the domain's volume and the
target porosity: the spheres' volume is (1 - porosity) x the domain's volume.

Algorithm (deterministic for a seed, bit-identical for any numba thread count):

1. radii evenly spread over [Rmin, Rmax] (both ends and the uniform distribution hold exactly),
   shuffled; centres drawn uniformly inside the domain; radii scaled down to a loose start;
2. sweeps of FIRE minimisation of the overlap energy sum(overlap^2) / 2: each sphere gathers the
   overlaps with its neighbours (a pair list with a skin, rebuilt through a uniform cell grid
   when the spheres have moved or grown enough), then moves; spheres poking out of the domain
   are projected back in (the walls are a hard constraint);
3. while the largest overlap stays moderate the radii grow by 0.5 % a sweep up to their targets;
4. done when the radii are at their targets and the largest overlap is below the tolerance;
   ValueError when the overlaps stop shrinking (the spheres jammed: porosity out of reach).

The domain is one of dem.domains (its shapes); a packing from another code is read by
dem.sphere_list.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..budget import check_model_size

# Packing fraction of the start (the radii scaled down to it): loose enough that the first
# sweeps only separate the random centres, dense enough that little growth is left to do.
START_FRACTION = 0.30
# Radius growth per sweep, allowed while the largest overlap is below GROWTH_GATE mean radii:
# the compression pauses whenever FIRE falls behind, which lets the spheres find denser
# arrangements than a fast compression (2000 spheres in a cube reach porosity 0.40; with a
# gate of 0.3 they jammed short of it).
GROWTH, GROWTH_GATE = 0.005, 0.05
# Pair-list skin, in mean radii: thicker lists, fewer rebuilds.
SKIN = 0.3
# FIRE (Bitzek et al., PRL 97, 170201, 2006), in units where the force is an overlap (m) and the
# masses are 1: step dt (dimensionless; the stiffest sphere, with ~12 contacts, vibrates with
# period ~2), its growth after FIRE_DELAY downhill sweeps and its cut when going uphill.
DT_START, DT_MAX = 0.1, 0.3
FIRE_DELAY, FIRE_DT_GROW, FIRE_DT_SHRINK = 5, 1.1, 0.5
ALPHA_START, FIRE_ALPHA_SHRINK = 0.1, 0.99
# Jammed: JAM_SWEEPS sweeps without lowering the largest overlap by JAM_PROGRESS (relative).
# Then the radii shrink by RETREAT each RETREAT_SWEEPS such sweeps until the spheres relax, to
# tell what porosity is reachable.
JAM_SWEEPS, JAM_PROGRESS = 400, 0.02
RETREAT, RETREAT_SWEEPS = 0.002, 50
# Porosity refused outright: random packings are not that dense for any radius range up to ~10.
MIN_POROSITY = 0.25
# Compaction past contact (particle_density): the spheres are first packed without overlap at
# COMPACTION_START porosity (reachable from a few hundred spheres on), then grow together by
# GROWTH a sweep while FIRE relaxes them, frictionless, and settle until no sphere's net overlap
# force exceeds SETTLED times the mean of the spheres' largest overlaps (a jammed packing in
# equilibrium).
COMPACTION_START = 0.45
SETTLED = 0.05
# What this generator reaches with Rmax / Rmin = 1.86 in a cube (measured; the walls loosen the
# layer of spheres along them, so fewer spheres reach less), for the messages.
REACHABLE = "~0.41 with 1000 spheres, ~0.40 with 2000, ~0.37 with 100,000"
# Fewest spheres for the parallel pair loops: below, starting a parallel loop each sweep costs
# more than it saves, and much more on a machine shared with other work (threads waiting for
# each other at the end of every loop). Both give the same bits.
PARALLEL_MIN = 5000
# Neighbours a sphere's pair list holds at first (grown when a sphere has more).
NEIGHBOUR_CAPACITY = 32
# Projections onto the nearest wall per sweep (a sphere in a box's corner needs three), and the
# poking out left to rounding, in radii.
PUSH_PASSES, PUSH_SLACK = 8, 1e-12


@dataclass(frozen=True, eq=False)
class Packing:
    """Spheres filling a domain: `centers` (n, 3, m), `radii` (n, m), the `domain`'s description,
    the `seed` that made it, the `porosity` reached (1 - spheres' volume / domain volume; the
    tiny lens of each remaining overlap is not deducted), the largest and the mean overlap (m)
    of the overlapping pairs (r_a + r_b - distance > 0; 0 when none overlap), and the number of
    relaxation `sweeps` it took. The spheres are numbered cell by cell (cells of 2 Rmax, x
    fastest, z slowest) so that neighbours are near in memory."""

    centers: np.ndarray
    radii: np.ndarray
    domain: dict
    seed: int
    porosity: float
    max_overlap: float
    mean_overlap: float
    sweeps: int

    def save(self, path: str | os.PathLike) -> None:
        """Write to an .npz file at exactly `path` (every number round-trips bit for bit)."""
        with open(path, "wb") as f:
            np.savez(f, centers=self.centers, radii=self.radii, domain=np.array(json.dumps(self.domain)),
                     seed=np.array(self.seed, dtype=np.int64), porosity=np.array(self.porosity),
                     max_overlap=np.array(self.max_overlap), mean_overlap=np.array(self.mean_overlap),
                     sweeps=np.array(self.sweeps, dtype=np.int64))

    @classmethod
    def load(cls, path: str | os.PathLike) -> Packing:
        """The packing written by `save`; ValueError for a file that is not one (another .npz, junk)."""
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls(centers=z["centers"], radii=z["radii"], domain=json.loads(str(z["domain"])),
                           seed=int(z["seed"]), porosity=float(z["porosity"]), max_overlap=float(z["max_overlap"]),
                           mean_overlap=float(z["mean_overlap"]), sweeps=int(z["sweeps"]))
        except (KeyError, ValueError, OSError, EOFError, zipfile.BadZipFile) as err:
            raise ValueError(f"not a packing crackle saved ({type(err).__name__}: {err}); a packing from another code "
                             "goes in a text sphere list, one 'x y z r' line per sphere (m)") from None


def radius_range(mean_radius: float, radius_ratio: float) -> tuple[float, float]:
    """(Rmin, Rmax) (m) of the uniform distribution with mean `mean_radius` (m) and Rmax / Rmin =
    `radius_ratio`."""
    r_min = 2.0 * mean_radius / (1.0 + radius_ratio)
    return r_min, radius_ratio * r_min


def pack_spheres(domain, *, porosity: float = 0.4, radius_ratio: float = 1.86, mean_radius: float | None = None,
                 count: int | None = None, seed: int = 0, overlap_tolerance: float = 0.01,
                 max_sweeps: int = 20000, particle_density: float | None = None,
                 max_memory: float | None = None) -> Packing:
    """A random dense packing of spheres inside `domain` (algorithm: the module's docstring).

    porosity: target void fraction of the domain, in (0, 1). With Rmax / Rmin = 1.86 in a cube the
        densest reached are ~0.41 with 1000 spheres, ~0.40 with 2000, ~0.37 with 100,000 (the
        walls loosen the layer of spheres along them).
    radius_ratio: Rmax / Rmin >= 1 of the uniform radius distribution (paper 003: 1.86).
    mean_radius: (Rmin + Rmax) / 2 (m); the number of spheres then follows from the porosity
        (rounded, so the porosity reached differs by up to half a sphere's volume).
    count: the number of spheres instead; the mean radius then follows from the porosity.
    seed: of numpy's default_rng; the same seed gives the same packing bit for bit, whatever
        the number of numba threads.
    overlap_tolerance: largest overlap r_a + r_b - distance accepted, as a fraction of the mean
        radius.
    max_sweeps: relaxation sweeps allowed.
    particle_density: instead of a porosity, the number of spheres per cubed mean diameter,
        n (2 mean_radius)^3 / V (paper 003: 1.47; a packing without overlap holds ~1.05 at
        porosity 0.40). The spheres are packed without overlap at porosity COMPACTION_START, then
        grown together to their radii, frictionless, and settled: the overlaps a DEM code's
        isotropic compaction by radius growth leaves (Yade, PFC), which the bonds start from
        unloaded. `porosity` is then not used; the Packing's is 1 - the spheres' volume / V
        (overlaps counted twice: 0.16 at 1.47).
    max_memory: bytes the packing may plan for (budget.check_model_size; None: what the machine
        has available): the count is checked before anything is allocated.

    Every sphere ends inside: domain.signed_distance(centre) <= -radius, to rounding (for a
    ClosedSurface, of its interpolated distance). ValueError naming the field on bad input, and
    naming packing.porosity when the spheres jam before reaching it.
    """
    porosity = float(porosity)
    if not (0.0 < porosity < 1.0):
        raise ValueError(f"packing.porosity must be in (0, 1), got {porosity!r}")
    if porosity < MIN_POROSITY:
        raise ValueError(f"packing.porosity = {porosity:g} is out of reach: random sphere packings are not denser "
                         f"than porosity ~{MIN_POROSITY:g} even for wide radius ranges; with Rmax / Rmin = 1.86 in a "
                         f"cube this generator reaches {REACHABLE}")
    radius_ratio = float(radius_ratio)
    if not (math.isfinite(radius_ratio) and radius_ratio >= 1.0):
        raise ValueError(f"packing.radius_ratio (Rmax / Rmin) must be >= 1, got {radius_ratio!r}")
    if (mean_radius is None) == (count is None):
        raise ValueError("packing.mean_radius / packing.count: give exactly one of them")
    overlap_tolerance = float(overlap_tolerance)
    if not (0.0 < overlap_tolerance < 1.0):
        raise ValueError(f"packing.overlap_tolerance (fraction of the mean radius) must be in (0, 1), "
                         f"got {overlap_tolerance!r}")
    if int(max_sweeps) < 1:
        raise ValueError(f"packing.max_sweeps must be a positive number of sweeps, got {max_sweeps!r}")
    seed = int(seed)
    volume = float(domain.volume)

    def unit_radii(n):
        # Radii for a mean radius of 1, evenly spread from Rmin to Rmax: both ends, their ratio and
        # the uniform distribution hold exactly whatever the count.
        return np.linspace(*radius_range(1.0, radius_ratio), n) if n > 1 else np.ones(1)

    growth = 1.0  # the final radii over those packed without overlap
    if particle_density is not None:
        particle_density = float(particle_density)
        if not (math.isfinite(particle_density) and particle_density > 0.0):
            raise ValueError(f"packing.particle_density must be a positive number of spheres per cubed mean "
                             f"diameter, got {particle_density!r}")
        if mean_radius is None:
            raise ValueError("packing.particle_density needs packing.mean_radius (the count follows from both)")
        mean_radius = float(mean_radius)
        if not (math.isfinite(mean_radius) and mean_radius > 0.0):
            raise ValueError(f"packing.mean_radius must be a positive length (m), got {mean_radius!r}")
        n = int(round(particle_density * volume / (2.0 * mean_radius) ** 3))
        if n < 1:
            raise ValueError(f"packing.mean_radius = {mean_radius:g} m with packing.particle_density = {particle_density:g}: "
                             f"fewer than one sphere in the domain ({volume:.3g} m^3); lengths are in metres (mm "
                             f"meant? write {mean_radius:g}e-3)")
        check_model_size(n, "spheres", "packing.mean_radius", max_memory)
        solid = 4.0 / 3.0 * math.pi * float(np.sum((mean_radius * unit_radii(n)) ** 3))
        if solid > volume:
            raise ValueError(f"packing.particle_density = {particle_density:g}: the spheres' volumes would add to "
                             f"{solid / volume:.3g}x the domain's, overlaps too deep for a packing (paper 003's 1.47 "
                             f"fills 0.84 of it); set it at most {particle_density * volume / solid:.3g}")
        growth = max(1.0, (solid / ((1.0 - COMPACTION_START) * volume)) ** (1.0 / 3.0))
        porosity, mean_radius, count = 1.0 - solid / growth**3 / volume, None, n
    solid_volume = (1.0 - porosity) * volume

    if mean_radius is not None:
        field_name = "packing.mean_radius"
        mean_radius = float(mean_radius)
        if not (math.isfinite(mean_radius) and mean_radius > 0.0):
            raise ValueError(f"{field_name} must be a positive length (m), got {mean_radius!r}")
        r_min, r_max = radius_range(mean_radius, radius_ratio)
        # Mean sphere volume of the uniform distribution: (4 pi / 3) (Rmax^4 - Rmin^4) / (4 (Rmax - Rmin)).
        mean_volume = (math.pi / 3.0 * (r_max**4 - r_min**4) / (r_max - r_min) if r_max > r_min
                       else 4.0 / 3.0 * math.pi * r_min**3)
        n = int(round(solid_volume / mean_volume))
        check_model_size(n, "spheres", field_name, max_memory)
        if n < 1:
            raise ValueError(f"{field_name} = {mean_radius:g} m: the domain ({volume:.4g} m^3) is smaller than one "
                             f"sphere at porosity {porosity:g}")
        radii = mean_radius * unit_radii(n)
    else:
        field_name = "packing.count"
        if not (isinstance(count, (int, np.integer)) and not isinstance(count, bool) and count >= 1):
            raise ValueError(f"packing.count must be a positive integer, got {count!r}")
        n = int(count)
        check_model_size(n, "spheres", field_name, max_memory)
        unit = unit_radii(n)
        mean_radius = (solid_volume / (4.0 / 3.0 * math.pi * float(np.sum(unit**3)))) ** (1.0 / 3.0)
        radii = mean_radius * unit
    if radii.max() >= domain.inradius:
        raise ValueError(f"{field_name}: the largest sphere (radius {radii.max():.4g} m) does not fit in the domain "
                         f"(inradius {domain.inradius:.4g} m); use smaller spheres")

    rng = np.random.default_rng(seed)
    radii = radii[rng.permutation(n)]
    centers = _random_inside(domain, n, rng)
    centers, radii, sweeps = _relax(domain, centers, radii, porosity, mean_radius, overlap_tolerance * mean_radius,
                                    int(max_sweeps))
    if growth > 1.0:
        centers, radii, more = _relax(domain, centers, radii * growth, porosity, mean_radius * growth,
                                      overlap_tolerance * mean_radius, int(max_sweeps), compact_from=1.0 / growth)
        sweeps += more
    # Final numbering: cell by cell on a grid fixed by the domain and the largest radius.
    lo, hi = domain.bounds
    cell = 2.0 * float(radii.max())
    dims = np.maximum(np.floor((hi - lo) / cell).astype(np.int64), 1)
    _, order = _bin(centers, lo, cell, dims)
    centers, radii = np.ascontiguousarray(centers[order]), np.ascontiguousarray(radii[order])
    max_overlap, mean_overlap = _overlap_stats(centers, radii, lo, dims, cell)
    reached = 1.0 - float(np.sum(4.0 / 3.0 * math.pi * radii**3)) / volume
    return Packing(centers=centers, radii=radii, domain=domain.description(), seed=seed, porosity=reached,
                   max_overlap=max_overlap, mean_overlap=mean_overlap, sweeps=sweeps)


def _random_inside(domain, n: int, rng) -> np.ndarray:
    """n points uniformly distributed in the domain (rejection from its bounding box)."""
    lo, hi = domain.bounds
    fill = min(max(domain.volume / float(np.prod(hi - lo)), 1e-3), 1.0)
    found, total = [], 0
    while total < n:
        p = lo + (hi - lo) * rng.random((int(1.1 * (n - total) / fill) + 16, 3))
        p = p[domain.signed_distance(p) < 0.0]
        found.append(p)
        total += len(p)
    return np.ascontiguousarray(np.concatenate(found)[:n])


def _push_inside(domain, centers, radii, candidates) -> None:
    """Move each candidate sphere that pokes out of the domain back in along the normal (in
    place). A few passes: each projects onto the nearest wall only (a box's corner needs one
    pass per wall it crosses)."""
    for _ in range(PUSH_PASSES):
        poke = domain.signed_distance(centers[candidates]) + radii[candidates]
        out = poke > PUSH_SLACK * radii[candidates]
        if not np.any(out):
            return
        candidates = candidates[out]
        centers[candidates] -= poke[out, None] * domain.normal(centers[candidates])


def _stop_at_walls(velocity, spheres, pushes) -> None:
    """Remove from the velocity of each pushed sphere its component against the push (the
    velocity into the wall). Not the push / dt: with a small FIRE step, a wall's rounding-level
    pushes would turn into large kicks."""
    length = np.sqrt(np.sum(pushes * pushes, axis=1))
    pushed = length > 0.0
    if not np.any(pushed):
        return
    spheres, inward = spheres[pushed], pushes[pushed] / length[pushed, None]
    v = velocity[spheres]
    against = np.minimum(np.sum(v * inward, axis=1), 0.0)
    velocity[spheres] = v - against[:, None] * inward


class _Fire:
    """FIRE (Bitzek et al. 2006): damped dynamics whose velocity is steered along the force while
    it goes downhill, and stopped, with a shorter step, when it turns uphill."""

    def __init__(self):
        self.dt, self.alpha, self.uphill_free = DT_START, ALPHA_START, 0

    def move(self, centers, velocity, force) -> None:
        power, force_sq, velocity_sq = _fire_sums(force, velocity)
        if power >= 0.0:
            mix = self.alpha * math.sqrt(velocity_sq / force_sq) if force_sq > 0.0 else 0.0
            keep = 1.0 - self.alpha
            self.uphill_free += 1
            if self.uphill_free > FIRE_DELAY:
                self.dt, self.alpha = min(self.dt * FIRE_DT_GROW, DT_MAX), self.alpha * FIRE_ALPHA_SHRINK
        else:
            keep, mix = 0.0, 0.0
            self.dt, self.alpha, self.uphill_free = self.dt * FIRE_DT_SHRINK, ALPHA_START, 0
        _fire_move(centers, velocity, force, keep, mix, self.dt)


def _relax(domain, centers, radii, porosity, mean_radius, tolerance, max_sweeps, compact_from=None):
    """Grow the radii from the START_FRACTION packing to their targets while minimising the
    overlap energy sum(overlap^2) / 2 with FIRE (Bitzek et al. 2006: damped dynamics whose
    velocity is steered along the force and reset when it turns uphill), the walls a hard
    constraint (a sphere pushed back in loses its velocity into the wall). Returns (centres,
    radii, sweeps), the spheres renumbered cell by cell.

    compact_from: instead, compaction past contact (particle_density): the spheres, packed
    without overlap at `compact_from` times their radii, grow by GROWTH a sweep whatever their
    overlaps and settle (_settled: every net force off the walls within SETTLED times the mean
    of the spheres' largest overlaps); ValueError when they do not within max_sweeps."""
    n = len(radii)
    target_fraction = 1.0 - porosity
    scale = min(1.0, (START_FRACTION / target_fraction) ** (1.0 / 3.0)) if compact_from is None else compact_from
    lo, hi = domain.bounds
    r_max = float(radii.max())
    skin = SKIN * mean_radius
    velocity = np.zeros_like(centers)
    force = np.empty_like(centers)
    worst = np.empty(n)
    fire = _Fire()
    best, stalled = np.inf, 0
    jammed = None  # (sweep, largest overlap in mean radii, radius scale) once the spheres jam
    _push_inside(domain, centers, scale * radii, np.arange(n))
    rebuild = True
    for sweep in range(1, max_sweeps + 1):
        if rebuild:
            # Renumber by cell (locality), then list the pairs within reach + skin: valid until
            # two spheres have closed the skin by moving or growing.
            cell = 2.0 * r_max * scale + skin
            dims = np.maximum(np.floor((hi - lo) / cell).astype(np.int64), 1)
            start, order = _bin(centers, lo, cell, dims)
            centers, radii, velocity = centers[order], radii[order], velocity[order]
            counts, neighbours = _neighbour_list(centers, radii, scale, skin, start, lo, cell, dims)
            near_wall = np.flatnonzero(domain.signed_distance(centers) > -(scale * radii + skin))
            reference, scale_at_build, rebuild = centers.copy(), scale, False
        _pair_forces(centers, radii, scale, counts, neighbours, force, worst)
        largest = float(worst.max())
        if compact_from is not None:
            if scale == 1.0 and _settled(domain, centers, radii, force, near_wall, SETTLED * float(worst.mean())):
                return centers, radii, sweep
            scale = min(1.0, scale * (1.0 + GROWTH))
        else:
            if largest <= tolerance and (scale == 1.0 or jammed is not None):
                if jammed is None:
                    return centers, radii, sweep
                _raise_jammed(porosity, jammed, 1.0 - scale**3 * target_fraction)
            if largest < best * (1.0 - JAM_PROGRESS):
                best, stalled = largest, 0
            else:
                stalled += 1
            if jammed is not None:
                if stalled > RETREAT_SWEEPS:
                    # Shrink until the jammed spheres relax: the porosity they do reach.
                    scale, best, stalled = scale * (1.0 - RETREAT), np.inf, 0
            elif scale < 1.0 and largest <= GROWTH_GATE * mean_radius * scale:
                scale = min(1.0, scale * (1.0 + GROWTH))
                best, stalled = np.inf, 0
            elif stalled > JAM_SWEEPS:
                jammed = (sweep, largest / mean_radius, scale)
                best, stalled = np.inf, 0
        fire.move(centers, velocity, force)
        before = centers[near_wall]
        _push_inside(domain, centers, scale * radii, near_wall)
        _stop_at_walls(velocity, near_wall, centers[near_wall] - before)
        shift = math.sqrt(_largest_shift_sq(centers, reference))
        rebuild = 2.0 * shift + 2.0 * r_max * (scale - scale_at_build) > skin
    if compact_from is not None:
        raise ValueError(f"packing.particle_density: the compacted spheres did not settle within packing.max_sweeps = "
                         f"{max_sweeps} sweeps; allow more sweeps or aim looser")
    if jammed is None:
        raise ValueError(f"packing.max_sweeps = {max_sweeps} sweeps were not enough to reach packing.porosity = "
                         f"{porosity:g} (largest overlap {largest / mean_radius:.3g} mean radii at "
                         f"{100.0 * scale:.1f} % of the target radii); allow more sweeps or aim looser")
    _raise_jammed(porosity, jammed, None)


def _settled(domain, centers, radii, force, near_wall, tolerance):
    """Whether the net overlap force of every sphere off the walls is within `tolerance` (m). A
    sphere resting on a wall (or in a corner, on two or three) is balanced by the walls' reactions,
    which the overlap force leaves out."""
    on_wall = near_wall[domain.signed_distance(centers[near_wall]) + radii[near_wall] > -PUSH_SLACK * radii[near_wall]]
    free = np.ones(len(radii), dtype=bool)
    free[on_wall] = False
    net = np.sum(force[free] ** 2, axis=1)
    return len(net) == 0 or math.sqrt(float(net.max())) <= tolerance


def _raise_jammed(porosity, jammed, reachable):
    """ValueError for a porosity the spheres jam before reaching; `reachable`: the porosity at
    which the jammed spheres relaxed (None: not found within the sweeps)."""
    sweep, largest, scale = jammed
    found = (f"shrunk, these spheres relax at porosity {reachable:.3f}" if reachable is not None
             else "they did not relax within packing.max_sweeps when shrunk")
    raise ValueError(
        f"packing.porosity = {porosity:g} is out of reach: the spheres jammed after {sweep} sweeps (largest overlap "
        f"{largest:.3g} mean radii at {100.0 * scale:.1f} % of the target radii); {found}. With Rmax / Rmin = 1.86 "
        f"in a cube, reachable porosities are {REACHABLE} (the walls loosen the layer of spheres along them)"
    )


@njit(cache=True)
def _cell_index(x, y, z, lo, cell, dims):
    i = min(max(int(math.floor((x - lo[0]) / cell)), 0), dims[0] - 1)
    j = min(max(int(math.floor((y - lo[1]) / cell)), 0), dims[1] - 1)
    k = min(max(int(math.floor((z - lo[2]) / cell)), 0), dims[2] - 1)
    return (k * dims[1] + j) * dims[0] + i


@njit(cache=True)
def _bin(centers, lo, cell, dims):
    """(start, order): the spheres sorted by cell (counting sort; within a cell by index), cell
    c holding order[start[c]:start[c + 1]]. Cells of `cell` (m) from `lo`, the last ones of
    each axis extended to hold everything beyond."""
    n = centers.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    start = np.zeros(n_cells + 1, dtype=np.int64)
    cell_of = np.empty(n, dtype=np.int64)
    for s in range(n):
        c = _cell_index(centers[s, 0], centers[s, 1], centers[s, 2], lo, cell, dims)
        cell_of[s] = c
        start[c + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for s in range(n):
        order[fill[cell_of[s]]] = s
        fill[cell_of[s]] += 1
    return start, order


@njit(cache=True, inline="always")
def _scan_neighbours(s, centers, radii, scale, skin, start, lo, cell, dims, neighbours):
    """The spheres within (r_s + r_o) scale + skin of sphere s (spheres numbered by cell, so
    cell c holds start[c]..start[c + 1] - 1) into row s of `neighbours`, as far as it holds them;
    returns their count."""
    capacity = neighbours.shape[1]
    x, y, z = centers[s, 0], centers[s, 1], centers[s, 2]
    own = _cell_index(x, y, z, lo, cell, dims)
    ci = own % dims[0]
    cj = (own // dims[0]) % dims[1]
    ck = own // (dims[0] * dims[1])
    found = 0
    for k in range(max(ck - 1, 0), min(ck + 2, dims[2])):
        for j in range(max(cj - 1, 0), min(cj + 2, dims[1])):
            for i in range(max(ci - 1, 0), min(ci + 2, dims[0])):
                c = (k * dims[1] + j) * dims[0] + i
                for o in range(start[c], start[c + 1]):
                    if o == s:
                        continue
                    ex, ey, ez = x - centers[o, 0], y - centers[o, 1], z - centers[o, 2]
                    reach = (radii[s] + radii[o]) * scale + skin
                    if ex * ex + ey * ey + ez * ez < reach * reach:
                        if found < capacity:
                            neighbours[s, found] = o
                        found += 1
    return found


def _neighbour_list(centers, radii, scale, skin, start, lo, cell, dims):
    """(counts, neighbours): sphere s's neighbours within reach + skin are
    neighbours[s, :counts[s]] (each pair listed from both sides), in a fixed order."""
    fill = _fill_neighbours_parallel if len(radii) >= PARALLEL_MIN else _fill_neighbours_serial
    capacity = NEIGHBOUR_CAPACITY
    while True:
        counts = np.empty(len(radii), dtype=np.int64)
        neighbours = np.empty((len(radii), capacity), dtype=np.int32)
        fill(centers, radii, scale, skin, start, lo, cell, dims, counts, neighbours)
        most = int(counts.max())
        if most <= capacity:
            return counts, neighbours
        capacity = most  # a row was cut short: again, wide enough


@njit(cache=True, parallel=True)
def _fill_neighbours_parallel(centers, radii, scale, skin, start, lo, cell, dims, counts, neighbours):
    """Each sphere writes only its own row: the same list for any thread count."""
    for s in prange(centers.shape[0]):
        counts[s] = _scan_neighbours(s, centers, radii, scale, skin, start, lo, cell, dims, neighbours)


@njit(cache=True)
def _fill_neighbours_serial(centers, radii, scale, skin, start, lo, cell, dims, counts, neighbours):
    for s in range(centers.shape[0]):
        counts[s] = _scan_neighbours(s, centers, radii, scale, skin, start, lo, cell, dims, neighbours)


def _pair_forces(centers, radii, scale, counts, neighbours, force, worst):
    """force[s]: the sum of sphere s's overlaps (m) with its neighbours, each along the line of
    centres away from the other (minus the gradient of sum(overlap^2) / 2); worst[s]: its
    largest overlap (m)."""
    kernel = _pair_forces_parallel if len(radii) >= PARALLEL_MIN else _pair_forces_serial
    kernel(centers, radii, scale, counts, neighbours, force, worst)


@njit(cache=True, parallel=True)
def _pair_forces_parallel(centers, radii, scale, counts, neighbours, force, worst):
    """Each sphere gathers and writes only its own entries: the same bits for any thread count."""
    for s in prange(centers.shape[0]):
        _sphere_force(s, centers, radii, scale, counts, neighbours, force, worst)


@njit(cache=True)
def _pair_forces_serial(centers, radii, scale, counts, neighbours, force, worst):
    for s in range(centers.shape[0]):
        _sphere_force(s, centers, radii, scale, counts, neighbours, force, worst)


@njit(cache=True, inline="always")
def _sphere_force(s, centers, radii, scale, counts, neighbours, force, worst):
    x, y, z = centers[s, 0], centers[s, 1], centers[s, 2]
    fx = fy = fz = 0.0
    largest = 0.0
    for m in range(counts[s]):
        o = neighbours[s, m]
        ex, ey, ez = x - centers[o, 0], y - centers[o, 1], z - centers[o, 2]
        reach = (radii[s] + radii[o]) * scale
        d2 = ex * ex + ey * ey + ez * ez
        if d2 >= reach * reach:
            continue
        d = math.sqrt(d2)
        overlap = reach - d
        largest = max(largest, overlap)
        if d > 0.0:
            fx += overlap * ex / d
            fy += overlap * ey / d
            fz += overlap * ez / d
        else:
            fx += overlap if s > o else -overlap  # coincident centres: split along x
    force[s, 0] = fx
    force[s, 1] = fy
    force[s, 2] = fz
    worst[s] = largest


@njit(cache=True)
def _fire_sums(force, velocity):
    """(force . velocity, |force|^2, |velocity|^2), summed in index order (deterministic)."""
    power = force_sq = velocity_sq = 0.0
    for s in range(force.shape[0]):
        for d in range(3):
            power += force[s, d] * velocity[s, d]
            force_sq += force[s, d] * force[s, d]
            velocity_sq += velocity[s, d] * velocity[s, d]
    return power, force_sq, velocity_sq


@njit(cache=True)
def _fire_move(centers, velocity, force, keep, mix, dt):
    """velocity <- keep velocity + mix force + dt force; centres += dt velocity (unit masses).
    Serial: too little work per sphere to pay for starting a parallel loop."""
    for s in range(centers.shape[0]):
        for d in range(3):
            v = keep * velocity[s, d] + (mix + dt) * force[s, d]
            velocity[s, d] = v
            centers[s, d] += dt * v


@njit(cache=True)
def _largest_shift_sq(centers, reference):
    largest = 0.0
    for s in range(centers.shape[0]):
        dx = centers[s, 0] - reference[s, 0]
        dy = centers[s, 1] - reference[s, 1]
        dz = centers[s, 2] - reference[s, 2]
        largest = max(largest, dx * dx + dy * dy + dz * dz)
    return largest


def _overlap_stats(centers, radii, lo, dims, cell):
    """(largest, mean) overlap (m) of the overlapping pairs; spheres numbered by `cell` cells."""
    start, _ = _bin(centers, lo, cell, dims)
    counts, neighbours = _neighbour_list(centers, radii, 1.0, 0.0, start, lo, cell, dims)
    return _pair_overlaps(centers, radii, counts, neighbours)


@njit(cache=True)
def _pair_overlaps(centers, radii, counts, neighbours):
    largest = total = 0.0
    pairs = 0
    for s in range(centers.shape[0]):
        for m in range(counts[s]):
            o = neighbours[s, m]
            if o < s:
                continue
            ex = centers[s, 0] - centers[o, 0]
            ey = centers[s, 1] - centers[o, 1]
            ez = centers[s, 2] - centers[o, 2]
            overlap = radii[s] + radii[o] - math.sqrt(ex * ex + ey * ey + ez * ez)
            if overlap > 0.0:
                largest = max(largest, overlap)
                total += overlap
                pairs += 1
    return largest, (total / pairs if pairs else 0.0)

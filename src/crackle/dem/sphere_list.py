"""Packings made by another code: a plain text sphere list (Yade's `export.text`, LIGGGHTS or PFC
dumps), checked as it is read, and a label column of it (a group, a material)."""

from __future__ import annotations

import math
import os

import numpy as np

from .packing import Packing, _bin, _overlap_stats


def read_sphere_list(path: str | os.PathLike, domain) -> Packing:
    """A packing made by another code, from a plain text sphere list: one sphere per line,
    `x y z r` (m) separated by blanks or commas, further columns ignored (Yade's
    `export.text` / `textExt`, LIGGGHTS or PFC dumps cut to these columns), `#` starting a
    comment, blank lines skipped. `domain` is the specimen the spheres fill (the scenario's):
    every centre must lie inside it. ValueError naming the line for anything else. The
    spheres keep the file's order; overlaps are measured, not removed (bonds rest where the
    spheres lie)."""
    rows, lines = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            text = line.split("#", 1)[0].replace(",", " ").split()
            if not text:
                continue
            lines.append(number)
            try:
                values = [float(v) for v in text[:4]]
            except ValueError:
                shown = line.strip()
                shown = shown if len(shown) <= 60 else shown[:60] + "..."
                raise ValueError(f"line {number}: {shown!r} is not 'x y z r' (four numbers; a header goes after #)") from None
            if len(values) < 4:
                raise ValueError(f"line {number}: {line.strip()!r} has {len(values)} columns, not 'x y z r'")
            if not all(math.isfinite(v) for v in values) or values[3] <= 0.0:
                raise ValueError(f"line {number}: {line.strip()!r}: the radius must be > 0 and every value finite")
            rows.append(values)
    if len(rows) < 2:
        raise ValueError("fewer than two spheres: a sphere list has one 'x y z r' line per sphere")
    table = np.array(rows)
    centers, radii = np.ascontiguousarray(table[:, :3]), np.ascontiguousarray(table[:, 3])
    outside = np.flatnonzero(domain.signed_distance(centers) > 0.0)
    if len(outside):
        lo, hi = domain.bounds
        raise ValueError(
            f"{len(outside)} of {len(radii)} sphere centres lie outside the specimen (the first is sphere "
            f"{outside[0] + 1}, at {centers[outside[0]].tolist()} m; the specimen spans {lo.tolist()} to "
            f"{hi.tolist()} m): give the specimen the packing's place and size, and the file in metres")
    _check_no_coincident_spheres(centers, radii, lines)
    _check_the_packing_fills(centers, radii, domain)
    # The overlap statistics of a generated packing, on a copy numbered by cell as they need.
    lo, hi = domain.bounds
    cell = 2.0 * float(radii.max())
    dims = np.maximum(np.floor((hi - lo) / cell).astype(np.int64), 1)
    _, order = _bin(centers, lo, cell, dims)
    max_overlap, mean_overlap = _overlap_stats(centers[order], radii[order], lo, dims, cell)
    solid = float(np.sum(4.0 / 3.0 * math.pi * radii**3))
    return Packing(centers=centers, radii=radii, domain=domain.description(), seed=0,
                   porosity=1.0 - solid / domain.volume, max_overlap=max_overlap, mean_overlap=mean_overlap, sweeps=0)


# Spheres whose centres lie closer than this fraction of the smallest radius are one place twice.
COINCIDENT = 1e-6


def _check_no_coincident_spheres(centers: np.ndarray, radii: np.ndarray, lines: list[int]) -> None:
    """ValueError for spheres sharing a centre (a clump's members, a list written twice): no
    direction joins them, so a bond or contact between them is undefined (it crashed the step)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(centers).query_pairs(COINCIDENT * float(radii.min()), output_type="ndarray")
    if len(pairs):
        a, b = sorted(pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))][0])
        raise ValueError(f"{len(pairs)} pairs of spheres share their centre, the first on lines {lines[a]} and "
                         f"{lines[b]} at {centers[a].tolist()} m (a clump's members, or a list written twice): "
                         "keep one sphere per place")


# How far the spheres may stop short of the specimen's faces: two of the largest radii (a packing
# grown between walls reaches them; one from another code may fill a smaller box).
FILL_MARGIN_RADII = 2.0


def _check_the_packing_fills(centers: np.ndarray, radii: np.ndarray, domain) -> None:
    """ValueError when the spheres fill a smaller box than the specimen's: stresses are forces over
    the specimen's section, so an imported 54 mm packing in a 100 mm specimen read a UCS 14-57x
    too small. The message gives the packing's extent to set instead."""
    lo, hi = domain.bounds
    reach_lo, reach_hi = (centers - radii[:, None]).min(axis=0), (centers + radii[:, None]).max(axis=0)
    short = np.maximum(reach_lo - lo, hi - reach_hi)
    if np.any(short > FILL_MARGIN_RADII * float(radii.max())):
        axis = "xyz"[int(np.argmax(short))]
        raise ValueError(
            f"the spheres fill {reach_lo.tolist()} to {reach_hi.tolist()} m, the specimen {lo.tolist()} to "
            f"{hi.tolist()} m: {float(short.max()) * 1e3:.3g} mm short of its faces along {axis} (stresses are "
            f"forces over the specimen's section); give the specimen the packing's extent (a box: origin = "
            f"{reach_lo.tolist()}, size = {(reach_hi - reach_lo).tolist()})")


def read_sphere_labels(path: str | os.PathLike, column: int) -> np.ndarray:
    """Each sphere's label in column `column` (1-based: 5 is the first after `x y z r`) of a text
    sphere list (read_sphere_list's format): a group, a material or a clump id, as written
    (str). ValueError naming the line that has no such column."""
    labels = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            text = line.split("#", 1)[0].replace(",", " ").split()
            if not text:
                continue
            if len(text) < column:
                raise ValueError(f"line {number}: {line.strip()!r} has {len(text)} columns: no column {column} "
                                 "(packing.group_column) to read the sphere's group from")
            labels.append(text[column - 1])
    return np.array(labels, dtype=str)

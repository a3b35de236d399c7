"""Two Gauss points through each particle's cell across a thin wall.

Nodal integration smooths the deformation gradient over each particle's cell, so a cell sees
the mean of the strain across its own thickness: where the strain varies linearly through the
wall (bending), the energy of the part that varies within the cell is lost. With 3 particles
through the wall (cells t/4, t/2, t/4 thick) that is 5/32 of the bending energy: a strip
vibrated 8 % below thin-plate theory, and more layers only reduce the loss as 1/layers^2.

Each cell is therefore integrated at two points across the wall, at its centroid -+ w / (2
sqrt 3) (w its extent through the wall), each with half its volume (Gauss-Legendre, exact for a
strain linear through the cell): F at those points is the cell's smoothed F plus or minus the
offset times dF/dzeta, the gradient of the smoothed F along the particle's line through the wall
from the cells on that line (the difference between the centroids of the nearest two cells two
apart that it lies between or next to: with 3 particles across the wall, the outer two, one slope
for the whole line; exact for F linear through the wall, which is all that 3 particles across a
wall can represent). Each Gauss point keeps its own plastic state (the law's radial
return there), so plastic bending is integrated at 2 x layers points through the wall. The
internal force is the exact derivative of the energy sum_I V_I / 2 (W(F_I-) + W(F_I+)):
    T_J = V_J (P_J- + P_J+) / 2 + sum_I c_IJ a_I V_I (P_I+ - P_I-) / 2
(c_IJ the weights of F_J in I's dF/dzeta, a_I the offset), gathered as before (kernels.py). A
uniform or membrane state has dF/dzeta = 0: both points equal the cell's, so the patch tests
and the membrane results are those of one point. A solid (no wall) keeps one point a cell."""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

# Offset of the two Gauss-Legendre points from the centre of an interval of width 1.
GAUSS_OFFSET = 0.5 / math.sqrt(3.0)

# start, member, coef: the CSR of each particle's dF/dzeta = sum_r coef[r] F[member[r]] (1/m);
# back_start, back_member, back_coef: its transpose (for particle J, every I whose stencil holds J
# and that weight, in order of I) for the gather; offset: a_I (m), 0 for one point; line: the
# particle's line through the wall (row of `lines`, -1 without); lines: (m, layers) the lines.
Columns = namedtuple("Columns", "start member coef back_start back_member back_coef offset line lines")


def thickness_columns(X: np.ndarray, lines: np.ndarray | None) -> Columns:
    """The Columns of particles at reference positions X (n, 3) on the lines through the wall
    `lines` (particles.wall_columns; None: a solid, one point a cell). The cells through the wall
    end half-way between successive particles and at the outer two (particles.py)."""
    n = len(X)
    if lines is None:
        empty = np.zeros(0, dtype=np.int64)
        return Columns(np.zeros(n + 1, dtype=np.int64), empty, np.zeros(0), np.zeros(n + 1, dtype=np.int64), empty,
                       np.zeros(0), np.zeros(n), np.full(n, -1, dtype=np.int64), np.zeros((0, 0), dtype=np.int64))
    lines = np.asarray(lines, dtype=np.int64)
    m, layers = lines.shape
    P = X[lines]
    direction = P[:, -1] - P[:, 0]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    zeta = np.einsum("mka,ma->mk", P - P[:, :1], direction)
    bounds = np.concatenate([zeta[:, :1], 0.5 * (zeta[:, 1:] + zeta[:, :-1]), zeta[:, -1:]], axis=1)
    centre = 0.5 * (bounds[:, 1:] + bounds[:, :-1])
    width = bounds[:, 1:] - bounds[:, :-1]
    k = np.arange(layers)
    below = np.clip(k - 1, 0, max(layers - 3, 0))
    above = np.minimum(below + 2, layers - 1)
    step = centre[:, above] - centre[:, below]
    row = np.repeat(lines.ravel(), 2)
    member = np.stack([lines[:, below], lines[:, above]], axis=2).ravel()
    coef = np.stack([-1.0 / step, 1.0 / step], axis=2).ravel()
    order = np.argsort(row, kind="stable")
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(row, minlength=n), out=start[1:])
    back = np.lexsort((row, member))
    back_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(member, minlength=n), out=back_start[1:])
    offset = np.zeros(n)
    offset[lines.ravel()] = GAUSS_OFFSET * width.ravel()
    line = np.full(n, -1, dtype=np.int64)
    line[lines.ravel()] = np.repeat(np.arange(m), layers)
    return Columns(start, member[order], coef[order], back_start, row[back], coef[back], offset, line, lines)


def line_mates(columns: Columns, rows: np.ndarray) -> np.ndarray:
    """The particles on the lines through the wall of `rows` (rows themselves where they have
    none), sorted: those whose Gauss points a change of the rows' F reaches."""
    rows = np.asarray(rows, dtype=np.int64)
    line = columns.line[rows]
    return np.union1d(rows[line < 0], columns.lines[np.unique(line[line >= 0])].ravel())


def single_point(columns: Columns, particles: np.ndarray) -> None:
    """One point a cell (offset 0, no dF/dzeta) on the whole lines of `particles`, in place: a
    free particle (all links cut, F = I) would put a false gradient on its line."""
    mates = line_mates(columns, particles)
    if len(mates) == 0:
        return
    columns.offset[mates] = 0.0
    for start, coef in ((columns.start, columns.coef), (columns.back_start, columns.back_coef)):
        for i in mates:
            coef[start[i]:start[i + 1]] = 0.0

"""Moving least-squares (MLS) shape functions of the element-free Galerkin method (paper 000
eqs 5-9), evaluated once at set-up and stored per neighbour link in CSR arrays, so that the step
only gathers: at the particles themselves (`shape_functions`: values and derivatives), and the
gradients the step uses, smoothed over each particle's cell (`smoothed_gradients`, stabilised
conforming nodal integration).

For the particle I at X_I and each neighbour J whose support (radius R, or R_J: one per particle
where the spacing is graded, `support_radii`) holds X_I (the links of row I):
  N_J(X_I) = V_J w_J p(xi_J) . A^-1 p(0)          A = sum_J V_J w_J p(xi_J) p(xi_J)^T
where xi_J = (X_J - X_I) / R (the basis centred on X_I and scaled by R keeps A well conditioned),
V_J the nodal volume (eq. 8 puts it in the weights), w the quartic spline of s = |X_J - X_I| / R_J
(eq. 9; material coordinates: the links never change with the motion; the weight belongs to the
particle J, so the approximation stays one smooth field however the supports vary, and a
point's basis is scaled by the smallest support it sees), and p the quadratic basis
  1, xi_x, xi_y, xi_z, xi_x^2, xi_y^2, xi_z^2, xi_x xi_y, xi_y xi_z, xi_x xi_z
(with two particles through a wall, the square of the through-thickness coordinate is dropped:
it is not independent of 1 and that coordinate on two planes). The gradient at X_I follows from
differentiating with the basis centre held fixed: A grad(gamma) = grad p(0) - grad(A) gamma,
gamma = A^-1 p(0), so that
  grad N_J(X_I) = V_J (grad w_J (p_J . gamma) + w_J (p_J . grad gamma)).
Both reproduce every field of the basis exactly: values and gradients of linear fields to
rounding (tests/meshfree/test_meshfree.py, the patch test).
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import get_num_threads, njit, prange
from scipy.spatial import cKDTree

FULL_BASIS = np.arange(10, dtype=np.int64)
# A moment matrix whose 2-norm condition number exceeds this is taken as singular.
MAX_CONDITION = 1e10


@njit(cache=True, inline="always")
def quartic_spline(s):
    """w(s) = 1 - 6 s^2 + 8 s^3 - 3 s^4 for s <= 1, else 0 (paper 000 eq. 9), and dw/ds."""
    if s >= 1.0:
        return 0.0, 0.0
    return 1.0 - s * s * (6.0 - s * (8.0 - 3.0 * s)), -12.0 * s + 24.0 * s * s - 12.0 * s * s * s


def basis_terms(thickness_axis: int, layers: int) -> np.ndarray:
    """Indices of the quadratic basis terms used: all 10, or without the square of the
    through-thickness coordinate (term 4 + axis) with only two particles through the wall (of a
    plate: no thickness axis, all 10)."""
    if layers >= 3 or thickness_axis is None:
        return FULL_BASIS.copy()
    return np.array([k for k in range(10) if k != 4 + thickness_axis], dtype=np.int64)


@njit(cache=True, inline="always")
def _basis(xi0, xi1, xi2, terms, p):
    full0 = 1.0
    for k in range(terms.shape[0]):
        t = terms[k]
        if t == 0:
            p[k] = full0
        elif t == 1:
            p[k] = xi0
        elif t == 2:
            p[k] = xi1
        elif t == 3:
            p[k] = xi2
        elif t == 4:
            p[k] = xi0 * xi0
        elif t == 5:
            p[k] = xi1 * xi1
        elif t == 6:
            p[k] = xi2 * xi2
        elif t == 7:
            p[k] = xi0 * xi1
        elif t == 8:
            p[k] = xi1 * xi2
        else:
            p[k] = xi0 * xi2


@njit(parallel=True, cache=True)
def _shape_functions(X, volume, start, neighbour, radius, terms, value, grad, condition):
    """value[r] = N_J(X_I), grad[r] = grad N_J(X_I) for every link r = (I, J) of row I;
    condition[I]: the 2-norm condition number of I's moment matrix (inf when singular; then
    I's rows are left zero). Each particle writes only its own rows: thread-count independent."""
    n = X.shape[0]
    m = terms.shape[0]
    for i in prange(n):
        A = np.zeros((m, m))
        dA = np.zeros((3, m, m))
        p = np.zeros(m)
        for r in range(start[i], start[i + 1]):
            j = neighbour[r]
            xi0 = (X[j, 0] - X[i, 0]) / radius
            xi1 = (X[j, 1] - X[i, 1]) / radius
            xi2 = (X[j, 2] - X[i, 2]) / radius
            s = np.sqrt(xi0 * xi0 + xi1 * xi1 + xi2 * xi2)
            w, dw = quartic_spline(s)
            if w <= 0.0:
                continue
            _basis(xi0, xi1, xi2, terms, p)
            vw = volume[j] * w
            # d w(|x - X_J| / R) / d x at x = X_I: dw/ds (X_I - X_J) / (R |X_I - X_J|) = -dw xi / (R s).
            g0 = g1 = g2 = 0.0
            if s > 0.0:
                c = -volume[j] * dw / (radius * s)
                g0 = c * xi0
                g1 = c * xi1
                g2 = c * xi2
            for a in range(m):
                for b in range(m):
                    pp = p[a] * p[b]
                    A[a, b] += vw * pp
                    dA[0, a, b] += g0 * pp
                    dA[1, a, b] += g1 * pp
                    dA[2, a, b] += g2 * pp
        cond = np.linalg.cond(A)
        condition[i] = cond
        if not np.isfinite(cond) or cond > MAX_CONDITION:
            continue
        Ainv = np.linalg.inv(A)
        gamma = Ainv[:, 0].copy()  # A^-1 p(0), p(0) = e_0
        dgamma = np.zeros((3, m))
        for k in range(3):
            rhs = np.zeros(m)
            rhs[1 + k] = 1.0 / radius  # d p / d x_k at the centre: only the linear term xi_k
            for a in range(m):
                acc = 0.0
                for b in range(m):
                    acc += dA[k, a, b] * gamma[b]
                rhs[a] -= acc
            for a in range(m):
                acc = 0.0
                for b in range(m):
                    acc += Ainv[a, b] * rhs[b]
                dgamma[k, a] = acc
        for r in range(start[i], start[i + 1]):
            j = neighbour[r]
            xi0 = (X[j, 0] - X[i, 0]) / radius
            xi1 = (X[j, 1] - X[i, 1]) / radius
            xi2 = (X[j, 2] - X[i, 2]) / radius
            s = np.sqrt(xi0 * xi0 + xi1 * xi1 + xi2 * xi2)
            w, dw = quartic_spline(s)
            _basis(xi0, xi1, xi2, terms, p)
            pg = 0.0
            for a in range(m):
                pg += p[a] * gamma[a]
            value[r] = volume[j] * w * pg
            c = -dw / (radius * s) if s > 0.0 else 0.0
            for k in range(3):
                xik = xi0 if k == 0 else (xi1 if k == 1 else xi2)
                pdg = 0.0
                for a in range(m):
                    pdg += p[a] * dgamma[k, a]
                grad[r, k] = volume[j] * (c * xik * pg + w * pdg)


def neighbour_links(X: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The links of every particle to the particles closer than `radius` (itself included), as
    CSR (start (n + 1), neighbour), each row in increasing neighbour order, and `mirror`: for the
    link (I, J) the position of (J, I) (the relation is symmetric: one radius for all)."""
    tree = cKDTree(X)
    lists = tree.query_ball_point(X, radius * (1.0 - 1e-12), return_sorted=True, workers=get_num_threads())
    counts = np.fromiter(map(len, lists), dtype=np.int64, count=len(lists))
    start = np.zeros(len(X) + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    neighbour = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(start[-1]))
    del lists
    row = np.repeat(np.arange(len(X), dtype=np.int64), counts)
    n = np.int64(len(X))
    key = row * n + neighbour  # increasing: rows in order, each row sorted
    mirror = np.searchsorted(key, neighbour * n + row)
    if not np.array_equal(key[mirror], neighbour * n + row):
        raise RuntimeError("neighbour links are not symmetric")
    return start, neighbour, mirror


def shape_functions(X: np.ndarray, volume: np.ndarray, start: np.ndarray, neighbour: np.ndarray, radius: float,
                    terms: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value (links,), grad (links, 3), condition (n,)) of the MLS shape functions at the
    particles; see the module docstring."""
    value = np.zeros(len(neighbour))
    grad = np.zeros((len(neighbour), 3))
    condition = np.zeros(len(X))
    _shape_functions(np.ascontiguousarray(X, dtype=float), np.asarray(volume, dtype=float), start, neighbour,
                     float(radius), terms, value, grad, condition)
    return value, grad, condition


def quartic_spline_array(s: np.ndarray) -> np.ndarray:
    """The quartic spline (eq. 9) of an array of s."""
    s = np.asarray(s, dtype=float)
    return np.where(s < 1.0, 1.0 - s * s * (6.0 - s * (8.0 - 3.0 * s)), 0.0)


@njit(parallel=True, cache=True)
def _values_at(points, X, volume, start, neighbour, radius, terms, value, condition):
    """value[r] = N_J(points[q]) for every link r = (q, J) of evaluation point q (the same MLS
    as _shape_functions, centred on the point and scaled by the smallest support radius[J] among
    its links: with one radius for all, that radius); condition[q] as there."""
    m = terms.shape[0]
    for q in prange(points.shape[0]):
        A = np.zeros((m, m))
        p = np.zeros(m)
        scale = np.inf
        for r in range(start[q], start[q + 1]):
            scale = min(scale, radius[neighbour[r]])
        for r in range(start[q], start[q + 1]):
            j = neighbour[r]
            xi0 = (X[j, 0] - points[q, 0]) / scale
            xi1 = (X[j, 1] - points[q, 1]) / scale
            xi2 = (X[j, 2] - points[q, 2]) / scale
            w, _ = quartic_spline(np.sqrt(xi0 * xi0 + xi1 * xi1 + xi2 * xi2) * (scale / radius[j]))
            if w <= 0.0:
                continue
            _basis(xi0, xi1, xi2, terms, p)
            vw = volume[j] * w
            for a in range(m):
                for b in range(m):
                    A[a, b] += vw * p[a] * p[b]
        cond = np.linalg.cond(A)
        condition[q] = cond
        if not np.isfinite(cond) or cond > MAX_CONDITION:
            continue
        gamma = np.linalg.solve(A, np.eye(m)[:, 0].copy())
        for r in range(start[q], start[q + 1]):
            j = neighbour[r]
            xi0 = (X[j, 0] - points[q, 0]) / scale
            xi1 = (X[j, 1] - points[q, 1]) / scale
            xi2 = (X[j, 2] - points[q, 2]) / scale
            w, _ = quartic_spline(np.sqrt(xi0 * xi0 + xi1 * xi1 + xi2 * xi2) * (scale / radius[j]))
            _basis(xi0, xi1, xi2, terms, p)
            pg = 0.0
            for a in range(m):
                pg += p[a] * gamma[a]
            value[r] = volume[j] * w * pg


def support_radii(radius, n: int) -> np.ndarray:
    """The support radius of each of n particles (n,): `radius` one for all (a number) or per
    particle (an array, e.g. dilation x the local spacing of a graded particle set)."""
    radius = np.asarray(radius, dtype=float)
    return np.full(n, float(radius)) if radius.ndim == 0 else np.ascontiguousarray(radius)


def within_supports(tree: cKDTree, X: np.ndarray, where: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray]:
    """For each point of `where` the particles (the first tree.n of X, the tree's) whose support
    holds it (|X_J - point| < R_J, to rounding), each list increasing: (counts, the lists
    concatenated). `radius`: a number (one for all: a ball query about each point) or per
    particle (the other way round: the points in each particle's ball, from a tree of the points,
    for the particles near them; a ball at the largest radius would hold thousands where the
    set is fine)."""
    radius = np.asarray(radius, dtype=float)
    if radius.ndim == 0 or np.all(radius == radius.flat[0]):
        reach = float(radius.flat[0]) * (1.0 - 1e-12)
        lists = tree.query_ball_point(where, reach, return_sorted=True, workers=get_num_threads())
        counts = np.fromiter(map(len, lists), dtype=np.int64, count=len(lists))
        return counts, np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(counts.sum()))
    X, radius = X[:tree.n], radius[:tree.n]
    reach = float(radius.max())
    near = np.flatnonzero(np.all((X >= where.min(axis=0) - reach) & (X <= where.max(axis=0) + reach), axis=1))
    lists = cKDTree(where).query_ball_point(X[near], radius[near] * (1.0 - 1e-12), workers=get_num_threads())
    held = np.fromiter(map(len, lists), dtype=np.int64, count=len(lists))
    point = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(held.sum()))
    particle = np.repeat(near, held)
    order = np.lexsort((particle, point))
    return np.bincount(point, minlength=len(where)), particle[order]


def mls_values(points, X, volume, start, neighbour, radius, terms, linear_fallback=False, max_condition=MAX_CONDITION):
    """(value (links,), condition (points,)): N_J(points[q]) for the links (q, J) of the CSR
    (start, neighbour), the MLS centred on each point (_values_at); `radius`: the support radius,
    one for all or per particle (support_radii). With `linear_fallback`, a
    point whose moment matrix is singular with the quadratic basis (near a crack face: the
    particles it still sees lie on too few planes) uses the linear basis 1, x, y, z instead (it
    still reproduces linear fields); its condition is then the linear one. `max_condition`: the
    condition number above which a moment matrix counts as singular (MAX_CONDITION or lower)."""
    X = np.ascontiguousarray(X, dtype=float)
    volume = np.asarray(volume, dtype=float)
    radius = support_radii(radius, len(X))
    value = np.zeros(len(neighbour))
    condition = np.zeros(len(points))
    _values_at(np.ascontiguousarray(points, dtype=float), X, volume, start, neighbour, radius, terms, value,
               condition)
    bad = np.flatnonzero(~np.isfinite(condition) | (condition > max_condition))
    if linear_fallback and len(bad):
        pos, sub_start = csr_positions(start, bad)
        sub_value = np.zeros(len(pos))
        sub_condition = np.zeros(len(bad))
        _values_at(np.ascontiguousarray(points[bad], dtype=float), X, volume, sub_start, neighbour[pos], radius,
                   terms[terms < 4], sub_value, sub_condition)
        value[pos] = sub_value
        condition[bad] = sub_condition
    return value, condition


def nodal_values(X, volume, radius, terms, start, neighbour, rows, hidden=None, max_condition=MAX_CONDITION):
    """The MLS values N_K(X_J) at the particles J = `rows` themselves, over their links (J, K)
    but for the `hidden` ones (a boolean per link: removed by fracture), with the linear
    fallback at a crack face (mls_values): what the stabilisation compares each particle's
    value with (kernels docstring). The links of J cover its own support: they are every
    particle within the support radius of one of its cell's quadrature points, which surround
    X_J closer than the radius. Returns (the positions of the rows' links, their values (0 on a
    hidden link), the condition number of each row's moment matrix)."""
    rows = np.asarray(rows, dtype=np.int64)
    pos, first = csr_positions(start, rows)
    counts = np.diff(first)
    keep = np.ones(len(pos), dtype=bool) if hidden is None else ~hidden[pos]
    kept_start = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(np.bincount(np.repeat(np.arange(len(rows)), counts)[keep], minlength=len(rows)), out=kept_start[1:])
    kept_value, condition = mls_values(X[rows], X, volume, kept_start, neighbour[pos[keep]], radius, terms,
                                       linear_fallback=True, max_condition=max_condition)
    value = np.zeros(len(pos))
    value[keep] = kept_value
    return pos, value, condition


def smoothed_gradients(X: np.ndarray, volume: np.ndarray, cells, radius, terms: np.ndarray):
    """Stabilised conforming nodal integration (Chen et al. 2001): the gradient of N_J at the
    particle I is the mean over I's cell (a closed polyhedron of planar faces, particles.Cells,
    volume V_I) by the divergence theorem, grad N_J(I) = (1 / V_I) sum_rows w N_J(point), the
    cell's quadrature rows (a plate's or tube's: one per face, its centroid with the area vector
    w = outward normal x area; a median-dual cell's: its faces' vertices), exact for linear
    fields. Neighbouring cells share their faces (and quadrature points, with opposite weights),
    so under a uniform stress the particle forces are the boundary's traction term: the
    integration constraint that direct nodal integration misses. Returns the CSR links of the
    particles (start, neighbour: every J that is nonzero at one of I's quadrature points, itself
    included, in increasing order), grad (links, 3), and the largest moment-matrix condition
    number over the quadrature points with the first bad point (or None)."""
    n = len(X)
    link_row, link_col, grad, condition, points, _ = cell_gradients(
        X, volume, cells, radius, terms, np.arange(n), cKDTree(X))
    bad = ~np.isfinite(condition) | (condition > MAX_CONDITION)
    first_bad = points[np.flatnonzero(bad)[0]] if bad.any() else None
    link_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(link_row, minlength=n), out=link_start[1:])
    return link_start, link_col, grad, float(np.max(condition)), first_bad


# Owners per block in cell_gradients. All at once, the supports of a plate's 6 n face centres
# (Python lists) and their ~310 contributions per particle, sorted and copied, peaked at 13.6 GB
# at 280k particles; a block holds ~1.3 M contributions (~0.1 GB).
OWNER_BLOCK = 4096


def cell_gradients(X, volume, cells, radius, terms, owners, tree, blocked=None, linear_fallback=False,
                   max_condition=MAX_CONDITION):
    """The smoothed gradients (smoothed_gradients) of the particles `owners` only, with the MLS
    at their cells' quadrature points summing over the particles within the support but for the
    pairs (owner, J) whose key owner * n + J is in the sorted array `blocked` (links removed by
    fracture: the crack hides J from the owner's cell). Returns (rows, cols, grad) of the links
    with a contribution, in the order of the (distinct) owners, each row's columns increasing,
    and per row of the owners' cells (the owners in turn, each cell's rows in order) the
    condition number of its point's moment matrix, the point and the owner. `linear_fallback`,
    `max_condition`: at a crack face (mls_values)."""
    X = np.ascontiguousarray(X, dtype=float)
    volume = np.asarray(volume, dtype=float)
    owners = np.asarray(owners, dtype=np.int64)
    rows_of_cells, row_first = csr_positions(cells.start, owners)
    point = cells.point[rows_of_cells]
    owner = np.repeat(owners, np.diff(row_first))
    weight = cells.weight[rows_of_cells] / volume[owner][:, None]
    condition = np.zeros(len(point))
    # A link's contributions all come from its row's cell, so they meet in one block of owners
    # and are summed there in the same order as all at once (bit-identical); with increasing
    # owners the blocks' links follow in order (else one block).
    block = OWNER_BLOCK if np.all(owners[1:] > owners[:-1]) else max(len(owners), 1)
    pieces = []
    for first_owner in range(0, len(owners), block):
        rows = slice(row_first[first_owner], row_first[min(first_owner + block, len(owners))])
        pieces.append(_block_gradients(X, volume, cells.points, point[rows], owner[rows], weight[rows], radius, terms,
                                       tree, blocked, linear_fallback, max_condition,
                                       condition[rows]))
    rows, cols, grad = (np.concatenate(parts) for parts in zip(*pieces)) if pieces else (
        np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    return rows, cols, grad, condition, cells.points[point], owner


def csr_positions(start: np.ndarray, rows: np.ndarray, counts=None) -> tuple[np.ndarray, np.ndarray]:
    """The positions of the entries of the CSR rows `rows` (start (n + 1,)), row after row, and
    where each row begins among them ((len(rows) + 1,)); with `counts`, the first counts[k] of
    row k only."""
    if counts is None:
        counts = start[rows + 1] - start[rows]
    first = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(counts, out=first[1:])
    return np.repeat(start[rows] - first[:-1], counts) + np.arange(first[-1]), first


def _block_gradients(X, volume, points, point, owner, weight, radius, terms, tree, blocked, linear_fallback,
                     max_condition, condition):
    """cell_gradients' (rows, cols, grad) of the cell rows with the quadrature points
    points[point] of `owner` (with the weight / cell volume `weight`), writing their condition
    numbers into `condition`."""
    n = len(X)
    # A point shared by several cells (a median-dual vertex) is evaluated once for all of them,
    at, of_row = np.unique(point, return_inverse=True)
    where = np.ascontiguousarray(points[at])
    counts, neighbour = within_supports(tree, X, where, radius)
    if blocked is not None and len(blocked) > 0:
        # but where a crack hides some of its particles from a cell's owner, the MLS there is the
        # owner's own: such a row gets an evaluation of its own, over the particles left.
        pos, _ = csr_positions(np.r_[0, np.cumsum(counts)], of_row)
        row_of = np.repeat(np.arange(len(point)), counts[of_row])
        key = owner[row_of] * np.int64(n) + neighbour[pos]
        hidden = blocked[np.minimum(np.searchsorted(blocked, key), len(blocked) - 1)] == key
        cut = np.zeros(len(point), dtype=bool)
        cut[row_of[hidden]] = True
        cut_rows = np.flatnonzero(cut)
        left = cut[row_of] & ~hidden
        shared = np.zeros(len(at), dtype=bool)  # the points some intact row still uses
        shared[of_row[~cut]] = True
        kept, _ = csr_positions(np.r_[0, np.cumsum(counts)], np.flatnonzero(shared))
        where = np.concatenate([where[shared], points[point[cut_rows]]])
        neighbour = np.concatenate([neighbour[kept], neighbour[pos[left]]])
        counts = np.concatenate([counts[shared], np.bincount(row_of[left], minlength=len(point))[cut_rows]])
        of_row = np.cumsum(shared)[of_row] - 1
        of_row[cut_rows] = np.count_nonzero(shared) + np.arange(len(cut_rows))
    start = np.zeros(len(where) + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    value, point_condition = mls_values(where, X, volume, start, neighbour, radius, terms, linear_fallback,
                                         max_condition)
    condition[:] = point_condition[of_row]
    # Each owner's rows lie in one run: per owner the sums (I, J, sum weight N_J / V_I) at once
    # (_cell_sums), at most one entry per contribution until compacted.
    owner_first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1], True])
    contribution_first = np.r_[0, np.cumsum(counts[of_row])][owner_first]
    cols = np.empty(contribution_first[-1], dtype=np.int64)
    grad = np.empty((contribution_first[-1], 3))
    found = np.zeros(len(owner_first) - 1, dtype=np.int64)
    _cell_sums(owner_first, contribution_first, of_row, weight, start, neighbour, value, cols, grad, found)
    keep, _ = csr_positions(contribution_first, np.arange(len(found)), found)
    return np.repeat(owner[owner_first[:-1]], found), cols[keep], grad[keep]


@njit(parallel=True, cache=True)
def _cell_sums(owner_first, contribution_first, of_row, weight, start, neighbour, value, cols, grad, found):
    """For each owner k (rows owner_first[k]:owner_first[k + 1], row r's point of_row[r] with
    its links start:neighbour and MLS `value`): the particles J it sees, increasing, in
    cols[contribution_first[k]:][:found[k]], and beside them in grad the sum of weight[r] N_J
    over its rows in order, as np.add.reduceat sums a run: the first term + (0 + the second +
    ...), so that a cell of fewer than 9 rows (a plate's or tube's 6 faces) gets the sums a
    stable sort of the contributions and np.add.reduceat gave, bit for bit."""
    for k in prange(owner_first.shape[0] - 1):
        lo = contribution_first[k]
        m = contribution_first[k + 1] - lo
        col = np.empty(m, dtype=np.int64)
        row = np.empty(m, dtype=np.int64)
        link = np.empty(m, dtype=np.int64)
        c = 0
        for r in range(owner_first[k], owner_first[k + 1]):
            q = of_row[r]
            for t in range(start[q], start[q + 1]):
                col[c] = neighbour[t]
                row[c] = r
                link[c] = t
                c += 1
        order = np.argsort(col, kind="mergesort")
        u = -1
        head = np.zeros(3)
        rest = np.zeros(3)
        for i in range(m):
            o = order[i]
            if i == 0 or col[o] != col[order[i - 1]]:
                if u >= 0:
                    for a in range(3):
                        grad[lo + u, a] = head[a] + rest[a]
                u += 1
                cols[lo + u] = col[o]
                for a in range(3):
                    head[a] = weight[row[o], a] * value[link[o]]
                    rest[a] = 0.0
            else:
                for a in range(3):
                    rest[a] += weight[row[o], a] * value[link[o]]
        if u >= 0:
            for a in range(3):
                grad[lo + u, a] = head[a] + rest[a]
        found[k] = u + 1

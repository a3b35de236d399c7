"""The J-integral of a crack tip on the shell (paper 002 section 4.2): the configurational force
of the membrane as a domain integral of the 2D Eshelby stress over a ring around the tip,

    J_membrane = sum over triangles A ( [(Hu^T P)_KJ - W delta_KJ] dV_K/dX_J - P : n n^T grad V ) / t,

with Hu the displacement gradient (3 x 2, in the triangle's reference frame), P = F N the first
Piola-Kirchhoff membrane force (N/m), W the membrane strain energy per area and V = q d the
extension field: d the crack's direction kept in each vertex's tangent plane, q a weight that is 1
inside r_in and falls linearly to 0 at r_out (distances in the reference configuration); its
in-plane gradient dV_K/dX_J, and n n^T grad V the part along the triangle's normal n, which a
field kept in the tangent planes has where the surface curves along d. Dividing
by the thickness t at the tip gives J in J/m^2, the energy released per crack area, comparable
with K^2 / E and Gc. The domain form needs no contour through the singular tip and, at
equilibrium and with traction-free crack faces, does not depend on the ring (Stokes): reporting it
for several rings measures the discretisation's path independence.

The bending part of the plate's Eshelby stress (W_b I - rotation gradient^T M) and the
configurational force of the loads inside the ring (a pressure on a bulging flank) are added as
the virtual crack extension reads them over the same ring (VirtualExtension: deLorenzi's identity
between the domain integral and the derivative of the energy under the extension field, taken
term by term); this shell's moments live on its edges and jump between triangles, where a
pointwise moment x rotation-gradient term has no value. So J holds bending and pressure and equals
G by virtual crack extension (the membrane's two readings agree to ~1e-7: on flat sheets, along
a cylinder's generators and across its curvature, a tube bent with a circumferential crack)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .kernels import face_energies
from .mesh import shell_mesh
from .model import Shell, build_arrays

BRANCH_COS = np.cos(np.radians(20.0))  # a crack-face pair this far off the tip's direction is behind a kink


def j_integral(shell: Shell, x: np.ndarray, tip, direction, r_in: float, r_out: float,
               external: np.ndarray | None = None, extension: VirtualExtension | None = None) -> float:
    """J (J/m^2) at the crack tip `tip` (a point, m) running along `direction` (a vector in the
    surface's tangent plane there), over the ring r_in < r < r_out about it: the membrane's
    Eshelby stress as the domain integral; the bending share and the configurational work of the
    external nodal forces `external` (n, 3) inside the ring (pressures, edge loads) over the same
    ring as the virtual extension reads them (VirtualExtension.bending_release, .load_release;
    `extension`, that tip's and ring's, if built already)."""
    if not 0.0 <= r_in < r_out:
        raise ValueError("the J-integral's ring needs 0 <= r_in < r_out")
    mesh, faces = shell.mesh, shell.faces
    tip = np.asarray(tip, dtype=float)
    d3 = np.asarray(direction, dtype=float)
    d3 = d3 / np.linalg.norm(d3)
    if extension is None:
        extension = VirtualExtension(shell, tip, d3, r_in, r_out)
    frame = shell.frames
    q = np.clip((r_out - np.linalg.norm(mesh.X - tip, axis=1)) / (r_out - r_in), 0.0, 1.0)
    # The extension field V = q d, d in each vertex's tangent plane (VirtualExtension.q_shift), in
    # each triangle's frame; J takes the Eshelby stress against its gradient. With d one vector
    # (a flat sheet) that is d_K dq/dX_J; on a curved sheet d turns with the surface, and the
    # part of grad V that turning makes is what a circumferential crack in a tube needs.
    shift = extension.q_shift[mesh.tri]  # (m, 3 corners, 3)
    ring = np.flatnonzero(np.any(q[mesh.tri] > 0.0, axis=1) & (np.ptp(shift.reshape(len(shift), -1), axis=1) > 0.0))
    dm_inv = faces.dm_inv[ring].reshape(-1, 2, 2)
    F, E, N = shell.membrane_kinematics(x, ring)
    Hu = F - frame[ring]
    trace = E[:, 0, 0] + E[:, 1, 1]
    lam_t, mu_t = faces.lam_t[ring], faces.mu_t[ring]
    W = mu_t * np.einsum("kab,kab->k", E, E) + 0.5 * lam_t * trace**2
    P = F @ N
    grad_v3 = np.einsum("kra,kri->kia", dm_inv, shift[ring, 1:] - shift[ring, :1])  # (k, 3, derivative)
    grad_v = np.einsum("kia,kib->kab", frame[ring], grad_v3)  # its in-plane part (k, component, derivative)
    eshelby = np.einsum("kia,kib->kab", Hu, P) - W[:, None, None] * np.eye(2)
    # V's component along the triangle's normal varies where the surface curves along d (it turns
    # with the surface): moving the deformed corners so strains the membrane by P : n n^T grad V,
    # zero on a flat sheet and along a cylinder's generators.
    normal = np.cross(frame[ring, :, 0], frame[ring, :, 1])
    across = np.einsum("ki,kj,kja->kia", normal, normal, grad_v3)
    line_j = float(np.sum(faces.area[ring] * (np.einsum("kab,kab->k", eshelby, grad_v)
                                              - np.einsum("kia,kia->k", P, across))))
    nearest = int(np.argmin(np.linalg.norm(mesh.X[mesh.tri].mean(axis=1) - tip, axis=1)))
    return line_j / float(mesh.thickness[nearest]) + extension.bending_release(shell, x) + extension.load_release(external)


def bending_density(shell: Shell, x, which=None) -> np.ndarray:
    """Bending energy per area (J/m^2) of the triangles `which` (default all)."""
    which = np.arange(len(shell.mesh.tri)) if which is None else np.asarray(which, dtype=np.int64)
    membrane_energy, bending_energy = np.zeros(len(which)), np.zeros(len(which))
    face_energies(x, shell.faces, shell.edges, which, membrane_energy, bending_energy)
    return bending_energy / shell.faces.area[which]


def stress_intensity(shell: Shell, x: np.ndarray, tip: int, direction, j: float,
                     pairs: int = 4) -> tuple[float, float, float]:
    """(K_I, K_II, K_III) (Pa m^1/2) at the tip vertex: the magnitude from J (their squares sum
    to E J, read as plane stress for all three: a measure of the mixity, not a plate-theory
    K_III), the mixity from the crack faces' relative displacement behind the tip (all ~ K
    sqrt(r) there: opening across the crack in the surface, sliding along it, tearing along the
    normal), summed over the vertex pairs 2 to `pairs` along the crack's faces from the tip
    (_flank_pairs) with weights 1 / sqrt(r), each in the frame of its chord to the tip; only the
    pairs on the tip's own branch count (branch_pairs: behind a kink the faces carry the old
    branch's mixity), the nearest alone if it is the only one; none (right after a kink) reads
    as mode I. The
    faces' displacement alone gives K 10-20 % low with constant-strain triangles (their error
    next to the tip), alike for the modes: their ratios are what is used. Sliding is along the
    chord towards the tip (d at the tip), opening along m = n x d, n the surface normal: K_II > 0
    when the m side slides towards the tip, K_III > 0 when it moves along n."""
    if not j > 0.0:
        return 0.0, 0.0, 0.0
    mesh = shell.mesh
    X = mesh.X
    branch = branch_pairs(mesh, tip, direction, pairs)
    jumps = np.zeros(3)  # opening, sliding, tearing
    for upper, lower in branch[1:] or branch:
        chord = X[tip] - X[upper]
        r = float(np.linalg.norm(chord))
        d = chord / r
        n = vertex_normal(mesh, upper) + vertex_normal(mesh, lower)
        n -= (n @ d) * d
        n /= np.linalg.norm(n)
        m = np.cross(n, d)
        side = [float(np.sum((X[mesh.tri[np.any(mesh.tri == v, axis=1)]].mean(axis=1) - X[v]) @ m)) for v in (upper, lower)]
        if side[0] < side[1]:
            upper, lower = lower, upper
        jump = (x[upper] - X[upper]) - (x[lower] - X[lower])
        jumps += np.array([jump @ m, jump @ d, jump @ n]) / np.sqrt(r)
    size = np.linalg.norm(jumps)
    if size == 0.0:
        jumps, size = np.array([1.0, 0.0, 0.0]), 1.0  # nothing measured: read as mode I
    at_tip = int(np.flatnonzero(np.any(mesh.tri == tip, axis=1))[0])
    k = np.sqrt(shell.triangle_material.youngs_modulus[at_tip] * j)
    return tuple(float(k * c / size) for c in jumps)


def branch_pairs(mesh, tip: int, direction, count: int = 4) -> list[tuple[int, int]]:
    """The crack-face vertex pairs (_flank_pairs, up to `count`) on the tip's own branch: each
    pair's chord to the tip, and the faces behind it, within BRANCH_COS of `direction`. A pair
    at a kink (the faces behind it run the old branch's way) opens with the old branch's mixity
    and ends the branch: right after a kink there is none."""
    X = mesh.X
    heading = np.asarray(direction, float) / np.linalg.norm(direction)
    flank = _flank_pairs(mesh, tip, count + 1)
    branch = []
    for k, pair in enumerate(flank[:count]):
        chord = X[tip] - X[pair[0]]
        if chord @ heading < BRANCH_COS * np.linalg.norm(chord):
            break
        if k + 1 < len(flank):
            behind = X[pair[0]] - X[flank[k + 1][0]]
            if behind @ heading < BRANCH_COS * np.linalg.norm(behind):
                break
        branch.append(pair)
    return branch


def _flank_pairs(mesh, tip: int, count: int) -> list[tuple[int, int]]:
    """Up to `count` pairs of coincident vertices (a vertex and its copy) on the crack's two
    faces, in order from the tip: the two boundary edges at the tip are the crack's faces, and
    each face is followed along the boundary while the two walks stay on coincident vertices
    (so the crack's far end, a kink or a curve, and another crack elsewhere do not matter)."""
    bounding = mesh.edge[mesh.boundary]
    at_tip = bounding[np.any(bounding == tip, axis=1)]
    if len(at_tip) != 2:
        return []
    walks = [[tip, int(e[0] if e[1] == tip else e[1])] for e in at_tip]
    apart = 1e-9 * mesh.element_size()
    pairs = []
    while len(pairs) < count:
        a, b = walks[0][-1], walks[1][-1]
        if a == b or np.linalg.norm(mesh.X[a] - mesh.X[b]) > apart:
            break
        pairs.append((a, b))
        for walk in walks:
            following = bounding[np.any(bounding == walk[-1], axis=1)].ravel()
            following = following[(following != walk[-1]) & (following != walk[-2])]
            if len(following) != 1:
                return pairs
            walk.append(int(following[0]))
    return pairs


def vertex_normal(mesh, vertex: int) -> np.ndarray:
    """The unit normal at a vertex: the sum of its triangles' area vectors, normalised."""
    tri = mesh.tri[np.any(mesh.tri == vertex, axis=1)]
    X = mesh.X
    n = np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]).sum(axis=0)
    return n / np.linalg.norm(n)


def mts_kink_angle(k1: float, k2: float, k3: float = 0.0) -> float:
    """The kink angle (rad, counter-clockwise from the crack's direction towards m) of the
    maximum tangential stress criterion (Erdogan and Sih 1963): -70.5 deg for pure mode II with
    K_II > 0, 0 for pure mode I. The criterion knows modes I and II in the surface; a shell's
    crack cannot twist out of it, so tearing (K_III) is counted with the opening, as a share
    that drives the crack straight on, and a closing K_I (< 0) as none: a torn sheet's crack
    runs straight (the in-plane mixity alone is noise there, and a negative K_I would turn the
    crack back on itself)."""
    k1 = _in_plane_mixity(k1, k3)
    if k2 == 0.0:
        return 0.0
    ratio = k1 / k2
    return 2.0 * np.arctan(0.25 * (ratio - np.sign(k2) * np.sqrt(ratio * ratio + 8.0)))


def _in_plane_mixity(k1: float, k3: float) -> float:
    """The opening share a kink criterion sees: tearing (K_III) counted with the opening, a
    closing K_I (< 0) as none (mts_kink_angle says why)."""
    return float(np.hypot(max(k1, 0.0), k3))


def kinked_release_rate(theta, k1: float, k2: float) -> np.ndarray:
    """G(theta) E' of an infinitesimal kink at theta (rad, this module's sign: towards m
    counter-clockwise) from a tip with K_I, K_II (Hussain, Pu and Underwood 1974):
    (4 / (3 + cos^2)^2) ((1 - t/pi) / (1 + t/pi))^(t/pi) [(1 + 3 cos^2) K_I^2 - 8 sin cos K_I K_II
    + (9 - 5 cos^2) K_II^2]: K_I^2 + K_II^2 at theta = 0."""
    theta = np.asarray(theta, dtype=float)
    c, s, t = np.cos(theta), np.sin(theta), theta / np.pi
    return (4.0 / (3.0 + c * c) ** 2 * ((1.0 - t) / (1.0 + t)) ** t
            * ((1.0 + 3.0 * c * c) * k1 * k1 - 8.0 * s * c * k1 * k2 + (9.0 - 5.0 * c * c) * k2 * k2))


def merr_kink_angle(k1: float, k2: float, k3: float = 0.0) -> float:
    """The kink angle (rad, as mts_kink_angle) of the maximum energy release rate, the crack
    path paper 002 prescribes: the theta that maximises kinked_release_rate, -75.2 deg for pure
    mode II with K_II > 0 (MTS: -70.5), 0 for pure mode I; K_III and a closing K_I as for MTS.
    Found on a 0.05 deg grid over +-89 deg, then refined by a parabola through the best three."""
    k1 = _in_plane_mixity(k1, k3)
    if k2 == 0.0:
        return 0.0
    theta = np.radians(np.linspace(-89.0, 89.0, 3561))
    g = kinked_release_rate(theta, k1, k2)
    best = int(np.argmax(g))
    if abs(g[best] - g[len(g) - 1 - best]) <= 1e-12 * g[best]:  # pure mode II: two mirror maxima
        best = min(best, len(g) - 1 - best) if k2 > 0.0 else max(best, len(g) - 1 - best)
    if 0 < best < len(g) - 1:
        left, middle, right = g[best - 1], g[best], g[best + 1]
        curvature = left - 2.0 * middle + right
        shift = 0.5 * (left - right) / curvature if curvature < 0.0 else 0.0
        return float(theta[best] + shift * (theta[1] - theta[0]))
    return float(theta[best])


KINK_CRITERIA = {"mts": mts_kink_angle, "merr": merr_kink_angle}


def energy_release_rate(shell: Shell, x: np.ndarray, tip, direction, r_in: float, r_out: float,
                        external: np.ndarray | None = None, step: float = 1e-4) -> float:
    """G (J/m^2) at a crack tip by virtual crack extension: move the vertices about the tip by
    q d in the reference and the current configuration alike (the displacements fixed; q the
    J-integral's weight on the ring r_in..r_out), G = -(dU/da - f . q d) / t, U the strain energy
    (membrane and bending: two rebuilt models, a central difference of `step` x the element
    size) and f the external nodal forces (`external` (n, 3): pressures, edge loads) that the
    moved vertices carry along. For in-plane loading this is the domain J above, term by term;
    it also holds bending and pressure, which that J leaves out. Like J it leaves out the
    kinetic terms: a quasi-static measure."""
    return VirtualExtension(shell, tip, direction, r_in, r_out, step).release_rate(shell, x, external)


class VirtualExtension:
    """The part of a virtual crack extension that only the reference mesh decides (the patch
    about the tip and its two shifted models), built once per tip, ring and shell so that G can
    be evaluated at every history sample for the cost of two patch energies."""

    def __init__(self, shell: Shell, tip, direction, r_in: float, r_out: float, step: float = 1e-4):
        mesh = shell.mesh
        tip = np.asarray(tip, dtype=float)
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        self.shell = shell
        q = np.clip((r_out - np.linalg.norm(mesh.X - tip, axis=1)) / (r_out - r_in), 0.0, 1.0)
        # (n, 3): each vertex's move per unit crack extension, d in its own tangent plane (on a
        # curved sheet a move along the tip's tangent would leave the surface and change its
        # curvature; in the plane, the same d; a second-order departure cancels in the central
        # difference)
        moved = np.flatnonzero(q > 0.0)
        normals = np.zeros((len(mesh.X), 3))
        area = np.cross(mesh.X[mesh.tri[:, 1]] - mesh.X[mesh.tri[:, 0]], mesh.X[mesh.tri[:, 2]] - mesh.X[mesh.tri[:, 0]])
        for c in range(3):
            np.add.at(normals, mesh.tri[:, c], area)
        normals[moved] /= np.linalg.norm(normals[moved], axis=1)[:, None]
        self.q_shift = q[:, None] * (d - np.einsum("ni,i->n", normals, d)[:, None] * normals)
        self.eps = step * mesh.element_size()
        local, self.keep, self.changed, self.edge_index = _patch(shell, q > 0.0)
        clamped = None if shell.clamped is None else shell.clamped[self.keep]
        shift = self.eps * self.q_shift[self.keep]
        self.models = [build_arrays(replace(local, X=local.X + sign * shift), shell.material, clamped)[:2]
                       for sign in (1.0, -1.0)]
        nearest = int(np.argmin(np.linalg.norm(mesh.X[mesh.tri].mean(axis=1) - tip, axis=1)))
        self.thickness = float(mesh.thickness[nearest])

    def release_rate(self, shell: Shell, x: np.ndarray, external: np.ndarray | None = None) -> float:
        """G (J/m^2) at the positions x (n, 3) of `shell` (the one this was built for), the
        external nodal forces `external` (n, 3) carried along with the moved vertices."""
        membrane, bending = self._energy_rates(shell, x)
        return -(membrane + bending) / self.thickness + self.load_release(external)

    def bending_release(self, shell: Shell, x: np.ndarray) -> float:
        """The bending energy's share of G (J/m^2): minus its derivative under the virtual
        extension, over the thickness. It is the ring's integral of the bending part of the
        plate's Eshelby stress, W_b I - (rotation gradient)^T M (deLorenzi's identity between the
        domain integral and the virtual extension, term by term), in the form this shell's
        bending takes: its moments live on the edges (hinges) and jump from one triangle to the
        next, where a pointwise M x rotation-gradient term has no value."""
        return -self._energy_rates(shell, x)[1] / self.thickness

    def load_release(self, external: np.ndarray | None) -> float:
        """The external nodal forces' share of G (J/m^2): their work as the vertices they act on
        move with the virtual extension (f . q d) over the thickness; the configurational force
        of the loads inside the ring (a follower pressure on a bulging flank), which the
        Eshelby stress alone leaves out. 0 without forces."""
        return 0.0 if external is None else float(np.sum(external * self.q_shift)) / self.thickness

    def _energy_rates(self, shell: Shell, x: np.ndarray) -> tuple[float, float]:
        """(dU_membrane / da, dU_bending / da) (J/m per unit extension, the whole thickness) by
        the central difference of the two shifted models."""
        if shell is not self.shell:
            raise ValueError("a virtual crack extension belongs to the shell it was built for; build one for the cut shell")
        xi = shell.edges.xi[self.edge_index]
        energies = []
        for sign, (faces, edges) in zip((1.0, -1.0), self.models):
            membrane_energy, bending_energy = np.zeros(len(self.changed)), np.zeros(len(self.changed))
            face_energies(x[self.keep] + sign * self.eps * self.q_shift[self.keep], faces, edges._replace(xi=xi),
                          self.changed, membrane_energy, bending_energy)
            energies.append((float(membrane_energy.sum()), float(bending_energy.sum())))
        (m_plus, b_plus), (m_minus, b_minus) = energies
        return (m_plus - m_minus) / (2.0 * self.eps), (b_plus - b_minus) / (2.0 * self.eps)


def _patch(shell: Shell, moved: np.ndarray):
    """The part of the shell a virtual crack extension needs: (its mesh, the kept vertices'
    indices, the triangles whose energy the moved vertices change, as indices into it, each of
    its edges' index in the shell's, where the mid-edge rotations are read). A triangle's energy depends on its corners and the far
    corners of its three neighbours, so it changes only within two layers of triangles about
    the moved vertices; a third layer keeps those triangles' hinges interior, as in the shell."""
    tri = shell.mesh.tri
    n = len(shell.mesh.X)

    def touching(vertices):
        return np.flatnonzero(np.any(vertices[tri], axis=1))

    def corners(faces):
        mask = np.zeros(n, dtype=bool)
        mask[tri[faces]] = True
        return mask

    changed = touching(corners(touching(moved)))
    context = touching(corners(changed))
    keep = np.unique(tri[context])
    index = np.full(n, -1, dtype=np.int64)
    index[keep] = np.arange(len(keep))
    local = shell_mesh(shell.mesh.X[keep], index[tri[context]], shell.mesh.thickness[context],
                       shell.mesh.region[context])
    full_keys = np.sort(shell.mesh.edge, axis=1) @ np.array([n, 1])
    local_keys = np.sort(keep[local.edge], axis=1) @ np.array([n, 1])
    order = np.argsort(full_keys)
    return local, keep, np.searchsorted(context, changed), order[np.searchsorted(full_keys[order], local_keys)]

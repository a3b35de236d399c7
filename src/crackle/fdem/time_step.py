"""The FDEM stable step and mass scaling.

Two estimates of the step's highest frequency omega_max:
- the element bound (Gershgorin): per node, its tet's bulk bound plus the springs on its faces,
  each kind counted (bulk, interfaces, surface contact, tools). Proven (omega_max never exceeds
  it), and per element: it says what sets the step and where, and mass scaling works on it;
- the assembled step's omega_max by Lanczos (solver.stability) on the linearised forces: each
  tet's linear elasticity and each interface's point-pair springs, the contact and tool springs as
  the bound counts them on the diagonal. Measured 1.07-1.28x the bound's step on the quick
  examples where interfaces or the bulk set it (docs/validation.md, "The assembled step by
  Lanczos").
The step is the larger: the bound's 2 / omega, or STEP_MARGIN x the Lanczos one; the bound's alone
where a tool or surface contact sets it (time_step).

Every interface is counted as carrying its law, an extrinsic face too: tying faces is a
constraint on the exploded mesh, and a constraint only lowers omega_max (interlacing), so the step
holds through every insertion; a face that fails keeps at most its springs (paired contact at the
same penalties), so through every failure as well. Not counted: the geometric stiffness of a
stressed tet (~stress / E), which STEP_MARGIN and run.safety cover.

The tied step (TimeStepReport.tied_dt): while every extrinsic face is still tied, its copies move
as one node and the face carries no spring, so the step is that of the conforming mesh (the same
two estimates on the clusters of copies, tied faces counting nothing). A run takes it until the
first insertion and then sub-steps at the step above (fdem.simulation).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..solver import stability
from .topology import FACE_CORNERS

if TYPE_CHECKING:
    from .model import _Bulk, _Pairs

TIME_STEP_KINDS = ("bulk tet", "interface penalty", "contact penalty", "tool penalty")
ONE_SIDED_KINDS = TIME_STEP_KINDS[2:]  # penalty springs that push only: surface contact, tools


@dataclass
class TimeStepReport:
    """The stable step and what sets it. The element bound: per node, the bulk tet and the springs
    on its faces each add to the squared frequency bound, and the node with the highest bound is
    the critical one; the run's step is that bound's or the Lanczos estimate's, the larger."""

    dt: float  # s, the largest stable step (no safety factor)
    kind: str  # the largest share of the bound at the critical node: "bulk tet", "interface penalty", "contact penalty", "tool penalty"
    element: int  # the critical node's tet (counted from 1)
    position: np.ndarray  # m, the critical node at set-up
    element_dt: np.ndarray  # s, per tet: the step its own nodes allow (the bound)
    bulk_dt: np.ndarray  # s, per tet: the step its bulk stiffness alone allows
    bound_dt: float  # s, the element bound's step (proven)
    estimate: str  # "lanczos" (the step is STEP_MARGIN x 2 / omega_max of the assembled step) or "element bound"
    lanczos_iterations: int = 0
    # s, the step while every extrinsic face is tied (module docstring), where longer than dt; 0: none
    tied_dt: float = 0.0

    def as_summary(self, label=lambda index: index + 1) -> dict:
        """summary.json's dt_limit; `label` numbers a tet as the user knows it (TetMesh.label)."""
        return {
            "kind": self.kind,
            "element": label(self.element - 1),
            "position": [float(c) for c in self.position],
            "dt": self.dt,
            "estimate": self.estimate,
            "bound_dt": self.bound_dt,
            "median_dt": float(np.median(self.element_dt)),
            "median_bulk_dt": float(np.median(self.bulk_dt)),
            "tied_dt": self.tied_dt or None,
        }


@dataclass
class MassScaling:
    """Mass added to the elements whose stable step is below a target (summary.json)."""

    target_dt: float | None = None  # s, the step asked for (run.target_dt); None: no scaling
    added_mass: float = 0.0  # fraction of the total mass
    elements: int = 0  # elements made heavier
    largest_factor: float = 1.0  # the largest density factor
    largest_factor_element: int | None = None  # its element, counted from 1
    added_mass_centroid: list[float] | None = None  # m, where the added mass sits on average

    def as_summary(self, label=lambda index: index + 1) -> dict:
        """summary.json's mass_scaling; `label` as TimeStepReport.as_summary's."""
        out = asdict(self)
        if self.largest_factor_element is not None:
            out["largest_factor_element"] = label(self.largest_factor_element - 1)
        return out


def scale_masses(bulk: "_Bulk", step: TimeStepReport, target_dt: float, safety: float,
                  max_added_mass: float) -> MassScaling:
    """Fixed mass scaling as explicit codes do it: each element whose step (safety x its stable
    step) is below `target_dt` gets its density (its nodes' masses) multiplied by (target_dt /
    its step)^2, which brings its step to the target (every term of a node's frequency bound goes
    as 1 / mass). Changes bulk.rho and bulk.mass (the nodes' masses) in place."""
    element_dt = safety * step.element_dt
    factor = np.maximum(1.0, (target_dt / element_dt) ** 2)
    tet_mass = bulk.rho * bulk.vol

    def added(f) -> float:
        return float(np.sum((f - 1.0) * tet_mass) / np.sum(tet_mass))

    fraction = added(factor)
    if fraction > max_added_mass:
        lo, hi = safety * step.dt, target_dt  # the largest target within the limit, by bisection
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if added(np.maximum(1.0, (mid / element_dt) ** 2)) <= max_added_mass else (lo, mid)
        share = np.count_nonzero(factor > 1.0) / len(factor)
        raise ValueError(
            f"run.target_dt = {target_dt:.3g} s would add {fraction:.1%} of the specimen's mass (more than "
            f"run.max_added_mass = {max_added_mass:.1%}): {share:.0%} of the elements take a shorter step (the stable "
            f"step is set by the {step.kind}); set run.target_dt at most {_round_down(lo):.3g} s or raise run.max_added_mass"
        )
    scaled = factor > 1.0
    bulk.rho *= factor
    bulk.mass *= np.repeat(factor, 4)
    if not scaled.any():
        return MassScaling(target_dt)
    extra = (factor - 1.0) * tet_mass
    centroids = bulk.x0.reshape(-1, 4, 3).mean(axis=1)
    worst = int(np.argmax(factor))
    return MassScaling(
        target_dt=target_dt,
        added_mass=fraction,
        elements=int(np.count_nonzero(scaled)),
        largest_factor=float(factor[worst]),
        largest_factor_element=worst + 1,
        added_mass_centroid=[float(c) for c in extra @ centroids / extra.sum()],
    )


def _round_down(x: float, digits: int = 3) -> float:
    """x rounded down to `digits` significant digits (an offered limit that is within it)."""
    unit = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.floor(x / unit) * unit


def time_step(bulk: "_Bulk", pairs: "_Pairs", face_iface, surface_penalty: float, tool_penalty: float,
              tied: np.ndarray | None = None, cluster: np.ndarray | None = None) -> TimeStepReport:
    """The stable step (module docstring): the element bound per node (bulk tet + interface +
    contact + tool springs) and the assembled step's omega_max by Lanczos. With `tied` (a mask
    of interfaces) and `cluster` (per node, its cluster of copies, numbered from 0): the step
    while those faces are tied (internal faces with no spring; Lanczos on the clusters)."""
    m = len(bulk.vol)
    grads = np.concatenate([-bulk.dm_inv.sum(axis=1, keepdims=True), bulk.dm_inv], axis=1)  # (m, 4, 3) grad N_k
    gtg = np.einsum("mki,mkj->mij", grads, grads)
    lam_max_g = np.linalg.eigvalsh(gtg)[:, -1]
    omega2_tet = 4.0 * (3.0 * bulk.lam + 2.0 * bulk.mu) * lam_max_g / bulk.rho  # lambda_max(M^-1 K_e) bound
    # Springs on each face (Gershgorin row sums per node), by kind. An interface face carries its
    # pair spring (twice, for the two sides' relative motion) or, once failed and when stiffer,
    # what a free face carries: surface contact and a tool. Surface contact is node-to-triangle
    # tested both ways, so a face pressed on another both pushes (its nodes) and is pushed (its
    # corners carry the other side's reactions): 2 x 2 x the penalty. Counting it once let the
    # crushed zone under a platen blow up at safety 0.7 (mass-scaled extrinsic Brazilian disc).
    # A tool spring acts on a node alone (k A / m exactly), but it is one-sided, and a node that
    # hits a one-sided spring at a large omega dt rebounds faster than it came (up to 1.25x at
    # omega dt = 1.5, 2.6x at 1.9): counting it on each of the node's faces (about 3x on a
    # surface node) keeps omega dt below ~0.8 at safety 0.7; the exact k A / m let a rattling
    # block create energy (tests/fdem/test_time_step.py).
    face_spring = np.zeros((4, m, 4))  # kind (as TIME_STEP_KINDS, bulk unused), tet, face
    interface = 2.0 * np.maximum(pairs.pn, pairs.ps)
    contact = 4.0 * surface_penalty
    exposed = contact + tool_penalty
    open_face = np.ones(len(interface)) if tied is None else np.where(tied, 0.0, 1.0)  # a tied face: no spring
    for tet, face in ((pairs.ta, pairs.fa), (pairs.tb, pairs.fb)):
        face_spring[1, tet, face] = np.where(interface >= exposed, interface, 0.0) * pairs.area / 3.0 * open_face
        face_spring[2, tet, face] = np.where(interface < exposed, contact, 0.0) * pairs.area / 3.0 * open_face
        face_spring[3, tet, face] = np.where(interface < exposed, tool_penalty, 0.0) * pairs.area / 3.0 * open_face
    outer = face_iface < 0
    face_spring[2][outer] = contact * bulk.face_area[outer] / 3.0
    face_spring[3][outer] = tool_penalty * bulk.face_area[outer] / 3.0
    omega2 = np.zeros((4, m, 4))  # kind, tet, corner
    omega2[0] = omega2_tet[:, None]
    for f in range(4):
        omega2[1:, :, FACE_CORNERS[f]] += face_spring[1:, :, f, None] / bulk.mass.reshape(m, 4)[None, :, FACE_CORNERS[f]]
    total = omega2.sum(axis=0)
    critical = int(np.argmax(total))
    tet, corner = divmod(critical, 4)
    bound_dt = float(2.0 / np.sqrt(total.max()))
    kind = TIME_STEP_KINDS[int(np.argmax(omega2[:, tet, corner]))]
    lanczos_dt, iterations = 0.0, 0
    # Where a one-sided spring (a tool, surface contact) sets the bound, the bound stays: its count
    # of those springs is what keeps their rebound in check (above), measured on the bound's step
    # (the rattling block: -1.7 % at 0.7 x the bound, -3.1 % at 0.7 x the Lanczos step, 1.4 % longer).
    if kind not in ONE_SIDED_KINDS:
        # The contact and tool springs as the bound counts them, one diagonal spring per node; each
        # interface as the bound counts it: its springs, or, where a tool or contact is stiffer,
        # the exposed springs on both its sides' nodes (in exposed_k).
        exposed_k = ((omega2[2] + omega2[3]) * bulk.mass.reshape(m, 4)).reshape(-1)
        carried = interface >= exposed
        if tied is not None:
            carried &= ~tied
        omega2_max, residual, iterations = highest_frequency2(bulk.x0, bulk.mass, bulk, pairs, exposed_k, carried,
                                                              cluster)
        # Not converged (at most LANCZOS_ITERATIONS): the top mode may not be found yet; the bound holds.
        if residual <= stability.LANCZOS_TOLERANCE * (omega2_max - residual):
            lanczos_dt = stability.STEP_MARGIN * 2.0 / math.sqrt(omega2_max)
    use_lanczos = lanczos_dt > bound_dt
    return TimeStepReport(
        dt=lanczos_dt if use_lanczos else bound_dt,
        kind=kind,
        element=tet + 1,
        position=bulk.x0[critical].copy(),
        element_dt=2.0 / np.sqrt(total.max(axis=1)),
        bulk_dt=2.0 / np.sqrt(omega2_tet),
        bound_dt=bound_dt,
        estimate="lanczos" if use_lanczos else "element bound",
        lanczos_iterations=iterations,
    )


def linearised_forces(x0: np.ndarray, tets, ifs, carried=None):
    """forces(x, out): the FDEM internal forces linearised about the reference positions x0, for
    solver.stability. tets: dm_inv, vol, lam, mu per tet (its linear elasticity); ifs: na, nb, area,
    pn, ps per interface (each point pair a spring of pn area / 3 along the face's normal and
    ps area / 3 across it: the laws' initial stiffnesses, which their tangents never exceed);
    only the interfaces `carried` (a mask; default all)."""
    m = len(tets.vol)
    n_nodes = len(x0)
    grads = np.concatenate([-tets.dm_inv.sum(axis=1, keepdims=True), tets.dm_inv], axis=1)  # (m, 4, 3) grad N_k
    lam, two_mu, vol = tets.lam[:, None], 2.0 * tets.mu[:, None, None], tets.vol[:, None, None]
    keep = slice(None) if carried is None else carried
    na, nb, area, pn, ps = ifs.na[keep], ifs.nb[keep], ifs.area[keep], ifs.pn[keep], ifs.ps[keep]
    corners = x0[na]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    kn, ks = (pn * area / 3.0)[:, None, None], (ps * area / 3.0)[:, None, None]
    a_nodes, b_nodes = na.ravel(), nb.ravel()

    def forces(x, out):
        u = x - x0
        grad_u = np.einsum("mki,mkj->mij", u.reshape(m, 4, 3), grads)
        strain = 0.5 * (grad_u + grad_u.transpose(0, 2, 1))
        stress = two_mu * strain
        stress[:, (0, 1, 2), (0, 1, 2)] += lam * np.trace(strain, axis1=1, axis2=2)[:, None]
        out[:] = (-vol * np.einsum("mij,mkj->mki", stress, grads)).reshape(n_nodes, 3)
        gap = u[nb] - u[na]  # (interfaces, 3 pairs, 3)
        gap_n = np.einsum("kpi,ki->kp", gap, normal)[:, :, None] * normal[:, None, :]
        pull = (kn * gap_n + ks * (gap - gap_n)).reshape(-1, 3)  # on A, towards B
        for c in range(3):
            out[:, c] += np.bincount(a_nodes, pull[:, c], minlength=n_nodes)
            out[:, c] -= np.bincount(b_nodes, pull[:, c], minlength=n_nodes)

    return forces


def highest_frequency2(x0, mass, tets, ifs, exposed_k, carried=None, cluster=None) -> tuple[float, float, int]:
    """omega_max^2 (1/s^2) of the linearised FDEM step (linearised_forces, the interfaces
    `carried`) with the per-node springs exposed_k (N/m) on the diagonal, by Lanczos: (value +
    residual bound, residual bound, iterations), as solver.stability.highest_frequency2. With
    `cluster` (per node, its cluster numbered from 0): the nodes of a cluster move as one (tied),
    with their masses and springs summed."""
    spacing = float(np.cbrt(np.median(tets.vol)))  # the probe's scale (any: the forces are linear)
    forces = linearised_forces(x0, tets, ifs, carried)
    if cluster is None:
        return stability.highest_frequency2(x0, mass, forces, spacing, exposed_k, linear=True)
    n_clusters = int(cluster.max()) + 1
    first = np.zeros(n_clusters, dtype=np.int64)
    first[cluster[::-1]] = np.arange(len(cluster))[::-1]  # a member of each cluster: its position
    node_forces = np.zeros((len(x0), 3))

    def cluster_forces(xc, out):
        forces(xc[cluster], node_forces)
        for c in range(3):
            out[:, c] = np.bincount(cluster, node_forces[:, c], minlength=n_clusters)

    return stability.highest_frequency2(x0[first], np.bincount(cluster, mass, minlength=n_clusters), cluster_forces,
                                        spacing, np.bincount(cluster, exposed_k, minlength=n_clusters), linear=True)


# A tool needs to be stiff only against what it presses on: the surface layer of tets and
# interfaces in series. Where the interfaces are far softer than E / h (a per-area stiffness
# from a paper, as the walnut's), a tool this many times stiffer than the stiffest interface
# already adds less compliance than a tenth of one interface layer.
TOOL_OVER_INTERFACE = 10.0


def tool_penalty_advice(bulk: "_Bulk", pairs: "_Pairs", face_iface, surface_penalty: float, tools, penalties,
                         step: TimeStepReport, penalty_keys: dict[str, str]) -> list[str]:
    """Advice when a tool's contact penalty, far stiffer than the interfaces, sets the stable step
    (before any mass scaling): the penalty that is stiff enough and the step it would give, with
    the key that sets it (tools.NAME.penalty, or what penalty_keys names)."""
    if step.kind != "tool penalty" or not len(pairs.pn):
        return []
    stiffest = float(np.max(np.maximum(pairs.pn, pairs.ps)))
    enough = float(f"{TOOL_OVER_INTERFACE * stiffest:.2g}")  # as the advice states it
    stiff = [(t.name, k) for t, k in zip(tools, penalties) if k > enough]
    if not stiff:
        return []
    softer = time_step(bulk, pairs, face_iface, surface_penalty, enough)  # every tool then at most `enough`
    if softer.dt < 1.1 * step.dt:
        return []
    names = ", ".join(f"'{name}'" for name, _ in stiff)
    worst = max(k for _, k in stiff)
    return [
        f"the stable step {step.dt * 1e9:.3g} ns is set by the contact penalty of tool{'s' if len(stiff) > 1 else ''} {names} ({worst:.3g} Pa/m, "
        f"{worst / stiffest:.0f}x the stiffest interface, {stiffest:.3g} Pa/m); {TOOL_OVER_INTERFACE:g}x the "
        f"interfaces is stiff enough (it adds under a tenth of one interface layer's compliance): "
        + ", ".join(dict.fromkeys(f"{penalty_keys.get(name, f'tools.{name}.penalty')} = {enough:g}" for name, _ in stiff))
        + f" gives a stable step of {softer.dt * 1e9:.3g} ns (set by the {softer.kind})"
    ]

"""The bonded-particle model's arrays: particles from a packing, bonds at set-up (paper 003 eq. 1:
D0 <= gamma_int (Ra + Rb), gamma_int chosen for a mean bond count), their stiffness and
strength (eqs 2-3), the geometric contacts found between chunks, and the stable step."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..materials.random_properties import draw, statistics
from scipy.spatial import cKDTree

from ..solver.body import body_arrays, pair_incidence
from .kernels import BONDED, CONTACT, GONE, JOINT, TRANSFER_COLUMNS, Interactions, Particles, pair_distances

# Largest gamma_int searched for the asked bond count: beyond it bonds would join particles that
# other particles separate.
MAX_GAMMA = 2.0


@dataclass(frozen=True)
class BondLaw:
    """The JCFpm parameters of a material (paper 003 Table 1, SI units)."""

    bond_modulus: float  # Y (Pa): kn = 2 Y Ra Rb / (Ra + Rb)
    stiffness_ratio: float  # P: kt = P kn
    tensile_strength: float  # t (Pa): a bond fails in tension at t Aint, Aint = pi min(Ra, Rb)^2
    cohesion: float  # c (Pa): in shear at c Aint + Fn tan(friction_angle)
    friction_angle: float  # rad, of bonds and of failed bonds in compression
    contact_friction_angle: float  # rad, of the contacts that form during the run


@dataclass(frozen=True)
class GroupedLaws:
    """Several materials' bond laws in one packing ([materials.NAME]): each particle's material
    (`group`, an index into `laws`) and the laws of the bonds between two materials (`pairs`:
    {(i, j): BondLaw} both ways round, from [interfaces."A-B"]; without one, the law of the side
    with the lower tensile strength). A pair's springs are the two particles' half-springs in
    series (2 Y R each, paper 003 eq. 3, and P times that in shear), its strengths and friction
    its law's. The scalars below are what the set-up's bounds read (the stiffest material for the
    tools' penalty and the wave transit)."""

    laws: tuple
    group: np.ndarray
    pairs: dict

    @property
    def bond_modulus(self) -> float:
        return max(law.bond_modulus for law in self.laws)

    @property
    def stiffness_ratio(self) -> float:
        return max(law.stiffness_ratio for law in self.laws)

    def governing(self, ga: np.ndarray, gb: np.ndarray) -> tuple[list, np.ndarray]:
        """The laws in play (the materials', then the pairs') and each (ga, gb) pair's index among them."""
        laws = list(self.laws)
        ft = np.array([law.tensile_strength for law in laws])
        which = np.where(ft[ga] <= ft[gb], ga, gb)
        for (i, j), law in self.pairs.items():
            if i < j:
                which[((ga == i) & (gb == j)) | ((ga == j) & (gb == i))] = len(laws)
                laws.append(law)
        return laws, which


def pair_parameters(law, radius: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Per pair (a, b): kn, kt (N/m), the tensile strength and cohesion (Pa) and the tangents of
    the bond's and the contacts' friction angles, of one BondLaw or of GroupedLaws."""
    ra, rb = radius[a], radius[b]
    if not isinstance(law, GroupedLaws):
        kn = normal_stiffness(law, ra, rb)
        return (kn, law.stiffness_ratio * kn, law.tensile_strength, law.cohesion, math.tan(law.friction_angle),
                math.tan(law.contact_friction_angle))
    ga, gb = law.group[a], law.group[b]
    ya = np.array([m.bond_modulus for m in law.laws])[ga] * ra
    yb = np.array([m.bond_modulus for m in law.laws])[gb] * rb
    pa = np.array([m.stiffness_ratio for m in law.laws])[ga] * ya
    pb = np.array([m.stiffness_ratio for m in law.laws])[gb] * yb
    laws, which = law.governing(ga, gb)

    def column(name, f=float):
        return np.array([f(getattr(m, name)) for m in laws])[which]

    return (2.0 * ya * yb / (ya + yb), 2.0 * pa * pb / (pa + pb), column("tensile_strength"), column("cohesion"),
            column("friction_angle", math.tan), column("contact_friction_angle", math.tan))


def bond_gamma(centers: np.ndarray, radii: np.ndarray, bonds_per_particle: float) -> float:
    """The interaction range gamma_int that gives `bonds_per_particle` bonds per particle on
    average (each bond counts for both its particles): the ratio D0 / (Ra + Rb) of the
    (bonds_per_particle n / 2)-th closest pair. ValueError when even MAX_GAMMA is too short."""
    n = len(radii)
    wanted = int(round(0.5 * bonds_per_particle * n))
    pairs = _pairs_within(centers, radii, MAX_GAMMA, 0.0)
    if wanted < 1 or len(pairs) < wanted:
        raise ValueError(
            f"bonds_per_particle = {bonds_per_particle:g} is out of reach: within gamma_int = {MAX_GAMMA} the "
            f"packing has {2 * len(pairs) / n:.1f} neighbours per particle; ask for fewer or pack denser"
        )
    ratio = np.sort(_range_ratio(centers, radii, pairs))
    return float(ratio[wanted - 1])


def _pairs_within(centers, radii, gamma, skin) -> np.ndarray:
    """Sorted (k, 2) pairs a < b with D <= gamma (Ra + Rb) + skin."""
    reach = gamma * 2.0 * float(radii.max()) + skin
    pairs = cKDTree(centers).query_pairs(reach, output_type="ndarray").astype(np.int64)
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    pairs.sort(axis=1)
    dist = np.linalg.norm(centers[pairs[:, 1]] - centers[pairs[:, 0]], axis=1)
    pairs = pairs[dist <= gamma * (radii[pairs[:, 0]] + radii[pairs[:, 1]]) + skin]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _range_ratio(centers, radii, pairs) -> np.ndarray:
    dist = np.linalg.norm(centers[pairs[:, 1]] - centers[pairs[:, 0]], axis=1)
    return dist / (radii[pairs[:, 0]] + radii[pairs[:, 1]])


def make_particles(centers, radii, density, supports, velocity=None) -> Particles:
    """Spheres at rest (or moving at `velocity`), with their masses and rotational inertias;
    supports: the (constraint, projection, support_tool) of support_constraints."""
    radii = np.asarray(radii, float)
    mass = density * 4.0 / 3.0 * math.pi * radii**3
    return Particles(**body_arrays(centers, mass, math.pi * radii**2, radii, supports, velocity),
                     spin=np.zeros((len(radii), 3)), inertia=0.4 * mass * radii**2)


def normal_stiffness(law: BondLaw, ra, rb):
    """kn = 2 Y Ra Rb / (Ra + Rb) (paper 003 eq. 3): two springs of stiffness 2 Y R in series."""
    return 2.0 * law.bond_modulus * ra * rb / (ra + rb)


def interactions(particles: Particles, law: BondLaw, pairs: np.ndarray, state: np.ndarray,
                 d0: np.ndarray, shear: np.ndarray | None = None, joints: dict | None = None) -> Interactions:
    """Interaction arrays for `pairs` (sorted a < b) in `state`, with their particle CSR.
    `joints`: the joint_* arrays to carry (none: no joint)."""
    k = len(pairs)
    a, b = pairs[:, 0].copy(), pairs[:, 1].copy()
    ra, rb = particles.radius[a], particles.radius[b]
    kn, kt, strength, cohesion, tan_bond, tan_contact = pair_parameters(law, particles.radius, a, b)
    area = math.pi * np.minimum(ra, rb) ** 2
    bonded = state == BONDED
    tan_phi = np.where(state == CONTACT, tan_contact, tan_bond)
    start, entry, sign = pair_incidence(len(particles.radius), a, b)
    return Interactions(
        a=a, b=b, state=state.astype(np.int8), d0=d0.astype(float), kn=kn, kt=kt,
        fn_max=np.where(bonded, strength * area, 0.0),
        cohesion=np.where(bonded, cohesion * area, 0.0),
        tan_phi=tan_phi,
        shear=np.zeros((k, 3)) if shear is None else shear,
        transfer=np.zeros((k, TRANSFER_COLUMNS)),
        fail_time=np.full(k, np.nan), fail_mode=np.zeros(k, dtype=np.int8),
        e_damage=np.zeros(k), e_friction=np.zeros(k), start=start, entry=entry, sign=sign,
        **(joints or _no_joints(k)),
    )


def _no_joints(k: int) -> dict:
    # One dummy row keeps the compiled signature the same with and without joints.
    return dict(joint=np.full(k, -1, dtype=np.int64), joint_normal=np.zeros((1, 3)), joint_un=np.zeros(1),
                joint_tan_psi=np.zeros(1), joint_slip=np.zeros(1))


@dataclass(frozen=True)
class Joint:
    """A planar closed flaw as smooth joints (paper 003 section 3): the bonds whose line of
    centres crosses the flaw's segment become JOINT interactions."""

    center: np.ndarray  # m, on the flaw
    normal: np.ndarray  # unit normal of the flaw's plane
    along: np.ndarray  # unit vector along the flaw (in its plane); it runs through along normal x along
    length: float  # m, along `along`
    normal_stiffness: float  # Pa/m, Kn_j: kn = Kn_j Aint (eq. 9)
    shear_stiffness: float  # Pa/m, Kt_j: kt = Kt_j Aint
    friction_angle: float  # rad, phi_j
    dilatancy_angle: float  # rad, psi_j

    def crossed(self, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
        """Which segments a-b cross the flaw (a mask)."""
        sa = (xa - self.center) @ self.normal
        sb = (xb - self.center) @ self.normal
        cross = sa * sb < 0.0
        t = np.where(cross, sa / np.where(cross, sa - sb, 1.0), 0.0)
        point = xa + t[:, None] * (xb - xa)
        return cross & (np.abs((point - self.center) @ self.along) <= 0.5 * self.length)


def with_joints(particles: Particles, inter: Interactions, joint: Joint) -> Interactions:
    """The bonds that cross `joint` turned into smooth joints (no cohesion, the joint's
    stiffness, friction and dilatancy; normal oriented from a to b). ValueError when none does."""
    x = particles.x
    ids = np.flatnonzero(joint.crossed(x[inter.a], x[inter.b]) & (inter.state == BONDED))
    if len(ids) == 0:
        raise ValueError("no bond crosses the flaw: check its center, angle and length")
    rest = x[inter.b[ids]] - x[inter.a[ids]]
    normal = np.where((rest @ joint.normal)[:, None] >= 0.0, joint.normal, -joint.normal)
    area = np.pi * np.minimum(particles.radius[inter.a[ids]], particles.radius[inter.b[ids]]) ** 2
    inter.state[ids] = JOINT
    inter.kn[ids] = joint.normal_stiffness * area
    inter.kt[ids] = joint.shear_stiffness * area
    inter.fn_max[ids] = 0.0
    inter.cohesion[ids] = 0.0
    inter.tan_phi[ids] = np.tan(joint.friction_angle)
    index = np.full(len(inter.a), -1, dtype=np.int64)
    index[ids] = np.arange(len(ids))
    return inter._replace(joint=index, joint_normal=np.ascontiguousarray(normal), joint_un=np.zeros(len(ids)),
                          joint_tan_psi=np.full(len(ids), np.tan(joint.dilatancy_angle)), joint_slip=np.zeros(len(ids)))


def bonds(particles: Particles, law: BondLaw, gamma: float) -> Interactions:
    """Bonds between every pair with D0 <= gamma (Ra + Rb), at rest at their set-up distance."""
    x, r = particles.x, particles.radius
    pairs = _pairs_within(x, r, gamma, 0.0)
    d0 = pair_distances(x, pairs[:, 0], pairs[:, 1])
    return interactions(particles, law, pairs, np.full(len(pairs), BONDED), d0)


# What [material.random] may draw per bond: the property and the bond array it scales.
RANDOM_BOND_PROPERTIES = {"tensile_strength": "fn_max", "cohesion": "cohesion"}


def draw_bond_strengths(particles: Particles, inter: Interactions, law: BondLaw, random: dict, seed: int,
                        material: str) -> tuple[dict, dict]:
    """The bonds' strengths drawn per bond at its mid-point (Material.random: property ->
    RandomProperty, the law's value the mean), written into the bond arrays; returns the drawn
    values and their statistics per property."""
    x = particles.x
    mid = 0.5 * (x[inter.a] + x[inter.b])
    drawn, stats_of = {}, {}
    for name, spec in random.items():
        mean = getattr(law, name)
        values = draw(spec, mean, mid, seed, material, name)
        column = getattr(inter, RANDOM_BOND_PROPERTIES[name])
        column *= values / mean  # strength x Aint, per bond
        drawn[name], stats_of[name] = values, statistics(spec, mid, values)
    return drawn, stats_of


def with_contacts(particles: Particles, law: BondLaw, current: Interactions, n_bonds: int, skin: float) -> Interactions:
    """The bonds (the first n_bonds entries, kept as they are) plus a CONTACT for every pair
    closer than Ra + Rb + skin that no live bond joins; contacts that persist keep their shear
    force. Deterministic: pairs in sorted order."""
    x, r = particles.x, particles.radius
    near = _pairs_within(x, r, 1.0, skin)
    n = len(r)
    key_near = near[:, 0] * n + near[:, 1]
    bond_key = current.a[:n_bonds] * n + current.b[:n_bonds]
    live = current.state[:n_bonds] != GONE
    near = near[~np.isin(key_near, bond_key[live])]
    key_near = near[:, 0] * n + near[:, 1]
    shear = np.zeros((len(near), 3))
    # A new contact rests at Ra + Rb, or where it is if already closer (a pair whose bond broke
    # while the spheres overlapped, as packed): its spring starts unloaded, no energy from nowhere.
    contact_d0 = np.minimum(r[near[:, 0]] + r[near[:, 1]], pair_distances(x, near[:, 0], near[:, 1]))
    old_key = current.a[n_bonds:] * n + current.b[n_bonds:]
    if len(old_key):
        # Old contacts are in sorted key order (they were built here); they keep their state.
        pos = np.searchsorted(old_key, key_near)
        pos = np.minimum(pos, len(old_key) - 1)
        kept = old_key[pos] == key_near
        shear[kept] = current.shear[n_bonds:][pos[kept]]
        contact_d0[kept] = current.d0[n_bonds:][pos[kept]]
    pairs = np.concatenate([np.stack([current.a[:n_bonds], current.b[:n_bonds]], axis=1), near])
    state = np.concatenate([current.state[:n_bonds], np.full(len(near), CONTACT)])
    d0 = np.concatenate([current.d0[:n_bonds], contact_d0])
    joints = dict(joint=np.concatenate([current.joint[:n_bonds], np.full(len(near), -1)]),
                  **{name: getattr(current, name) for name in ("joint_normal", "joint_un", "joint_tan_psi", "joint_slip")})
    merged = interactions(particles, law, pairs, state, d0, np.concatenate([current.shear[:n_bonds], shear]), joints)
    # The bonds' own state (stiffness and strengths of joints, strengths zeroed at failure,
    # failure records, energies) carries over.
    for name in ("kn", "kt", "fn_max", "cohesion", "tan_phi", "fail_time", "fail_mode", "e_damage", "e_friction"):
        getattr(merged, name)[:n_bonds] = getattr(current, name)[:n_bonds]
    return merged


def stable_dt(particles: Particles, inter: Interactions, tool_stiffness: np.ndarray) -> float:
    """Largest stable step (no safety factor): per particle, Gershgorin bounds of its
    translation (2 (kn + kt) per interaction, both particles moving) plus the tools, and of its
    spin (2 kt l^2 / I with the lever l = its radius); the stiffest particle sets the step.
    `tool_stiffness` (per particle) adds whatever else may press on it: the tools, and in the
    default step room for contacts that form later (dem.build)."""
    n = len(particles.radius)
    k_sum = np.zeros(n)
    kt_sum = np.zeros(n)
    for end in (inter.a, inter.b):
        np.add.at(k_sum, end, inter.kn + inter.kt)
        np.add.at(kt_sum, end, inter.kt)
    omega2 = (2.0 * k_sum + tool_stiffness) / particles.mass + 2.0 * kt_sum * particles.radius**2 / particles.inertia
    return float(2.0 / math.sqrt(omega2.max())) if omega2.max() > 0 else math.inf

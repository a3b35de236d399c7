"""The meshfree EFG method (crackle.meshfree, paper 000): MLS shape functions, nodal integration
with its stabilisation, the J2 and the thermo-elasto-viscoplastic material points, the explicit
step on the shared base, the energy audit and the scenario checks. Small particle counts: the
whole file is meant to take seconds once the kernels are compiled."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from crackle.cli import main
from crackle.io import read_history_csv
from crackle.meshfree import build_simulation
from crackle.meshfree.build import build_meshfree_simulation
from crackle.meshfree.step import gershgorin_frequency2, highest_frequency2
from crackle.meshfree.fracture import FRACTURE_CHECK
from crackle.meshfree.kernels import internal_forces
from crackle.meshfree.material import J2Law, ThermoLaw, material_point
from crackle.meshfree.particles import plate_particles
from crackle.meshfree.shape import basis_terms, neighbour_links, shape_functions, smoothed_gradients
from crackle.scenario import load_scenario
from crackle.solver import RunControl, UnstableRunError
from crackle.solver import run as run_simulation
from crackle.analysis.energy import energy_error, relative_imbalance
from crackle.solver.integrator import FUSED_MATH
from crackle.solver.stability import STEP_MARGIN
from meshfree_fields import LINEAR_A, LINEAR_B, ROUNDING, approximated, gradient
from threads import outputs_with_1_and_2_threads

E_AL, NU, RHO_AL = 71e9, 0.3, 2700.0

PLATE = """
name = "mf-plate"
method = "meshfree"

[specimen]
shape = "box"
size = [0.04, 0.04, 0.002]
origin = [-0.02, -0.02, 0.0]

[particles]
spacing = 0.002
layers = 3

[material]
density = 2700.0
youngs_modulus = 71e9
poissons_ratio = 0.3

[[tools]]
name = "ball"
shape = "sphere"
radius = 0.005
center = [0.0, 0.0, 0.0071]
direction = [0.0, 0.0, -1.0]
speed = 20.0

[[supports]]
kind = "fixed"
where = { box_min = [-0.021, -0.021, -0.001], box_max = [-0.019, 0.021, 0.003] }
[[supports]]
kind = "fixed"
where = { box_min = [0.019, -0.021, -0.001], box_max = [0.021, 0.021, 0.003] }

[run]
end_time = 2e-5
history_samples = 50
field_frames = 1
"""
# The same plate yielding: aluminium of paper 000's impact (150 MPa), linear hardening, rate dependent.
PLASTIC = ["--set", "tools.ball.speed=60.0", "--set", "material.yield_stress=150e6",
           "--set", "material.hardening_exponent=1.0", "--set", "material.reference_plastic_strain=0.1",
           "--set", "material.rate_exponent=0.05", "--set", "material.reference_strain_rate=1e3"]
# ... and breaking: a particle fails at 3 x 100 MPa of maximum principal stress.
FRACTURE = ("material.tensile_strength=100e6",)
# ... or with the thermo law (the same sigma0, eps0, N = 1, rate0 and 1/m), its thermal effects
# exaggerated so that they show: alpha 10 x aluminium's, c 1/9 of it (the plastic work heats
# ~9 x more), E falling by 200 MPa/K, thermal softening with delta 0.8 over kappa = 200 K.
THERMO = ("material.model=thermo", "material.thermal_expansion=2e-4", "material.specific_heat=100.0",
          "material.thermal_softening=0.8", "material.softening_temperature=200.0",
          "material.youngs_modulus_temperature=[-2e8, 0.0]")


@pytest.fixture(scope="module")
def plate_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mf") / "plate.toml"
    path.write_text(PLATE)
    return path


def _links(layers, spacing=0.002, size=(0.02, 0.016, 0.002), dilation=2.5):
    plate = plate_particles((0.0, 0.0, 0.0), size, spacing, layers)
    radius = dilation * float(np.max(plate.spacing))
    start, neighbour, _ = neighbour_links(plate.X, radius)
    value, grad, condition = shape_functions(plate.X, plate.volume, start, neighbour, radius,
                                             basis_terms(plate.thickness_axis, layers))
    return plate, start, neighbour, value, grad, condition


@pytest.mark.parametrize("layers", [2, 3])
def test_patch_linear_field_reproduced(layers):
    """Values and gradients of a linear field u = A X + b are reproduced at every particle,
    corners and faces included: max error below 1e-10 (values, m, for |u| ~ 0.01; gradients
    relative to |A| = 1; measured ~1e-14 and ~5e-11)."""
    plate, start, neighbour, value, grad, _ = _links(layers)
    u = plate.X @ LINEAR_A.T + LINEAR_B
    assert np.max(np.abs(approximated(start, neighbour, value, u) - u)) < 1e-10
    assert np.max(np.abs(gradient(start, neighbour, grad, u) - LINEAR_A)) / np.max(np.abs(LINEAR_A)) < 1e-10
    # The quadratic basis: a quadratic in-plane field is reproduced too.
    q = (plate.X[:, 0] ** 2 + 3.0 * plate.X[:, 0] * plate.X[:, 1]) / 0.02
    assert np.max(np.abs(approximated(start, neighbour, value, q) - q)) < 1e-10 * np.max(np.abs(q))


@pytest.mark.parametrize("layers", [2, 3])
def test_patch_smoothed_gradients(layers):
    """The gradients nodal integration uses (smoothed over each particle's cell, SCNI) are exact
    for a linear field at every particle: error below 1e-10 of |A| (measured ~1e-13)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.02, 0.016, 0.004), 0.002, layers)
    start, neighbour, grad, condition, bad = smoothed_gradients(
        plate.X, plate.volume, plate.cells, 2.5 * float(np.max(plate.spacing)),
        basis_terms(plate.thickness_axis, layers))
    assert bad is None and condition < 1e4
    u = plate.X @ LINEAR_A.T
    assert np.max(np.abs(gradient(start, neighbour, grad, u) - LINEAR_A)) < 1e-10 * np.max(np.abs(LINEAR_A))


def test_single_precision_links_leave_rest_translation_and_momentum_exact():
    """The links' gradients and values are stored in single precision (kernels.LINK_FLOAT), their
    sums in double, in relative form (kernels docstring). What must not rest on their rounding
    (6e-8) does not: a plate (10 x 8 x 3 particles) at rest has F = I and no stabilisation force
    exactly, so nothing moves (every velocity exactly 0 after a step); translated rigidly by
    (1, -2, 0.5) m its F is I to 1e-12 (measured 2e-15); and under a random displacement field
    (1e-5 m) its internal forces sum to zero to 1e-12 of their size (momentum; measured 2e-17,
    where the self links' single-precision values alone, without links.link_sums, leave 3e-10)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.018, 0.014, 0.002), 0.002, 3)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU))
    p = sim.particles
    assert sim.links.grad.dtype == np.float32 and sim.links.value.dtype == np.float32
    sim.advance(1, 1e-9)
    assert np.all(p.deformation == np.eye(3).ravel()) and not np.any(p.stab_force) and not np.any(p.v)
    p.x[:] = p.X + [1.0, -2.0, 0.5]
    sim.advance(1, 1e-12)
    assert np.abs(p.deformation - np.eye(3).ravel()).max() < 1e-12
    p.x[:] = p.X + 1e-5 * np.random.default_rng(3).standard_normal(p.X.shape)
    p.v[:] = 0.0
    dt = 1e-12
    sim.advance(1, dt)
    force = p.v * p.mass[:, None] / dt
    assert np.abs(force.sum(axis=0)).max() < 1e-12 * np.abs(force).sum()


def test_vectorised_link_sums_equal_the_scalar_code_bit_for_bit():
    """The gradient pass's sums over a particle's links (kernels._relative_sums) are compiled with
    LLVM's SLP vectoriser (solver.integrator.slp_vectorised: each row of F and its stabilisation
    component as one four-wide multiply-add per link). Each lane does the scalar arithmetic, so
    on a plate under a random displacement field (1e-4 m) every particle's twelve sums equal, bit
    for bit, the same function compiled without it (numba's default), and numba's setting is as
    before once the kernel is compiled."""
    import numba

    from crackle.meshfree.kernels import _relative_sums

    plate = plate_particles((0.0, 0.0, 0.0), (0.018, 0.014, 0.002), 0.002, 3)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU))
    links = sim.links
    x = sim.particles.X + 1e-4 * np.random.default_rng(5).standard_normal(sim.particles.X.shape)
    before = numba.config.SLP_VECTORIZE
    vectorised = np.array([_relative_sums(i, x, links.start, links.neighbour, links.grad_value) for i in range(len(x))])
    assert numba.config.SLP_VECTORIZE == before
    numba.config.SLP_VECTORIZE = 0
    try:
        scalar_sums = numba.njit(fastmath=FUSED_MATH)(_relative_sums.py_func)
        scalar = np.array([scalar_sums(i, x, links.start, links.neighbour, links.grad_value) for i in range(len(x))])
    finally:
        numba.config.SLP_VECTORIZE = before
    assert np.array_equal(vectorised, scalar)
    assert np.abs(vectorised[:, [0, 5, 10]]).min() > 0.5  # F - R: the identity and a real strain
    assert np.abs(vectorised[:, [3, 7, 11]]).max() > 1e-6  # the stabilisation's sums of relative positions


def test_uniform_stress_leaves_the_inside_in_equilibrium():
    """The integration constraint: a block (16 x 9 x 3 particles) in uniaxial stress (Green strain
    e = 1e-3 along x, -nu e across: S = E e along x, 0 elsewhere) pulls only the particles that
    the x faces' traction reaches; every particle farther than R + a/2 from them (R the support
    radius, 270 of 432) is in equilibrium to ROUNDING of E e a^2 (the stress to ROUNDING of E e).
    Direct nodal
    integration (gradients at the particles) left up to 0.43 E e a^2 there."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.03, 0.016, 0.004), 0.002, 3)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU))
    p = sim.particles
    e = 1e-3
    p.x[:] = p.X * np.sqrt(1.0 + 2.0 * np.array([e, -NU * e, -NU * e]))
    dt = 1e-10
    sim.advance(1, dt)  # from rest: v = dt f / m
    force = p.v * p.mass[:, None] / dt
    assert p.stress[:, 0] == pytest.approx(E_AL * e, rel=ROUNDING)
    lo, hi = p.X[:, 0].min(), p.X[:, 0].max()
    far = np.minimum(p.X[:, 0] - lo, hi - p.X[:, 0]) >= sim.support_radius + 0.001 - 1e-9
    assert far.sum() == 270
    assert np.max(np.abs(force[far])) < ROUNDING * E_AL * e * 0.002**2
    assert np.max(np.abs(force[~far])) > 1e-2 * E_AL * e * 0.002**2  # the faces do pull


def _block(law=None, stabilisation=0.1, **kw):
    plate = plate_particles((0.0, 0.0, 0.0), (0.02, 0.012, 0.004), 0.002, 3)
    return build_meshfree_simulation(plate, RHO_AL, law or J2Law(E_AL, NU), stabilisation=stabilisation, **kw)


def test_uniform_tension_gives_uniform_stress():
    """A block stretched by a linear displacement field (1e-3 along x with lateral contraction
    -3e-4, a shear of 2e-4) has the same stress at every particle, corners included, within 1e-6
    of its magnitude, equal to St. Venant-Kirchhoff's S = lambda tr E + 2 mu E of the Green strain
    of that F (measured 3e-12), and the stabilisation stays at rest (|k eps| ~ 0)."""
    sim = _block()
    p = sim.particles
    F = np.array([[1.001, 2e-4, 0.0], [0.0, 0.9997, 0.0], [0.0, 0.0, 0.9997]])
    p.x[:] = p.X @ F.T
    sim.advance(1, 1e-12)  # the stress pass sees x before the step moves it (v = 0: x stays put but for rounding)
    Eg = 0.5 * (F.T @ F - np.eye(3))
    lam, mu = sim.law[0, 0], sim.law[0, 1]
    S = lam * np.trace(Eg) * np.eye(3) + 2.0 * mu * Eg
    expected = np.array([S[0, 0], S[1, 1], S[2, 2], S[0, 1], S[1, 2], S[0, 2]])
    scale = np.max(np.abs(expected))
    assert np.max(np.abs(p.stress - expected)) < 1e-6 * scale
    # The stabilisation forces k eps (N) against the force scale stress x spacing^2 (~380 N here).
    assert np.max(np.abs(p.stab_force)) < 1e-6 * scale * 0.002**2


def test_stabilisation_stiffens_the_zero_energy_mode():
    """The checkerboard field u = d (-1)^(i+j+k) e_x is a zero-energy mode of nodal integration:
    at a particle whose support is symmetric its MLS gradient vanishes, so without stabilisation
    it stores almost nothing there (< 1e-3 of E (d/a)^2 V / 2, a the spacing: its cell's F is I;
    its two Gauss points through the wall see the gradient of F along its line, from the cells
    of the face particles, whose supports are one-sided: measured 5.4e-4, ~3e-25 at one point). The
    stabilisation (alpha = 0.1: each particle's displacement against the MLS approximation at
    it) gives it an energy of the order alpha E (d/a)^2 V / 2 (measured 0.69 x that; asserted
    between 0.5 and 3 x), while a uniform strain stores no stabilisation energy at all (< 1e-12
    of its elastic energy; measured 1e-27)."""
    for alpha in (0.0, 0.1):
        sim = _block(stabilisation=alpha)
        p = sim.particles
        a, d = 0.002, 1e-6
        sign = (-1.0) ** np.rint(p.X / a).astype(int).sum(axis=1)
        x = p.X.copy()
        x[:, 0] += d * sign
        elastic, stab = sim.strain_energies(x)
        R, lo, hi = sim.support_radius, p.X.min(axis=0), p.X.max(axis=0)
        inside = np.all((p.X[:, :2] >= lo[:2] + R - 1e-9) & (p.X[:, :2] <= hi[:2] - R + 1e-9), axis=1)
        symmetric = inside & (np.abs(p.X[:, 2] - 0.5 * (lo[2] + hi[2])) < 1e-9)
        assert symmetric.sum() == 5
        scale = 0.5 * E_AL * (d / a) ** 2 * p.volume[symmetric]
        assert np.all(elastic[symmetric] < 1e-3 * scale)
        if alpha == 0.0:
            assert np.all(stab == 0.0)
        else:
            ratio = stab[symmetric] / (alpha * scale)
            assert np.all((ratio > 0.5) & (ratio < 3.0))
            smooth_elastic, smooth_stab = sim.strain_energies(p.X * np.array([1.0005, 1.0, 1.0]))
            assert smooth_stab.sum() < 1e-12 * smooth_elastic.sum()


def test_rod_vibration_gives_the_bar_wave_speed():
    """A free rod 80 mm long (2 x 2 mm section: 41 x 3 x 3 particles, steel) started in its first
    axial mode v = cos(pi X / L): the end's velocity crosses zero every half period T/2 with
    T = 2 L / c, c = sqrt(E / rho) = 5064 m/s (the slender-bar speed; the lateral inertia correction
    is 2e-4 here). c measured from the 1st and 3rd crossings within 3 % (measured -0.05 %); the
    energy audit of the free vibration within 1e-3 (measured -2.8e-4: the audit's half-step kinetic
    and mid-step elastic energies differ from the central difference's conserved energy by
    ~(omega dt)^2 / 8, 2e-4 for this mode at 0.7 x the Lanczos step)."""
    a, E, rho = 0.002, 200e9, 7800.0
    L = 40 * a
    plate = plate_particles((0.0, 0.0, 0.0), (L, 2 * a, 2 * a), a, 3)
    sim = build_meshfree_simulation(plate, rho, J2Law(E, 0.3))
    p = sim.particles
    p.v[:, 0] = np.cos(np.pi * p.X[:, 0] / L)
    sim._initial_energy = sim.kinetic_energy()
    c = np.sqrt(E / rho)
    dt = 0.7 * sim.stable_dt
    end = p.X[:, 0] < 1e-9
    times, speeds = [], []
    for _ in range(int(1.6 * 2 * L / c / dt)):
        sim.advance(1, dt)
        times.append(sim.time - 0.5 * dt)
        speeds.append(p.v[end, 0].mean())
    times, speeds = np.array(times), np.array(speeds)
    k = np.flatnonzero(np.sign(speeds[:-1]) != np.sign(speeds[1:]))
    crossings = times[k] - speeds[k] * dt / (speeds[k + 1] - speeds[k])
    assert len(crossings) >= 3
    measured = 2.0 * L / (crossings[2] - crossings[0])
    assert measured == pytest.approx(c, rel=0.03)
    terms = sim.energies(dt)
    external = terms.pop("energy.external")
    assert abs(external - sum(terms.values())) < 1e-3 * external


def _dense_stiffness(sim):
    """The linearised stiffness (3n x 3n) assembled from the links, independently of the kernels:
    small strain B_I u = sym(sum_J u_J (x) grad N_J) at each particle, at its two Gauss points
    through the wall B_I -+ a_I sum_J c_IJ B_J (thickness.py) with Hooke's C, weight V / 2 each,
    plus the Hessian of the stabilisation sum_I k_I |u_I - sum_M N_M(X_I) u_M|^2 / 2."""
    p, links = sim.particles, sim.links
    n = len(p.mass)
    lam, mu = sim.law[0, 0], sim.law[0, 1]
    C = np.zeros((6, 6))  # Voigt xx yy zz, engineering xy yz xz
    C[:3, :3] = lam
    C[np.arange(3), np.arange(3)] += 2.0 * mu
    C[3:, 3:] = mu * np.eye(3)
    K = np.zeros((3 * n, 3 * n))
    B = np.zeros((n, 6, 3 * n))
    for i in range(n):
        r = slice(links.start[i], links.start[i + 1])
        J, g = links.neighbour[r], links.grad[r]
        for a in range(3):
            B[i, a, 3 * J + a] = g[:, a]
        for v, (a, b) in zip((3, 4, 5), ((0, 1), (1, 2), (0, 2))):
            B[i, v, 3 * J + a] = g[:, b]
            B[i, v, 3 * J + b] = g[:, a]
    columns = sim.columns
    for i in range(n):
        r = slice(columns.start[i], columns.start[i + 1])
        slope = np.einsum("k,kab->ab", columns.coef[r], B[columns.member[r]])
        for side in (-1.0, 1.0):
            Bs = B[i] + side * columns.offset[i] * slope
            K += 0.5 * p.volume[i] * Bs.T @ C @ Bs
    for i in range(n):
        r = slice(links.start[i], links.start[i + 1])
        J = links.neighbour[r]
        D = -links.value[r]  # d eps_I / d u_M (the same for each component)
        D[np.searchsorted(J, i)] += 1.0
        S = p.stab_k[i] * np.outer(D, D)
        for a in range(3):
            K[np.ix_(3 * J + a, 3 * J + a)] += S
    return K


def test_forces_are_the_derivative_of_the_energy_at_two_gauss_points():
    """The internal forces (kernels.internal_forces, with the two Gauss points through the wall of
    thickness.py and their pass back along the line) are minus the derivative of the stored
    energy (kernels.strain_energies): central differences (1e-9 m) at 24 coordinates of a randomly
    displaced 7 x 3 x 5 plate whose thin side is y (the lines through the wall not along z), within
    1e-6 of the largest force (measured 4e-10). And the points see bending exactly: bent to
    u_x = -kappa x zeta, u_y = kappa x^2 / 2 (zeta = y - the mid-plane, lateral strains held at 0)
    the plate stores (lambda + 2 mu) kappa^2 t^3 / 24 per unit of its area, within 1e-5 (measured
    2e-9), where one point a cell stored 27/32 of it (measured -0.156250) (a quadratic field: the MLS reproduces it and each cell's mean gradient is
    exact, so only the quadrature through the wall can miss)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.012, 0.004, 0.008), 0.002, 3)
    sim = build_meshfree_simulation(plate, 7800.0, J2Law(200e9, 0.3), stabilisation=0.0)
    p = sim.particles
    assert plate.thickness_axis == 1
    rng = np.random.default_rng(1)
    x = p.X + 1e-5 * rng.normal(size=p.X.shape)
    force = np.zeros_like(x)
    internal_forces(0.0, p._replace(x=x.copy()), sim.links, sim.columns, sim.law, force)

    def energy(y):
        return sim.strain_energies(y)[0].sum()

    worst = 0.0
    for i in rng.choice(len(x), 8, replace=False):
        for c in range(3):
            plus, minus = x.copy(), x.copy()
            plus[i, c] += 1e-9
            minus[i, c] -= 1e-9
            worst = max(worst, abs(-(energy(plus) - energy(minus)) / 2e-9 - force[i, c]))
    assert worst < 1e-6 * np.abs(force).max()
    kappa, t = 1e-3, 0.004
    zeta = p.X[:, 1] - 0.5 * t
    bent = p.X.copy()
    bent[:, 0] -= kappa * p.X[:, 0] * zeta
    bent[:, 1] += 0.5 * kappa * p.X[:, 0] ** 2
    lam, mu = sim.law[0, 0], sim.law[0, 1]
    exact = 0.5 * (lam + 2.0 * mu) * kappa**2 * t**3 / 12.0 * 0.012 * 0.008
    assert energy(bent) == pytest.approx(exact, rel=1e-5)


def test_stable_step_matches_the_dense_eigenvalue():
    """The stable step's omega_max^2 (Lanczos on the step's own forces, step.highest_frequency2)
    against the largest eigenvalue of M^-1/2 K M^-1/2 from numpy's dense eigvalsh, K assembled
    from the links (_dense_stiffness), on a 9 x 8 x 3 steel plate (216 particles): at or above
    it (the Ritz value plus its residual bound, which ends the iteration at 0.1 % of it) and
    within 1 % (measured +0.08 % after 22 iterations; the Ritz value alone -2e-6). The step is
    STEP_MARGIN x 2 / omega; Gershgorin's bound stays above the eigenvalue (measured 11 x)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.016, 0.014, 0.004), 0.002, 3)
    sim = build_meshfree_simulation(plate, 7800.0, J2Law(200e9, 0.3))
    p, n = sim.particles, len(plate.X)
    assert n == 216
    m = np.repeat(p.mass, 3)
    K = _dense_stiffness(sim)
    assert np.max(np.abs(K - K.T)) < 1e-12 * np.max(np.abs(K))
    dense = np.linalg.eigvalsh(K / np.sqrt(np.outer(m, m)))[-1]
    omega2, residual, _ = highest_frequency2(p, sim.links, sim.columns, sim.law, np.zeros(n), 0.002)
    assert 0.0 <= (omega2 - dense) / dense < 0.01
    assert sim.stable_dt == pytest.approx(STEP_MARGIN * 2.0 / np.sqrt(omega2), rel=1e-12)
    row = np.repeat(np.arange(n), np.diff(sim.links.start))
    assert gershgorin_frequency2(p, sim.links, row, sim.law, 0.0) > dense


def _random_plate():
    """A 16 x 9 x 3 steel plate, free, with random velocities (every mode excited)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.03, 0.016, 0.004), 0.002, 3)
    sim = build_meshfree_simulation(plate, 7800.0, J2Law(200e9, 0.3))
    sim.particles.v[:] = np.random.default_rng(0).normal(size=sim.particles.v.shape) * 1e-3
    sim._initial_energy = sim.kinetic_energy()
    return sim


def test_stable_step_is_sharp(tmp_path):
    """Central differences are stable for dt <= 2 / omega_max. With the estimated limit 2 / omega
    (= stable_dt / STEP_MARGIN), random velocities on a 16 x 9 x 3 plate stay bounded for 1,000
    steps at 0.98 x it (stored + kinetic energy within 30 % of the initial: at this step the
    audit's half-step energies differ from the scheme's conserved one in the highest modes;
    measured +13 %) and blow up at 1.02 x it: the estimate is within 2 % of the true limit. Through
    the driver at 1.5 x it, the run is stopped as unstable with its message. (The audit at the
    default step, 0.7 x stable_dt: test_plate_impact_run_and_energy_audit, < 1 %.)"""
    def run(factor):
        sim = _random_plate()
        dt = factor * sim.stable_dt / STEP_MARGIN
        sim.advance(1000, dt)
        terms = sim.energies(dt)
        external = terms.pop("energy.external")
        return sum(terms.values()) / external

    assert abs(run(0.98) - 1.0) < 0.3
    assert not np.isfinite(run(1.02))
    sim = _random_plate()
    sim.stable_dt *= 1.5 / STEP_MARGIN  # past the driver's guard against a step above the stable one
    control = RunControl(end_time=500 * sim.stable_dt, safety=1.0, history_samples=50, field_frames=0,
                         plots=False, checkpoint=False)
    with pytest.raises(UnstableRunError, match="went unstable"):
        run_simulation(sim, control, tmp_path / "unstable")



# Clamped-free beam: beta L of the first two modes, and their shapes (x = position / L).
CANTILEVER_BETA = {1: 1.875104, 2: 4.694091}


def _cantilever_shape(beta, x):
    s = beta * x
    sigma = (np.cosh(beta) + np.cos(beta)) / (np.sinh(beta) + np.sin(beta))
    return np.cosh(s) - np.cos(s) - sigma * (np.sinh(s) - np.sin(s))


@pytest.mark.parametrize("spacing, t, L, width, bending, mode, tolerance, measured", [
    (0.002, 0.002, 0.06, 5, "cylindrical", 1, 0.03, "-0.20 %"),
    (0.004, 0.002, 0.06, 5, "cylindrical", 1, 0.03, "-0.64 %"),
    (0.004, 0.0008, 0.03, 5, "cylindrical", 1, 0.03, "-1.94 %"),
    (0.002, 0.002, 0.06, 2, "narrow", 1, 0.03, "-0.06 %"),
    (0.002, 0.002, 0.06, 5, "cylindrical", 2, 0.05, "-1.13 %"),
    (0.002, 0.002, 0.06, 2, "narrow", 2, 0.05, "-1.05 %"),
])
def test_cantilever_bends_at_the_thin_wall_frequency(spacing, t, L, width, bending, mode, tolerance, measured):
    """Thin-wall bending with the paper's 3 particles through the thickness, free of the in-plane
    spacing: a steel strip of length L, `width` spacings wide, clamped at x = 0, started in the
    shape of its first or second mode (velocity along z): the tip's period gives the bending
    frequency f = (beta L)^2 / (2 pi L^2) sqrt(E' t^2 / (12 rho)), beta L = 1.8751 and 4.6941,
    E' = E / (1 - nu^2) in cylindrical bending (rollers across the width on every particle:
    plane strain; a wide plate) and E' = E for a narrow strip (2 spacings = 2 t wide, free edges:
    a beam). First mode within 3 %, second within 5 % (the issue's acceptance); measured in the
    parameters (before the two Gauss points through the wall, thickness.py, each cell saw its mean
    strain and the bending energy was 27/32 of the continuum's: -8.3 %, -8.8 %, -9.8 % in
    cylindrical bending). The stabilisation is zero for quadratic fields, so it hardly resists
    the bending: its largest energy stays below 2 % of the largest elastic energy (measured
    0.03 %, 0.1 %, 1.1 % in the first three; the link stabilisation it replaced gave +35 % at 2 t
    and x 2.6 at 6 t)."""
    from crackle.loading import Selection, Support

    E, nu, rho = 210e9, 0.3, 7800.0
    plate = plate_particles((0.0, 0.0, 0.0), (L, width * spacing, t), spacing, 3)
    X = plate.X
    beta = CANTILEVER_BETA[mode]
    velocity = np.zeros_like(X)
    velocity[:, 2] = 0.05 * _cantilever_shape(beta, X[:, 0] / L)
    supports = [Support("fixed", Selection(box_min=(-1e-9, -1.0, -1.0), box_max=(1e-9, 1.0, 1.0)))]
    if bending == "cylindrical":
        supports.append(Support("roller", Selection(box_min=(-1.0, -1.0, -1.0), box_max=(1.0, 1.0, 1.0)),
                                (0.0, 1.0, 0.0)))
    sim = build_meshfree_simulation(plate, rho, J2Law(E, nu), supports=supports, velocity=velocity)
    modulus = E / (1.0 - nu**2) if bending == "cylindrical" else E
    expected = beta**2 / (2.0 * np.pi * L**2) * np.sqrt(modulus * t**2 / (12.0 * rho))
    dt = 0.9 * sim.stable_dt
    tip = X[:, 0] > L - 1e-9
    chunk = 10
    deflection, energies = [], []
    for _ in range(int(2.5 / expected / (chunk * dt))):
        sim.advance(chunk, dt)
        deflection.append(np.mean(sim.particles.x[tip, 2] - X[tip, 2]))
        if len(deflection) % 20 == 0:
            energies.append([e.sum() for e in sim.strain_energies(sim.particles.x)])
    z = np.array(deflection)
    times = chunk * dt * (np.arange(len(z)) + 1)
    k = np.flatnonzero((z[:-1] > 0.0) & (z[1:] <= 0.0))  # downward zero crossings, one per period
    crossings = times[k] - z[k] * (times[k + 1] - times[k]) / (z[k + 1] - z[k])
    assert len(crossings) >= 2
    assert 1.0 / np.mean(np.diff(crossings)) == pytest.approx(expected, rel=tolerance)
    elastic, stab = np.max(energies, axis=0)
    assert stab < 0.02 * elastic


def _uniaxial(law, strains, dt, thermal=None):
    """Uniaxial stress by a secant search on the lateral strain (S22 = S33 = 0) at each axial
    Green strain; returns the axial stresses and the plastic work density (and updates
    `thermal`, the thermo law's temperature and released energy, (1, 2), in place)."""
    plastic, eq = np.zeros((1, 6)), np.zeros(1)
    lateral, out, work = 0.0, [], 0.0
    for e11 in strains:
        def s22(e22):
            s, _ = material_point(np.array([e11, e22, e22, 0.0, 0.0, 0.0]), plastic.copy(), eq.copy(), dt, law,
                                  None if thermal is None else thermal.copy())
            return s[1]
        a, b = lateral, lateral - 1e-6
        fa, fb = s22(a), s22(b)
        for _ in range(60):
            if fb == fa or abs(fb) < 1e-6:
                break
            a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
            fb = s22(b)
        lateral = b
        s, w = material_point(np.array([e11, lateral, lateral, 0.0, 0.0, 0.0]), plastic, eq, dt, law, thermal)
        out.append(s[0])
        work += w
    return np.array(out), work, eq[0]


def test_j2_uniaxial_linear_hardening_closed_form():
    """Rate independent, linear hardening (eq. 14 with 1/n = 1: H = sigma0 / ep0 = 3 GPa), E =
    210 GPa, sigma0 = 305 MPa (paper 000's tearing steel): the axial stress is E e below
    e_y = sigma0 / E and (sigma0 + H e) / (1 + H / E) above it (uniaxial: e = S / E + ep), to
    1e-6 relative (measured ~1e-12); the plastic work is the area sigma0 ep + H ep^2 / 2."""
    E, s0, ep0 = 210e9, 305e6, 305e6 / 3e9
    law = J2Law(E, 0.3, s0, ep0, 1.0).table()
    strains = np.linspace(0.0, 0.01, 201)[1:]
    stress, work, ep = _uniaxial(law, strains, 1e-6)
    H = s0 / ep0
    expected = np.where(strains < s0 / E, E * strains, (s0 + H * strains) / (1.0 + H / E))
    assert np.max(np.abs(stress - expected)) < 1e-6 * s0
    assert ep == pytest.approx(strains[-1] - stress[-1] / E, rel=1e-9)
    assert work == pytest.approx(s0 * ep + 0.5 * H * ep**2, rel=2e-3)  # backward Euler in the increments


def test_j2_rate_dependence_of_eq_15():
    """Perfectly plastic (1/n = 0) with rate sensitivity 1/m = 0.1 at ep_rate0 = 100/s: pulled at
    a constant strain rate, the plastic flow settles at that rate and the stress at
    sigma0 (1 + rate / ep_rate0)^(1/m): x 1.072 at 1,000/s, x 1.175 at 1e5/s (eq. 15), within
    1e-6 (measured ~1e-12); without the rate term it stays at sigma0."""
    E, s0 = 70e9, 275e6
    for rate, mexp, factor in ((1e3, 0.1, 11.0**0.1), (1e5, 0.1, 1001.0**0.1), (1e5, 0.0, 1.0)):
        law = J2Law(E, 0.3, s0, 1.0, 0.0, 100.0, mexp).table()
        strains = np.linspace(0.0, 0.05, 101)[1:]
        dt = (strains[1] - strains[0]) / rate
        stress, _, _ = _uniaxial(law, strains, dt)
        assert stress[-1] == pytest.approx(s0 * factor, rel=1e-6)


# The thermo law's uniaxial path: aluminium (paper 000 section 4.3: 70 GPa, 0.3, 275 MPa, 2700
# kg/m^3, c = 900 J/(kg K), chi = 0.9), eps0 = sigma0 / E, N = 0.04, 1/m = 0.02 at rate0 = 1/s,
# pulled to a Green strain of 0.5 at 1,000/s in 500 steps.
TQ_E, TQ_S0, TQ_N, TQ_M, TQ_RHOC, TQ_CHI, TQ_T0 = 70e9, 275e6, 0.04, 0.02, 2700.0 * 900.0, 0.9, 293.0


def _thermo_uniaxial(delta, kappa, rate=1e3, strain=0.5, steps=500):
    law = ThermoLaw(TQ_E, 0.3, TQ_S0, TQ_S0 / TQ_E, TQ_N, 1.0, TQ_M, initial_temperature=TQ_T0, density=2700.0,
                    specific_heat=900.0, taylor_quinney=TQ_CHI, thermal_softening=delta, softening_temperature=kappa)
    strains = np.linspace(0.0, strain, steps + 1)[1:]
    dt = strain / steps / rate
    thermal = np.array([[TQ_T0, 0.0]])
    stress, _, ep = _uniaxial(law.table(), strains, dt, thermal)
    # Uniaxial St. Venant-Kirchhoff with an additive plastic strain: E11 - Ep11 = S11 / E exactly.
    eps_p = strains - stress / TQ_E
    dep = np.diff(np.r_[0.0, eps_p])
    # The temperature the plastic work gives, step by step (the backward-Euler sum).
    T = TQ_T0 + TQ_CHI / TQ_RHOC * np.cumsum(stress * dep)
    g = TQ_S0 * (1.0 + eps_p / (TQ_S0 / TQ_E)) ** TQ_N * (1.0 - delta * (np.exp((T - TQ_T0) / kappa) - 1.0))
    closed = g * (dep / dt) ** TQ_M  # eq. 19 inverted, rate0 = 1/s
    return stress, closed, eps_p, T, thermal, ep, dep / dt


def test_thermo_uniaxial_steady_flow_closed_form():
    """The thermo law (eqs 19-20) on one material point in uniaxial stress at 1,000/s: past the
    first 10 % of the path every step's stress is g(ep, T) (rate / rate0)^(1/m) to 1e-6
    relative (measured ~1e-13), with ep = E11 - S11 / E and its rate from the stress history
    and T - T0 = chi sum S dep / (rho c) (the model's temperature the same to 1e-9 of the rise,
    its ep to 1e-9; the trapezoidal integral of S over ep within 1e-3 of the rise). The plastic
    rate is the imposed one to 1 % (measured 0.3 %; softening makes it slightly larger); the
    temperature rises by 64 K (asserted 30-100 K; the trapezoid measured 1.3e-4 off) and the
    softening factor falls to 0.89."""
    delta, kappa = 0.8, 500.0
    stress, closed, eps_p, T, thermal, ep, rate = _thermo_uniaxial(delta, kappa)
    late = slice(50, None)
    assert np.max(np.abs(stress[late] / closed[late] - 1.0)) < 1e-6
    rise = T[-1] - TQ_T0
    assert 30.0 < rise < 100.0
    assert abs(thermal[0, 0] - T[-1]) < 1e-9 * rise and ep == pytest.approx(eps_p[-1], rel=1e-9)
    integral = TQ_CHI / TQ_RHOC * np.sum(0.5 * (stress[1:] + stress[:-1]) * np.diff(eps_p))
    assert abs(integral + TQ_CHI / TQ_RHOC * 0.5 * stress[0] * eps_p[0] - rise) < 1e-3 * rise
    assert np.all(np.abs(rate[late] / 1e3 - 1.0) < 0.01)
    assert 1.0 - delta * (np.exp(rise / kappa) - 1.0) < 0.9


def test_thermo_thermal_softening_lowers_the_flow_stress():
    """The same path with the softening changed: kappa 500 -> 100 K and delta 0.8 -> 0 each follow
    their own closed form (to 1e-6, as above), and the end stress is lower with more softening in
    the closed-form ratio: S / S(delta = 0) = the softening factor 1 - delta (exp((T - T0) /
    kappa) - 1) x the hardening and rate factors of the two states, to 1e-6 (the factor is 0.48
    at kappa = 100 K: asserted below 0.7)."""
    ends = {}
    for delta, kappa in ((0.0, 500.0), (0.8, 500.0), (0.8, 100.0)):
        stress, closed, eps_p, T, _, _, rate = _thermo_uniaxial(delta, kappa)
        assert np.max(np.abs(stress[50:] / closed[50:] - 1.0)) < 1e-6
        ends[delta, kappa] = stress[-1], eps_p[-1], T[-1], rate[-1]
    s_ref, ep_ref, _, rate_ref = ends[0.0, 500.0]
    assert ends[0.8, 100.0][0] < ends[0.8, 500.0][0] < s_ref
    for (delta, kappa), (s, ep, T, rate) in ends.items():
        soft = 1.0 - delta * (np.exp((T - TQ_T0) / kappa) - 1.0)
        hard = ((1.0 + ep * TQ_E / TQ_S0) / (1.0 + ep_ref * TQ_E / TQ_S0)) ** TQ_N * (rate / rate_ref) ** TQ_M
        assert s / s_ref == pytest.approx(soft * hard, rel=1e-6)
    assert 1.0 - 0.8 * (np.exp((ends[0.8, 100.0][2] - TQ_T0) / 100.0) - 1.0) < 0.7


def test_thermo_without_thermal_effects_is_rate_independent_j2():
    """delta = 0, alpha = 0, temperature-independent constants and 1/m = 1e-6 at rate0 = the
    imposed 1,000/s: the thermo law's uniaxial curve (E = 70 GPa, sigma0 = 275 MPa, eps0 =
    sigma0 / E, N = 0.04, to a Green strain of 0.05 in 200 steps) is model = "j2"'s
    rate-independent one with ep0 = eps0 and 1/n = N, within 5e-5 of sigma0 at every step (the
    bound (1/m) |ln(rate / rate0)| is ~1e-5 at the step that first yields, ~1e-8 after;
    measured 1.2e-6), and both yield (end plastic strains the same within 1e-6; measured
    1.5e-11)."""
    strains = np.linspace(0.0, 0.05, 201)[1:]
    dt = 0.05 / 200 / 1e3
    thermo = ThermoLaw(TQ_E, 0.3, TQ_S0, TQ_S0 / TQ_E, TQ_N, 1e3, 1e-6).table()
    j2 = J2Law(TQ_E, 0.3, TQ_S0, TQ_S0 / TQ_E, TQ_N).table()
    s_thermo, _, ep_thermo = _uniaxial(thermo, strains, dt, np.array([[293.0, 0.0]]))
    s_j2, _, ep_j2 = _uniaxial(j2, strains, dt)
    assert np.max(np.abs(s_thermo - s_j2)) < 5e-5 * TQ_S0
    assert ep_j2 > 0.04 and abs(ep_thermo - ep_j2) < 1e-6


def test_thermo_thermal_strain_and_temperature_dependent_moduli():
    """Eq. 22 at a material point held at zero strain, 150 K above T0, with paper 000's
    coefficients as crackle reads them (E(T) = E0 - 1.6e6 (T - T0) Pa, nu(T) = nu0 + 5e-5 (T -
    T0), alpha(T) = (2.2 + 0.0016 (T - T0)) 1e-5 /K, sigma0(T) = sigma0 - 1.5e3 (T - T0)^2 Pa):
    the stress is the hydrostatic -E(T) / (1 - 2 nu(T)) theta with theta = int alpha dT = 2.2e-5
    dT + 0.8e-8 dT^2, to 1e-12 relative, and no plastic flow (a pressure has no deviator)."""
    law = ThermoLaw(TQ_E, 0.3, TQ_S0, initial_temperature=TQ_T0, youngs_modulus_temperature=(-1.6e6, 0.0),
                    poissons_ratio_temperature=(5e-5, 0.0), yield_stress_temperature=(0.0, -1.5e3),
                    thermal_expansion=2.2e-5, thermal_expansion_temperature=(1.6e-8, 0.0), rate_exponent=0.02).table()
    d = 150.0
    plastic, eq, thermal = np.zeros((1, 6)), np.zeros(1), np.array([[TQ_T0 + d, 0.0]])
    s, work = material_point(np.zeros(6), plastic, eq, 1e-7, law, thermal)
    E, nu, theta = TQ_E - 1.6e6 * d, 0.3 + 5e-5 * d, 2.2e-5 * d + 0.8e-8 * d**2
    expected = -E / (1.0 - 2.0 * nu) * theta
    assert np.abs(s[:3] / expected - 1.0).max() < 1e-12 and not np.any(s[3:])
    assert work == 0.0 and eq[0] == 0.0 and thermal[0, 0] == TQ_T0 + d


def test_plate_impact_run_and_energy_audit(plate_file, tmp_path):
    """A 10 mm steel ball at 20 m/s on a 40 x 40 x 2 mm aluminium plate (1,323 particles, 3
    through the thickness) clamped on two edges, through the command line: the output contract
    (method, particles, broken_links, a VTU per frame), the ball's force, and the energy audit
    below 1 % (measured -0.18 % at 0.7 x the Lanczos step)."""
    out = tmp_path / "elastic"
    assert main(["run", str(plate_file), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["method"] == "meshfree" and s["particles"] == 21 * 21 * 3 and s["broken_links"] == 0
    assert s["peak_force"] > 1e3
    assert abs(s["energy_error"]) < 0.01
    assert len(list((out / "fields").glob("*.vtu"))) == 2
    h = read_history_csv(out / "history.csv")
    assert h["energy.elastic"].max() > 0 and h["energy.plastic"][-1] == 0.0


def _plastic_plate(plate_file, fracture=False, thermo=False):
    overrides = ([o for o in PLASTIC if o != "--set"] + (list(FRACTURE) if fracture else [])
                 + (list(THERMO) if thermo else []))
    scenario, base = load_scenario(plate_file, overrides)
    return build_simulation(scenario, base), scenario


def test_plastic_impact_energy_audit(plate_file):
    """The same plate at 60 m/s with J2 (150 MPa, linear hardening, rate dependent): the plate
    yields (plastic strain > 1e-3, plastic work > 5 % of the work put in; measured 0.16 and
    55 %) and the audit, plastic work included, closes within 3 % of the largest energy
    (measured -0.14 %)."""
    sim, scenario = _plastic_plate(plate_file)
    dt = 0.7 * sim.stable_dt
    rows = []
    for _ in range(20):
        sim.advance(30, dt)
        rows.append(sim.energies(dt))
    history = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    assert np.max(sim.particles.eq_plastic) > 1e-3
    assert history["energy.plastic"][-1] > 0.05 * history["energy.external"][-1]
    assert abs(energy_error(history)) < 0.03


def test_thermo_plastic_impact_outputs_and_energy_audit(plate_file, tmp_path):
    """The plastic impact with the thermo law (THERMO: exaggerated thermal effects), through the
    command line, to 10 us: the plate yields and heats (max_temperature in summary.json,
    measured 26 K above T0 = 293 K; asserted 5-500 K; the VTU carries `temperature`), and the
    audit with `energy.thermal` (the stored energy the temperature changes released) closes
    within 3 % (measured +0.54 %); that term matters here: left out, the imbalance would be
    -1.8 % (asserted more than 3 x the imbalance with it)."""
    out = tmp_path / "thermo"
    args = ["run", str(plate_file), "--out", str(out), "--set", "run.end_time=1e-5"] + list(PLASTIC)
    for o in THERMO:
        args += ["--set", o]
    assert main(args) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["max_plastic_strain"] > 1e-3
    assert 293.0 + 5.0 < s["max_temperature"] < 293.0 + 500.0
    vtu = sorted((out / "fields").glob("*.vtu"))[-1].read_text(errors="ignore")
    assert 'Name="temperature"' in vtu
    h = read_history_csv(out / "history.csv")
    assert h["energy.plastic"][-1] > 0.05 * h["energy.external"][-1]
    assert abs(s["energy_error"]) < 0.03 and s["energy_error"] == pytest.approx(energy_error(h), abs=1e-9)
    without = {k: v for k, v in h.items() if k != "energy.thermal"}
    assert abs(energy_error(without)) > 3.0 * abs(energy_error(h))


def test_thermo_identical_for_1_and_2_threads(plate_file):
    """The plastic impact with the thermo law and links breaking: positions, velocities, plastic
    strain, temperature, released energy and the cracks after 600 steps bit-identical with 1
    and 2 numba threads (subprocesses); the compared run yields, heats (measured 56 K), breaks
    and detaches particles (measured 26 failed, 33 detached), and a detached particle carries
    no stress although it is hot (its plastic strain takes up its thermal strain)."""
    script = (
        "import sys, hashlib, numpy as np; sys.path.insert(0, %r); import test_meshfree as t; "
        "sim, _ = t._plastic_plate(%r, fracture=True, thermo=True); dt = 0.7 * sim.stable_dt; "
        "sim.advance(300, dt); sim.advance(300, dt); p = sim.particles; b = sim.breaking; h = hashlib.sha256(); "
        "[h.update(np.ascontiguousarray(a).tobytes()) for a in (p.x, p.v, p.eq_plastic, p.w_plastic, p.thermal, "
        "b.failed, b.blocked, np.array([b.damage]))]; gone = np.flatnonzero(b.detached); "
        "print(h.hexdigest(), float(p.eq_plastic.max()), float(p.thermal[:, 0].max()), len(gone), "
        "float(np.abs(sim.cauchy_stress()[gone]).max(initial=0.0)), float(p.thermal[2 * gone, 0].max(initial=0.0)))"
    ) % (os.path.dirname(__file__), str(plate_file))
    digests = outputs_with_1_and_2_threads(script)
    assert digests[0][0] == digests[1][0]
    _, ep, T, detached, stress, T_detached = digests[0]
    assert float(ep) > 0.0 and float(T) > 293.0 + 5.0, "the compared run must yield and heat"
    assert int(detached) > 0 and float(T_detached) > 293.0 + 5.0 and float(stress) == 0.0


def test_plate_impact_example_quick(tmp_path):
    """The shipped example plate-impact --quick (a free rigid 40 mm steel sphere, 0.2614 kg,
    launched at 300 m/s on a clamped 10 mm aluminium plate, 21 x 21 x 3 particles, 60 us,
    fracture at 3 x 150 MPa): the plate yields under the sphere (measured max plastic strain
    0.045) and breaks (measured 21 particles failed, 15 detached, 1,445 links removed; each
    failure a row of events.csv, mode tension; the VTU carries the failed flag and the crack
    normals), the sphere slows (measured to 281.2 m/s: it gave the plate 1.43 kJ) with the
    audit, damage included, within 3 % (measured -0.50 %). The plate is perforated by a plug,
    not petals (summary.json, analysis/perforation.py): a hole between 20 and 100 mm across
    (measured 60 mm at this 20 mm spacing, the sphere 40 mm), no petals, every detached particle
    off the plate (measured 15 plug particles, all detached)."""
    out = tmp_path / "o"
    assert main(["run", "plate-impact", "--quick", "--out", str(out), "--set", "run.field_frames=1"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["particles"] == 1323
    assert 0.02 < s["max_plastic_strain"] < 1.0
    assert s["peak_force"] > 1e5
    assert s["broken_links"] > 100 and s["failed_particles"] > 0
    events = (out / "events.csv").read_text().splitlines()[1:]
    assert len(events) == s["failed_particles"] and all(e.split(",")[4] == "tension" for e in events)
    vtu = sorted((out / "fields").glob("*.vtu"))[-1].read_text(errors="ignore")
    assert 'Name="failed"' in vtu and 'Name="crack_normal"' in vtu
    assert 250.0 < s["free_tools"]["sphere"]["speed"] < 299.0
    assert abs(s["energy_error"]) < 0.03
    assert 0.02 < s["hole_diameter"] < 0.1 and s["petals"] == 0
    assert s["plug_particles"] >= s["detached_particles"] > 0


@pytest.mark.parametrize("safety", [0.7, 0.9])
def test_identical_for_1_and_2_threads(plate_file, safety):
    """The plastic impact with links breaking: its state after 600 steps (positions, velocities,
    plastic strain, tool force, failed particles, removed links, damage energy) bit-identical
    with 1 and 2 numba threads (subprocesses, as tests/core/test_determinism.py); the compared run
    yields and breaks, and detaches particles (measured: 20 failed, 31 detached, 1,740 links
    removed). At safety 0.9 link breaking makes it sub-step (2 compiled steps a step from ~9 us:
    test_the_step_follows_link_breaking), and that too is the same with either thread count."""
    script = (
        "import sys, hashlib, numpy as np; sys.path.insert(0, %r); import test_meshfree as t; "
        "sim, _ = t._plastic_plate(%r, fracture=True); dt = %r * sim.stable_dt; sim.advance(300, dt); "
        "sim.advance(300, dt); p = sim.particles; b = sim.breaking; h = hashlib.sha256(); "
        "[h.update(np.ascontiguousarray(a).tobytes()) for a in (p.x, p.v, p.eq_plastic, p.w_plastic, "
        "sim.tools.cell_state, b.failed, b.blocked, sim.links.grad, np.array([b.damage]))]; "
        "print(h.hexdigest(), float(p.eq_plastic.max()), sim.broken, int(b.detached.sum()), sim.substeps)"
    ) % (os.path.dirname(__file__), str(plate_file), safety)
    digests = outputs_with_1_and_2_threads(script)
    assert digests[0][0] == digests[1][0]
    assert float(digests[0][1]) > 0.0, "the compared run must yield"
    assert int(digests[0][2]) > 0 and int(digests[0][3]) > 0, "the compared run must break links and detach"
    assert int(digests[0][4]) == (2 if safety == 0.9 else 1)


def _plastic_fracture_args(plate_file, out, *more):
    args = ["run", str(plate_file), "--out", str(out), "--set", "run.field_frames=0", *PLASTIC, *more]
    for o in FRACTURE:
        args += ["--set", o]
    return args


def test_the_step_follows_link_breaking(plate_file, tmp_path):
    """Issue 63 item 2: the plastic impact with links breaking at run.safety = 0.9. A rebuild at
    ~9.2 us lowers the estimated stable step to 0.82 x the set-up's (one-sided gradients at the
    crack faces), within a tenth of the step in use: from there each driver step is 2 compiled
    steps (history.csv's dt halves, the summary says when), where before the run kept its step
    and only warned. The audit closes within 3 % (measured -0.84 %). Continued from a
    checkpoint at 8 us (before the change) to the end, the rows after 8 us, the events and the
    results are bit-identical to the uninterrupted run's: the decision falls on the fracture
    checks' fixed steps."""
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert main(_plastic_fracture_args(plate_file, whole, "--set", "run.safety=0.9")) == 0
    s = json.loads((whole / "summary.json").read_text())
    history = read_history_csv(whole / "history.csv")
    assert s["status"] == "completed" and abs(s["energy_error"]) < 0.03
    [note] = [w for w in s["warnings"] if "sub-steps" in w]
    assert "is now 2 sub-steps" in note
    changed = history["time"][history["dt"] < s["dt"]]
    assert history["dt"][0] == s["dt"] and np.all(history["dt"][-3:] == 0.5 * s["dt"])
    assert 5e-6 < changed[0] < 1.5e-5
    assert main(_plastic_fracture_args(plate_file, part, "--set", "run.safety=0.9", "--set", "run.end_time=8e-6")) == 0
    assert json.loads((part / "summary.json").read_text()).get("warnings", []) == []
    assert main(_plastic_fracture_args(plate_file, part, "--set", "run.safety=0.9", "--resume", str(part))) == 0
    resumed = read_history_csv(part / "history.csv")
    later_whole, later_part = history["time"] > 8e-6, resumed["time"] > 8e-6
    assert later_whole.sum() == later_part.sum() > 0
    for name in history:
        assert np.array_equal(history[name][later_whole], resumed[name][later_part], equal_nan=True), name
    assert (whole / "events.csv").read_bytes() == (part / "events.csv").read_bytes()


def test_fracture_criterion_fires_at_the_closed_form_stress():
    """A block (11 x 7 x 3 particles) stretched uniformly, F = diag(1 + e, 1, 1): the maximum
    principal Cauchy stress is (1 + e) (lambda + 2 mu) (e + e^2 / 2) along x. With the fracture
    stress 3 x 100 MPa, nothing fails at 0.995 x it; at 1.005 x it every particle fails, at the
    first check step (FRACTURE_CHECK), with its crack normal along x (within ROUNDING). Without a
    fracture stress nothing is checked."""
    law = J2Law(E_AL, NU)
    lam, mu = law.table()[0], law.table()[1]
    fracture_stress = 3.0 * 100e6

    def strain_at(stress):  # the cubic (1 + e) (lambda + 2 mu) (e + e^2 / 2) = stress
        roots = np.roots([0.5 * (lam + 2 * mu), 1.5 * (lam + 2 * mu), lam + 2 * mu, -stress])
        return float(roots[np.abs(roots.imag) < 1e-9 * np.abs(roots)].real.max())

    for ratio, fails in ((0.995, False), (1.005, True)):
        sim = _block(fracture_stress=fracture_stress)
        p = sim.particles
        p.x[:] = p.X * np.array([1.0 + strain_at(ratio * fracture_stress), 1.0, 1.0])
        sim.advance(FRACTURE_CHECK - 1, 1e-12)  # v = 0: x stays put but for rounding
        sigma = sim.cauchy_stress()
        assert np.abs(sigma[:, 0] - ratio * fracture_stress).max() < 1e-6 * fracture_stress
        sim.advance(1, 1e-12)  # the check step
        b = sim.breaking
        assert b.failed.all() if fails else not b.failed.any()
        if fails:
            assert np.abs(b.normal - [1.0, 0.0, 0.0]).max() < ROUNDING
            assert np.all(b.fail_time == sim.time)
    assert _block().breaking is None


def test_links_across_the_crack_and_only_those_are_removed():
    """The centre particle c of a 2 mm plate (11 x 11 x 3 particles, spacing 2 mm, 1 mm through
    the thickness) fails with its crack normal along x: the crack is the disc of radius 2 mm (the
    largest grid step) in the plane x = X_c. Removed: exactly the links (I, J), both directions,
    with X_I on the plane or behind it and X_J in front whose segment meets the plane within
    2 mm of X_c (checked link by link against that rule), among them all 24 links of c to
    particles in front and none of its 39 others (itself included); the links of the particle on
    the plane 4 mm from c stay. After the rebuild every particle still reproduces a linear field
    (to ROUNDING), and a jump of the particles in front (u = 1 um along x) is invisible to c (F = I to
    1e-15) while it strained c by 0.56 x the jump over the spacing before."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.02, 0.02, 0.002), 0.002, 3)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU), fracture_stress=1e9)
    X, links, b = sim.particles.X, sim.links, sim.breaking
    n = len(X)
    c = int(np.argmin(np.linalg.norm(X - [0.01, 0.01, 0.001], axis=1)))
    row = np.repeat(np.arange(n), np.diff(links.start))
    col = links.neighbour
    jump = np.where(X[:, 0] > 0.01 + 1e-9, 1e-6, 0.0)

    def F_at(i):  # F_xx - 1 at particle i under the jump
        return float(np.sum(jump[col[row == i]] * links.grad[row == i, 0]))

    before = F_at(c)
    b.fail(sim, np.array([c]), np.array([[1.0, 0.0, 0.0]]), 1e-9)
    expected = set()
    for i, j in zip(row.tolist(), col.tolist()):
        for a, z in ((i, j), (j, i)):
            da, dz = X[a, 0] - 0.01, X[z, 0] - 0.01
            if da <= 1e-12 < dz:
                hit = X[a] + (-da / (dz - da)) * (X[z] - X[a])
                if np.linalg.norm(hit - X[c]) <= 0.002 * (1 + 1e-9):
                    expected.update({i * n + j, j * n + i})
    removed = set(b.blocked.tolist()) & set((row * n + col).tolist())
    assert removed == expected and len(removed) > 0
    mine = row == c
    front = X[col, 0] > 0.01 + 1e-9
    assert np.isin(row[mine & front] * n + col[mine & front], b.blocked).sum() == 24 == (mine & front).sum()
    assert not np.isin(row[mine & ~front] * n + col[mine & ~front], b.blocked).any() and (mine & ~front).sum() == 39
    far = int(np.argmin(np.linalg.norm(X - [0.01, 0.014, 0.001], axis=1)))
    assert not np.isin(row[row == far] * n + col[row == far], b.blocked).any()
    assert b.broken_links == len(removed) // 2 and not b.detached.any()
    # The rebuilt gradients: linear fields exact, the jump hidden from c.
    A = np.array([[1e-3, 2e-4, 0.0], [3e-4, -5e-4, 1e-4], [0.0, 2e-4, 7e-4]])
    F = np.zeros((n, 3, 3))
    np.add.at(F, row, ((X[col] - X[row]) @ A.T)[:, :, None] * links.grad[:, None, :])
    assert np.abs(F - A).max() < ROUNDING * np.abs(A).max()
    assert abs(before) > 0.25 * 1e-6 / 0.002 and abs(F_at(c)) < 1e-15


def test_the_rebuild_touches_only_what_the_crack_changes():
    """A yielded, stretched 300 x 200 x 10 mm plate (21 x 14 x 3 particles) loses a line of
    particles across it and a cluster at a corner, one failure at a time, with cracks at three
    angles, until particles detach (measured 49). The rebuild reads and writes only the links of
    the particles it changes (fracture.py); against the whole model after every failure: the
    released energy booked as damage equals the drop of the whole plate's stored energy (elastic
    plus stabilisation at the mid-step positions) within 1e-12 of that energy, the transposed
    copies the gather reads, updated where the rebuild wrote, equal the links' gradients and
    values bit for bit, and the kept Gershgorin bounds of the step check equal a recomputation from all
    links bit for bit."""
    from crackle.meshfree.step import gershgorin_bounds

    plate = plate_particles((0.0, 0.0, 0.0), (0.3, 0.2, 0.01), 0.015, 3)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU, yield_stress=150e6), fracture_stress=450e6)
    p, links, b = sim.particles, sim.links, sim.breaking
    rng = np.random.default_rng(1)
    p.x[:] = p.X * np.array([1.002, 0.999, 1.0]) + 1e-6 * rng.standard_normal(p.X.shape)
    p.v[:] = 0.1 * rng.standard_normal(p.X.shape)
    sim.advance(3, 1e-9)  # the stretch yields the plate: plastic strains to carry over
    dt = 0.7 * sim.stable_dt
    line = np.flatnonzero(np.abs(p.X[:, 0] - 0.15) < 1e-9)
    corner = np.flatnonzero((p.X[:, 0] > 0.25) & (p.X[:, 1] < 0.05))
    normals = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5), 0.0]])
    for k, c in enumerate(np.concatenate([line[np.argsort(p.X[line, 1])], corner])):
        x_mid = p.x - 0.5 * dt * p.v
        stored = sum(float(np.sum(e)) for e in sim.strain_energies(x_mid))
        damage = b.damage
        b.fail(sim, np.array([c]), normals[k % 3][None], dt)
        drop = stored - sum(float(np.sum(e)) for e in sim.strain_energies(x_mid))
        assert abs((b.damage - damage) - drop) < 1e-12 * stored
        assert np.array_equal(links.back_grad[links.to_back], links.grad)
        assert np.array_equal(links.back_value[links.to_back], links.value)
    assert b.detached.sum() > 10
    assert all(np.array_equal(kept, full)
               for kept, full in zip(b._bounds, gershgorin_bounds(p, links, b.row, sim.law, b.tool_k)))


def stretched_plate(notched, law, steps, after_chunk=None, **fracture):
    """A free 40 x 40 x 2 mm aluminium plate (21 x 21 x 3 particles) stretched along x by an
    initial velocity 20 m/s x X / 20 mm, with an edge notch along x = 0 from y = -20 to -10 mm
    (its particles failed with normal x at t = 0) if `notched`, the `fracture` keywords of
    build_meshfree_simulation; 20 chunks of `steps` steps, `after_chunk(sim)` after each. Returns
    the simulation, the particles failed beyond the notch and the energies after each chunk."""
    plate = plate_particles((-0.02, -0.02, 0.0), (0.04, 0.04, 0.002), 0.002, 3)
    X = plate.X
    velocity = np.zeros_like(X)
    velocity[:, 0] = 20.0 * X[:, 0] / 0.02
    sim = build_meshfree_simulation(plate, RHO_AL, law, velocity=velocity, **fracture)
    dt = 0.7 * sim.stable_dt
    notch = np.flatnonzero((np.abs(X[:, 0]) < 1e-9) & (X[:, 1] < -0.0099)) if notched else np.zeros(0, int)
    if notched:
        sim.breaking.fail(sim, notch, np.tile([1.0, 0.0, 0.0], (len(notch), 1)), dt)
    rows = []
    for _ in range(20):
        sim.advance(steps, dt)
        if after_chunk is not None:
            after_chunk(sim)
        rows.append(sim.energies(dt))
    history = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    new = sim.breaking.failed.copy()
    new[notch] = False
    return sim, np.flatnonzero(new), history


def test_notched_plate_in_tension_cracks_from_the_notch():
    """A free 40 x 40 x 2 mm aluminium plate (21 x 21 x 3 particles) stretched along x by an
    initial velocity 20 m/s x X / 20 mm, with fracture at 3 x 100 MPa and an edge notch along
    x = 0 from y = -20 to -10 mm (its 18 particles failed with normal x at t = 0): the nominal
    stress peaks below the fracture stress (the same plate without the notch breaks nothing),
    the notch tip's concentration fails the first particle within 5 mm ahead of the tip, the
    crack runs across the plate (at least 8 mm past the tip; measured 18 mm in 42 us, 64
    particles) with normals within 30 deg of x (measured 1-16 deg for the first 12) and in the
    plate's plane (the crack cuts through the wall), and the energy audit, the released stored
    energy booked as damage, closes within 3 % (measured -1.4 %)."""
    def run(notched):
        return stretched_plate(notched, J2Law(E_AL, NU), 20, fracture_stress=300e6)

    sim, grown, _ = run(notched=False)
    assert len(grown) == 0
    sim, grown, history = run(notched=True)
    b, X = sim.breaking, sim.particles.X
    grown = grown[np.lexsort((grown, b.fail_time[grown]))]
    assert len(grown) >= 12
    assert abs(X[grown[0], 0]) <= 0.002 and -0.010 < X[grown[0], 1] <= -0.005
    assert X[grown, 1].max() >= -0.010 + 0.008
    assert np.all(np.abs(b.normal[grown[:12], 0]) > np.cos(np.radians(30.0)))
    assert not np.any(b.normal[grown, 2])
    assert history["energy.damage"][-1] > 0.0
    assert abs(energy_error(history)) < 0.03


def test_ductile_criterion_fails_particles_at_the_plastic_strain_from_the_notch():
    """The notched plate above with a perfectly plastic 100 MPa J2 law and the ductile criterion
    alone (failure_plastic_strain 0.01, no fracture stress): no particle keeps an equivalent
    plastic strain of 0.01 or more unfailed after a check, and every failed one reached it (the
    criterion at the particle, measured 0.010006 at the lowest); the plate without the notch
    stays below it (measured 0.0072) and breaks nothing; the notched one fails first within 5 mm
    ahead of the notch tip (measured 4 mm at 4.7 us), the crack runs at least 8 mm past the tip
    (measured across the plate, 30 particles by 44 us), its first 8 normals within 30 deg of x
    (measured 12-15 deg at most), and the audit with plastic work and damage closes within 3 %
    (measured -0.12 %)."""
    eps_f = 0.01

    def none_left_above(sim):
        b, ep = sim.breaking, sim.per_particle(sim.particles.eq_plastic)
        assert np.all(ep[~b.failed & ~b.detached] < eps_f)

    def run(notched):  # chunks of 7 checks: each ends on a check
        return stretched_plate(notched, J2Law(E_AL, NU, 100e6), 7 * FRACTURE_CHECK, none_left_above,
                               failure_plastic_strain=eps_f)

    sim, grown, _ = run(notched=False)
    assert len(grown) == 0 and sim.per_particle(sim.particles.eq_plastic).max() > 0.5 * eps_f  # it did yield
    sim, grown, history = run(notched=True)
    b, X = sim.breaking, sim.particles.X
    assert np.all(sim.per_particle(sim.particles.eq_plastic)[grown] >= eps_f)
    grown = grown[np.lexsort((grown, b.fail_time[grown]))]
    assert len(grown) >= 12
    assert abs(X[grown[0], 0]) <= 0.002 and -0.010 < X[grown[0], 1] <= -0.005
    assert X[grown, 1].max() >= -0.010 + 0.008
    assert np.all(np.abs(b.normal[grown[:8], 0]) > np.cos(np.radians(30.0)))
    assert history["energy.plastic"][-1] > 0.0 and history["energy.damage"][-1] > 0.0
    assert abs(energy_error(history)) < 0.03


def test_split_advance_calls_give_the_same_fracture(plate_file):
    """The plastic impact with links breaking: 600 steps in one advance call and in calls of
    7, 293 and 300 steps (not on the fracture-check grid) end in bit-identical states
    (positions, velocities, plastic strain, failed and detached particles, removed links,
    gradients, damage); links did break and particles were detached (measured 1,740 and 31): a
    detached particle has no links and no stress, no rebuilt particle's gradients sum to more
    than fracture.GRADIENT_GROWTH x the set-up's largest (the guard that keeps the set-up's
    step stable), and the run stays finite; the audit with plastic work and damage closes within
    3 % of the work put in (measured -0.85 %)."""
    states = []
    for chunks in ((600,), (7, 293, 300)):
        sim, _ = _plastic_plate(plate_file, fracture=True)
        dt = 0.7 * sim.stable_dt
        for k in chunks:
            sim.advance(k, dt)
        p, b = sim.particles, sim.breaking
        states.append([p.x.copy(), p.v.copy(), p.eq_plastic.copy(), b.failed.copy(), b.detached.copy(),
                       b.blocked.copy(), sim.links.grad.copy(), np.array([b.damage])])
        assert sim.broken > 0 and b.detached.any()
        gone = np.flatnonzero(b.detached)
        row = np.repeat(np.arange(len(p.x)), np.diff(sim.links.start))
        touching = np.isin(row, gone) | np.isin(sim.links.neighbour, gone)
        assert sim.state_is_finite() and not np.any(sim.cauchy_stress()[gone])
        assert not np.any(sim.links.grad[touching]) and not np.any(sim.links.value[touching])
        steepness = np.bincount(row, weights=np.linalg.norm(sim.links.grad, axis=1), minlength=len(p.x))
        assert steepness.max() <= b.gradient_limit
        # Plastic work and fracture together: the audit closes within 3 %.
        terms = sim.energies(dt)
        assert abs(relative_imbalance(terms)) < 0.03 and terms["energy.plastic"] > 0 and terms["energy.damage"] > 0
    for one, split in zip(*states):
        assert np.array_equal(one, split)


@pytest.mark.parametrize("override, field", [
    ("particles.layers=1", "particles.layers"),
    ("particles.dilation=2.0", "particles.dilation"),
    ("particles.spacing=0.03", "particles.spacing"),
    ("specimen.element_size=0.002", "element_size"),
    ("material.specific_heat=900.0", "specific_heat"),  # a thermo key with model = "j2"
    ("material.thermal_softening=0.5", "thermal_softening"),
])
def test_bad_input_exits_2_naming_the_field(plate_file, tmp_path, capsys, override, field):
    assert main(["run", str(plate_file), "--out", str(tmp_path / "o"), "--set", override]) == 2
    assert field in capsys.readouterr().err


@pytest.mark.parametrize("override, field", [
    ("material.specific_heat=-900.0", "material.specific_heat"),
    ("material.taylor_quinney=1.5", "material.taylor_quinney"),
    ("material.softening_temperature=0.0", "material.softening_temperature"),
    ("material.yield_stress=inf", "yield_stress"),
    ("material.model=viscous", "material.model"),
])
def test_thermo_bad_input_exits_2_naming_the_field(plate_file, tmp_path, capsys, override, field):
    args = ["run", str(plate_file), "--out", str(tmp_path / "o"), "--set", "material.model=thermo",
            "--set", "material.yield_stress=275e6", "--set", override]
    assert main(args) == 2
    assert field in capsys.readouterr().err


def test_thermo_scenario_defaults(plate_file):
    """model = "thermo" through the schema: eps0 defaults to sigma0 / E (eq. 20; j2 keeps 1), the
    law table carries chi / (rho c) = 0.9 / (2700 x 900) K m^3/J, and the particles start at T0."""
    from crackle.meshfree.material import HEATING, MODEL, THERMO

    scenario, _ = load_scenario(plate_file, ["material.model=thermo", "material.yield_stress=275e6",
                                             "material.initial_temperature=300.0"])
    law = scenario.material.law()
    assert isinstance(law, ThermoLaw) and law.reference_plastic_strain == 275e6 / 71e9
    table = law.table()
    assert table[MODEL] == THERMO and table[HEATING] == pytest.approx(0.9 / (2700.0 * 900.0), rel=1e-15)
    sim = build_simulation(scenario, None)
    assert np.all(sim.particles.thermal[:, 0] == 300.0) and sim.thermo
    j2, _ = load_scenario(plate_file, ["material.yield_stress=275e6"])
    assert j2.material.law().reference_plastic_strain == 1.0 and not isinstance(j2.material.law(), ThermoLaw)


def test_precrack_removes_the_links_across_it_and_hides_each_side():
    """A 20 x 20 x 2 mm plate (11 x 11 x 3 particles) with a pre-crack on the plane x = 10 mm in
    the box y < 10 mm (a notch from one edge to the middle): removed are exactly the links
    (I, J), both directions, with one end behind the plane (or on it) and the other in front
    whose segment meets the plane at y <= 10 mm (checked link by link); no particle fails and
    no link counts as broken; linear fields stay exact (to ROUNDING). Then the plate is cut right
    across: given the particles behind the cut 5 m/s along -x, the particles in front never
    move (their velocities stay exactly 0 for 200 steps: nothing interpolates across the cut)
    and the moving part translates rigidly (kinetic energy kept to 1e-12)."""
    from crackle.loading import Precrack

    plate = plate_particles((0.0, 0.0, 0.0), (0.02, 0.02, 0.002), 0.002, 3)
    notch = Precrack((0.01, 0.0, 0.0), (1.0, 0.0, 0.0), box_max=(np.inf, 0.01, np.inf))
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU), precracks=[notch])
    X, links, b = sim.particles.X, sim.links, sim.breaking
    n = len(X)
    row = np.repeat(np.arange(n), np.diff(links.start))
    col = links.neighbour
    expected = set()
    for i, j in zip(row.tolist(), col.tolist()):
        da, dz = X[i, 0] - 0.01, X[j, 0] - 0.01
        if (da <= 1e-12) != (dz <= 1e-12):
            hit = X[i] + (-da / (dz - da)) * (X[j] - X[i])
            if hit[1] <= 0.01 + 1e-9:
                expected.add(i * n + j)
    removed = set(b.blocked.tolist()) & set((row * n + col).tolist())
    assert removed == expected and len(removed) > 0
    assert not b.failed.any() and b.broken_links == 0 and sim.summary()["precrack_links"] == len({(min(k // n, k % n), max(k // n, k % n)) for k in removed})
    A = np.array([[1e-3, 2e-4, 0.0], [3e-4, -5e-4, 1e-4], [0.0, 2e-4, 7e-4]])
    F = np.zeros((n, 3, 3))
    np.add.at(F, row, ((X[col] - X[row]) @ A.T)[:, :, None] * links.grad[:, None, :])
    assert np.abs(F - A).max() < ROUNDING * np.abs(A).max()

    cut = Precrack((0.01, 0.0, 0.0), (1.0, 0.0, 0.0))
    behind = X[:, 0] <= 0.01 + 1e-12
    velocity = np.where(behind[:, None], [-5.0, 0.0, 0.0], 0.0)
    sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU), velocity=velocity, precracks=[cut])
    kinetic = sim.energies(0.0)["energy.kinetic"]
    sim.advance(200, 0.7 * sim.stable_dt)
    assert np.all(sim.particles.v[~behind] == 0.0) and np.all(sim.particles.x[~behind] == X[~behind])
    assert abs(sim.energies(0.0)["energy.kinetic"] / kinetic - 1.0) < 1e-12


def test_precrack_off_the_specimen_exits_2(tmp_path, capsys):
    path = tmp_path / "notched.toml"
    path.write_text(PLATE + '\n[[precracks]]\npoint = [0.5, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n')
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "precracks.0" in capsys.readouterr().err

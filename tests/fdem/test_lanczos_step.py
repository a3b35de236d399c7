"""The FDEM stable step from the assembled step's highest frequency (fdem.time_step, issue 42):
Lanczos on the linearised forces against the dense eigenvalues of the same operator and against
the element bound, on three meshes; and the step is the limit of the real (nonlinear) kernels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse.linalg import LinearOperator, eigsh

from crackle.fdem import time_step as T
from crackle.fdem.model import build_fdem_model
from crackle.fdem.simulation import FdemSimulation
from crackle.geometry import gmsh_cylinder, gmsh_sphere, structured_box

from fdem_helpers import rock

pytestmark = pytest.mark.filterwarnings("ignore:element size")

# Strong interfaces, so that nothing is damaged by the vibrations below (the springs stay at
# their initial stiffness, which the linearisation takes); the default penalty (200 E / h) makes
# the interfaces set the step, 0.5 E / h leaves it to the bulk tets.
STRONG = dict(tensile_strength=1e12, cohesion=1e12)

MESHES = {
    "structured box": lambda: structured_box((0.01, 0.01, 0.005), 0.005),  # 96 tets
    "gmsh cylinder": lambda: gmsh_cylinder(0.006, 0.012, 0.005),  # 947
    "gmsh sphere": lambda: gmsh_sphere(0.006, 0.005),  # 650
}


def _reference_omega2(model) -> float:
    """The largest eigenvalue of M^-1/2 K M^-1/2 (K: linearised_forces, no tools): dense
    eigenvalues of K assembled column by column on a small mesh, else ARPACK's restarted Lanczos
    (scipy eigsh, full reorthogonalisation, to 1e-12) on the same operator."""
    forces = T.linearised_forces(model.x0, model.tets, model.ifs)
    n = len(model.x0)
    s = 1.0 / np.sqrt(np.repeat(model.nodes.mass, 3))
    out = np.empty((n, 3))

    def apply(q):
        x = model.x0 + (s * q).reshape(n, 3)
        forces(x, out)
        return -s * out.reshape(-1)

    if 3 * n <= 1500:
        K = np.column_stack([apply(e) for e in np.eye(3 * n)])
        assert np.allclose(K, K.T, rtol=0, atol=1e-9 * np.abs(K).max())  # the operator is symmetric
        return float(np.linalg.eigvalsh(K)[-1])
    operator = LinearOperator((3 * n, 3 * n), matvec=apply, dtype=float)
    return float(eigsh(operator, k=1, which="LA", tol=1e-12, v0=np.ones(3 * n))[0][0])


@pytest.mark.parametrize("penalty_factor", [200.0, 0.5])
@pytest.mark.parametrize("mesh", list(MESHES))
def test_lanczos_finds_the_highest_frequency_and_the_bound_lies_above(mesh, penalty_factor):
    """Lanczos' value (Ritz value + residual bound) within 1 % above the reference eigenvalue of
    the same operator and at most 1e-4 below it: the residual bounds the distance to the nearest
    eigenvalue, and where the top modes cluster (the structured box at 200 E / h under the default
    law, whose shear penalty equals the normal one) Lanczos can settle on a neighbour (measured
    7.3e-5 below), which STEP_MARGIN (10 % in omega^2) covers; the element bound above both; the
    run's step is the longer of STEP_MARGIN x the Lanczos one and the bound's."""
    model = build_fdem_model(MESHES[mesh](), rock(penalty_factor=penalty_factor, **STRONG))
    exact = _reference_omega2(model)
    lanczos, residual, iterations = T.highest_frequency2(model.x0, model.nodes.mass, model.tets, model.ifs,
                                                         np.zeros(len(model.x0)))
    assert exact * (1 - 1e-4) <= lanczos <= 1.01 * exact
    step = model.time_step
    assert (2.0 / step.bound_dt) ** 2 >= exact
    # The run's step is the longer of the two (time_step.time_step): the Lanczos one with its margin,
    # except where the bound is within it (the structured box at 200 E / h under the default law,
    # whose shear penalty equals the normal one, so the bound's row sums are nearly attained).
    lanczos_dt = 0.95 * 2.0 / math.sqrt(lanczos)
    assert step.dt == pytest.approx(max(lanczos_dt, step.bound_dt), rel=1e-12)
    assert step.estimate == ("lanczos" if lanczos_dt > step.bound_dt else "element bound")


def _kinetic_growth(model, dt: float, steps: int) -> float:
    """The largest kinetic energy over `steps` steps of dt (checked every 10) over its start, from
    seeded random velocities (1 mm/s: amplitudes far below any nonlinearity); stops at 1e6x."""
    sim = FdemSimulation(model)
    nodes = sim.model.nodes
    nodes.v[:] = 1e-3 * np.random.default_rng(7).standard_normal(nodes.v.shape)

    def kinetic():
        return 0.5 * float(np.sum(nodes.mass[:, None] * nodes.v ** 2))

    start, largest = kinetic(), 0.0
    for _ in range(steps // 10):
        sim.advance(10, dt)
        largest = max(largest, kinetic() / start)
        if not largest < 1e6:
            break
    return largest


@pytest.mark.parametrize("penalty_factor", [200.0, 0.5])
def test_the_estimated_frequency_is_the_kernels_limit(penalty_factor):
    """The real step (interface laws, St. Venant-Kirchhoff tets) from random velocities: at 0.98 x
    2 / omega_max (Lanczos, no margin) the kinetic energy stays bounded (never 2x its start over
    2,000 steps), at 1.05 x it blows up (1e6x within 400 steps); interfaces (200 E / h) or bulk
    tets (0.5 E / h) setting the step."""
    make = lambda: build_fdem_model(MESHES["gmsh cylinder"](), rock(penalty_factor=penalty_factor, **STRONG))
    model = make()
    omega2, _, _ = T.highest_frequency2(model.x0, model.nodes.mass, model.tets, model.ifs, np.zeros(len(model.x0)))
    limit = 2.0 / math.sqrt(omega2)
    assert _kinetic_growth(make(), 0.98 * limit, 2000) < 2.0
    assert _kinetic_growth(make(), 1.05 * limit, 400) > 1e6

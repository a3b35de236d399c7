"""The Kirchhoff-Love shell on triangles (paper 002): forces as the energy's gradient, the membrane
patch test, bending of a strip into a cylinder against the plate's closed form, objectivity, the
J-integral of a centre crack against Tada's handbook value, pre-cracks and bad surfaces."""

from __future__ import annotations

import json
import math

import meshio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from crackle.cli import main
from crackle.io import read_history_csv
from crackle.scenario import load_scenario
from crackle.shell import build_simulation
from crackle.shell.kernels import LoadFactor
from crackle.shell.jintegral import (bending_density, energy_release_rate, j_integral, kinked_release_rate,
                                     merr_kink_angle, mts_kink_angle, stress_intensity)
from crackle.shell.mesh import SurfaceError, edge_path, rectangle, shell_mesh, split_along
from crackle.shell.model import ShellMaterial, build_shell, edge_loads
from crackle.shell.static import relax
from crackle.analysis.energy import relative_imbalance
from threads import outputs_with_1_and_2_threads

STEEL = ShellMaterial(density=7800.0, youngs_modulus=2.0e11, poissons_ratio=0.3)


def jittered_rectangle(width, height, nx, ny, thickness, amount=0.2, seed=0):
    """A rectangle whose inner vertices are moved in-plane by up to amount x the cell size."""
    mesh = rectangle(width, height, nx, ny, thickness)
    X = mesh.X.copy()
    inner = (X[:, 0] > 1e-12) & (X[:, 0] < width - 1e-12) & (X[:, 1] > 1e-12) & (X[:, 1] < height - 1e-12)
    rng = np.random.default_rng(seed)
    X[inner, :2] += rng.uniform(-amount, amount, (inner.sum(), 2)) * [width / nx, height / ny]
    return shell_mesh(X, mesh.tri, thickness)


def cylinder(X, R):
    """The plane (x, y) wrapped onto a cylinder of radius R about an axis along y."""
    return np.stack([R * np.sin(X[:, 0] / R), X[:, 1], R * (1.0 - np.cos(X[:, 0] / R))], axis=1)


def numeric_forces(shell, x, eps=1e-7):
    """-dE/dx by central differences of the shell's strain energy."""
    numeric = np.zeros_like(x)
    for i in range(len(x)):
        for d in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, d] += eps
            xm[i, d] -= eps
            numeric[i, d] = -(sum(shell.strain_energies(xp)) - sum(shell.strain_energies(xm))) / (2 * eps)
    return numeric


def test_forces_are_minus_the_gradient_of_the_strain_energy():
    """Membrane and bending forces against central differences of the energy at a random
    non-flat state, and bending alone (its forces are 100 x smaller here): relative error below
    1e-6."""
    shell = build_shell(jittered_rectangle(0.04, 0.03, 4, 3, 0.002), STEEL)
    bending_only = build_shell(shell.mesh, STEEL)
    bending_only.faces.lam_t[:] = 0.0
    bending_only.faces.mu_t[:] = 0.0
    x = shell.mesh.X + np.random.default_rng(1).normal(scale=1e-3, size=shell.mesh.X.shape)
    for model in (shell, bending_only):
        forces = np.zeros_like(x)
        model.forces(x, forces)
        numeric = numeric_forces(model, x)
        assert np.abs(forces - numeric).max() < 1e-6 * np.abs(numeric).max()


def test_uniform_membrane_strain_is_reproduced_exactly():
    """Patch test on a distorted mesh: a homogeneous in-plane deformation gives every triangle the
    closed-form membrane energy t A (mu E:E + lambda/2 tr(E)^2) (plane stress) to 1e-12, and no
    force on any inner vertex (1e-9 of the boundary forces)."""
    t = 0.001
    mesh = jittered_rectangle(0.05, 0.04, 6, 5, t)
    shell = build_shell(mesh, STEEL)
    F = np.array([[1.002, 0.0007, 0.0], [-0.0004, 0.9985, 0.0], [0.0, 0.0, 1.0]])
    x = mesh.X @ F.T
    E = 0.5 * (F[:2, :2].T @ F[:2, :2] - np.eye(2))
    lam, mu = STEEL.lame_plane_stress()
    density = t * (mu * np.sum(E * E) + 0.5 * lam * np.trace(E) ** 2)
    membrane, bending = shell.strain_energies(x)
    assert membrane == pytest.approx(density * 0.05 * 0.04, rel=1e-12)
    assert bending == 0.0
    forces = np.zeros_like(x)
    shell.forces(x, forces)
    inner = ~np.isin(np.arange(len(x)), mesh.edge[mesh.boundary].ravel())
    assert np.abs(forces[inner]).max() < 1e-9 * np.abs(forces).max()


def test_strip_bent_into_a_cylinder_stores_the_plate_bending_energy():
    """A flat strip wrapped onto a cylinder of radius R (curvature 1/R, no stretching) against the
    closed form D / 2 / R^2 x area, D = E t^3 / (12 (1 - nu^2)). The mid-edge shape operator is
    exact on a mesh along the generators: every triangle off the free ends holds D / 2 / R^2 x
    its area to 1e-4. At the free ends the moment vanishes (a free edge carries none, as in the
    continuum) and one layer of triangles relaxes, as do the Poisson curvatures at the free sides
    (below): an error of first order in the cell size, within 2 % at 128 x 32 cells and halving
    with the cell size."""
    t, L, b, R = 0.001, 0.1, 0.02, 0.1
    density = 0.5 * STEEL.bending_stiffness(t) / R**2
    errors = []
    for nx in (64, 128):
        shell = build_shell(rectangle(L, b, nx, nx // 4, t), STEEL)
        x = cylinder(shell.mesh.X, R)
        membrane, bending = shell.strain_energies(x)
        errors.append(abs(bending / (density * L * b) - 1.0))
        assert membrane < 1e-4 * bending  # wrapping does not stretch the mid-surface
    assert errors[1] < 0.02
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)
    # Triangle by triangle, away from the ends (where x = 0 or L is a corner).
    shell = build_shell(rectangle(L, b, 16, 4, t), STEEL)
    x = cylinder(shell.mesh.X, R)
    per_area = bending_density(shell, x)
    corners_x = shell.mesh.X[shell.mesh.tri][:, :, 0]
    inner = (corners_x.min(axis=1) > 1e-9) & (corners_x.max(axis=1) < L - 1e-9)
    side = shell.mesh.boundary[shell.mesh.face_edge].any(axis=1)
    np.testing.assert_allclose(per_area[inner & ~side], density, rtol=1e-4)
    # A free side along the bend lets the section curl the other way (anticlastic): the
    # triangles there hold (1 - nu^2) of it.
    np.testing.assert_allclose(per_area[inner & side], density * (1 - STEEL.poissons_ratio**2), rtol=1e-4)


def test_rigid_motion_stores_no_energy():
    """Objectivity: a rotation and translation of the flat sheet stores nothing (1e-18 J), and one
    of a bent and stretched sheet changes neither energy (1e-9 relative)."""
    mesh = jittered_rectangle(0.05, 0.04, 6, 5, 0.001)
    shell = build_shell(mesh, STEEL)
    Q = Rotation.from_euler("xyz", [0.7, -1.2, 2.0]).as_matrix()
    shift = np.array([1.0, 2.0, -3.0])
    assert max(shell.strain_energies(mesh.X @ Q.T + shift)) < 1e-18
    x = cylinder(mesh.X * [1.001, 0.999, 1.0], 0.05)
    before = np.array(shell.strain_energies(x))
    after = np.array(shell.strain_energies(x @ Q.T + shift))
    assert before.min() > 0
    np.testing.assert_allclose(after, before, rtol=1e-9)


def tada_centre_crack(a, half_width):
    """Y = K / (sigma sqrt(pi a)) of a centre crack 2a in a strip 2 b wide (Tada's handbook,
    Feddersen's secant with Tada's correction; 0.1 % for any a/b)."""
    alpha = a / half_width
    return (1.0 - 0.025 * alpha**2 + 0.06 * alpha**4) * math.sqrt(1.0 / math.cos(math.pi * alpha / 2.0))


def centre_crack_static(cells_per_crack, a=0.025, sigma=1.0e8, t=0.001):
    """The static centre crack 2a in a plate 4a wide and 8a tall pulled by sigma on its ends:
    (shell, positions, a); in-plane, held on its symmetry lines away from the crack."""
    b, h = 2 * a, 4 * a
    nx = 4 * cells_per_crack
    mesh = rectangle(2 * b, 2 * h, nx, 2 * nx, t, origin=(-b, -h, 0.0))
    mesh, _ = split_along(mesh, edge_path(mesh, [(-a, 0, 0), (a, 0, 0)]))
    shell = build_shell(mesh, STEEL)
    boundary = np.flatnonzero(mesh.boundary)
    mid_y = 0.5 * (mesh.X[mesh.edge[boundary, 0], 1] + mesh.X[mesh.edge[boundary, 1], 1])
    load = (edge_loads(mesh, boundary[np.isclose(mid_y, h)], (0, sigma, 0))
            + edge_loads(mesh, boundary[np.isclose(mid_y, -h)], (0, -sigma, 0)))
    free = np.ones_like(mesh.X)
    free[:, 2] = 0.0  # in-plane
    X = mesh.X
    free[np.isclose(X[:, 0], 0.0) & (np.abs(X[:, 1]) > 1e-9), 0] = 0.0  # symmetry lines, away from the crack
    free[np.isclose(np.abs(X[:, 0]), b) & np.isclose(X[:, 1], 0.0), 1] = 0.0
    result = relax(shell, load, free, tolerance=1e-7)
    assert result.converged
    return shell, result.x, a


RINGS = (0.2, 0.5), (0.4, 0.7), (0.6, 0.9)  # of a


def centre_crack_j(cells_per_crack, sigma=1.0e8):
    """J (J/m^2) at both tips (rows) of the static centre crack for the RINGS (columns), with
    J's closed form."""
    shell, x, a = centre_crack_static(cells_per_crack, sigma=sigma)
    j = np.array([[j_integral(shell, x, tip, direction, r_in * a, r_out * a) for r_in, r_out in RINGS]
                  for tip, direction in (((a, 0, 0), (1, 0, 0)), ((-a, 0, 0), (-1, 0, 0)))])
    K = sigma * math.sqrt(math.pi * a) * tada_centre_crack(a, 2 * a)
    return j, K**2 / STEEL.youngs_modulus


def test_centre_crack_j_integral_matches_tada():
    """Centre crack 2a in a plate 2b = 4a wide (a/b = 0.5) under remote tension: J = K^2 / E,
    K = sigma sqrt(pi a) Y(a/b), Y = 1.186 (Tada). Constant-strain triangles converge to it at
    first order in the cell size (measured 0.938 and 0.969 of it at 10 and 20 cells along a):
    the finer within 5 %, the Richardson extrapolation of the two within 1 %. Path independence:
    three rings within 2 % of each other, both tips equal (symmetry) to 1e-6."""
    coarse, reference = centre_crack_j(10)
    fine, _ = centre_crack_j(20)
    assert np.ptp(fine / reference) < 0.02 and np.ptp(coarse / reference) < 0.02
    np.testing.assert_allclose(fine[0], fine[1], rtol=1e-6)
    assert abs(fine.mean() / reference - 1.0) < 0.05
    extrapolated = 2.0 * fine.mean() - coarse.mean()
    assert abs(extrapolated / reference - 1.0) < 0.01


def test_a_precrack_splits_the_vertices_between_its_tips():
    """A crack inside the surface duplicates its inner vertices (the tips stay joined); one from
    the boundary also opens the boundary vertex; the cut faces become boundary edges."""
    mesh = rectangle(0.1, 0.1, 10, 10, 0.001)
    inside, parent = split_along(mesh, edge_path(mesh, [(0.03, 0.05, 0), (0.07, 0.05, 0)]))
    assert len(parent) == 3 and len(inside.X) == len(mesh.X) + 3
    assert inside.boundary.sum() == mesh.boundary.sum() + 8  # 4 cut edges, two sides each
    edge, parent = split_along(mesh, edge_path(mesh, [(0.0, 0.05, 0), (0.04, 0.05, 0)]))
    assert len(parent) == 4  # x = 0, 0.01, 0.02, 0.03; the tip at 0.04 stays
    # The path follows a slanted polyline along the mesh's edges, not off it.
    path = edge_path(mesh, [(0.0, 0.0, 0), (0.05, 0.05, 0)])
    assert np.abs(mesh.X[path, 0] - mesh.X[path, 1]).max() < 0.0101


def test_bad_surfaces_are_refused_with_the_reason():
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 1.0]], float)
    with pytest.raises(SurfaceError, match="non-manifold"):
        shell_mesh(X, [[0, 1, 2], [1, 3, 2], [1, 2, 4]], 0.01)
    with pytest.raises(SurfaceError, match="oriented inconsistently"):
        shell_mesh(X, [[0, 1, 2], [1, 2, 3]], 0.01)
    with pytest.raises(SurfaceError, match="thickness must be positive"):
        shell_mesh(X, [[0, 1, 2]], 0.0)
    with pytest.raises(SurfaceError, match="zero area"):
        shell_mesh(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), [[0, 1, 2]], 0.01)
    mesh = rectangle(0.1, 0.1, 10, 10, 0.001)
    with pytest.raises(SurfaceError, match="off the surface"):
        edge_path(mesh, [(0.05, 0.05, 0.05), (0.07, 0.05, 0)])


# --- the scenario: method = "shell" -------------------------------------------------------------


def run_quick(tmp_path, *overrides):
    out = tmp_path / "out"
    args = ["run", "shell-centre-crack", "--quick", "--out", str(out)]
    for o in overrides:
        args += ["--set", o]
    assert main(args) == 0
    return out, json.loads((out / "summary.json").read_text())


def test_centre_crack_example_reaches_the_static_j(tmp_path):
    """The shipped example shell-centre-crack --quick (5 mm cells, 5 along a): the damped, ramped
    explicit run ends at rest with the J of the static solution on the same mesh (dynamic
    relaxation of the same forces and loads) to 0.1 %, both tips equal; J / (K^2 / E) = 0.85 at
    this resolution (measured 0.849; first order in the cell size, the test above); the energy
    audit closes to 1e-6 (measured 2e-9). In plane the domain J is G (to 1e-5): no warning that
    the sheet bends."""
    out, s = run_quick(tmp_path)
    assert s["method"] == "shell" and s["status"] == "completed" and s["triangles"] == 1600
    assert s["warnings"] == []
    assert s["j_reference"] == pytest.approx(5525.87, rel=1e-5)  # K = 100 MPa sqrt(pi 25 mm) 1.186
    assert 0.80 < s["j_ratio"] < 0.90
    assert abs(s["energy_error"]) < 1e-6
    np.testing.assert_allclose(s["j_tips"][0], s["j_tips"][1], rtol=1e-9)
    scenario, _ = load_scenario("shell-centre-crack", quick=True)
    sim = build_simulation(scenario)
    nodes = sim.nodes
    free = np.ones_like(nodes.x)
    held = nodes.constraint >= 0
    free[held] = np.diagonal(nodes.projection[nodes.constraint[held]], axis1=1, axis2=2)  # rollers along the axes
    static = relax(sim.shell, nodes.load, free, tolerance=1e-9)
    assert static.converged
    j_static = [j_integral(sim.shell, static.x, sim.shell.mesh.X[tip.vertex], tip.direction, *ring)
                for tip in sim.tips for ring in sim.rings]
    np.testing.assert_allclose(np.ravel(s["j_tips"]), j_static, rtol=1e-3)
    history = read_history_csv(out / "history.csv")
    assert history["j.tip0"][-1] == pytest.approx(s["j_integral"], rel=1e-3)


def test_identical_for_1_and_2_threads():
    """The shell's step (four gathers) gives the same state bit for bit with 1 and 2 threads,
    here with a suddenly loaded crack that grows (Gc = 300 J/m^2) and out-of-plane motion free
    (no roller on z)."""
    script = (
        "import hashlib, numpy as np\n"
        "from crackle.scenario import load_scenario\n"
        "from crackle.shell import build_simulation\n"
        "s, _ = load_scenario('shell-centre-crack', quick=True, overrides=['fracture.toughness=300', "
        "'edge_loads.0.ramp_time=0', 'edge_loads.1.ramp_time=0'])\n"
        "s = s.model_copy(update={'supports': s.supports[1:]})\n"
        "sim = build_simulation(s)\n"
        "sim.nodes.v[:, 2] = 1e-3 * np.sin(np.arange(len(sim.nodes.v)))\n"
        "sim.advance(300, 0.5 * sim.stable_dt)\n"
        "print(hashlib.sha256(sim.nodes.x.tobytes() + sim.nodes.v.tobytes()).hexdigest(), "
        "float(np.abs(sim.nodes.x[:, 2]).max()), len(sim.advances))"
    )
    digests = outputs_with_1_and_2_threads(script)
    assert digests[0][0] == digests[1][0]
    assert float(digests[0][1]) > 0.0, "the compared run must bend"
    assert int(digests[0][2]) >= 2, "the crack must grow in the compared run"


@pytest.mark.parametrize("override, field", [
    ("shell.thickness=0", "shell.thickness"),
    ("cracks.0.polyline=[[0.0, 0.0, 0.05], [0.02, 0.0, 0.05]]", "cracks.0.polyline"),
    ("edge_loads.0.ramp_time=1e-4", "ramp_time"),
    ('shell.surface="file"', "shell"),
    ("edge_loads.0.where.plane_point=[0.0, 0.5, 0.0]", "edge_loads.0.where"),
])
def test_bad_input_exits_2_naming_the_field(tmp_path, capsys, override, field):
    args = ["run", "shell-centre-crack", "--quick", "--out", str(tmp_path / "o"), "--set", override]
    assert main(args) == 2
    assert field in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_bad_surface_files_exit_2(tmp_path, capsys):
    """A non-manifold triangle file and one with a flipped triangle: exit 2 naming shell.file
    and the reason."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 1.0]], float) * 0.01
    for name, triangles, reason in (("fan.vtu", [[0, 1, 2], [1, 3, 2], [1, 2, 4]], "non-manifold"),
                                    ("flip.vtu", [[0, 1, 2], [1, 2, 3]], "oriented inconsistently")):
        meshio.write(tmp_path / name, meshio.Mesh(points, [("triangle", np.array(triangles))]))
        args = ["run", "shell-centre-crack", "--quick", "--out", str(tmp_path / "o"), "--set",
                'shell.surface="file"', "--set", f'shell.file="{tmp_path / name}"', "--set", 'fracture.reference="none"']
        assert main(args) == 2
        err = capsys.readouterr().err
        assert "shell.file" in err and reason in err


def test_griffith_growth_starts_within_one_load_increment_of_the_closed_form():
    """Griffith: the centre-crack plate (2.5 mm cells) loaded in held increments of 4 % of the
    full 100 MPa (0.50, 0.54, 0.58 ...; 150 us each, damped to rest), Gc set so that the
    closed form K^2 / E = Gc at 0.59 (J at full load 5,526 J/m^2, Tada). With J = 0.937 of the
    closed form at this resolution (the test above) the model's own threshold is 0.609: growth
    must start in the increment at 0.62, within one increment of 0.59, never below it; both tips
    together (symmetry); then the crack runs (J rises with a under a held load), each tip no
    faster than V_max (the Rayleigh speed); the energy audit (with the cuts) closes to 1 %."""
    reference = 5525.870364357421
    critical = 0.59
    scenario, _ = load_scenario("shell-centre-crack", overrides=[
        f"fracture.toughness={critical**2 * reference}", "edge_loads.0.ramp_time=0", "edge_loads.1.ramp_time=0"])
    sim = build_simulation(scenario)
    hold, levels = 1.5e-4, np.array([0.50, 0.54, 0.58, 0.62])
    times = np.concatenate([[0.0], np.repeat(np.arange(1, len(levels)) * hold, 2), [len(levels) * hold]])
    sim.load_factor = LoadFactor(times, np.repeat(levels, 2), len(times))
    dt = 0.7 * sim.stable_dt
    while sim.time < len(levels) * hold:
        sim.advance(100, dt)
    assert sim.advances, "no growth by the end of the 0.62 increment"
    start = sim.advances[0].time
    level = levels[int(start // hold)]
    assert level == 0.62 and 0.0 < level - critical <= 0.04
    assert sorted(a.tip for a in sim.advances[:2]) == [0, 1] and sim.advances[1].time == start
    extensions = [tip.extension for tip in sim.tips]
    assert extensions[0] == pytest.approx(extensions[1], rel=1e-12) and min(extensions) >= 0.005  # running
    max_speed = sim.growth.max_speed
    assert max_speed == pytest.approx((2.0e11 / (2.6 * 7800.0)) ** 0.5 * (0.862 + 1.14 * 0.3) / 1.3, rel=1e-9)
    assert max(extensions) <= max_speed * (sim.time - start) + 0.0025
    assert abs(relative_imbalance(sim.energies(dt))) < 0.01


def test_mixed_mode_kink_angle_is_the_maximum_tangential_stress_one():
    """The centre crack (5 cells along a) under remote tension, under pure in-plane shear (tau on
    the four sides) and under both. K from J and the crack faces' displacement mixity
    (stress_intensity): tension K_II / K_I < 1e-3 and a kink of 0; shear K_I / K_II < 1e-3 and
    the maximum tangential stress kink, 2 atan(-1 / sqrt(2)) = -70.53 deg, within 0.5 deg (the
    issue allows 3); both: the kink of the superposed K (K_I of the first, K_II of the second,
    -53.0 deg here) within 2 deg, and sqrt(E J) = |K| by construction. (The maximum energy
    release rate would give ~ -75.6 deg in pure mode II: the criterion here is MTS.)"""
    a, b, h, sigma = 0.025, 0.05, 0.1, 1.0e8
    mesh = rectangle(2 * b, 2 * h, 20, 40, 0.001, origin=(-b, -h, 0.0))
    path = edge_path(mesh, [(-a, 0, 0), (a, 0, 0)])
    mesh, _ = split_along(mesh, path)
    shell = build_shell(mesh, STEEL)
    boundary = np.flatnonzero(mesh.boundary)
    mid = 0.5 * (mesh.X[mesh.edge[boundary, 0]] + mesh.X[mesh.edge[boundary, 1]])

    def side(axis, value, traction):
        return edge_loads(mesh, boundary[np.isclose(mid[:, axis], value)], traction)

    tension = side(1, h, (0, sigma, 0)) + side(1, -h, (0, -sigma, 0))
    shear = side(1, h, (sigma, 0, 0)) + side(1, -h, (-sigma, 0, 0)) + side(0, b, (0, sigma, 0)) + side(0, -b, (0, -sigma, 0))
    free = np.ones_like(mesh.X)
    free[:, 2] = 0.0
    corners = [np.flatnonzero(np.isclose(mesh.X[:, 0], x) & np.isclose(mesh.X[:, 1], -h))[0] for x in (-b, b)]
    free[corners[0], :2] = 0.0  # a pin and a roller: no rigid motion; the loads balance
    free[corners[1], 1] = 0.0
    tip = path[-1]
    k = {}
    for name, load in (("tension", tension), ("shear", shear), ("both", tension + shear)):
        x = relax(shell, load, free, tolerance=1e-6).x
        j = j_integral(shell, x, mesh.X[tip], (1, 0, 0), 0.4 * a, 0.7 * a)
        k[name] = stress_intensity(shell, x, tip, (1, 0, 0), j)
        assert np.linalg.norm(k[name]) == pytest.approx(math.sqrt(STEEL.youngs_modulus * j), rel=1e-12)
        assert abs(k[name][2]) < 1e-9 * np.linalg.norm(k[name])  # in plane: no tearing
    assert abs(k["tension"][1]) < 1e-3 * k["tension"][0] and abs(mts_kink_angle(*k["tension"])) < 1e-3
    assert abs(k["shear"][0]) < 1e-3 * k["shear"][1]
    assert math.degrees(mts_kink_angle(*k["shear"])) == pytest.approx(-70.53, abs=0.5)
    expected = math.degrees(mts_kink_angle(k["tension"][0], k["shear"][1]))
    assert math.degrees(mts_kink_angle(*k["both"])) == pytest.approx(expected, abs=2.0)
    # Tearing counts with the opening (the crack cannot twist out of the surface), closing as
    # nothing: the kink of K_II against K_III alone is the mode I/II one with K_I = K_III.
    assert mts_kink_angle(-5.0, 1.0, 0.0) == pytest.approx(mts_kink_angle(0.0, 1.0), abs=1e-15)
    assert mts_kink_angle(-5.0, 1.0, 2.0) == pytest.approx(mts_kink_angle(2.0, 1.0), abs=1e-15)
    assert abs(mts_kink_angle(0.0, 1e-6, 1.0)) < 1e-5


def test_pressurised_pipe_expands_by_the_membrane_closed_form():
    """The pipe-axial-crack example's pipe without its crack (R = 50 mm, t = 1 mm, open ends,
    2.5 mm cells) under an internal pressure of 2 MPa applied at once. The step's pressure pass
    puts p / 6 x (x1 - x0) x (x2 - x0) on each corner of every triangle (to 1e-12), outward for
    wall = "inner"; the energy audit with the pressure's work closes over 400 steps (1e-4); and
    the static solution under those forces expands the mid-length ring by the membrane hoop
    strain's p R^2 / (E t) = 25 um within 1 % (open ends: no axial stress), uniformly to 1 %."""
    scenario, _ = load_scenario("pipe-axial-crack", quick=True, overrides=[
        "cracks=[]", 'fracture.reference="none"', "pressures.0.ramp_time=0", "run.damping=0"])
    sim = build_simulation(scenario)
    shell, nodes = sim.shell, sim.nodes
    X, tri = shell.mesh.X, shell.mesh.tri
    dt = 0.7 * sim.stable_dt
    sim.advance(1, dt)
    twice_area = np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]])
    np.testing.assert_allclose(shell.faces.pressure_force, 2e6 / 6.0 * twice_area, rtol=1e-12, atol=1e-12)
    outward = X[tri].mean(axis=1) * [1.0, 1.0, 0.0]
    assert np.all(np.einsum("ij,ij->i", shell.faces.pressure_force, outward) > 0)
    sim.advance(399, dt)
    assert abs(relative_imbalance(sim.energies(dt))) < 1e-4  # measured 4.6e-5: a follower load, O(dt^2)
    load = np.zeros_like(X)
    for c in range(3):
        np.add.at(load, tri[:, c], 2e6 * twice_area / 6.0)
    free = np.ones_like(X)
    held = nodes.constraint >= 0
    free[held] = np.diagonal(nodes.projection[nodes.constraint[held]], axis1=1, axis2=2)
    x = relax(shell, load, free, tolerance=1e-7).x
    ring = np.isclose(X[:, 2], 0.1)
    radial = np.linalg.norm(x[ring, :2], axis=1) - np.linalg.norm(X[ring, :2], axis=1)
    expected = 2e6 * 0.05**2 / (2e11 * 0.001)
    assert np.mean(radial) == pytest.approx(expected, rel=0.01)
    assert np.ptp(radial) < 0.01 * expected


def test_energy_release_rate_by_virtual_crack_extension_equals_j_in_plane():
    """G by virtual crack extension (the strain energy's derivative when the vertices about the
    tip move in both configurations, energy_release_rate) against the domain J on the static
    centre crack (10 cells along a): equal to 1e-4 on each of three rings (measured 1e-5): the
    two are the same energy release for in-plane loading; G also holds bending and pressure,
    where J does not yet (the pipe, docs/validation.md)."""
    shell, x, a = centre_crack_static(10)
    for r_in, r_out in RINGS:
        j = j_integral(shell, x, (a, 0, 0), (1, 0, 0), r_in * a, r_out * a)
        assert energy_release_rate(shell, x, (a, 0, 0), (1, 0, 0), r_in * a, r_out * a) == pytest.approx(j, rel=1e-4)


def test_virtual_crack_extension_on_its_patch_equals_the_whole_shell():
    """energy_release_rate rebuilds only the triangles about the tip (jintegral._patch: the two
    layers whose energy the moved vertices change, and a third for their hinges): on a
    pre-cracked sheet in a random state with membrane, bending and mid-edge rotations (and a
    clamped edge), its G equals the same derivative with the whole shell rebuilt, to 1e-7
    (measured 3e-11 and 4e-9: the whole shell's difference loses digits to the energy far from
    the tip)."""
    from dataclasses import replace

    from crackle.shell.kernels import strain_energies
    from crackle.shell.model import build_arrays

    mesh = rectangle(0.1, 0.1, 20, 20, 0.001)
    path = edge_path(mesh, [(0.0, 0.05, 0.0), (0.04, 0.05, 0.0)])
    mesh, _ = split_along(mesh, path)
    clamped = np.isclose(mesh.X[:, 0], 0.1)
    shell = build_shell(mesh, STEEL, clamped)
    rng = np.random.default_rng(3)
    x = mesh.X + rng.normal(0.0, 2e-5, mesh.X.shape) + np.array([0.0, 0.0, 1e-3]) * np.sin(30 * mesh.X[:, :1])
    shell.edges.xi[:] = rng.normal(0.0, 1e-3, len(shell.edges.xi)) * (shell.edges.xi_inertia > 0)
    tip, d = mesh.X[path[-1]], np.array([1.0, 0.0, 0.0])
    for r_in, r_out in ((0.005, 0.0125), (0.01, 0.02)):
        q = np.clip((r_out - np.linalg.norm(mesh.X - tip, axis=1)) / (r_out - r_in), 0.0, 1.0)
        eps = 1e-4 * mesh.element_size()
        energies = []
        for sign in (1.0, -1.0):
            faces, edges, *_ = build_arrays(replace(mesh, X=mesh.X + sign * eps * q[:, None] * d), STEEL, clamped)
            energies.append(sum(strain_energies(x + sign * eps * q[:, None] * d, faces, edges._replace(xi=shell.edges.xi))))
        whole = -(energies[0] - energies[1]) / (2.0 * eps) / 0.001
        assert energy_release_rate(shell, x, tip, d, r_in, r_out) == pytest.approx(whole, rel=1e-7)


def test_shell_tear_example_quick_tears_straight():
    """The shipped example shell-tear --quick (a 0.5 mm aluminium sheet with a 30 mm edge crack,
    its two flaps pulled out of plane by rigid grips, 800 triangles, Gc = 10 kJ/m^2 on G by
    virtual crack extension). At 2 ms, before any cut: G is path independent over the two rings
    in this bending-dominated case, within 3 % (measured 2.1 %; 4.09 and 4.17 kJ/m^2), and the
    J-integral, its bending share now in it, is G within 3 % on each ring (issue 40; measured
    1e-7; before, without the moments' share, 0.89 and 0.34 kJ/m^2); the grips pull (> 10 N;
    42.9 N). By 4 ms: the crack has torn at least two cells straight on along its line (every
    new tip on y = 0, x increasing; measured 3 cuts from 2.74 ms: tearing, K_III, must not turn
    it), each cut only after G reached Gc, and the energy audit with contact, damping, the
    mid-edge rotations and the cuts closes to 1 % (measured -0.19 %)."""
    scenario, _ = load_scenario("shell-tear", quick=True)
    sim = build_simulation(scenario)
    assert sim.warnings == []  # growth on G: nothing to say at set-up
    dt = 0.7 * sim.stable_dt
    while sim.time < 2e-3 - 0.5 * dt:
        sim.advance(20, dt)
    assert len(sim.shell.mesh.tri) == 800 and not sim.advances
    g, j = sim.g_values()[0], sim.j_values()[0]
    assert min(g) > 1000.0 and np.ptp(g) < 0.03 * np.mean(g)
    assert np.allclose(j, g, rtol=0.03, atol=0.0)
    assert np.max(np.abs(sim.sample(dt)["tool.press_over.fz"])) > 10.0
    while sim.time < scenario.run.end_time:
        sim.advance(20, dt)
    positions = np.array([a.position for a in sim.advances])
    assert len(positions) >= 2 and np.all(positions[:, 1] == 0.0) and np.all(np.diff(positions[:, 0]) > 0.0)
    assert positions[0, 0] > 0.03 and sim.advances[0].time > 2e-3
    assert abs(relative_imbalance(sim.energies(dt))) < 0.01


BENT_TUBE = """
name = "bent-tube"
method = "shell"
[shell]
surface = "cylinder"
radius = 0.05
length = 0.2
element_size = 0.0025
thickness = 0.001
[material]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
[[cracks]]
polyline = [[0.0433, -0.025, 0.1], [0.05, 0.0, 0.1], [0.0433, 0.025, 0.1]]
[[edge_loads]]
where = { box_min = [0.0, -1.0, 0.199], box_max = [1.0, 1.0, 1.0] }
traction = [0.0, 0.0, 50e6]
ramp_time = 2e-4
[[edge_loads]]
where = { box_min = [-1.0, -1.0, 0.199], box_max = [0.0, 1.0, 1.0] }
traction = [0.0, 0.0, -50e6]
ramp_time = 2e-4
[[supports]]
kind = "roller"
normal = [0.0, 0.0, 1.0]
where = { plane_point = [0.0, 0.0, 0.0], plane_normal = [0.0, 0.0, 1.0] }
[[supports]]
kind = "roller"
normal = [0.0, 1.0, 0.0]
where = { box_min = [-0.06, -1e-4, -1e-4], box_max = [0.06, 1e-4, 1e-4] }
[[supports]]
kind = "roller"
normal = [1.0, 0.0, 0.0]
where = { box_min = [-1e-4, -0.06, -1e-4], box_max = [1e-4, 0.06, 1e-4] }
[fracture]
j_rings = [[0.005, 0.0125], [0.0075, 0.015]]
[run]
end_time = 5e-4
damping = 2e4
"""


def test_j_is_g_on_a_tube_bent_with_a_through_crack(tmp_path):
    """A 100 mm tube (t = 1 mm, 2.5 mm cells) bent by +-50 MPa on the two halves of its free end,
    with a circumferential through crack of 60 deg on the tension side at mid-length: the flanks
    bend (the bending energy's share of G above 5 % at both tips); G by virtual crack extension,
    its moves kept in each vertex's tangent plane (a move along the tip's tangent would leave
    the curved surface), is the same over the two rings within 1 % (measured 0.13 %), and the
    J-integral is G within 3 % on every ring (issue 40; measured 1e-9: before the membrane's
    domain integral held the strain of the extension field turning with the surface,
    P : n n^T grad V, it read 8-11 % above)."""
    path = tmp_path / "bent.toml"
    path.write_text(BENT_TUBE)
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    dt = 0.7 * sim.stable_dt
    while sim.time < scenario.run.end_time:
        sim.advance(20, dt)
    g = sim.g_values()
    assert len(sim.tips) == 2 and np.all(g > 1000.0)
    assert np.all(np.ptp(g, axis=1) < 0.01 * g.mean(axis=1))
    assert np.allclose(sim.j_values(), g, rtol=0.03, atol=0.0)
    bending = np.array([[sim._extension(tip, ring).bending_release(sim.shell, sim.nodes.x) for ring in sim.rings]
                        for tip in sim.tips])
    assert np.all(bending > 0.05 * g)


@pytest.mark.parametrize("criterion", ["j", "g"])
def test_growth_starts_at_the_same_load_with_j_or_g_in_plane(criterion):
    """In plane G (virtual crack extension) equals J, so Griffith's check starts the centre crack
    of the quick example (5 mm cells, where J is 0.849 of the closed form: the model's threshold
    0.59 / sqrt(0.849) = 0.640 of the full load) in the same held increment, 0.66, with either
    criterion."""
    reference = 5525.870364357421
    scenario, _ = load_scenario("shell-centre-crack", quick=True, overrides=[
        f"fracture.toughness={0.59**2 * reference}", f'fracture.criterion="{criterion}"',
        "edge_loads.0.ramp_time=0", "edge_loads.1.ramp_time=0"])
    sim = build_simulation(scenario)
    hold, levels = 1.5e-4, np.array([0.58, 0.62, 0.66])
    times = np.concatenate([[0.0], np.repeat(np.arange(1, len(levels)) * hold, 2), [len(levels) * hold]])
    sim.load_factor = LoadFactor(times, np.repeat(levels, 2), len(times))
    dt = 0.7 * sim.stable_dt
    while sim.time < len(levels) * hold and not sim.advances:
        sim.advance(100, dt)
    assert sim.advances and levels[int(sim.advances[0].time // hold)] == 0.66


PLATE = """
name = "plate"
method = "shell"
[shell]
surface = "rectangle"
size = [0.2, 0.2]
element_size = {h}
thickness = 0.002
[material]
density = 7800.0
youngs_modulus = 2e11
poissons_ratio = 0.3
[[pressures]]
faces = "where"
where = {{ box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }}
wall = "inner"
value = 1e3
[[supports]]
kind = "{kind}"
where = {{ plane_point = [0.0, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }}
[[supports]]
kind = "{kind}"
where = {{ plane_point = [0.2, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }}
[[supports]]
kind = "{kind}"
where = {{ plane_point = [0.0, 0.0, 0.0], plane_normal = [0.0, 1.0, 0.0] }}
[[supports]]
kind = "{kind}"
where = {{ plane_point = [0.0, 0.2, 0.0], plane_normal = [0.0, 1.0, 0.0] }}
[run]
end_time = 1e-3
"""


def plate_centre_deflection(tmp_path, kind, cells):
    """Centre deflection / the closed form of a 200 mm square steel plate, 2 mm thick, under
    1 kPa, all edges simply supported (kind "fixed": fixed nodes, free slopes) or clamped:
    w = alpha p a^4 / D with alpha 0.00406 and 0.00126 (Timoshenko and Woinowsky-Krieger,
    nu = 0.3), statically."""
    path = tmp_path / f"plate-{kind}-{cells}.toml"
    path.write_text(PLATE.format(h=0.2 / cells, kind=kind))
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    shell, nodes = sim.shell, sim.nodes
    X, tri = shell.mesh.X, shell.mesh.tri
    twice_area = np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]])
    load = np.zeros_like(X)
    for c in range(3):
        np.add.at(load, tri[:, c], 1e3 * twice_area / 6.0)
    free = np.ones_like(X)
    free[nodes.constraint >= 0] = 0.0
    result = relax(shell, load, free, tolerance=1e-6)  # round-off stalls it near 2e-7
    assert result.converged
    centre = np.argmin(np.linalg.norm(X[:, :2] - 0.1, axis=1))
    alpha = 0.00406 if kind == "fixed" else 0.00126
    return (result.x[centre, 2] - X[centre, 2]) / (alpha * 1e3 * 0.2**4 / STEEL.bending_stiffness(0.002))


def test_square_plates_under_pressure_converge_to_the_closed_forms(tmp_path):
    """Plate bending with twist (a pure twist's energy and the moments across edges are what the
    mid-edge rotations xi make right; with xi held at 0 the simply supported plate comes out at
    0.65 of the closed form and does not converge). Simply supported on a mesh with its inner
    vertices moved by up to 20 % of a cell, 16 x 16 cells: within 2 % (measured +1.4 %; +1.3 % on
    the regular mesh, 1.003 at 32 x 32). Clamped (kind = "clamped", through a scenario: the edges
    keep their slope): +8.7 % at 16 x 16, +2.5 % at 32 x 32; within 3 % at 32 and the error
    shrinking at least 2.5 times per halving."""
    a, t, p = 0.2, 0.002, 1e3
    mesh = jittered_rectangle(a, a, 16, 16, t)
    X, tri = mesh.X, mesh.tri
    shell = build_shell(mesh, STEEL)
    load = np.zeros_like(X)
    twice_area = np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]])
    for c in range(3):
        np.add.at(load, tri[:, c], p * twice_area / 6.0)
    free = np.ones_like(X)
    free[np.isclose(X[:, 0], 0) | np.isclose(X[:, 0], a) | np.isclose(X[:, 1], 0) | np.isclose(X[:, 1], a)] = 0.0
    result = relax(shell, load, free, tolerance=1e-6)
    assert result.converged
    deflection = np.max(result.x[:, 2] - X[:, 2])  # the jittered mesh has no vertex at the centre
    assert deflection == pytest.approx(0.00406 * p * a**4 / STEEL.bending_stiffness(t), rel=0.02)
    coarse, fine = (plate_centre_deflection(tmp_path, "clamped", cells) - 1.0 for cells in (16, 32))
    assert abs(fine) < 0.03
    assert abs(coarse) > 2.5 * abs(fine)


def test_tip_neighbours_turn_onto_the_heading_keeping_a_linear_field():
    """Local remeshing at a crack tip (growth.align_ahead) on the criss-cross mesh, at a tip with
    eight neighbours and one with four, for headings 5 to 120 deg off the crack: the edge that
    the cut will take is turned onto the heading, or 3/4 or 1/2 of the way (measured: the whole
    turn, within 0.5 deg, in 12 of the 18 cases, the rest within 4.9-20 deg where the mesh's
    nearest edge was 19.5-45 deg off; asserted: 12 whole turns, none worse than 22.5 deg); the vertices move in the reference plane (z = 0 exactly), the crack's flanks and the
    outer boundary not at all; a linear displacement and velocity field stays exact at the moved
    vertices (1e-15 m), so a uniform membrane strain keeps its energy (1e-12) and the mass is
    conserved (1e-12); no triangle thinner than ALTITUDE_KEPT x the thinnest before."""
    from crackle.shell.growth import ALTITUDE_KEPT, align_ahead, step_ahead
    from crackle.shell.mesh import altitudes

    F = np.array([[1.01, 0.003, 0.0], [-0.002, 0.995, 0.0], [0.0, 0.0, 1.0]])
    G = np.array([[30.0, -5.0, 0.0], [2.0, 10.0, 0.0], [0.0, 0.0, 0.0]])
    base = rectangle(0.1, 0.1, 20, 20, 0.001, origin=(-0.05, -0.05, 0.0))
    errors = []
    for end in (0.0, 0.005):  # the tip with eight neighbours, then four
        path = edge_path(base, [(-0.025, 0.0, 0.0), (end, 0.0, 0.0)])
        mesh, _ = split_along(base, path)
        tip = path[-1]
        fixed = np.unique(mesh.edge[mesh.boundary])
        shell = build_shell(mesh, STEEL)
        shell.nodes.x[:] = mesh.X @ F.T + [1e-3, 2e-3, 0.0]
        shell.nodes.v[:] = mesh.X @ G.T
        thinnest = altitudes(mesh.X, mesh.tri).min()
        energy = sum(shell.strain_energies(shell.nodes.x))
        for degrees in (5.0, 10.0, 20.0, 30.0, -22.5, -40.0, -70.5, 100.0, 120.0):
            heading = np.array([math.cos(math.radians(degrees)), math.sin(math.radians(degrees)), 0.0])
            new = align_ahead(shell, tip, heading, thinnest)
            assert new is not None
            X = new.mesh.X
            vertex, _ = step_ahead(new, tip, heading)
            arm = X[vertex] - X[tip]
            errors.append(abs(math.degrees(math.atan2(arm[1], arm[0])) - degrees))
            assert np.all(X[:, 2] == 0.0) and np.array_equal(X[fixed], mesh.X[fixed])
            assert np.abs(new.nodes.x - (X @ F.T + [1e-3, 2e-3, 0.0])).max() < 1e-15
            assert np.abs(new.nodes.v - X @ G.T).max() < 1e-15
            assert sum(new.strain_energies(new.nodes.x)) == pytest.approx(energy, rel=1e-12)
            assert new.nodes.mass.sum() == pytest.approx(shell.nodes.mass.sum(), rel=1e-12)
            assert altitudes(X, new.mesh.tri).min() >= ALTITUDE_KEPT * thinnest * (1 - 1e-12)
    assert max(errors) <= 22.5 + 1e-9 and sum(e < 0.5 for e in errors) >= 12
    # Aligned already, or a heading back into the crack: nothing to move.
    assert align_ahead(shell, tip, np.array([1.0, 0.0, 0.0]), thinnest) is None
    assert align_ahead(shell, tip, np.array([-1.0, 0.0, 0.0]), thinnest) is None


KINK = """
name = "shear-kink"
method = "shell"
[shell]
surface = "rectangle"
size = [0.1, 0.2]
origin = [-0.05, -0.1, 0.0]
element_size = 0.005
thickness = 0.001
[material]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
[[cracks]]
polyline = [[-0.025, 0.0, 0.0], [0.025, 0.0, 0.0]]
[[edge_loads]]
where = { plane_point = [0.0, 0.1, 0.0], plane_normal = [0.0, 1.0, 0.0] }
traction = [100e6, 0.0, 0.0]
ramp_time = 2e-4
[[edge_loads]]
where = { plane_point = [0.0, -0.1, 0.0], plane_normal = [0.0, 1.0, 0.0] }
traction = [-100e6, 0.0, 0.0]
ramp_time = 2e-4
[[edge_loads]]
where = { plane_point = [0.05, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
traction = [0.0, 100e6, 0.0]
ramp_time = 2e-4
[[edge_loads]]
where = { plane_point = [-0.05, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
traction = [0.0, -100e6, 0.0]
ramp_time = 2e-4
[[supports]]
kind = "roller"
normal = [0.0, 0.0, 1.0]
where = { box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }
[[supports]]
kind = "fixed"
where = { box_min = [-0.051, -0.101, -1.0], box_max = [-0.049, -0.099, 1.0] }
[[supports]]
kind = "roller"
normal = [0.0, 1.0, 0.0]
where = { box_min = [0.049, -0.101, -1.0], box_max = [0.051, -0.099, 1.0] }
[fracture]
toughness = 2000.0
j_rings = [[0.005, 0.0125], [0.010, 0.0175], [0.015, 0.0225]]
[run]
end_time = 2.2e-4
damping = 1e5
"""


def _first_cuts(tmp_path, kink: str):
    """The shear-kink plate grown to its end with the kink criterion `kink`: (each tip's first cut
    as an angle from the x axis in degrees, the relative energy imbalance at the end)."""
    path = tmp_path / "kink.toml"
    path.write_text(KINK.replace("[fracture]", f'[fracture]\nkink = "{kink}"'))
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    dt = 0.7 * sim.stable_dt
    origin = {0: np.array([0.025, 0.0]), 1: np.array([-0.025, 0.0])}
    while sim.time < scenario.run.end_time:
        sim.advance(20, dt)
    first = {}
    for advance in sim.advances:
        first.setdefault(advance.tip, advance.position[:2] - origin[advance.tip])
    assert set(first) == {0, 1}
    return ({tip: math.degrees(math.atan2(d[1], d[0])) for tip, d in first.items()},
            relative_imbalance(sim.energies(dt)))


def test_mode_ii_crack_kinks_at_the_mts_angle_off_the_mesh_lines(tmp_path):
    """The centre crack (5 mm cells) under pure in-plane shear (tau ramped to 100 MPa on the four
    sides), Gc = 2 kJ/m^2: growth starts in mode II and the first cut at each tip runs at the
    maximum tangential stress kink, -70.5 deg from the crack (and its image, +109.5 deg from the
    x axis, at the other tip), within 3 deg (the issue's tolerance), although the mesh's edges
    there run at -45 and -90 deg (19.5 deg off at best: the tip's neighbours were turned,
    growth.align_ahead); the energy audit with the cuts and moves closes to 1 %."""
    angles, imbalance = _first_cuts(tmp_path, "mts")
    assert angles[0] == pytest.approx(-70.5, abs=3.0)
    assert angles[1] == pytest.approx(109.5, abs=3.0)
    assert abs(imbalance) < 0.01


def test_mode_ii_crack_kinks_at_the_merr_angle(tmp_path):
    """The same plate with fracture.kink = "merr" (paper 002's criterion): the first cuts run at
    the maximum energy release rate kink of pure mode II, -75.2 deg (Hussain, Pu and Underwood;
    paper 002 quotes ~ -75.6), and its image +104.8 deg, within 2 deg (issue 40), 4.7 deg
    beyond the MTS cut of the test above."""
    angles, imbalance = _first_cuts(tmp_path, "merr")
    assert angles[0] == pytest.approx(-75.2, abs=2.0)
    assert angles[1] == pytest.approx(104.8, abs=2.0)
    assert abs(imbalance) < 0.01


def test_merr_kink_angle_maximises_the_kinked_release_rate():
    """merr_kink_angle against the closed form it maximises (kinked_release_rate): pure mode II
    -75.23 deg (K_II > 0; +75.23 for K_II < 0) within 0.01 deg, pure mode I 0; at K_II / K_I =
    1, 0.5 and 0.1 no angle within +-89 deg on a 0.001 deg grid releases more (to 1e-9), and it
    turns further than MTS (the energy criterion's known ~4 deg beyond MTS in mode II)."""
    assert math.degrees(merr_kink_angle(0.0, 1.0)) == pytest.approx(-75.23, abs=0.01)
    assert math.degrees(merr_kink_angle(0.0, -1.0)) == pytest.approx(75.23, abs=0.01)
    assert merr_kink_angle(1.0, 0.0) == 0.0
    grid = np.radians(np.linspace(-89.0, 89.0, 178001))
    for k2 in (1.0, 0.5, 0.1):
        best = merr_kink_angle(1.0, k2)
        assert kinked_release_rate(best, 1.0, k2) >= kinked_release_rate(grid, 1.0, k2).max() * (1 - 1e-9)
        assert best < mts_kink_angle(1.0, k2) < 0.0
    assert kinked_release_rate(0.0, 2.0, 3.0) == pytest.approx(13.0, rel=1e-12)  # K_I^2 + K_II^2 straight on


def _static_plate(tmp_path, text: str, name: str):
    """A plate of this file's templates without growth (toughness inf), damped to 500 us."""
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace("toughness = 400.0", "toughness = inf").replace("toughness = 2000.0", "toughness = inf")
                    .replace("end_time = 3.5e-4", "end_time = 5e-4").replace("end_time = 2.2e-4", "end_time = 5e-4"))
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    dt = 0.7 * sim.stable_dt
    while sim.time < scenario.run.end_time:
        sim.advance(20, dt)
    return sim


def test_configurational_force_across_the_crack(tmp_path):
    """The configurational force in the surface (summary configurational_force: G by virtual
    extension along the crack, = J, and across it): for a straight crack the across component is
    J_2 = -2 K_I K_II / E (J_1 = (K_I^2 + K_II^2) / E), so -J_1 where K_I = K_II (the 45-deg
    crack pulled along y, 2.5 mm cells, static: -1.07 and -0.81 at the two tips, asymmetric
    supports; within 25 %) and 0 in pure mode II (the shear plate: within 3 % of J_1; measured
    1.2-1.5 %). The along component is J to 1e-6 (the membrane's domain integral against its
    virtual extension). Its sign is the side the kink turns to (negative: clockwise, as MTS)."""
    inclined = _static_plate(tmp_path, INCLINED, "inclined")
    forces = inclined.configurational_forces()
    assert np.allclose(forces[:, 0], inclined.j_values().mean(axis=1), rtol=1e-6, atol=0.0)
    assert np.all(forces[:, 1] / forces[:, 0] > -1.25) and np.all(forces[:, 1] / forces[:, 0] < -0.75)
    shear = _static_plate(tmp_path, KINK, "shear")
    forces = shear.configurational_forces()
    assert np.all(np.abs(forces[:, 1]) < 0.03 * forces[:, 0])
    summary = shear.summary()
    assert np.allclose(summary["configurational_force"], forces, rtol=1e-12)


HOLE = """name = "hole"
method = "shell"
[shell]
surface = "file"
file = "plate.msh"
thickness = 0.001
[material]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
[[edge_loads]]
where = { plane_point = [0.05, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
traction = [100e6, 0.0, 0.0]
ramp_time = 2e-4
[[edge_loads]]
where = { plane_point = [-0.05, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
traction = [-100e6, 0.0, 0.0]
ramp_time = 2e-4
[[supports]]
kind = "roller"
normal = [0.0, 0.0, 1.0]
where = { box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }
[[supports]]
kind = "fixed"
where = { box_min = [-0.051, -0.051, -1.0], box_max = [-0.049, -0.049, 1.0] }
[[supports]]
kind = "roller"
normal = [0.0, 1.0, 0.0]
where = { box_min = [0.049, -0.051, -1.0], box_max = [0.051, -0.049, 1.0] }
[fracture]
toughness = 1e5
strength = 250e6
[run]
end_time = 3e-4
damping = 1e5
"""


def _plate_with_a_hole(path, half=0.05, radius=0.01, size=0.0025):
    """A gmsh triangle surface: a 100 x 100 mm square in the x-y plane with a 20 mm hole at its
    middle, 2.5 mm triangles."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        occ.cut([(2, occ.addRectangle(-half, -half, 0, 2 * half, 2 * half))], [(2, occ.addDisk(0, 0, 0, radius, radius))])
        occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def test_a_crack_nucleates_where_a_hole_concentrates_the_stress(tmp_path):
    """The 100 mm plate with a 20 mm hole pulled along x (100 MPa ramped over 200 us), strength
    250 MPa (fracture.strength), toughness high enough that nothing grows: exactly two cracks
    start, at the hole's top and bottom (Kirsch: the stress along the edge is 3 sigma at (0, +-R),
    -sigma at (+-R, 0)), within one cell (2.5 mm) of them, each first cut running into the sheet
    along +-y (within 20 deg), when the edge stress reached the strength, at a load where
    strength / applied stress is 2.5-3.2 (the vertex reads its triangles' mean: Kirsch gives 3 at
    the edge and 2.5 at their centroids; measured 2.74); none starts at the loaded or supported
    edges. events.csv has both first cuts."""
    from crackle.io import read_events_csv

    _plate_with_a_hole(tmp_path / "plate.msh")
    path = tmp_path / "hole.toml"
    path.write_text(HOLE)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    starts = summary["nucleations"]
    assert len(starts) == 2
    for start in starts:
        x, y, _ = start["position"]
        assert np.hypot(x, abs(y) - 0.01) < 0.0025
        assert start["stress"] >= 250e6
        assert 2.5 < 250e6 / (100e6 * start["time"] / 2e-4) < 3.2
    for (x, y, _), tip in zip((s["position"] for s in starts), summary["crack_tips"]):
        heading = np.degrees(np.arctan2(tip[1] - y, tip[0] - x))
        assert abs(abs(heading) - 90.0) < 20.0 and np.sign(heading) == np.sign(y)
    assert len(read_events_csv(out / "events.csv")["time"]) == 2


def test_strength_without_toughness_is_refused(tmp_path, capsys):
    """fracture.strength alone (the crack it starts could never grow): exit 2 naming
    fracture.strength and fracture.toughness."""
    _plate_with_a_hole(tmp_path / "plate.msh")
    path = tmp_path / "hole.toml"
    path.write_text(HOLE.replace("toughness = 1e5\n", ""))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "fracture.strength" in err and "fracture.toughness" in err


def test_a_j_read_mid_oscillation_is_flagged(tmp_path):
    """shell-centre-crack's quick plate, undamped (run.damping = 0), read at 300 us, 100 us after
    its ramp: it rings about equilibrium (kinetic energy ~1e-3 of the strain energy; J 0.82 of
    the closed form where the damped run settles at 0.85): summary j_static false, its
    kinetic_to_strain above STATIC_KINETIC (1e-4) and a warning that says so and what to do; the
    example as shipped (damped, 500 us) reads j_static true with no such warning
    (tests/core/test_outputs.py runs it)."""
    from crackle.shell.simulation import STATIC_KINETIC

    out = tmp_path / "ringing"
    assert main(["run", "shell-centre-crack", "--quick", "--set", "run.damping=0", "--set", "run.end_time=3e-4",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["j_static"] is False and summary["kinetic_to_strain"] > STATIC_KINETIC
    assert any("still moved" in w and "run.damping" in w for w in summary["warnings"])


INCLINED = """
name = "inclined-crack"
method = "shell"
[shell]
surface = "rectangle"
size = [0.1, 0.2]
origin = [-0.05, -0.1, 0.0]
element_size = 0.0025
thickness = 0.001
[material]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
[[cracks]]
polyline = [[-0.0088388, -0.0088388, 0.0], [0.0088388, 0.0088388, 0.0]]
[[edge_loads]]
where = { plane_point = [0.0, 0.1, 0.0], plane_normal = [0.0, 1.0, 0.0] }
traction = [0.0, 100e6, 0.0]
ramp_time = 2e-4
[[edge_loads]]
where = { plane_point = [0.0, -0.1, 0.0], plane_normal = [0.0, 1.0, 0.0] }
traction = [0.0, -100e6, 0.0]
ramp_time = 2e-4
[[supports]]
kind = "roller"
normal = [0.0, 0.0, 1.0]
where = { box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }
[[supports]]
kind = "fixed"
where = { box_min = [-0.051, -0.101, -1.0], box_max = [-0.049, -0.099, 1.0] }
[[supports]]
kind = "roller"
normal = [0.0, 1.0, 0.0]
where = { box_min = [0.049, -0.101, -1.0], box_max = [0.051, -0.099, 1.0] }
[fracture]
toughness = 400.0
max_speed = 300.0
[run]
end_time = 3.5e-4
damping = 1e5
"""


@pytest.mark.parametrize("kink, first", [("mts", -8.13), ("merr", -12.33)])
def test_inclined_crack_turns_normal_to_the_load_and_stays(tmp_path, kink, first):
    """A 25 mm crack at 45 deg in the 100 x 200 mm plate pulled along y (100 MPa; K_I = K_II,
    G ~ 2.4 Gc), 2.5 mm cells: the first cut of tip 0 turns by the criterion's kink (MTS
    -53.13 deg, MERR -57.33 deg from the crack: -8.13 / -12.33 deg from x) within 2 deg; after
    it each tip's path (the chord from the end of its first cut to its last tip, 20-30 mm)
    runs within 10 deg of x, the line normal to the load (issue 40), and no two successive cuts
    stray more than 20 deg from it on the same side (the swing past the normal the issue saw:
    -32.9 then -30.3 deg, before a step right after a kink aimed on instead of reading the
    mixity across the kink). Single cuts follow the mesh's edges: up to ~20 deg off where the
    mesh cannot be turned (growth.align_ahead)."""
    path = tmp_path / "inclined.toml"
    path.write_text(INCLINED.replace("[fracture]", f'[fracture]\nkink = "{kink}"'))
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    dt = 0.7 * sim.stable_dt
    while sim.time < scenario.run.end_time:
        sim.advance(20, dt)
    for tip, along in ((0, 0.0), (1, 180.0)):
        points = [sim._tip_starts[tip][:2]] + [a.position[:2] for a in sim.advances if a.tip == tip]
        assert len(points) >= 6
        off = [((math.degrees(math.atan2(*(q - p)[::-1])) - along + 180.0) % 360.0) - 180.0
               for p, q in zip(points, points[1:])]
        if tip == 0:
            assert off[0] == pytest.approx(first, abs=2.0)
        chord = points[-1] - points[1]
        assert abs(((math.degrees(math.atan2(chord[1], chord[0])) - along + 180.0) % 360.0) - 180.0) < 10.0
        assert not any(abs(a) > 20.0 and abs(b) > 20.0 and a * b > 0 for a, b in zip(off[1:], off[2:]))


STRIP = """
name = "two-region strip"
method = "shell"
[shell]
surface = "rectangle"
size = [0.1, 0.02]
element_size = 0.005
thickness = 0.001
[material]
density = 7800.0
youngs_modulus = 2e11
poissons_ratio = 0.0
[[regions]]
where = {{ box_min = [{x0}, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }}
thickness = 0.002
[regions.material]
density = 2700.0
youngs_modulus = 7e10
poissons_ratio = 0.0
[[edge_loads]]
where = {{ plane_point = [0.1, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }}
traction = [1e6, 0.0, 0.0]
[run]
end_time = 1e-3
"""


def test_regions_carry_their_own_thickness_and_material(tmp_path, capsys):
    """A 100 x 20 mm strip, steel 1 mm thick for x < 50 mm and a [[regions]] of aluminium 2 mm
    thick beyond (nu = 0 in both, so each part's strain is uniform), pulled by 1 MPa on its
    aluminium end (F = 40 N), statically: the end moves F L1 / (E1 t1 w) + F L2 / (E2 t2 w)
    (5.0e-7 + 7.14e-7 m) and the joint the steel's share, to 1e-4 (St. Venant-Kirchhoff at a
    strain of 1e-5); the masses add up to sum rho t A to 1e-12. The same strip wrapped onto a
    cylinder of radius R stores D_i / 2 / R^2 per area in every triangle off the free ends, D_i
    = E_i t_i^3 / 12 of its own region (to 1e-4). A region that selects no triangle: exit 2
    naming regions.0.where."""
    path = tmp_path / "strip.toml"
    path.write_text(STRIP.format(x0=0.05 - 1e-9))
    scenario, _ = load_scenario(path)
    sim = build_simulation(scenario)
    shell, nodes = sim.shell, sim.nodes
    X = shell.mesh.X
    centroid_x = X[shell.mesh.tri].mean(axis=1)[:, 0]
    aluminium = centroid_x > 0.05
    assert np.array_equal(shell.mesh.region, aluminium.astype(int))
    np.testing.assert_array_equal(shell.mesh.thickness, np.where(aluminium, 0.002, 0.001))
    assert nodes.mass.sum() == pytest.approx(7800 * 0.001 * 0.05 * 0.02 + 2700 * 0.002 * 0.05 * 0.02, rel=1e-12)
    free = np.ones_like(X)
    free[:, 1:] = 0.0
    free[X[:, 0] < 1e-9, 0] = 0.0
    result = relax(shell, nodes.load, free, tolerance=1e-9)
    assert result.converged
    force = 1e6 * 0.002 * 0.02
    joint, end = force * 0.05 / (2e11 * 0.001 * 0.02), force * 0.05 / (7e10 * 0.002 * 0.02)
    ux = result.x[:, 0] - X[:, 0]
    np.testing.assert_allclose(ux[np.abs(X[:, 0] - 0.1) < 1e-9], joint + end, rtol=1e-4)
    np.testing.assert_allclose(ux[np.abs(X[:, 0] - 0.05) < 1e-9], joint, rtol=1e-4)
    R = 0.1
    per_area = bending_density(shell, cylinder(X, R))
    inner = (X[shell.mesh.tri][:, :, 0].min(axis=1) > 1e-9) & (X[shell.mesh.tri][:, :, 0].max(axis=1) < 0.1 - 1e-9)
    D = np.where(aluminium, 7e10 * 0.002**3, 2e11 * 0.001**3) / 12.0
    np.testing.assert_allclose(per_area[inner], (D / 2 / R**2)[inner], rtol=1e-4)
    path.write_text(STRIP.format(x0=0.2))
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "regions.0.where" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()

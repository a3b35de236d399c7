"""The meshfree method on particles at a tet mesh's nodes (crackle.meshfree.particles:
tet_node_particles, shell_particles): the median-dual cells (closed, volumes, shared faces), the
patch test and the integration constraint on them, the crack normal of a solid, a pressurised
spherical shell walled from a triangle surface, and the scenario shapes "mesh" and "shell".
Small gmsh meshes: seconds each once the kernels are compiled."""

from __future__ import annotations

import json
import math

import meshio
import numpy as np
import pytest

from crackle.cli import main
from crackle.geometry.meshes import gmsh_box, gmsh_sphere
from crackle.geometry.walnut import _unit_sphere_surface
from crackle.loading import History, Pressure, Selection
from crackle.meshfree.build import SetupError, build_meshfree_simulation
from crackle.meshfree.fracture import FRACTURE_CHECK
from crackle.meshfree.material import J2Law
from crackle.meshfree.particles import INNER, OUTER, shell_particles, tet_node_particles
from crackle.meshfree.shape import FULL_BASIS
from meshfree_fields import ROUNDING, linear_field_errors

E_AL, NU, RHO_AL = 70e9, 0.3, 2700.0
EVERYWHERE = Selection(box_min=(-1.0, -1.0, -1.0), box_max=(1.0, 1.0, 1.0))
# A bar 80 x 20 x 20 mm of gmsh tets, 5 mm edges (458 nodes).
BAR = (0.08, 0.02, 0.02)


def _bar():
    mesh = gmsh_box(BAR, 0.005)
    return mesh, tet_node_particles(mesh.points, mesh.tets)


def _rows(cells):
    return np.repeat(np.arange(len(cells.start) - 1), np.diff(cells.start))


def test_median_dual_cells_are_closed_and_fill_the_mesh():
    """On the bar (458 nodes, 1,480 tets; 83 triangles a cell on average, integrated at their
    vertices: 20,950 rows (cell, vertex), 7,516 distinct points): the cell volumes (a quarter of
    each tet to each of its nodes) sum to the bar's 3.2e-5 m^3 (1e-12 rel; measured 0) and equal
    each cell's divergence-theorem volume sum w.(x - X) / 3 (1e-12 rel; measured 2.4e-15); every
    cell's weights sum to zero (closed: below 1e-12 of the largest; measured 5.8e-15); the
    cells' weights at a quadrature point inside the bar cancel (the integration constraint: below
    1e-12 of the largest weight; measured 1e-16), exactly at an edge midpoint (two cells, summed
    in the same order), and those on the boundary cover each side of the bar: |w| summed is
    2 (Ly Lz, Lx Lz, Lx Ly) (1e-12 rel; measured 1.1e-15), as the boundary faces (the wall
    surface, all OUTER) do, whose vector sum is zero (1e-12 of Lx Ly; measured 8e-16)."""
    mesh, bar = _bar()
    cells, n = bar.cells, len(bar.X)
    assert np.array_equal(bar.X, mesh.points) and bar.shape == "mesh" and bar.wall_frame is None
    assert bar.volume.sum() == pytest.approx(np.prod(BAR), rel=1e-12)
    row = _rows(cells)
    x = cells.points[cells.point]
    divergence = np.bincount(row, weights=np.einsum("ka,ka->k", cells.weight, x - bar.X[row]), minlength=n)
    assert np.abs(divergence / 3.0 / bar.volume - 1.0).max() < 1e-12
    closure = np.zeros((n, 3))
    np.add.at(closure, row, cells.weight)
    largest = np.abs(cells.weight).max()
    assert np.abs(closure).max() < 1e-12 * largest
    assert len(cells.point) == 20950 and len(cells.points) == 7516
    total = np.zeros_like(cells.points)
    np.add.at(total, cells.point, cells.weight)
    Lx, Ly, Lz = BAR
    P = cells.points
    on_boundary = np.any((np.abs(P) < 1e-12) | (np.abs(P - np.array(BAR)) < 1e-12), axis=1)
    assert np.abs(total[~on_boundary]).max() < 1e-12 * largest
    shared_by = np.bincount(cells.point, minlength=len(P))
    pairs = np.flatnonzero((shared_by == 2) & ~on_boundary)
    assert len(pairs) and np.all(total[pairs] == 0.0)
    assert np.abs(total[on_boundary]).sum(axis=0) == pytest.approx(2 * np.array([Ly * Lz, Lx * Lz, Lx * Ly]),
                                                                   rel=1e-12)
    surface = bar.surface
    assert np.all(surface.side == OUTER)
    assert np.abs(surface.area).sum(axis=0) == pytest.approx(2 * np.array([Ly * Lz, Lx * Lz, Lx * Ly]), rel=1e-12)
    assert np.abs(surface.area.sum(axis=0)).max() < 1e-12 * Lx * Ly
    # What build needs: a global support from the edges, the contact area volume^(2/3).
    assert bar.spacing[0] >= bar.spacing[1] >= bar.spacing[2] > 0.0
    assert np.allclose(bar.area, bar.volume ** (2.0 / 3.0))


def test_mesh_patch_test_linear_field():
    """A gmsh ball (radius 10 mm, 4 mm edges: 201 nodes, curved faceted boundary): the MLS
    reproduces a linear field u = A X + b at every node (1e-10 of |u|; measured 4e-15) and the
    gradients smoothed over the median-dual cells are exact at every node, boundary included
    (1e-10 of |A|; measured 1.2e-14)."""
    mesh = gmsh_sphere(0.01, 0.004)
    ball = tet_node_particles(mesh.points, mesh.tets)
    value_error, gradient_error = linear_field_errors(ball.X, ball.volume, ball.cells, 2.5 * float(np.max(ball.spacing)),
                                                      FULL_BASIS)
    assert value_error < 1e-10 and gradient_error < 1e-10


def test_mesh_uniform_stress_leaves_the_inside_in_equilibrium():
    """The integration constraint on the median-dual cells: the bar in uniaxial stress along x
    (Green strain e = 1e-3 along x, -nu e across: S = E e along x only) is loaded only through
    its x faces (the other boundary faces' normals see no traction), so every node farther than
    the support radius R (19.9 mm) from both x faces (216 of 458) is in equilibrium to ROUNDING
    of E e h^2 (h the median edge), while the ends do pull (> 1e-2 of it;
    measured 0.92)."""
    _, bar = _bar()
    sim = build_meshfree_simulation(bar, RHO_AL, J2Law(E_AL, NU))
    p = sim.particles
    e = 1e-3
    p.x[:] = p.X * np.sqrt(1.0 + 2.0 * np.array([e, -NU * e, -NU * e]))
    dt = 1e-10
    sim.advance(1, dt)  # from rest: v = dt f / m
    force = p.v * p.mass[:, None] / dt
    assert p.stress[:, 0] == pytest.approx(E_AL * e, rel=ROUNDING)
    x = p.X[:, 0]
    far = np.minimum(x, BAR[0] - x) >= sim.support_radius * (1.0 + 1e-9)
    assert far.sum() == 216
    scale = E_AL * e * bar.spacing[1] ** 2
    assert np.max(np.abs(force[far])) < ROUNDING * scale
    assert np.max(np.abs(force[~far])) > 1e-2 * scale


def test_too_small_a_support_names_the_dilation():
    """With dilation 1 (the support radius one 90th-percentile edge) a quadrature point of the bar
    sees too few nodes for the quadratic basis: SetupError naming particles.dilation."""
    _, bar = _bar()
    with pytest.raises(SetupError) as err:
        build_meshfree_simulation(bar, RHO_AL, J2Law(E_AL, NU), dilation=1.0)
    assert err.value.field == "particles.dilation" and "increase particles.dilation" in str(err.value)


def test_solid_crack_normal_keeps_the_principal_direction():
    """A solid has no wall to cut through (wall_frame None): a cube of gmsh tets (20 mm, 10 mm
    edges) stretched uniformly along z,
    F = diag(1, 1, 1 + e), over the fracture stress fails every node at the first check with its
    crack normal along z (within ROUNDING); a plate's would be projected into its wall."""
    mesh = gmsh_box((0.02, 0.02, 0.02), 0.01)
    cube = tet_node_particles(mesh.points, mesh.tets)
    sim = build_meshfree_simulation(cube, RHO_AL, J2Law(E_AL, NU), fracture_stress=300e6)
    p = sim.particles
    p.x[:] = p.X * np.array([1.0, 1.0, 1.004])  # (lambda + 2 mu) e ~ 380 MPa
    sim.advance(FRACTURE_CHECK, 1e-12)
    b = sim.breaking
    assert b.failed.all()
    assert np.abs(b.normal - [0.0, 0.0, 1.0]).max() < ROUNDING


def _sphere_surface(path, radius, size):
    """A gmsh triangulation of the sphere (relative edge `size`) written as STL."""
    points, triangles = _unit_sphere_surface(size)
    meshio.write(path, meshio.Mesh(points * radius, [("triangle", triangles)]))
    return path


def test_pressurised_spherical_shell_gives_the_membrane_stress(tmp_path):
    """A closed spherical shell walled inwards from a triangle surface (outer radius b = 50 mm,
    10 mm triangles; wall t = 2.5 mm, 3 particle layers: 412 x 3 = 1,236 particles) under an
    internal pressure p = 1 MPa ramped over one breathing period, damped at twice the breathing
    frequency and run 4 periods (kinetic energy below 1e-6 of the elastic; measured 5e-9): the
    hoop stress averaged over each layer and through the wall with the layers' shares (1/4, 1/2,
    1/4) is the thin-shell membrane stress p r / 2t, with r = a^2 / r_mean the hemisphere's force
    balance p a^2 / (b^2 - a^2) = 9.26 MPa (a = b - t), within 3 % (measured -0.3 %; +1.5 % with
    12.5 mm triangles, -0.6 % with 7 mm; p r_mean / 2t = 9.75 MPa). The support (2.5 x the
    90th-percentile edge, 25 mm) spans half the radius here: the quadratic fit across it smears
    the wall's through-thickness strain (the layers measured 10.3, 9.0, 8.6 MPa outer to inner
    against Lame's 9.0, 9.3, 9.5; 9.3, 9.2, 9.2 with 7 mm triangles) and the stabilisation holds a
    third of the stored energy (0.33; 0.13 with 7 mm triangles). The pressure acts on the INNER
    faces only and their net force vanishes (1e-12)."""
    b, t = 0.05, 0.0025
    a = b - t
    shell = shell_particles(_sphere_surface(tmp_path / "sphere.stl", b, 0.2), t, 3)
    n = len(shell.X)
    layer = np.arange(n) % 3
    r = np.linalg.norm(shell.X, axis=1)
    assert np.allclose(r[layer == 0], b) and np.allclose(r[layer == 2], a, rtol=0.01)
    assert np.all(shell.surface.particle[shell.surface.side == INNER] % 3 == 2)
    assert np.all(shell.surface.particle[shell.surface.side == OUTER] % 3 == 0)
    omega = math.sqrt(2.0 * E_AL / (RHO_AL * (1.0 - NU))) / (0.5 * (a + b))  # breathing, thin sphere
    p0 = 1e6
    load = Pressure(History.ramp(p0, 2.0 * math.pi / omega), EVERYWHERE, wall="inner")
    sim = build_meshfree_simulation(shell, RHO_AL, J2Law(E_AL, NU), pressures=[load], damping=2.0 * omega)
    dt = 0.7 * sim.stable_dt
    sim.advance(int(4 * 2.0 * math.pi / omega / dt), dt)
    terms = sim.energies(dt)
    assert terms["energy.kinetic"] < 1e-6 * terms["energy.elastic"]
    X = sim.particles.X
    normal = X / np.linalg.norm(X, axis=1)[:, None]
    s = sim.cauchy_stress()
    S = np.stack([s[:, [0, 3, 5]], s[:, [3, 1, 4]], s[:, [5, 4, 2]]], axis=1)
    radial = np.einsum("na,nab,nb->n", normal, S, normal)
    hoop = 0.5 * (np.trace(S, axis1=1, axis2=2) - radial)  # the mean of the two tangential stresses
    mean = 0.25 * hoop[layer == 0].mean() + 0.5 * hoop[layer == 1].mean() + 0.25 * hoop[layer == 2].mean()
    assert mean == pytest.approx(p0 * a**2 / (b**2 - a**2), rel=0.03)
    inner = shell.surface.side == INNER
    assert np.abs(shell.surface.area[inner].sum(axis=0)).max() < 1e-12 * np.abs(shell.surface.area[inner]).sum()


def test_open_surface_shell_walls_against_the_winding(tmp_path):
    """An open surface (the upper half of the sphere's triangles, z > 0 centroids) is walled too,
    against its triangles' right-hand normals (outwards here): 3 layers, the outer layer on the
    file's points, the faces on the file surface OUTER and on the offset one INNER, the rim's
    faces (normal to the wall) on neither; the cells still close (1e-12) and fill the walled
    mesh (volumes sum to the tets'); wall_frame's third row is the outward normal (its radial
    component above 0.99 on this 10 mm triangulation of a 50 mm sphere; measured 0.991)."""
    points, triangles = _unit_sphere_surface(0.2)
    upper = triangles[points[triangles].mean(axis=1)[:, 2] > 0.0]
    path = tmp_path / "cap.stl"
    meshio.write(path, meshio.Mesh(points * 0.05, [("triangle", upper)]))
    shell = shell_particles(path, 0.0025, 3)
    layer = np.arange(len(shell.X)) % 3
    assert np.allclose(np.linalg.norm(shell.X[layer == 0], axis=1), 0.05)
    row = _rows(shell.cells)
    closure = np.zeros_like(shell.X)
    np.add.at(closure, row, shell.cells.weight)
    assert np.abs(closure).max() < 1e-12 * np.abs(shell.cells.weight).max()
    radial = shell.X / np.linalg.norm(shell.X, axis=1)[:, None]
    assert np.einsum("na,na->n", shell.wall_frame[:, 2], radial).min() > 0.99
    side = shell.surface.side
    assert np.all(layer[shell.surface.particle[side == OUTER]] == 0)
    assert np.all(layer[shell.surface.particle[side == INNER]] == 2)
    # The outer faces cover the cap's triangles: the same total area vector.
    P = points[upper] * 0.05
    cap = 0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]).sum(axis=0)
    assert np.abs(shell.surface.area[side == OUTER].sum(axis=0) - cap).max() < 1e-12 * np.abs(cap).max()


MESH = """
name = "mf-mesh"
method = "meshfree"

[specimen]
shape = "mesh"
file = "bar.vtu"

[material]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3

[[tools]]
name = "ball"
shape = "sphere"
radius = 0.005
center = [0.04, 0.01, 0.0251]
direction = [0.0, 0.0, -1.0]
speed = 20.0

[[supports]]
kind = "fixed"
where = { box_min = [-0.001, -0.001, -0.001], box_max = [0.081, 0.021, 0.0001] }

[run]
end_time = 2e-6
history_samples = 5
field_frames = 1
"""

SHELL = """
name = "mf-shell"
method = "meshfree"

[specimen]
shape = "shell"
file = "sphere.stl"
wall = 0.0025

[particles]
layers = 3

[material]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3

[[pressures]]
faces = "where"
where = { box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }
wall = "inner"
value = 1e6

[run]
end_time = 2e-6
history_samples = 5
field_frames = 0
"""


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mfmesh")
    mesh = gmsh_box(BAR, 0.008)
    meshio.write(folder / "bar.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    _sphere_surface(folder / "sphere.stl", 0.05, 0.3)
    (folder / "mesh.toml").write_text(MESH)
    (folder / "shell.toml").write_text(SHELL)
    return folder, mesh.n_points


@pytest.mark.parametrize("name", ["mesh", "shell"])
def test_mesh_and_shell_scenarios_run(scenario_dir, tmp_path, name):
    """The shapes "mesh" (the bar's nodes, 8 mm tets; a ball pressing) and "shell" (a sphere
    walled from an STL, 3 layers, internal pressure) through the command line: they complete a
    few steps and summary.json has method "meshfree" and the particle count (the mesh's nodes;
    3 per surface node), layers 0 for the solid."""
    folder, n_nodes = scenario_dir
    out = tmp_path / "o"
    assert main(["run", str(folder / f"{name}.toml"), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["method"] == "meshfree" and s["status"] == "completed" and s["steps"] > 0
    if name == "mesh":
        assert s["particles"] == n_nodes and s["layers"] == 0
    else:
        assert s["particles"] % 3 == 0 and s["layers"] == 3
    assert abs(s["energy_error"]) < 0.01


@pytest.mark.parametrize("name, overrides, field", [
    ("mesh", ["particles.spacing=0.002"], "particles.spacing"),
    ("mesh", ["particles.layers=3"], "particles.layers"),
    ("mesh", ["specimen.size=[0.1, 0.1, 0.1]"], "size"),
    ("mesh", ["specimen.wall=0.001"], "wall"),
    ("mesh", ['specimen.file="missing.vtu"'], "specimen.file"),
    ("mesh", ["particles.dilation=1.0"], "particles.dilation"),
    ("shell", ["particles.layers=2"], "particles.layers"),
    ("shell", ['specimen.file="missing.stl"'], "specimen.file"),
    ("shell", ["specimen.origin=[0.0, 0.0, 0.0]"], "origin"),
    ("shell", ["specimen.suture_wall=0.002"], "suture_wall"),
    ("shell", ["specimen.wall=0.03"], "specimen.wall"),
])
def test_bad_mesh_and_shell_input_exits_2(scenario_dir, tmp_path, capsys, name, overrides, field):
    folder, _ = scenario_dir
    args = ["run", str(folder / f"{name}.toml"), "--out", str(tmp_path / "o")]
    for o in overrides:
        args += ["--set", o]
    assert main(args) == 2
    assert field in capsys.readouterr().err


@pytest.mark.parametrize("remove, field", [("wall = 0.0025\n", "wall"), ('file = "sphere.stl"\n', "file")])
def test_shell_needs_its_wall_and_file(scenario_dir, tmp_path, capsys, remove, field):
    """shape = "shell" without wall or file exits 2 naming it (FDEM's walnut wall is not taken)."""
    folder, _ = scenario_dir
    path = folder / f"no-{field}.toml"
    path.write_text(SHELL.replace(remove, ""))
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert field in capsys.readouterr().err

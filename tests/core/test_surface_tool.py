"""Rigid tools made of triangle surfaces (shape "surface"): STL or any meshio surface file, or
arrays (e.g. from gmsh), in penalty contact with Coulomb friction through the same tool path as
the analytic tools."""

from __future__ import annotations

import math
import warnings

import meshio
import numpy as np
import pytest
from numba import njit

from crackle.cli import main
from crackle.loading.tools import tool_gap
from crackle.fdem.model import build_fdem_model
from crackle.fdem.simulation import FdemSimulation
from crackle.geometry import structured_box
from crackle.io import read_history_csv
from crackle.loading import History, Tool, load_surface
from crackle.fdem.laws import GuoMunjizaLaw
from crackle.materials import Material


def _elastic(friction=0.3, penalty_factor=200.0):
    """Rock elasticity (paper 001 Table 1) with interfaces too strong to break: pure contact."""
    law = GuoMunjizaLaw(3e9, 15e9, 30.0, 1e6, friction=friction, penalty_factor=penalty_factor)
    return Material(2340.0, 26e9, 0.2, law, name="elastic rock")


def _square(path, half=0.1, z=0.0, down=False, rotate=None, binary=False):
    """A flat square of two triangles at height z, normal +z (or -z with down=True), optionally
    rotated by the matrix `rotate`, written with meshio (ASCII STL keeps float64 coordinates
    exactly; binary STL rounds them to float32)."""
    pts = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    if down:
        tris = tris[:, ::-1]
    if rotate is not None:
        pts = pts @ np.asarray(rotate).T
    meshio.write(path, meshio.Mesh(pts, [("triangle", tris)]), binary=binary)
    return str(path)


def _build(mesh, tools, penalty_factor=200.0, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return build_fdem_model(mesh, _elastic(penalty_factor=penalty_factor), tools=tools, **kw)


def _still(name, friction, **kw):
    return dict(name=name, direction=(0, 0, 1), speed=History.constant(0.0), friction=friction, **kw)


def test_flat_stl_base_and_platen_match_plane_tools(tmp_path):
    """A 384-tet block thrown at 0.5 m/s down and 0.3 m/s sideways onto a two-triangle STL base
    (friction 0.3) while a two-triangle STL platen (normals down) moves down onto it at 1 m/s:
    for a flat surface the gap and normal are those of the plane tool, so over 1000 steps both
    tools' sampled force histories equal those of `plane` tools to 1e-9 of the peak force, and
    the final node positions to 1e-12 m."""
    mesh = structured_box((0.02, 0.02, 0.02), 0.005)
    base_file = _square(tmp_path / "base.stl")
    top_file = _square(tmp_path / "top.stl", z=0.020002, down=True)
    down = dict(direction=(0, 0, -1), speed=History.constant(1.0), friction=0.2)
    plane = [
        Tool(shape="plane", center=(0, 0, 0), normal=(0, 0, 1), **_still("base", 0.3)),
        Tool("top", "plane", center=(0, 0, 0.020002), normal=(0, 0, -1), **down),
    ]
    surface = [
        Tool(shape="surface", surface=base_file, **_still("base", 0.3)),
        Tool("top", "surface", surface=top_file, **down),
    ]
    runs = []
    for tools in (plane, surface):
        model = _build(mesh, tools, initial_velocity=(0.3, 0.0, -0.5))
        sim = FdemSimulation(model)
        dt = 0.8 * model.stable_dt
        forces = []
        for _ in range(20):
            sim.advance(50, dt)
            forces.append(sim.tool_forces())
        runs.append((np.array(forces), model.nodes.x.copy(), dt))
    (f_plane, x_plane, dt_p), (f_surf, x_surf, dt_s) = runs
    assert dt_p == dt_s
    peak = np.abs(f_plane).max()
    assert peak > 100.0, "both tools must have touched the block"
    assert np.all(np.abs(f_plane[:, :, 2]).max(axis=0) > 0.1 * peak)
    print("force diff / peak", np.abs(f_surf - f_plane).max() / peak, "x diff", np.abs(x_surf - x_plane).max())
    assert np.abs(f_surf - f_plane).max() <= 1e-9 * peak
    assert np.abs(x_surf - x_plane).max() <= 1e-12


def _block_on_tilted_stl(tmp_path, theta_deg, mu, t_settle=1.5e-3, t_slide=3e-3):
    """A 20 mm block (48 tets; interface penalty factor 20 for a 3x longer time step) resting on
    an STL square tilted by theta about y (friction mu), block and surface rotated together. It
    first settles under the normal part of gravity with damping; then damping is removed and the
    full vertical gravity acts. Returns the block's mean
    velocity down the slope gained over t_slide, and t_slide."""
    th = math.radians(theta_deg)
    rot = np.array([[math.cos(th), 0.0, math.sin(th)], [0.0, 1.0, 0.0], [-math.sin(th), 0.0, math.cos(th)]])
    normal, downhill = rot[:, 2], rot[:, 0]
    mesh = structured_box((0.02, 0.02, 0.02), 0.01, origin=(-0.01, -0.01, 0.0))
    mesh.points[:] = mesh.points @ rot.T
    tool = Tool(shape="surface", surface=_square(tmp_path / f"incline{theta_deg:.3f}.stl", rotate=rot), **_still("incline", mu))
    g = 9.81
    model = _build(mesh, [tool], penalty_factor=20.0, gravity=-g * math.cos(th) * normal, damping=2000.0)
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    sim.advance(int(t_settle / dt), dt)
    model.controls.damping[0] = 0.0
    model.controls.gravity[:] = (0.0, 0.0, -g)
    along = lambda: float(np.average(model.nodes.v @ downhill, weights=model.nodes.mass))  # noqa: E731
    v0 = along()
    steps = int(t_slide / dt)
    sim.advance(steps, dt)
    return along() - v0, steps * dt


@pytest.mark.parametrize("delta", [-3.0, 3.0])
def test_block_slides_on_tilted_stl_iff_tan_theta_exceeds_mu(tmp_path, delta):
    """Coulomb on a tilted triangle surface, mu = 0.5: at theta = atan(mu) - 3 deg the block
    sticks (speed gained below 1 % of the free-slide speed g (sin - mu cos) t at +3 deg); at
    atan(mu) + 3 deg it slides, at between 0.5 and 2 times that speed (as for the plane tool in
    test_fdem_contact.py: the block's vibration lowers the effective friction a little)."""
    mu = 0.5
    v, t = _block_on_tilted_stl(tmp_path, math.degrees(math.atan(mu)) + delta, mu)
    th = math.atan(mu) + math.radians(3.0)
    slide = 9.81 * (math.sin(th) - mu * math.cos(th)) * t
    print(f"delta {delta}: v {v:.4g} m/s, free slide {slide:.4g} m/s")
    if delta < 0:
        assert abs(v) < 0.01 * slide
    else:
        assert 0.5 * slide < v < 2.0 * slide


# ------------------------------------------------------------------------------------------------
# Geometry: orientation, broad phase, a gmsh-generated surface.


def _tet_surface(inward=False):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) * 0.01
    tris = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward
    return pts, (tris[:, ::-1] if inward else tris)


def test_closed_surface_is_oriented_outwards_and_open_one_kept(tmp_path):
    """A closed surface (a tet of 10 mm legs, in a .obj file, scale 10) wound inwards is flipped:
    its enclosed volume after loading is +(0.1 m)^3 / 6 to 1e-12 relative; an open surface
    keeps its winding (normal -z stays -z); a closed surface with one triangle flipped is
    refused, as is a file without triangles."""
    pts, tris = _tet_surface(inward=True)
    meshio.write(tmp_path / "tet.obj", meshio.Mesh(pts, [("triangle", tris)]))
    v, t = load_surface(tmp_path / "tet.obj", scale=10.0, offset=(1.0, 2.0, 3.0))
    p0, p1, p2 = (v[t[:, i]] - (1.0, 2.0, 3.0) for i in range(3))
    assert np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0 == pytest.approx(0.1**3 / 6.0, rel=1e-12)
    down = Tool(shape="surface", vertices=[[0, 0, 0], [0, 1, 0], [1, 0, 0]], triangles=[[0, 1, 2]], **_still("d", 0.0))
    n = np.cross(down.vertices[1] - down.vertices[0], down.vertices[2] - down.vertices[0])
    assert n[2] < 0
    bad = tris.copy()
    bad[0] = bad[0, ::-1]
    with pytest.raises(ValueError, match="wound consistently"):
        Tool(shape="surface", vertices=pts, triangles=bad, **_still("b", 0.0))
    meshio.write(tmp_path / "lines.vtu", meshio.Mesh(pts, [("line", np.array([[0, 1], [1, 2]]))]))
    with pytest.raises(ValueError, match="no triangles"):
        load_surface(tmp_path / "lines.vtu")


@njit
def _gaps(j, points, tools):
    out = np.empty((len(points), 4))
    for i in range(len(points)):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = tool_gap(j, points[i, 0], points[i, 1], points[i, 2], 0.0, tools)
    return out


def _brute_force(points, v, t, depth, tol=0.01):
    """The kernel's rule over all triangles, in numpy: among the triangles whose projection
    holds the point and whose plane is less than depth away, the nearest; contact if behind it."""
    p0 = v[t[:, 0]]
    e1, e2 = v[t[:, 1]] - p0, v[t[:, 2]] - p0
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d00, d01, d11 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    r = points[:, None, :] - p0[None]
    gap = (r * n).sum(2)
    d20, d21 = (r * e1).sum(2), (r * e2).sum(2)
    den = d00 * d11 - d01 * d01
    l1 = (d11 * d20 - d01 * d21) / den
    l2 = (d00 * d21 - d01 * d20) / den
    ok = (np.abs(gap) < depth) & (l1 >= -tol) & (l2 >= -tol) & (1 - l1 - l2 >= -tol)
    best = np.where(ok, np.abs(gap), np.inf).argmin(axis=1)
    g = gap[np.arange(len(points)), best]
    hit = ok.any(axis=1) & (g < 0)
    return np.where(hit, g, np.inf), n[best], hit


def test_gmsh_sphere_surface_grid_matches_brute_force_and_analytic_sphere():
    """A 10 mm sphere surface meshed by gmsh (about 1 mm triangles), given as arrays, moved by
    (3, -2, 5) mm: at 3000 random points within 3 mm of its surface the grid look-up finds
    exactly the contacts of a search over all triangles, with gaps equal to 1e-15 m; inside, the
    gap matches the analytic sphere to the facets' sagitta (measured, < 0.05 mm) and the normal
    to 6 degrees; points deeper than the contact depth, or outside, are not in contact."""
    import gmsh

    R, h = 0.01, 0.001
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("sphere_tool")
        gmsh.model.occ.addSphere(0, 0, 0, R)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, elem_nodes = gmsh.model.mesh.getElementsByType(2)
    finally:
        gmsh.finalize()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    vertices = coords.reshape(-1, 3)
    triangles = index[elem_nodes.astype(np.int64)].reshape(-1, 3)
    tool = Tool(shape="surface", vertices=vertices, triangles=triangles, **_still("ball", 0.0))
    specimen = structured_box((0.005, 0.005, 0.005), 0.0025, origin=(0.1, 0.1, 0.1))  # far away; sets the depth
    model = _build(specimen, [tool])
    tools = model.tools
    depth = tools.geom[0, 4]
    shift = np.array([0.003, -0.002, 0.005])
    tools.disp[0] = shift
    rng = np.random.default_rng(7)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radius = R + rng.uniform(-3e-3, 1e-3, size=(3000, 1))
    points = shift + radius * d
    got = _gaps(0, points, tools)
    gap_bf, n_bf, hit_bf = _brute_force(points - shift, tool.vertices, tool.triangles, depth)
    hit = np.isfinite(got[:, 0]) & (got[:, 0] < 0)
    assert 0 < depth < 3e-3 and hit.sum() > 500
    assert np.array_equal(hit, hit_bf)
    assert np.abs(got[hit, 0] - gap_bf[hit]).max() <= 1e-15
    assert np.array_equal(got[hit, 1:], n_bf[hit])
    # Largest distance between a facet's plane and the sphere: the faceting error of the gap.
    p0 = tool.vertices[tool.triangles[:, 0]]
    n = np.cross(tool.vertices[tool.triangles[:, 1]] - p0, tool.vertices[tool.triangles[:, 2]] - p0)
    sagitta = R - np.min(np.abs(np.einsum("ij,ij->i", n, p0)) / np.linalg.norm(n, axis=1))
    assert 0 < sagitta < 0.05e-3
    exact = radius[:, 0] - R
    assert np.all(exact[hit] < sagitta)
    assert np.abs(got[hit, 0] - exact[hit]).max() < sagitta
    cos = np.einsum("ij,ij->i", got[hit, 1:], d[hit])
    assert cos.min() > math.cos(math.radians(6.0))
    assert not np.any(hit & ((exact < -depth - sagitta) | (exact > sagitta)))
    assert np.all(hit[(exact < -sagitta) & (exact > -depth + sagitta)])


# ------------------------------------------------------------------------------------------------
# Scenario files and the command line.

SCENARIO = """
name = "drop-on-stl"
[specimen]
shape = "box"
size = [0.02, 0.02, 0.02]
element_size = 0.01
initial_velocity = [0.0, 0.0, -0.5]

[material]
density = 2340.0
youngs_modulus = 26e9
poissons_ratio = 0.2

[material.interface]
tensile_strength = 3e9
cohesion = 15e9
friction_angle = 30.0
fracture_energy = 1e6

[[tools]]
name = "base"
direction = [0.0, 0.0, 1.0]
friction = 0.3
TOOL

[run]
end_time = 2e-5
history_samples = 10
field_frames = 0
"""


def _cli(tmp_path, capsys, tool_keys, name):
    path = tmp_path / f"{name}.toml"
    path.write_text(SCENARIO.replace("TOOL", tool_keys))
    code = main(["run", str(path), "--out", str(tmp_path / name)])
    return code, capsys.readouterr().err


def test_scenario_surface_tool_in_mm_matches_plane(tmp_path, capsys):
    """`shape = "surface"` from a scenario: an STL in mm (scale = 1e-3) lying at z = 5 mm,
    shifted by offset = -5 mm to z = 0, relative to the scenario's folder, catches a block
    dropped at 0.5 m/s exactly like a plane tool at z = 0: the history's base force columns
    agree to 1e-9 of the peak force (which is above 100 N)."""
    (tmp_path / "parts").mkdir()
    _square(tmp_path / "parts" / "base_mm.stl", half=100.0, z=5.0)
    surface = 'shape = "surface"\nfile = "parts/base_mm.stl"\nscale = 1e-3\noffset = [0.0, 0.0, -0.005]'
    code, err = _cli(tmp_path, capsys, surface, "surface")
    assert code == 0, err
    code, err = _cli(tmp_path, capsys, 'shape = "plane"\nnormal = [0.0, 0.0, 1.0]', "plane")
    assert code == 0, err
    cols = [f"tool.base.f{a}" for a in "xyz"]
    a = read_history_csv(tmp_path / "surface" / "history.csv")
    b = read_history_csv(tmp_path / "plane" / "history.csv")
    a, b = (np.stack([h[c] for c in cols], axis=1) for h in (a, b))
    peak = np.abs(b).max()
    assert peak > 100.0
    assert np.abs(a - b).max() <= 1e-9 * peak


@pytest.mark.parametrize(
    "setup, keys, expected",
    [
        (None, 'shape = "surface"\nfile = "nowhere.stl"', ["tools.0.file", "nowhere.stl", "does not exist"]),
        ("garbage", 'shape = "surface"\nfile = "garbage.stl"', ["tools.0.file", "garbage.stl", "cannot read"]),
        ("lines", 'shape = "surface"\nfile = "lines.vtu"', ["tools.0.file", "lines.vtu", "no triangles"]),
        (None, 'shape = "surface"', ["tools.0", "needs file"]),
        (None, 'shape = "plane"\nfile = "base.stl"', ["tools.0", "only for shape"]),
    ],
)
def test_bad_surface_tool_exits_2_naming_the_field(tmp_path, capsys, setup, keys, expected):
    """A missing, unreadable or triangle-less surface file, a surface tool without a file, or a
    file on another shape: exit code 2, one line naming the field (tools.0.file / tools.0) and
    the file, no traceback, nothing written."""
    if setup == "garbage":
        (tmp_path / "garbage.stl").write_text("this is not a mesh")
    elif setup == "lines":
        meshio.write(tmp_path / "lines.vtu", meshio.Mesh(np.eye(3), [("line", np.array([[0, 1], [1, 2]]))]))
    code, err = _cli(tmp_path, capsys, keys, "out")
    assert code == 2
    for text in expected:
        assert text in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_thin_closed_plate_pushes_out_through_the_nearest_face():
    """A closed 40 x 40 x 0.5 mm plate (12 triangles), thinner than the 1.5 mm contact depth:
    points above it (0 to 1 mm) or beside it (0.01 to 0.2 mm off a side face) are not in contact,
    although they lie behind the far face's plane within the depth; points inside are, with the
    gap and normal of the nearer of the two large faces (to 1e-15 m)."""
    from scipy.spatial import ConvexHull

    t = 0.5e-3
    corners = np.array([[x, y, z] for x in (-0.02, 0.02) for y in (-0.02, 0.02) for z in (-t / 2, t / 2)])
    tris = ConvexHull(corners).simplices
    p0 = corners[tris[:, 0]]
    n = np.cross(corners[tris[:, 1]] - p0, corners[tris[:, 2]] - p0)
    outward = np.einsum("ij,ij->i", n, corners[tris].mean(axis=1)) > 0
    tris = np.where(outward[:, None], tris, tris[:, ::-1])
    tool = Tool(shape="surface", vertices=corners, triangles=tris, **_still("plate", 0.0))
    specimen = structured_box((0.005, 0.005, 0.005), 0.0025, origin=(0.1, 0.1, 0.1))  # far away; sets the depth
    tools = _build(specimen, [tool]).tools
    assert tools.geom[0, 4] > 2.5 * t
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.019, 0.019, size=(500, 2))
    above = np.column_stack([xy, t / 2 + rng.uniform(1e-6, 1e-3, 500)])
    below = np.column_stack([xy, -t / 2 - rng.uniform(1e-6, 1e-3, 500)])
    beside = np.column_stack([0.02 + rng.uniform(1e-5, 2e-4, 500), xy[:, 1], rng.uniform(-0.05e-3, 0.05e-3, 500)])
    for outside in (above, below, beside):
        assert np.all(np.isinf(_gaps(0, outside, tools)[:, 0]))
    z = rng.uniform(-t / 2 + 1e-6, t / 2 - 1e-6, 500)
    got = _gaps(0, np.column_stack([xy, z]), tools)
    expect = -(t / 2 - np.abs(z))
    assert np.abs(got[:, 0] - expect).max() <= 1e-15
    assert np.array_equal(got[:, 3], np.sign(z))

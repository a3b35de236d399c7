"""The outputs a user looks at first (issue 44): the fields each method writes, read back as
ParaView reads them (meshio), and the status a polling tool reads."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from crackle.cli import main


def _last_frame(out):
    return meshio.read(sorted((out / "fields").glob("*.vtu"))[-1])


def test_dem_fields_carry_bond_forces_and_particle_ids(tmp_path):
    """The quick UCS sample after 100 steps: its VTU has per bond line `normal_force` and
    `shear_force` (N, one value per bond, finite, the platens' load in some of them) and per point
    `id` (0..n-1 on the particles, -1 on the stress grid's corners)."""
    out = tmp_path / "ucs"
    assert main(["run", "dem-ucs", "--quick", "--set", "run.end_time=5e-6", "--set", "run.field_frames=1",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    mesh = _last_frame(out)
    lines = [k for k, block in enumerate(mesh.cells) if block.type == "line"]
    assert len(lines) == 1 and len(mesh.cells[lines[0]].data) == summary["bonds"]
    for name in ("normal_force", "shear_force"):
        values = mesh.cell_data[name][lines[0]]
        assert values.shape == (summary["bonds"],) and np.all(np.isfinite(values))
    normal = mesh.cell_data["normal_force"][lines[0]]
    assert normal.min() < 0.0  # the platens press: some bonds in compression
    assert np.all(mesh.cell_data["shear_force"][lines[0]] >= 0.0)
    ids = mesh.point_data["id"]
    particles = summary["particles"]
    assert ids[:particles].tolist() == list(range(particles)) and np.all(ids[particles:] == -1)


def test_status_json_follows_the_run(tmp_path):
    """status.json in the output folder: at the end, the run's state, its steps and the fraction
    done (1), as a tool polling a cluster job reads it."""
    out = tmp_path / "beam"
    assert main(["run", "three-point-bending", "--quick", "--set", "run.end_time=2e-5", "--out", str(out)]) == 0
    status = json.loads((out / "status.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    assert status["state"] == summary["status"] == "completed"
    assert status["steps"] == summary["steps"] and status["fraction"] == 1.0 and status["broken"] == summary["broken"]


def test_sweep_plots_name_the_scenario_and_the_units(tmp_path, monkeypatch):
    """plots/sweep_KEY.png: a title with the scenario and what is plotted, units in brackets from
    the schema (the varied key) and from the summary's units (the scalars)."""
    import crackle.io.plots as plots
    from crackle.sweep.table import plot_against

    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig))
    records = [{"material.interface.tensile_strength": t, "status": "completed", "peak_force": 1e3 * t / 1e6,
                "energy_error": 1e-3} for t in (2e6, 3e6, 4e6)]
    plot_against(tmp_path / "p.png", "material.interface.tensile_strength", ["material.interface.tensile_strength"],
                 records, ["peak_force", "energy_error"], "three-point-bending")
    axes = figures[0].axes
    assert axes[0].get_title() == "three-point-bending: peak_force, energy_error against tensile_strength"
    assert [ax.get_ylabel() for ax in axes] == ["peak_force [N]", "energy_error [-]"]
    assert axes[-1].get_xlabel() == "material.interface.tensile_strength [Pa]"


def test_key_units_come_from_the_schema():
    from crackle.keys import key_unit

    assert key_unit("three-point-bending", "tools.top.speed") == "m/s"
    assert key_unit("three-point-bending", "tools.0.speed") == "m/s"
    assert key_unit("brazilian-disc", "loading.angle") == "degrees"
    assert key_unit("walnut-crush", "material.interface.fracture_energy") == "J/m^2"
    assert key_unit("dem-ucs", "packing.seed") is None  # a number without a unit


def test_a_crowded_crack_pattern_shows_slices(tmp_path, monkeypatch):
    """10,000 failures spread through a 27 x 12 x 54 mm sample: each view shows the slice a tenth
    of the depth thick through the middle (about 1,000 each), and says so in its title."""
    import crackle.io.plots as plots

    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig))
    rng = np.random.default_rng(0)
    n = 10_000
    size = np.array([0.027, 0.012, 0.054])
    xyz = rng.random((n, 3)) * size
    events = {"time": rng.random(n) * 1e-3, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
              "mode": np.array(["tension"] * n)}
    plots.plot_crack_pattern(events, ((0.0, 0.0, 0.0), tuple(size)), tmp_path / "c.png")
    axes = figures[0].axes[:3]
    assert [ax.get_title().split(",")[0] for ax in axes] == ["xy slice", "xz slice", "yz slice"]
    for ax, k in zip(axes, (2, 1, 0)):
        inside = int(np.count_nonzero(np.abs(xyz[:, k] - 0.5 * size[k]) <= 0.05 * size[k]))
        assert f"({inside:,} of 10,000)" in ax.get_title() and 800 < inside < 1200


def test_shell_fields_carry_the_membrane_force_of_a_uniform_strain():
    """The shell-tear plate (E, nu, t of its scenario) stretched uniformly along x by 2^-10 (exact
    in binary): every triangle's membrane_force has N_xx = E t e / (1 - nu^2) and N_yy = nu N_xx
    within 1e-9, e the Green strain (1 + 2^-10)^2 / 2 - 1/2 that membrane_strain reports, the
    rest zero (issue 44)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario("shell-tear", quick=True)
    sim = build_simulation(scenario, base)[0]
    mesh = sim.shell.mesh
    stretch = 2.0**-10
    sim.nodes.x[:] = mesh.X
    sim.nodes.x[:, 0] = mesh.X[:, 0] * (1.0 + stretch)
    fields = sim.fields()
    name, cells, data = fields["blocks"][0]
    assert name == "triangle" and data["membrane_force"].shape == (len(cells), 6)
    e = 0.5 * ((1.0 + stretch) ** 2 - 1.0)
    E, nu, t = scenario.material.youngs_modulus, scenario.material.poissons_ratio, scenario.shell.thickness
    strain, force = data["membrane_strain"], data["membrane_force"]
    assert np.allclose(strain[:, 0], e, rtol=1e-9, atol=0.0) and np.all(np.abs(strain[:, 1:]) < 1e-9 * e)
    n_xx = E * t * e / (1.0 - nu**2)
    assert np.allclose(force[:, 0], n_xx, rtol=1e-9, atol=0.0)
    assert np.allclose(force[:, 1], nu * n_xx, rtol=1e-9, atol=0.0)
    assert np.all(np.abs(force[:, 2:]) < 1e-9 * n_xx)
    assert np.all(data["bending_energy"] < 1e-12 * n_xx * e)  # flat: no bending


def test_shell_vtu_has_membrane_fields(tmp_path):
    """The quick shell-tear run's last frame read back: membrane_strain, membrane_force and
    bending_moment (6 components per triangle) and bending_energy (one per triangle), finite."""
    out = tmp_path / "tear"
    assert main(["run", "shell-tear", "--quick", "--set", "run.end_time=5e-5", "--set", "run.field_frames=1",
                 "--out", str(out)]) == 0
    mesh = _last_frame(out)
    triangles = len(mesh.cells[0].data)
    assert mesh.cells[0].type == "triangle"
    assert mesh.cell_data["membrane_force"][0].shape == (triangles, 6)
    assert mesh.cell_data["membrane_strain"][0].shape == (triangles, 6)
    assert mesh.cell_data["bending_moment"][0].shape == (triangles, 6)
    assert mesh.cell_data["bending_energy"][0].shape == (triangles,)
    assert all(np.all(np.isfinite(mesh.cell_data[k][0]))
               for k in ("membrane_force", "membrane_strain", "bending_moment", "bending_energy"))


@pytest.fixture(scope="module")
def centre_crack(tmp_path_factory):
    """shell-centre-crack's quick form run to its end (quasi-static under 100 MPa): (the output
    folder, its summary, every figure's ("suptitle|first axes' title", [(line label, xy)]) as
    written)."""
    import crackle.io.plots as plots

    out = tmp_path_factory.mktemp("centre") / "crack"
    figures = []
    save = plots._save

    def keep(fig, path):
        figures.append((fig.get_suptitle() + "|" + fig.axes[0].get_title(),
                        [(line.get_label(), line.get_xydata().copy()) for line in fig.axes[0].get_lines()]))
        return save(fig, path)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plots, "_save", keep)
        assert main(["run", "shell-centre-crack", "--quick", "--out", str(out)]) == 0
    return out, json.loads((out / "summary.json").read_text()), figures


def _figure(figures, title):
    """The lines of the last figure with that title (the shell redraws its crack pattern)."""
    return [lines for names, lines in figures if any(name.startswith(title) for name in names.split("|"))][-1]


def test_shell_centre_crack_plots_j_and_g_over_time(centre_crack):
    """plots/j_history.png: J and G of both tips against time and the closed form (the summary's
    j_reference) as a line; history.csv's last g.tip0 is the summary's energy_release_rate (the
    same state, within 1e-12), and G follows J in plane (paper 002: they are the same integral
    for in-plane loading; within 1e-3 at the end)."""
    from crackle.io import read_history_csv

    out, summary, figures = centre_crack
    assert (out / "plots" / "j_history.png").stat().st_size > 0
    lines = _figure(figures, "Energy release")
    assert [label for label, _ in lines] == ["J, tip 0", "G, tip 0", "J, tip 1", "G, tip 1", "closed form"]
    assert lines[-1][1][0, 1] == summary["j_reference"]
    history = read_history_csv(out / "history.csv")
    assert history["g.tip0"][-1] == pytest.approx(summary["energy_release_rate"], rel=1e-12)
    assert history["g.tip0"][-1] == pytest.approx(history["j.tip0"][-1], rel=1e-3)
    assert summary["j_static"] is True and not any("still moved" in w for w in summary["warnings"])


def test_shell_edge_loads_make_a_load_displacement_curve(centre_crack):
    """An edge-loaded shell's load_displacement.png has the curve "edge loads": at the end the
    force is both ends' 100 MPa x 100 mm x 1 mm (20 kN, within 1e-12) and the area under
    force against displacement is the external work the energy audit books (energy.external,
    within 1e-3: the trapezoid over ~100 samples)."""
    from crackle.io import read_history_csv

    out, _, figures = centre_crack
    history = read_history_csv(out / "history.csv")
    force, displacement = history["edge_load.force"], history["edge_load.displacement"]
    assert force[-1] == pytest.approx(2 * 100e6 * 0.1 * 0.001, rel=1e-12)
    assert np.trapezoid(force, displacement) == pytest.approx(history["energy.external"][-1], rel=1e-3)
    assert [label for label, _ in _figure(figures, "Load-displacement")] == ["edge loads"]


def test_shell_crack_faces_are_line_cells_with_the_opening(centre_crack):
    """The last frame's crack faces: 2 x 10 line cells (both faces of the 50 mm pre-crack's
    ten 5 mm edges), crack_opening the same on both faces of an edge, symmetric about the
    centre, and at the middle within 15 % of the closed form 2v = 4 sigma a / E V1(a/b)
    sqrt(1 - x^2/a^2) (Tada's centre-cracked strip, V1(0.5) = 1.191; the 5 mm triangles are
    stiffer: 0.87 of it here)."""
    out, _, _ = centre_crack
    mesh = _last_frame(out)
    kinds = [block.type for block in mesh.cells]
    assert kinds == ["triangle", "line"] and len(mesh.cells[1].data) == 20
    opening = mesh.cell_data["crack_opening"][1]
    assert np.all(opening[0::2] == opening[1::2]) and np.all(opening > 0.0)
    x = mesh.points[mesh.cells[1].data].mean(axis=1)[0::2, 0]
    by_x = opening[0::2][np.argsort(x)]
    assert np.allclose(by_x, by_x[::-1], rtol=1e-6)
    sigma, E, a, ratio = 100e6, 200e9, 0.025, 0.5
    v1 = -0.071 - 0.535 * ratio + 0.169 * ratio**2 + 0.020 * ratio**3 - 1.071 / ratio * np.log(1.0 - ratio)
    middle = np.argmin(np.abs(x))
    closed = 4 * sigma * a / E * v1 * np.sqrt(1.0 - (x[middle] / a) ** 2)
    assert opening[0::2][middle] == pytest.approx(closed, rel=0.15)
    assert np.all(mesh.cell_data["crack_opening"][0] == 0.0)


def test_shell_crack_pattern_draws_the_pre_crack(centre_crack):
    """shell-centre-crack (no growth in its quick form): crack_pattern.png draws the pre-crack as
    cut, from -25 to 25 mm along x at y = 0 (the chain of edges nearest the polyline)."""
    _, _, figures = centre_crack
    pre = [xy for label, xy in _figure(figures, "Crack pattern") if label == "pre-crack"]
    assert len(pre) == 1
    assert pre[0][:, 0].min() == pytest.approx(-25.0, abs=1e-9) and pre[0][:, 0].max() == pytest.approx(25.0, abs=1e-9)
    assert np.all(np.abs(pre[0][:, 1]) < 1e-9)


def test_crack_faces_pair_the_cut_edges_only():
    """ShellMesh.crack_faces on a 4 x 2 rectangle: none before a cut; a cut along two edges of
    the middle line gives exactly those two edge pairs, each pair on the same reference points."""
    from crackle.shell.mesh import edge_path, rectangle, split_along

    mesh = rectangle(0.4, 0.2, 4, 2, 0.01)
    assert mesh.crack_faces().shape == (0, 2)
    cut, _ = split_along(mesh, edge_path(mesh, [[0.0, 0.1, 0.0], [0.2, 0.1, 0.0]]))
    pairs = cut.crack_faces()
    assert pairs.shape == (2, 2)
    ends = np.sort(cut.X[cut.edge[pairs]][..., 0], axis=2)  # (pair, face, end) x
    assert np.array_equal(ends[:, 0], ends[:, 1])
    assert np.all(np.abs(cut.X[cut.edge[pairs]][..., 1] - 0.1) < 1e-12)


def test_shell_bending_moment_of_a_cylindrical_bend():
    """The shell-tear plate bent onto a cylinder of radius 1 m about y (x = R sin(X/R), z = R (1 -
    cos(X/R))): every triangle without a free edge has M_xx = -D / R (D = E t^3 / 12 (1 - nu^2);
    negative for a bend towards the surface's normal), M_yy = nu M_xx and M_xy = 0, within 1e-9
    (issue 44: the moment tensor the bending form H implies)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario("shell-tear", quick=True)
    sim = build_simulation(scenario, base)[0]
    shell = sim.shell
    X, R = shell.mesh.X, 1.0
    x = X.copy()
    x[:, 0] = R * np.sin(X[:, 0] / R)
    x[:, 2] = R * (1.0 - np.cos(X[:, 0] / R))
    moment = shell.bending_moment_state(x)
    E, nu, t = scenario.material.youngs_modulus, scenario.material.poissons_ratio, scenario.shell.thickness
    D = E * t**3 / (12.0 * (1.0 - nu**2))
    inner = ~shell.mesh.boundary[shell.mesh.face_edge].any(axis=1)
    assert inner.sum() > 0.8 * len(moment)
    assert np.allclose(moment[inner, 0], -D / R, rtol=1e-9, atol=0.0)
    assert np.allclose(moment[inner, 1], -nu * D / R, rtol=1e-9, atol=0.0)
    assert np.all(np.abs(moment[inner, 2:]) < 1e-9 * D / R)

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


def test_shell_centre_crack_plots_its_j_history(tmp_path, monkeypatch):
    """shell-centre-crack writes plots/j_history.png: J of both tips against time, the closed form
    (the summary's j_reference) as a line and each tip's final G as a marker."""
    import crackle.io.plots as plots

    out = tmp_path / "crack"
    assert main(["run", "shell-centre-crack", "--quick", "--set", "run.end_time=1e-4", "--out", str(out)]) == 0
    assert (out / "plots" / "j_history.png").stat().st_size > 0
    summary = json.loads((out / "summary.json").read_text())
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig))
    from crackle.io import read_history_csv

    plots.plot_j_history(read_history_csv(out / "history.csv"), tmp_path / "j.png", summary["j_reference"], [1.0, 2.0])
    ax = figures[0].axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["J, tip 0", "G at the end, tip 0", "J, tip 1", "G at the end, tip 1", "closed form"]
    assert ax.get_lines()[-1].get_ydata()[0] == summary["j_reference"]
    assert ax.get_ylabel() == "J, G [J/m^2]" and ax.get_title()


def test_shell_crack_pattern_draws_the_pre_crack(tmp_path, monkeypatch):
    """shell-centre-crack (no growth in its quick form): crack_pattern.png draws the pre-crack as
    cut, from -25 to 25 mm along x at y = 0 (the chain of edges nearest the polyline)."""
    import crackle.io.plots as plots

    figures = []
    save = plots._save

    def keep(fig, path):
        figures.append((fig.get_suptitle(), [(line.get_label(), line.get_xydata().copy()) for line in fig.axes[0].get_lines()]))
        return save(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    assert main(["run", "shell-centre-crack", "--quick", "--set", "run.end_time=5e-5", "--out", str(tmp_path / "o")]) == 0
    patterns = [lines for title, lines in figures if title.startswith("Crack pattern")]
    pre = [xy for label, xy in patterns[-1] if label == "pre-crack"]
    assert len(pre) == 1
    assert pre[0][:, 0].min() == pytest.approx(-25.0, abs=1e-9) and pre[0][:, 0].max() == pytest.approx(25.0, abs=1e-9)
    assert np.all(np.abs(pre[0][:, 1]) < 1e-9)


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

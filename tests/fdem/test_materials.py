"""Several materials in one FDEM model ([materials.NAME], [interfaces."A-B"]): a two-material bar
against the closed form of two springs in series, where it breaks, and materials read from a
mesh file's groups (gmsh physical volumes, Abaqus *Elset)."""

from __future__ import annotations

import json
from collections import Counter

import meshio
import numpy as np
import pytest

from crackle.cli import main
from crackle.geometry.meshes import read_mesh, structured_box
from crackle.io import read_events_csv, read_history_csv, read_pvd

# A 40 x 10 x 10 mm bar, x < 20 mm soft (E = 20 GPa, ft = 2 MPa), x > 20 mm stiff (40 GPa, 4 MPa),
# pulled apart by glued grips at 0.01 m/s (the peak after ~20 wave transits of the bar); a low Gf so
# that it separates within the run.
BAR = """
name = "two-material-bar"
method = "fdem"

[specimen]
shape = "box"
size = [0.04, 0.01, 0.01]
element_size = 0.005
mesh = "structured"

[materials.soft]
density = 2400.0
youngs_modulus = 20e9
poissons_ratio = 0.2
[materials.soft.interface]
tensile_strength = 2e6
cohesion = 10e6
friction_angle = 30.0
fracture_energy = 2.0

[materials.stiff]
density = 2400.0
youngs_modulus = 40e9
poissons_ratio = 0.2
zones = [{shape = "half-space", point = [0.02, 0.0, 0.0], normal = [1.0, 0.0, 0.0]}]
[materials.stiff.interface]
tensile_strength = 4e6
cohesion = 20e6
friction_angle = 30.0
fracture_energy = 2.0
{pair}
[[tools]]
name = "right"
shape = "box"
center = [0.045, 0.005, 0.005]
size = [0.01, 0.02, 0.02]
direction = [1.0, 0.0, 0.0]
speed = 0.01
ramp_time = 5e-5
glued = true
touch = true

[[tools]]
name = "left"
shape = "box"
center = [-0.005, 0.005, 0.005]
size = [0.01, 0.02, 0.02]
direction = [-1.0, 0.0, 0.0]
speed = 0.01
ramp_time = 5e-5
glued = true
touch = true

[run]
end_time = 6e-4
history_samples = 100
field_frames = 6
"""

PAIR = """
[interfaces."soft-stiff"]
tensile_strength = {ft}
cohesion = 20e6
friction_angle = 30.0
fracture_energy = 2.0
"""


def _run(tmp_path, name: str, pair_ft: float | None = None) -> tuple[dict, object]:
    scenario = tmp_path / f"{name}.toml"
    scenario.write_text(BAR.replace("{pair}", "" if pair_ft is None else PAIR.replace("{ft}", repr(pair_ft))))
    out = tmp_path / name
    assert main(["run", str(scenario), "--out", str(out)]) == 0
    return json.loads((out / "summary.json").read_text()), out


def test_two_material_bar_is_two_springs_in_series_and_breaks_at_the_weaker(tmp_path):
    """Elastic, at 100 us (past the grips' ramp, before the peak): both parts carry the same
    stress (tets' mean sigma_xx within 1 %), the soft part strains twice as much (E ratio, within
    1 %), and each part's E x strain (node displacements 10 mm apart) is the tets' stress within
    1.5 % (the interface penalties add about 1 % of compliance). Fracture: with the default rule (a
    face between the two takes the weaker law, 2 MPa) the bar's nominal strength is 2 MPa within
    10 % and every failed face lies at the soft side or the junction."""
    summary, out = _run(tmp_path, "default")
    t, frame = read_pvd(out / "fields.pvd")[1]
    mesh = meshio.read(frame)
    tets = [c.type for c in mesh.cells].index("tetra")
    centroid = mesh.points[mesh.cells[tets].data].mean(axis=1)
    sxx, material = mesh.cell_data["stress"][tets][:, 0], mesh.cell_data["material"][tets]
    inner = (centroid[:, 0] > 0.005) & (centroid[:, 0] < 0.035)
    soft, stiff = sxx[inner & (material == 0)].mean(), sxx[inner & (material == 1)].mean()
    assert soft > 0.5e6 and soft == pytest.approx(stiff, rel=0.01)
    u = mesh.point_data["displacement"]
    x0 = mesh.points - u

    def strain(a, b):
        return (u[np.abs(x0[:, 0] - b) < 1e-9, 0].mean() - u[np.abs(x0[:, 0] - a) < 1e-9, 0].mean()) / (b - a)

    strain_soft, strain_stiff = strain(0.005, 0.015), strain(0.025, 0.035)
    assert strain_soft / strain_stiff == pytest.approx(2.0, rel=0.01)
    assert 20e9 * strain_soft == pytest.approx(soft, rel=0.015)
    assert 40e9 * strain_stiff == pytest.approx(stiff, rel=0.015)

    assert summary["nominal_strength"] == pytest.approx(2e6, rel=0.10)
    assert summary["broken"] > 0 and set(summary["failures_by_material"]) <= {"soft", "soft-stiff"}


@pytest.mark.parametrize("pair_ft, where", [(6e6, "soft"), (1e6, "soft-stiff")])
def test_a_pair_law_moves_the_break(tmp_path, pair_ft, where):
    """[interfaces."soft-stiff"]: a junction stronger than both (6 MPa) leaves the break to the
    soft material (nominal strength 2 MPa within 10 %, failures in "soft" only); a weak one
    (1 MPa, a bedding plane) breaks the bar there at 1 MPa within 10 %, and that run is
    byte-identical with 2 numba threads (history and events)."""
    summary, out = _run(tmp_path, f"pair-{pair_ft:g}", pair_ft)
    expected = min(pair_ft, 2e6)
    assert summary["nominal_strength"] == pytest.approx(expected, rel=0.10)
    assert summary["broken"] > 0 and set(summary["failures_by_material"]) == {where}
    # events.csv names the material (pair) of each failure: the same counts
    assert Counter(read_events_csv(out / "events.csv")["material"]) == summary["failures_by_material"]
    if pair_ft < 2e6:
        import os
        import subprocess
        import sys

        two = tmp_path / "two-threads"
        subprocess.run([sys.executable, "-m", "crackle.cli", "run", str(tmp_path / f"pair-{pair_ft:g}.toml"),
                        "--out", str(two)], env=dict(os.environ, NUMBA_NUM_THREADS="2"), check=True, capture_output=True)
        assert (out / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
        assert (out / "events.csv").read_bytes() == (two / "events.csv").read_bytes()


def _two_volume_msh(path) -> None:
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("two")
        a = gmsh.model.occ.addBox(0, 0, 0, 0.02, 0.01, 0.01)
        b = gmsh.model.occ.addBox(0.02, 0, 0, 0.02, 0.01, 0.01)
        gmsh.model.occ.fragment([(3, a)], [(3, b)])
        gmsh.model.occ.synchronize()
        (_, left), (_, right) = gmsh.model.getEntities(3)
        gmsh.model.addPhysicalGroup(3, [left], name="mortar")
        gmsh.model.addPhysicalGroup(3, [right], name="aggregate")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.005)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _inp_with_elsets(path) -> None:
    mesh = structured_box((0.04, 0.01, 0.01), 0.005)
    x = mesh.points[mesh.tets].mean(axis=1)[:, 0]
    meshio.Mesh(mesh.points, [("tetra", mesh.tets)],
                cell_sets={"mortar": [np.flatnonzero(x < 0.02)], "aggregate": [np.flatnonzero(x >= 0.02)]}).write(path)


def _grouped_scenario(tmp_path, mesh_file: str, groups=("mortar", "aggregate")) -> str:
    text = BAR.replace("{pair}", "").replace('shape = "box"\nsize = [0.04, 0.01, 0.01]\nelement_size = 0.005\nmesh = "structured"',
                                             f'shape = "mesh"\nfile = "{mesh_file}"')
    text = text.replace("[materials.soft]", f'[materials.soft]\ngroup = "{groups[0]}"')
    text = text.replace('zones = [{shape = "half-space", point = [0.02, 0.0, 0.0], normal = [1.0, 0.0, 0.0]}]',
                        f'group = "{groups[1]}"')
    path = tmp_path / "grouped.toml"
    path.write_text(text.replace("end_time = 6e-4", "end_time = 2e-6"))
    return str(path)


@pytest.mark.parametrize("writer, suffix", [(_two_volume_msh, "msh"), (_inp_with_elsets, "inp")])
def test_materials_by_the_mesh_files_groups(tmp_path, writer, suffix):
    """A gmsh .msh with two physical volumes and an Abaqus .inp with two *Elset: each material
    fills its group (by name) and the VTU's `material` says so; a run of a few steps completes."""
    writer(tmp_path / f"bar.{suffix}")
    groups = read_mesh(tmp_path / f"bar.{suffix}").groups
    assert set(groups) == {"mortar", "aggregate"}
    scenario = _grouped_scenario(tmp_path, f"bar.{suffix}")
    out = tmp_path / "out"
    assert main(["run", scenario, "--out", str(out)]) == 0
    mesh = meshio.read(read_pvd(out / "fields.pvd")[0][1])
    tets = [c.type for c in mesh.cells].index("tetra")
    material = mesh.cell_data["material"][tets]
    centroid = mesh.points[mesh.cells[tets].data].mean(axis=1)
    assert np.array_equal(material, (centroid[:, 0] > 0.02).astype(material.dtype))


def test_unmatched_groups_stop_with_both_lists(tmp_path, capsys):
    """A material naming a group the file lacks ("paste"), and the file's group no material names
    ("mortar"): exit 2 before anything runs, naming both."""
    _two_volume_msh(tmp_path / "bar.msh")
    scenario = _grouped_scenario(tmp_path, "bar.msh", groups=("paste", "aggregate"))
    assert main(["run", scenario, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "named by no material: mortar" in err and "in no group of the file: paste" in err
    assert not (tmp_path / "out" / "history.csv").exists()


@pytest.mark.parametrize("change, message", [
    (("[materials.soft]", "[material]\nname = \"x\"\ndensity = 2400.0\nyoungs_modulus = 1e9\npoissons_ratio = 0.2\n"
      "[material.interface]\ntensile_strength = 1e6\ncohesion = 1e6\nfriction_angle = 30.0\nfracture_energy = 2.0\n\n"
      "[materials.soft]"), "not both"),
    (('zones = [{shape = "half-space", point = [0.02, 0.0, 0.0], normal = [1.0, 0.0, 0.0]}]', ""), "only one material"),
    (("[[tools]]", '[interfaces."soft-hard"]\ntensile_strength = 1e6\ncohesion = 1e6\nfriction_angle = 30.0\n'
      "fracture_energy = 2.0\n\n[[tools]]"), "soft-hard"),
    (('normal = [1.0, 0.0, 0.0]}]', 'normal = [1.0, 0.0, 0.0], radius = 0.01}]'), "radius"),
    (("[materials.stiff", '[materials."stiff,hard"', 2), "may not be empty or hold a comma"),
])
def test_bad_material_tables_are_refused(tmp_path, capsys, change, message):
    """[material] beside [materials], two materials filling the rest, a pair naming no material,
    a zone key its shape does not take, a name events.csv cannot carry: exit 2 naming it."""
    path = tmp_path / "bad.toml"
    old, new, count = (*change, 1)[:3]
    path.write_text(BAR.replace("{pair}", "").replace(old, new, count))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err



def test_a_layered_disc_is_meshed_with_planar_bedding_planes():
    """brazilian-layered --quick (bed layers 4 mm thick every 10 mm, normal x, in a 40 mm disc):
    gmsh cuts the disc along the layers' planes, so every face between rock and bed lies on one
    of them (its normal along x within 1e-9, its corners within 1e-9 m of a plane) and together
    they cover the planes' chords, sum of 2 sqrt(R^2 - d^2) x thickness over the 8 planes at
    d = +-2, +-8, +-12, +-18 mm: 3,777 mm^2 within 1 % (measured within 0.01 %: the chords end on the
    rim).
    Taken by their centroids alone, the tets made staircases whose faces had every orientation
    (94 % of their area more than 15 deg off the planes, 1.5 times the planes' area; 5-6 % within
    15 deg at both 4 and 2 mm)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario("brazilian-layered", quick=True)
    sim, _ = build_simulation(scenario, base)
    ifs, x = sim.model.ifs, sim.model.nodes.x
    bedding = ifs.law == 2  # the rows: rock, bed, then the pair's law
    corners = x[ifs.na[bedding]]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    assert np.all(1.0 - np.abs(normal[:, 0]) < 1e-9)
    planes = np.array([-0.018, -0.012, -0.008, -0.002, 0.002, 0.008, 0.012, 0.018])
    assert np.all(np.min(np.abs(corners[..., 0, None] - planes), axis=-1) < 1e-9)
    chords = 2.0 * np.sqrt(0.02**2 - planes**2) * 0.015
    assert ifs.area[bedding].sum() == pytest.approx(chords.sum(), rel=0.01)

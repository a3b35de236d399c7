"""Walnut shells (paper 004): the ellipsoidal shell mesh with its suture band, and the quick
uniaxial crush between two plates (walnut-crush --quick)."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest

from crackle.geometry import (
    LOCAL_FACE_VERTICES,
    SUTURE,
    check_tets,
    ellipsoid_shell_volume,
    equivalent_diameter,
    internal_faces,
    walnut_shell,
)

L, W, T = 39.15e-3, 35.0e-3, 33.5e-3  # walnut-crush's nut: D_p = 35.81 mm
BAND = 4e-3


def test_equivalent_diameter_of_the_example_nut():
    assert equivalent_diameter(L, W, T) == pytest.approx(35.81e-3, rel=1e-3)


@pytest.mark.parametrize("layers", [1, 2])
def test_shell_volume_closedness_and_suture_band(layers):
    """Same wall everywhere: the mesh volume equals the analytic shell volume
    4/3 pi (abc - (a-t)(b-t)(c-t)) within 1 % at 2 mm elements (measured -0.42 %, the facets'
    chord error, O(h^2)); the mesh is a closed conforming shell (outer and inner surfaces only,
    as many boundary faces as 2 x the surface triangles) with `layers` tets through the wall;
    suture tets are exactly those whose centroid is within half the band of x = 0."""
    mesh, region = walnut_shell(L, W, T, 2e-3, wall=1.11e-3, suture_wall=None, suture_band=BAND, layers=layers)
    check_tets(mesh)
    exact = ellipsoid_shell_volume((W / 2, T / 2, L / 2), 1.11e-3)
    assert mesh.volumes().sum() == pytest.approx(exact, rel=1e-2)
    topo = internal_faces(mesh.tets)
    assert len(topo.boundary_faces) * 3 * layers == 2 * mesh.n_tets
    cx = mesh.points[mesh.tets, 0].mean(axis=1)
    assert region.shape == (mesh.n_tets,)
    assert np.all(np.abs(cx[region == SUTURE]) <= BAND / 2)
    assert np.all(np.abs(cx[region != SUTURE]) > BAND / 2)
    assert 0.05 < np.mean(region == SUTURE) < 0.2
    # Every boundary node lies on the outer ellipsoid or the inner one (a - t, ...).
    semi = np.array([W, T, L]) / 2
    bt, bf = topo.boundary_faces[:, 0], topo.boundary_faces[:, 1]
    bnodes = np.unique(mesh.tets[bt[:, None], LOCAL_FACE_VERTICES[bf]])
    r_out = np.sum((mesh.points[bnodes] / semi) ** 2, axis=1)
    r_in = np.sum((mesh.points[bnodes] / (semi - 1.11e-3)) ** 2, axis=1)
    assert np.all(np.minimum(abs(r_out - 1), abs(r_in - 1)) < 1e-9)


def test_thicker_suture_adds_its_extra_wall():
    """A 1.34 mm suture wall makes the shell heavier than the 1.11 mm one by about the band's
    share of the extra wall, and leaves the outer surface as it is."""
    thin, _ = walnut_shell(L, W, T, 2e-3, suture_wall=None, suture_band=BAND)
    thick, region = walnut_shell(L, W, T, 2e-3, suture_wall=1.34e-3, suture_band=BAND)
    extra = thick.volumes().sum() - thin.volumes().sum()
    band_volume = thin.volumes()[region == SUTURE].sum()
    assert 0.5 * band_volume * (0.23 / 1.11) < extra < 1.5 * band_volume * (0.23 / 1.11)
    assert np.allclose(thin.bounds()[1], thick.bounds()[1])


@pytest.mark.slow
def test_quick_walnut_crush_cracks_through_the_suture(tmp_path):
    """`crackle run walnut-crush --quick`: the plates crush the shell to a peak (measured 241.8 N,
    3,378 tets, 1.25 m/s; 2026-12-06), then cracks run and the plate force drops below 30 % of
    its peak (the run's force-drop stop; measured 88 failed interfaces). A failure is in the
    suture when its interface (the `id` column of events.csv) carries the suture's law: both tets,
    or one of them, in the band |x| <= 2 mm (an interface between the two regions takes the weaker,
    suture law); measured 82 of 97 before the turning forces of failed faces. Energy error below
    3 % (measured -0.27 %; -0.8 % before the turning forces, -1.5 % before the half-step damage
    booking)."""
    from crackle.api import build_simulation, run_scenario
    from crackle.scenario import load_scenario

    out = tmp_path / "walnut"
    run_scenario("walnut-crush", out, quick=True, plots=False)  # plots/: seconds, read by no check here
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "stopped" and "below 30%" in s["message"]
    assert 150.0 < s["peak_force"] < 400.0  # paper 004: ~237 N (CT-scanned nut, 0.95 mm mesh)
    assert s["broken"] >= 20
    assert abs(s["energy_error"]) < 0.03
    assert s["cracks"] >= 1  # measured 1: a single meridional crack along the suture, both ways
    # issue 38: the count at the ring rule's scale x 0.75 / 1 / 1.5 (measured 3 / 2 / 1), and the
    # crack bursts in the dissipated energy (a crack running through the wall at >= 0.05 c_R):
    # at least one, the first as the interfaces soften towards the first complete failure
    # (measured 7 bursts, the first at 0.82 of the first failure's time)
    assert [round(r / s["crack_scale"], 12) for r, _ in s["cracks_at_scales"]] == [0.75, 1.0, 1.5]
    assert s["cracks_at_scales"][1][1] == s["cracks"]
    first = s["main_crack"]["first_failure"]
    assert s["energy_jumps"] >= 1 and 0.5 * first < s["energy_jump_times"][0] < 1.1 * first
    assert s["loading_index"] == pytest.approx(2.0 / 3.0**0.5, abs=1e-12)  # two opposite plates

    with open(out / "events.csv") as fh:
        events = list(csv.DictReader(fh))
    ids = np.array([int(e["id"]) for e in events])
    scenario, base = load_scenario("walnut-crush", quick=True)
    model = build_simulation(scenario, base)[0].model
    suture_law = model.ifs.law[ids] == 1  # material 1 = [suture]
    assert suture_law.sum() >= 1
    # ... and those failures lie in the band (positions at failure, within an element of it).
    x = np.array([float(e["x"]) for e in events])
    assert np.all(np.abs(x[suture_law]) <= BAND / 2 + scenario.specimen.element_size)


def test_suture_table_is_only_for_walnuts():
    from crackle.scenario import ScenarioError, load_scenario

    with pytest.raises(ScenarioError, match="suture"):
        load_scenario("brazilian-disc", overrides=["suture.density=1250.0"])
    scenario, _ = load_scenario("walnut-crush")
    assert scenario.suture.interface.tensile_strength == 3.5e6
    assert scenario.material.interface.tensile_strength == 7e6


def _ellipsoid_stl(path, semi_mm, h_rel=0.1):
    """A closed ellipsoid surface in mm, as a scanner would export it."""
    import meshio

    from crackle.geometry.walnut import _unit_sphere_surface

    unit, tris = _unit_sphere_surface(h_rel)
    meshio.write(path, meshio.Mesh(unit * np.asarray(semi_mm), [("triangle", tris)]))


@pytest.mark.parametrize("element_size", [None, 2e-3])
def test_shell_from_a_scanned_surface(tmp_path, element_size):
    """A closed outer surface (STL in mm, scale 1e-3) walled inwards by 1.11 mm: the shell's volume
    is the ellipsoid shell's within 1 % (measured 0.3-0.5 %), the tets are valid, and the suture
    band |x| <= 2 mm holds 5-20 % of them (11-12 %); as given (None) and remeshed by gmsh at 2 mm."""
    from crackle.geometry import shell_from_surface

    semi = 0.5 * np.array([W, T, L])
    _ellipsoid_stl(tmp_path / "nut.stl", semi * 1e3)
    mesh, region = shell_from_surface(tmp_path / "nut.stl", element_size, wall=1.11e-3, suture_wall=1.11e-3, scale=1e-3)
    check_tets(mesh)
    assert mesh.volumes().sum() == pytest.approx(ellipsoid_shell_volume(semi, 1.11e-3), rel=1e-2)
    cx = mesh.points[mesh.tets].mean(axis=1)[:, 0]
    # The band is about the surface's area centroid, within 0.1 mm of x = 0 for this triangulation.
    assert np.all(np.abs(cx[region == SUTURE]) <= BAND / 2 + 1e-4)
    assert 0.05 < np.mean(region == SUTURE) < 0.2


def test_shell_scenario_and_bad_surfaces(tmp_path):
    """specimen.shape = "shell" builds the walnut-crush model on a scanned surface (suture
    interfaces present); an open surface and a wall thicker than the curvature allows end with a
    MeshError naming the problem."""
    import meshio

    from crackle.api import build_simulation
    from crackle.geometry import MeshError, read_surface, shell_from_surface
    from crackle.scenario import load_scenario

    _ellipsoid_stl(tmp_path / "nut.stl", 0.5 * np.array([W, T, L]) * 1e3, h_rel=0.15)
    from crackle.scenario import examples_dir

    # walnut-crush with the scanned surface for the ellipsoid (its length, width and thickness,
    # which a shell does not read, left out)
    text = re.sub(r"\n(length|width|thickness) = [^\n]*", "", (examples_dir() / "walnut-crush.toml").read_text(), count=3)
    (tmp_path / "scanned.toml").write_text(text)
    scenario, base = load_scenario(
        str(tmp_path / "scanned.toml"),
        ["specimen.shape=shell", f"specimen.file={tmp_path / 'nut.stl'}", "specimen.scale=1e-3", "specimen.element_size=3e-3"],
        quick=True,
    )
    model = build_simulation(scenario, base)[0].model
    assert np.any(model.ifs.law == 1) and np.any(model.ifs.law == 0)

    points, tris = read_surface(tmp_path / "nut.stl")
    meshio.write(tmp_path / "open.stl", meshio.Mesh(points, [("triangle", tris[1:])]))
    with pytest.raises(MeshError, match="not closed"):
        shell_from_surface(tmp_path / "open.stl", None, scale=1e-3)
    with pytest.raises(MeshError, match="too thick"):
        shell_from_surface(tmp_path / "nut.stl", None, wall=15e-3, suture_wall=15e-3, scale=1e-3)

"""Pressures and supports on named surfaces of a mesh file (where.group: gmsh physical surfaces).

A 20 mm cube meshed by gmsh (tets of about 5 mm) with the physical volume "rock" and the physical
surfaces "top" (z = 20 mm) and "bottom" (z = 0), read as a user's mesh file (specimen.shape =
"mesh"); the rock of tests/fdem/test_initial_stress.py (E = 26 GPa, nu = 0.2, Guo-Munjiza faces).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from crackle.api import build_simulation
from crackle.cli import main
from crackle.fdem.kernels import tet_energy_and_stress
from crackle.geometry.meshes import read_mesh
from crackle.scenario import load_scenario
from crackle.solver.integrator import FREE

L = 0.02
P = 10e6  # Pa

SCENARIO = f"""
name = "named-surfaces"
method = "fdem"

[specimen]
shape = "mesh"
file = "cube.msh"

[material]
density = 2340.0
youngs_modulus = 26e9
poissons_ratio = 0.2

[material.interface]
law = "guo-munjiza"
tensile_strength = 3e6
cohesion = 15e6
friction_angle = 30.0
fracture_energy = 50.0

[initial_stress]
stress = [0.0, 0.0, {-P}, 0.0, 0.0, 0.0]

{{loads}}

[run]
end_time = 1e-3
history_samples = 10
field_frames = 0
checkpoint = false
"""


def _cube_msh(path) -> None:
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("cube")
        box = gmsh.model.occ.addBox(0, 0, 0, L, L, L)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [box], name="rock")
        for name, z in (("top", L), ("bottom", 0.0)):
            faces = [tag for _, tag in gmsh.model.getEntities(2)
                     if abs(gmsh.model.occ.getCenterOfMass(2, tag)[2] - z) < 1e-9]
            gmsh.model.addPhysicalGroup(2, faces, name=name)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.005)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _on(group: str, value: float = P) -> str:
    return f'[[pressures]]\nfaces = "where"\nvalue = {value}\nwhere = {{ group = "{group}" }}\n'


def _scenario(tmp_path, loads: str):
    _cube_msh(tmp_path / "cube.msh")
    path = tmp_path / "cube.toml"
    path.write_text(SCENARIO.format(loads=loads))
    return path


def _build(path, overrides=()):
    scenario, base = load_scenario(path, list(overrides))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim, _ = build_simulation(scenario, base)
    return sim, 0.7 * sim.stable_dt


def test_pressures_on_named_surfaces_hold_an_initial_stress(tmp_path):
    """sigma_zz = -10 MPa from t = 0 and a 10 MPa pressure on each of the file's surfaces "top"
    and "bottom": the loaded faces are exactly the groups' triangles (their count, and their area
    2 L^2 to 1e-9), and the cube stays at rest: kinetic energy below 1e-6 of the stored over 500
    steps, every tet's stress within 1e-6 of -10 MPa (a face of a side loaded, or one of the
    groups' missed, would set it moving)."""
    path = _scenario(tmp_path, _on("top") + _on("bottom"))
    surfaces = read_mesh(tmp_path / "cube.msh").surfaces
    sim, dt = _build(path)
    tets = sim.model.tets
    loaded = tets.face_pressure >= 0
    assert loaded.sum() == len(surfaces["top"]) + len(surfaces["bottom"])
    assert abs(tets.face_area[loaded].sum() - 2 * L**2) < 1e-9 * L**2
    sim.advance(500, dt)
    m = sim.model
    energy, stress = np.zeros(m.n_tets), np.zeros((m.n_tets, 6))
    tet_energy_and_stress(m.nodes.x, m.tets, energy, stress)
    en = sim.energies(dt)
    print(f"KE / stored {en['energy.kinetic'] / en['energy.elastic']:.3g}, "
          f"stress drift {np.abs(stress[:, 2] + P).max() / P:.3g}")
    assert en["energy.kinetic"] < 1e-6 * (en["energy.elastic"] + en["energy.cohesive"])
    assert np.abs(stress[:, 2] + P).max() < 1e-6 * P
    assert np.abs(stress[:, [0, 1, 3, 4, 5]]).max() < 1e-6 * P


def test_support_on_a_named_surface_holds_its_nodes(tmp_path):
    """A fixed support on "bottom" holds exactly the nodes on z = 0 (the exploded mesh's copies of
    the group's nodes), the same support table as the plane z = 0 gives."""
    support = '[[supports]]\nkind = "fixed"\nwhere = { group = "bottom" }\n'
    by_group, _ = _build(_scenario(tmp_path, _on("top") + support))
    by_plane, _ = _build(tmp_path / "cube.toml", ["supports.0.where={plane_point=[0.0, 0.0, 0.0], "
                                                  "plane_normal=[0.0, 0.0, 1.0]}"])
    held = by_group.model.nodes.constraint != FREE
    on_bottom = np.abs(by_group.model.nodes.x[:, 2]) < 1e-12
    assert held.any() and np.array_equal(held, on_bottom)
    assert np.array_equal(by_group.model.nodes.constraint, by_plane.model.nodes.constraint)


@pytest.mark.parametrize("loads, overrides, message", [
    (_on("roof"), [], "no surface of that name (its named surfaces: bottom, top"),
    (_on("top"), ['specimen={shape="box", size=[0.02, 0.02, 0.02], element_size=0.01}'],
     "named surfaces are those of an FDEM specimen's mesh file"),
])
def test_bad_named_surface_is_refused(tmp_path, capsys, loads, overrides, message):
    """A group the file does not have (the message lists the file's), a group on a built-in shape:
    exit 2 before anything runs."""
    path = _scenario(tmp_path, loads)
    extra = [arg for o in overrides for arg in ("--set", o)]
    assert main(["run", str(path), "--out", str(tmp_path / "out"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert not (tmp_path / "out" / "history.csv").exists()

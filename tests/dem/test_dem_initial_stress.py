"""[initial_stress] with the DEM: bonds preloaded by a static solve on the bond network
(dem.prestress) so that the packing carries the stress at its set-up places.

A 20 mm cube of the paper 003 limestone (JCFpm, Table 1: Y = 50 GPa, P = 1/3, t = 4.5 MPa,
c = 45 MPa, 18 deg; density 2500 kg/m^3, local damping 0.2), spheres of mean radius 1.25 mm
(paper 003's 1.47 spheres per cubed diameter: about 750 particles), built from a scenario file as
a user writes it. The step: the set-up's.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crackle.api import build_simulation
from crackle.cli import main
from crackle.dem.kernels import TRANSFER_FORCE, TRANSFER_LEVER_A, TRANSFER_LEVER_B, TRANSFER_MOMENT
from crackle.dem.membrane import box_faces
from crackle.dem.prestress import face_tractions, surface_loads
from crackle.scenario import load_scenario

from threads import outputs_with_1_and_2_threads

L = 0.02
PRINCIPAL = (-8e6, -6e6, -4e6)  # Pa, along x, y, z

CUBE = f"""
name = "dem-prestressed-cube"
method = "dem"

[specimen]
shape = "box"
size = [{L}, {L}, {L}]
origin = [0.0, 0.0, 0.0]

[packing]
mean_radius = 1.25e-3
particle_density = 1.47
seed = 3

[material]
density = 2500.0
bond_modulus = 50e9
stiffness_ratio = 0.3333333333333333
tensile_strength = 4.5e6
cohesion = 45e6
friction_angle = 18.0
bonds_per_particle = 12.0
local_damping = 0.2

[initial_stress]
{{initial}}

{{loads}}

[run]
end_time = 2e-3
history_samples = 20
field_frames = 0
checkpoint = false
"""


def _pressure(value: float, axis: int) -> str:
    """[[pressures]] on the two faces normal to `axis` (a plane through each would select one; a
    box around both, thin along the other axes, selects exactly these two)."""
    lo, hi = [-0.001] * 3, [L + 0.001] * 3
    for other in range(3):
        if other != axis:
            lo[other], hi[other] = 0.001, L - 0.001
    return f"[[pressures]]\nfaces = \"where\"\nvalue = {value}\n[pressures.where]\nbox_min = {lo}\nbox_max = {hi}\n"


MATCHING = "\n".join(_pressure(-s, axis) for axis, s in enumerate(PRINCIPAL))
DIAGONAL = f"principal = {list(PRINCIPAL)}"


def _scenario(tmp_path, initial=DIAGONAL, loads=MATCHING):
    path = tmp_path / "cube.toml"
    path.write_text(CUBE.format(initial=initial, loads=loads))
    return path


def _build(path, overrides=()):
    scenario, base = load_scenario(path, list(overrides))
    sim, control = build_simulation(scenario, base)
    return sim, control.dt or sim.stable_dt * control.safety


def _net_bond_loads(sim):
    """Per particle, the force and torque of its bonds and contacts at the start of the last step
    (the interaction pass's transfer rows, summed as the particle pass does)."""
    s, n = sim.inter, len(sim.particles.radius)
    f = s.transfer[:, TRANSFER_FORCE:TRANSFER_FORCE + 3]
    moment = s.transfer[:, TRANSFER_MOMENT:TRANSFER_MOMENT + 3]
    force, torque = np.zeros((n, 3)), np.zeros((n, 3))
    for d in range(3):
        force[:, d] = np.bincount(s.b, f[:, d], n) - np.bincount(s.a, f[:, d], n)
        torque[:, d] = (np.bincount(s.b, s.transfer[:, TRANSFER_LEVER_B] * moment[:, d], n)
                        + np.bincount(s.a, s.transfer[:, TRANSFER_LEVER_A] * moment[:, d], n))
    return force, torque


def _mean_stress(sim):
    """The packing's mean stress over the cube (the particles' stresses, membrane moments
    included, times their volumes, over the cube's volume), (6,) in STRESS_ORDER."""
    stress = sim.particle_stress()
    volume = 4.0 / 3.0 * math.pi * sim.particles.radius**3
    return (stress * volume[:, None]).sum(axis=0) / L**3


def test_prestressed_cube_stays_at_rest_under_matching_pressures(tmp_path):
    """Principal stresses (-8, -6, -4) MPa along x, y, z and the pressures that match them on the
    six faces (the DEM's membrane, dem.membrane): over 1,000 steps the kinetic energy stays below
    1e-6 of the stored energy and every particle's stress stays within 1e-6 of the largest
    (measured: 2e-22 and 2e-11). The packing carries the stress: its mean stress over the cube
    within 7 % of each principal value (measured: 5 % low on each, the rasterised surface: the
    cells' forces act where their rays meet the spheres, on average 0.5 mm inside the faces of the
    20 mm cube), shears below 1 % of the largest; the stored energy is the summary's initial_stored_energy and lies within 30 % of
    the continuum's sigma : C^-1 : sigma / 2 V (the packing's modulus E = 57 GPa, docs/validation.md's
    dem-ucs rows; nu = 0.2 assumed; measured: 0.8 of it, the mean stress being 5 % low)."""
    sim, dt = _build(_scenario(tmp_path))
    stored = sim.interaction_energy(0.0)
    assert stored > 0.0 and sim._initial_stored == stored
    sim.advance(1, dt)
    first = sim.particle_stress()
    kinetic = 0.0
    for _ in range(9):
        sim.advance(111, dt)
        kinetic = max(kinetic, sim.kinetic_energy())
    drift = np.abs(sim.particle_stress() - first).max() / np.abs(first).max()
    print(f"KE / stored {kinetic / stored:.3g}, stress drift {drift:.3g}")
    assert kinetic < 1e-6 * stored
    assert drift < 1e-6
    mean = _mean_stress(sim)
    print("mean stress (MPa)", np.round(mean / 1e6, 3))
    assert np.allclose(mean[:3], PRINCIPAL, rtol=0.07)
    assert np.abs(mean[3:]).max() < 0.01 * max(abs(s) for s in PRINCIPAL)
    e, nu = 57e9, 0.2
    s = np.array(PRINCIPAL)
    continuum = 0.5 * L**3 * (np.sum(s**2) - 2.0 * nu * (s[0] * s[1] + s[1] * s[2] + s[0] * s[2])) / e
    print(f"stored {stored:.4g} J, continuum {continuum:.4g} J")
    assert 0.7 * continuum < stored < 1.3 * continuum
    assert sim.summary()["initial_stored_energy"] == stored


def test_bonds_carry_a_general_stress_with_its_gradient_and_weight(tmp_path):
    """A general tensor (shears included) plus a gradient with depth (k0 = 0.5, the surface 0.5 m
    above the cube, the packing's bulk density) under run.gravity, no loads: after the preload each
    particle's bonds balance the stress's tractions on the box faces and its weight: the forces to
    1e-10 of the largest (measured: 9e-12), the torques to 1e-8 of it times the cube's side
    (measured: 9e-10: the particles' centre of mass lies a few micrometres off the cube's, so the
    weight has a net moment about it that no bond carries, left as equal torques on all). With
    the tractions' first moments (each cell's force at its centre on the face), the packing's mean
    stress is the stress at the cube's centre within 1 % of its largest component (measured:
    equal to 4 digits)."""
    general = (-8e6, -5e6, -6e6, 1.5e6, -1e6, 0.5e6)
    initial = f"stress = {list(general)}\ndensity = 2500.0\nk0 = 0.5\nsurface = 0.52"
    gravity = ["run.gravity=[0.0, 0.0, -9.81]"]
    sim, dt = _build(_scenario(tmp_path, initial, loads=""), gravity)
    # The overburden at the particles' density is heavier than the packing (its pores): the set-up
    # says the two do not balance and gives the packing's bulk density; with it they do.
    said = [w for w in sim.warnings if "do not balance" in w]
    assert len(said) == 1
    bulk = float(np.sum(sim.particles.mass)) / L**3
    assert f"bulk density is {bulk:.5g} kg/m^3" in said[0]
    initial = initial.replace("density = 2500.0", f"density = {bulk!r}")
    sim, dt = _build(_scenario(tmp_path, initial, loads=""), gravity)
    assert not any("initial_stress" in w for w in sim.warnings)
    scenario, _ = load_scenario(_scenario(tmp_path, initial, loads=""), gravity)
    p = sim.particles
    force, torque = surface_loads(p.x, p.radius, box_faces(np.zeros(3), np.full(3, L)), scenario.initial_stress.at)
    force += p.mass[:, None] * np.array([0.0, 0.0, -9.81])
    sim.advance(1, dt)
    bond_force, bond_torque = _net_bond_loads(sim)
    scale = np.abs(force).max()
    print(f"force residual {np.abs(bond_force + force).max() / scale:.3g}, "
          f"torque residual {np.abs(bond_torque + torque).max() / (scale * L):.3g}")
    assert np.abs(bond_force + force).max() < 1e-10 * scale
    assert np.abs(bond_torque + torque).max() < 1e-8 * scale * L
    # The mean stress of the bonds and the loads' lines of action: the tractions' own moments.
    centre = scenario.initial_stress.at(np.full((1, 3), 0.5 * L))[0]
    stress = sim.particle_stress()
    volume = 4.0 / 3.0 * math.pi * p.radius**3
    mean = (stress * volume[:, None]).sum(axis=0)
    point_moments = np.zeros((3, 3))
    for owner, point, f in face_tractions(p.x, p.radius, box_faces(np.zeros(3), np.full(3, L)),
                                          scenario.initial_stress.at):
        point_moments += np.einsum("ki,kj->ij", point - p.x[owner], f)
    sym = 0.5 * (point_moments + point_moments.T)
    mean = (mean + sym[[0, 1, 2, 0, 1, 0], [0, 1, 2, 1, 2, 2]]) / L**3
    print("mean stress (MPa)", np.round(mean / 1e6, 4), "at the centre", np.round(centre / 1e6, 4))
    assert np.abs(mean - centre).max() < 0.01 * np.abs(centre).max()


def test_relaxing_cube_audit_with_1_and_2_threads(tmp_path):
    """The free cube released from -5 MPa all round (the particles of its faces unbalanced by the
    missing tractions, as a continuum's free surface is): it springs out, rings and is damped
    (local damping 0.2: 0.1 ms, 1,550 steps; one bond at a corner breaks). Run with 1 and 2 numba
    threads: history.csv byte-identical; the audit (the stored energy at t = 0 counted as put in)
    within 1 % (measured: 5e-8), with a relaxation that moves: the kinetic energy reaches 1 % of
    the stored (measured: 33 %)."""
    path = _scenario(tmp_path, "stress = [-5e6, -5e6, -5e6, 0.0, 0.0, 0.0]", loads="")
    script = f"""
import csv, hashlib, json, os
from pathlib import Path
from crackle.api import run_scenario
out = Path({str(tmp_path)!r}) / ("threads" + os.environ["NUMBA_NUM_THREADS"])
run_scenario({str(path)!r}, out, ["run.end_time=1e-4"], plots=False)
summary = json.loads((out / "summary.json").read_text())
kinetic = max(float(row["energy.kinetic"]) for row in csv.DictReader(open(out / "history.csv")))
print(hashlib.sha256((out / "history.csv").read_bytes()).hexdigest(), summary["energy_error"],
      summary["initial_stored_energy"], kinetic)
"""
    one, two = outputs_with_1_and_2_threads(script)
    print(one)
    assert one[0] == two[0]
    energy_error, stored, kinetic = (float(v) for v in one[1:])
    assert abs(energy_error) < 0.01 and kinetic > 0.01 * stored


@pytest.mark.parametrize("initial, overrides, message", [
    # Beyond the bonds' tensile strength (4.5 MPa over a bond's area): most bonds would fail at t = 0.
    ("stress = [20e6, 0.0, 0.0, 0.0, 0.0, 0.0]", [], "would fail at t = 0"),
    ("stress = [-1e6, -1e6, -1e6, 0.0, 0.0, 0.0]", ['specimen.shape="sphere"', "specimen.diameter=0.02",
                                                     "specimen.center=[0.01, 0.01, 0.01]"], "on a box specimen"),
])
def test_bad_initial_stress_is_refused(tmp_path, capsys, initial, overrides, message):
    """A tensile stress beyond the bonds' strength, a specimen that is not a box: exit 2 before
    anything runs, the message naming [initial_stress] and what to change."""
    path = _scenario(tmp_path, initial, loads="")
    extra = [arg for o in overrides for arg in ("--set", o)]
    if overrides:  # a sphere has no size or origin
        path.write_text(path.read_text().replace(f"size = [{L}, {L}, {L}]\norigin = [0.0, 0.0, 0.0]\n", ""))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "initial_stress" in err
    assert not (tmp_path / "out" / "history.csv").exists()

"""Meshfree bodies and the particle contact (crackle.meshfree.contact): two bodies colliding, crack
faces closing, a folded wall's arms meeting, the reach rule, the scenario's [[bodies]]."""

from __future__ import annotations

import os

import numpy as np
import pytest

from crackle.loading import Precrack
from crackle.meshfree.build import MeshfreeBody, build_meshfree_simulation
from crackle.meshfree.material import J2Law
from crackle.meshfree.particles import plate_particles
from crackle.scenario import ScenarioError, load_scenario
from threads import outputs_with_1_and_2_threads

ALUMINIUM = J2Law(70e9, 0.3)
STEEL = J2Law(210e9, 0.3)
STORED = ("energy.kinetic", "energy.elastic", "energy.stabilisation", "energy.contact")


def _total(sim, dt) -> float:
    e = sim.energies(dt)
    return sum(e[k] for k in STORED)


def _two_plates():
    """A 20 x 20 x 2 mm aluminium plate (6 x 6 x 3 particles) and a 12 x 12 x 2 mm steel plate
    (4 x 4 x 3) above it, 0.1 mm beyond contact (their contact radii: half the 4 mm spacing),
    falling onto it at 50 m/s; both free, elastic."""
    target = plate_particles((0.0, 0.0, 0.0), (0.02, 0.02, 0.002), 0.004, 3)
    striker = plate_particles((0.004, 0.004, 0.0061), (0.012, 0.012, 0.002), 0.004, 3)
    return build_meshfree_simulation(target, 2700.0, ALUMINIUM,
                                     bodies=[MeshfreeBody(striker, 7800.0, STEEL, (0.0, 0.0, -50.0))])


def test_two_bodies_collide_conserving_momentum_and_energy():
    """Two elastic plates, one striking the other face on at 50 m/s for 1,000 steps (through the
    contact and apart again): total momentum unchanged to 1e-10 of the initial, the stored plus
    kinetic energy to 1 % (measured: 2e-16 and -0.07 %); the striker lost most of its speed to
    the target (measured: 50 -> 15.2 m/s), so they did meet."""
    sim = _two_plates()
    p = sim.particles
    dt = 0.7 * sim.stable_dt
    momentum = p.mass @ p.v
    energy = _total(sim, dt)
    sim.advance(1000, dt)
    assert np.max(np.abs(p.mass @ p.v - momentum)) <= 1e-10 * np.max(np.abs(momentum))
    assert abs(_total(sim, dt) - energy) < 0.01 * energy
    striker = sim.bodies()["bodies"][0]
    assert striker["velocity"][2] > -40.0, "the striker must have been slowed by the contact"
    assert sim.contact.builds >= 2


def _cut_strip(contact: bool, speed: float = 20.0):
    """A 40 x 20 x 2 mm plate (11 x 6 x 3 particles, 4 mm apart) cut through at x = 22 mm by a
    pre-crack; the piece beyond it moves back into the other at `speed` (m/s)."""
    strip = plate_particles((0.0, 0.0, 0.0), (0.04, 0.02, 0.002), 0.004, 3)
    v = np.zeros((len(strip.X), 3))
    v[strip.X[:, 0] > 0.022, 0] = -speed
    cut = Precrack(point=(0.022, 0.0, 0.0), normal=(1.0, 0.0, 0.0))
    return build_meshfree_simulation(strip, 2700.0, ALUMINIUM, velocity=v, precracks=[cut], self_contact=contact), strip


def _smallest_gap(sim, strip, steps: int, dt: float) -> float:
    """The smallest x distance, over the run, between the particles either side of the cut that
    faced each other (x = 20 and 24 mm, same y and z)."""
    X = strip.X
    left = np.flatnonzero(np.isclose(X[:, 0], 0.020))
    right = np.flatnonzero(np.isclose(X[:, 0], 0.024))
    left = left[np.lexsort((X[left, 2], X[left, 1]))]
    right = right[np.lexsort((X[right, 2], X[right, 1]))]
    gap = np.inf
    for _ in range(steps // 20):
        sim.advance(20, dt)
        gap = min(gap, float(np.min(sim.particles.x[right, 0] - sim.particles.x[left, 0])))
    return gap


def test_crack_faces_closing_do_not_pass_through_each_other():
    """Self-contact across a crack: a strip cut through by a pre-crack, its far piece driven back
    into the near one at 20 m/s for 2 spacings' worth of travel. With run.contact the faces meet
    and part (the particles that faced each other across the cut never come closer than 0.9 of
    their 4 mm spacing; measured 3.995 mm) and the energy holds to 1 % (measured +0.20 %); without it the pieces pass
    through each other (the same gap goes negative), so the check can fail."""
    sim, strip = _cut_strip(contact=True)
    dt = 0.7 * sim.stable_dt
    energy = _total(sim, dt)
    steps = int(0.008 / 20.0 / dt)
    assert _smallest_gap(sim, strip, steps, dt) > 0.9 * 0.004
    assert abs(_total(sim, dt) - energy) < 0.01 * energy
    loose, strip = _cut_strip(contact=False)
    assert _smallest_gap(loose, strip, steps, dt) < 0.0


def _folded_wall(contact: bool):
    """A wall folded into a U (gmsh, 2 mm tets, a particle at each node: 357): a 20 x 20 x 6 mm
    block less a 14 x 17 mm slot, two 3 mm arms 14 mm apart on a 3 mm base; a soft solid (2 GPa,
    1000 kg/m^3), the arms thrown at each other at 60 m/s."""
    from crackle.geometry.meshes import _gmsh_model, _gmsh_tets
    from crackle.meshfree.particles import tet_node_particles

    with _gmsh_model(0.002) as gmsh:
        block = gmsh.model.occ.addBox(0.0, 0.0, 0.0, 0.020, 0.020, 0.006)
        slot = gmsh.model.occ.addBox(0.003, 0.003, 0.0, 0.014, 0.017, 0.006)
        gmsh.model.occ.cut([(3, block)], [(3, slot)])
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(3)
        mesh = _gmsh_tets(gmsh)
    wall = tet_node_particles(mesh.points, mesh.tets)
    X = wall.X
    v = np.zeros_like(X)
    arms = X[:, 1] > 0.006
    v[arms & (X[:, 0] < 0.01), 0] = 60.0
    v[arms & (X[:, 0] > 0.01), 0] = -60.0
    return build_meshfree_simulation(wall, 1000.0, J2Law(2e9, 0.3), velocity=v, self_contact=contact), X


def test_the_arms_of_a_folded_wall_do_not_pass_through_each_other():
    """Self-contact between particles of one body that were never linked (further apart than its
    support radius, as a flap folded onto its plate): the two arms of a U thrown at each other at
    60 m/s for 3,000 steps. With run.contact their inner faces stop short of each other (the
    smallest gap between them stays positive; measured 1.31 mm, the contact reach 2 mm) and the
    energy holds to 1 % (measured +0.07 %); without it they pass through (measured -7.9 mm)."""
    for contact in (True, False):
        sim, X = _folded_wall(contact)
        dt = 0.7 * sim.stable_dt
        energy = _total(sim, dt)
        left, right = np.flatnonzero(X[:, 0] < 0.0031), np.flatnonzero(X[:, 0] > 0.0169)
        gap = np.inf
        for _ in range(150):
            sim.advance(20, dt)
            gap = min(gap, float(sim.particles.x[right, 0].min() - sim.particles.x[left, 0].max()))
        if contact:
            assert gap > 0.0
            assert abs(_total(sim, dt) - energy) < 0.01 * energy
        else:
            assert gap < -0.002


def test_a_crack_opening_under_compression_starts_without_overlap():
    """The reach of a pair whose link fracture cut is at most their distance when the contact
    first sees them: two particles of one body 4 mm apart in the reference, pressed to 3.9 mm
    when their link is cut, get a reach of 3.9 mm (no spring loaded by the cut itself), and keep it
    on the next build even when they have moved apart."""
    sim, strip = _cut_strip(contact=True, speed=0.0)
    c = sim.contact
    i = int(np.flatnonzero(np.isclose(strip.X[:, 0], 0.020))[0])
    j = int(np.flatnonzero(np.all(np.isclose(strip.X, strip.X[i] + [0.004, 0.0, 0.0]), axis=1))[0])
    x = strip.X.copy()
    x[j, 0] -= 0.0001
    c.build(x, sim.breaking.blocked)
    row = slice(c.pairs.start[i], c.pairs.start[i + 1])
    assert c.pairs.reach[row][c.pairs.other[row] == j][0] == pytest.approx(0.0039, rel=1e-9)
    assert c.energy(x) == 0.0
    x[j, 0] += 0.0002
    c.build(x, sim.breaking.blocked)
    row = slice(c.pairs.start[i], c.pairs.start[i + 1])
    assert c.pairs.reach[row][c.pairs.other[row] == j][0] == pytest.approx(0.0039, rel=1e-9)


def test_two_body_contact_identical_for_1_and_2_threads():
    """The two plates' collision: positions and velocities after 600 steps bit-identical with 1
    and 2 numba threads (the contact pass gathers; both rows of a pair compute the same numbers)."""
    script = (
        "import sys, hashlib, numpy as np; sys.path.insert(0, %r); import test_meshfree_contact as t; "
        "sim = t._two_plates(); dt = 0.7 * sim.stable_dt; sim.advance(300, dt); sim.advance(300, dt); "
        "p = sim.particles; h = hashlib.sha256(); [h.update(np.ascontiguousarray(a).tobytes()) for a in (p.x, p.v)]; "
        "print(h.hexdigest(), sim.contact.builds)"
    ) % os.path.dirname(__file__)
    out = outputs_with_1_and_2_threads(script)
    assert out[0] == out[1]


def _scenario(tmp_path, body: str) -> str:
    path = tmp_path / "s.toml"
    path.write_text(f"""
method = "meshfree"
[specimen]
shape = "box"
size = [0.1, 0.1, 0.005]
[particles]
spacing = 0.02
[material]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3
[run]
end_time = 1e-6
{body}
""")
    return str(path)


def test_body_keys_are_checked_with_their_names(tmp_path):
    """[[bodies]]: a sphere needs its radius and element size, a body cannot fracture, and a body
    placed into the specimen is refused at set-up, each naming the key."""
    sphere = """[[bodies]]
shape = "sphere"
radius = 0.01
center = [0.05, 0.05, 0.05]
{extra}
[bodies.material]
density = 7800.0
youngs_modulus = 210e9
poissons_ratio = 0.3
{material}"""
    with pytest.raises(ScenarioError, match="needs radius, element_size|needs element_size"):
        load_scenario(_scenario(tmp_path, sphere.format(extra="", material="")))
    with pytest.raises(ScenarioError, match="tensile_strength: a body besides the specimen does not fracture"):
        load_scenario(_scenario(tmp_path, sphere.format(extra="element_size = 0.005",
                                                        material="tensile_strength = 1e8")))
    from crackle.api import build_simulation

    inside = sphere.format(extra="element_size = 0.005", material="").replace("[0.05, 0.05, 0.05]",
                                                                             "[0.05, 0.05, 0.012]")
    scenario, base = load_scenario(_scenario(tmp_path, inside))
    with pytest.raises(ScenarioError, match="bodies: .* overlap at the start"):
        build_simulation(scenario, base)


def test_plate_impact_deformable_example_quick(tmp_path):
    """The shipped example plate-impact-deformable --quick: paper 000's steel sphere (a 40 mm ball
    of 384 particles, 210 GPa, 1400 MPa) at 300 m/s on the clamped plate (21 x 21 x 3 particles,
    60 us), meeting it by the particle contact: the plate is perforated (a hole between 20 and 100
    mm across; measured 63 mm), the sphere slowed but through (measured 237 m/s; summary.json
    bodies), the energy audit, contact and damage included, within 1 % (measured +0.0003 %)."""
    from crackle.cli import main
    import json

    out = tmp_path / "o"
    assert main(["run", "plate-impact-deformable", "--quick", "--out", str(out), "--set", "run.field_frames=1"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["particles"] == 1323 + 384
    sphere = s["bodies"][0]
    assert sphere["particles"] == 384 and 150.0 < sphere["speed"] < 295.0 and sphere["velocity"][2] < 0.0
    assert 0.02 < s["hole_diameter"] < 0.1 and s["failed_particles"] > 0
    assert abs(s["energy_error"]) < 0.01

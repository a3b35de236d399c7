"""Several materials in one meshfree specimen ([materials.NAME] with zones or a mesh file's groups):
each particle steps with its own material's law, density and fracture thresholds. A two-metal
strip pulled quasi-statically is two springs in series; the weaker half yields or breaks alone;
the stable step follows the stiffest, lightest material; bad tables stop with exit 2."""

from __future__ import annotations

import json
import os

import meshio
import numpy as np
import pytest

from crackle.cli import main
from crackle.geometry.meshes import read_mesh, structured_box
from crackle.io import read_events_csv, read_pvd
from crackle.meshfree import build_simulation
from crackle.scenario import load_scenario
from threads import outputs_with_1_and_2_threads

# A 120 x 6 x 2 mm strip along x (61 x 4 x 3 particles), its end faces on rollers along x: the
# left one held, the right one pulled by `grip` (a velocity history). {materials} are the two
# halves, the left one filling the rest, the right one the half-space x >= 60 mm.
STRIP = """
name = "two-metal-strip"
method = "meshfree"

[specimen]
shape = "box"
size = [0.12, 0.006, 0.002]

[particles]
spacing = 0.002
layers = 3

{materials}

[[supports]]
kind = "roller"
normal = [1.0, 0.0, 0.0]
where = {{ box_min = [-0.001, -0.001, -0.001], box_max = [0.0005, 0.007, 0.003] }}

[[supports]]
name = "grip"
kind = "roller"
normal = [1.0, 0.0, 0.0]
where = {{ box_min = [0.1195, -0.001, -0.001], box_max = [0.121, 0.007, 0.003] }}
{grip}

[run]
end_time = {end_time}
damping = {damping}
history_samples = 20
field_frames = 1
"""
RIGHT_HALF = 'zones = [{shape = "half-space", point = [0.06, 0.0, 0.0], normal = [1.0, 0.0, 0.0]}]'
# Aluminium and steel, elastic; one Poisson's ratio, so that the interface does not hold the
# halves' lateral contraction against each other (uniaxial stress in both).
ALUMINIUM_STEEL = f"""
[materials.aluminium]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3

[materials.steel]
density = 7800.0
youngs_modulus = 210e9
poissons_ratio = 0.3
{RIGHT_HALF}
"""
# The grip's speed rises to 0.2 m/s at 40 us and falls back to 0 at 80 us (an 8 um pull, ~7 MPa in
# the strip), then holds: slow against the first axial mode (a period 2 L / c ~ 47 us).
SLOW_PULL = 'speed_table = { time = [0.0, 4e-5, 8e-5], speed = [0.0, 0.2, 0.0] }'
# Damping 1.3e5 /s (half the first axial mode's critical 2 omega_1 = 2.7e5 /s): every mode decays at
# 6.5e4 /s, by e^-5 from 80 to 160 us; at rest the damping force is 0: the final state is the static one.
SETTLE = {"end_time": 1.6e-4, "damping": 1.3e5}


def _scenario(tmp_path, materials: str, grip: str = SLOW_PULL, name: str = "strip", **run) -> str:
    path = tmp_path / f"{name}.toml"
    path.write_text(STRIP.format(materials=materials, grip=grip, **{**SETTLE, **run}))
    return str(path)


def _build(path, *overrides):
    scenario, base = load_scenario(path, list(overrides))
    return build_simulation(scenario, base)


def _advance_to_end(sim, end_time: float) -> None:
    dt = 0.7 * sim.stable_dt
    sim.advance(int(np.ceil(end_time / dt)), dt)


def _window(X, lo, hi):
    return (X[:, 0] > lo) & (X[:, 0] < hi)


def _strain_and_stress(sim, lo, hi):
    """The axial strain (the slope of u_x over X, least squares) and the mean Cauchy sigma_xx (Pa)
    of the particles with lo < X < hi (m)."""
    p = sim.particles
    inside = _window(p.X, lo, hi)
    slope = np.polyfit(p.X[inside, 0], (p.x - p.X)[inside, 0], 1)[0]
    return slope, float(np.mean(sim.cauchy_stress()[inside, 0]))


def test_two_metal_strip_is_two_springs_in_series(tmp_path):
    """Aluminium (E = 70 GPa, x < 60 mm) and steel (210 GPa) halves of one strip, pulled slowly
    by 8 um and left to settle: in the middle 30 mm of each half (15 mm, 3 support radii, from
    the ends and the interface) the axial stress is one value (measured 7.06 MPa), sigma_al =
    sigma_st within 1 % (measured 0.02 %), the strains' ratio is E_st / E_al = 3 within 2 %
    (measured 2.9987), and each half's stress over its strain is its own modulus within 2 %
    (measured 70.10 and 210.24 GPa: uniaxial stress, the lateral contraction free). The
    particles carry their material (0, 1) by their reference position (the interface's column,
    on the half-space's plane, steel's) and its density, and the settled strip is at rest (its
    fastest particle below 0.5 % of the grip's peak speed; measured 0.1 %)."""
    sim = _build(_scenario(tmp_path, ALUMINIUM_STEEL))
    p = sim.particles
    right = p.X[:, 0] >= 0.06
    assert np.array_equal(p.material, right.astype(np.int64)) and sim.material_names == ["aluminium", "steel"]
    assert p.mass / p.volume == pytest.approx(np.where(right, 7800.0, 2700.0), rel=1e-12)
    _advance_to_end(sim, SETTLE["end_time"])
    eps_al, sigma_al = _strain_and_stress(sim, 0.015, 0.045)
    eps_st, sigma_st = _strain_and_stress(sim, 0.075, 0.105)
    assert sigma_al > 5e6, "the strip must be loaded"
    assert sigma_st == pytest.approx(sigma_al, rel=0.01)
    assert eps_al / eps_st == pytest.approx(3.0, rel=0.02)
    assert sigma_al / eps_al == pytest.approx(70e9, rel=0.02)
    assert sigma_st / eps_st == pytest.approx(210e9, rel=0.02)
    assert np.max(np.abs(p.v)) < 5e-3 * 0.2


# Two steels, one yielding at 100 MPa (the right half, next to the grip), one at 300 MPa,
# perfectly plastic; pulled by 0.12 mm (an elastic strip would carry E 0.12 / 120 = 200 MPa).
HARD_SOFT = f"""
[materials.hard]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
yield_stress = 300e6

[materials.soft]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
yield_stress = 100e6
{RIGHT_HALF}
"""
# 3 m/s at 40 us, 0 at 80 us: a pull of 0.12 mm, then held.
LONG_PULL = 'speed_table = { time = [0.0, 4e-5, 8e-5], speed = [0.0, 3.0, 0.0] }'


def test_the_lower_yield_stress_half_yields_alone(tmp_path):
    """Steel halves yielding at 300 MPa (left) and 100 MPa (right), pulled by 0.12 mm and left to
    settle: the strip carries no more than the weaker yield stress (an elastic one would carry
    200 MPa): both halves' axial stress is one value between 0.9 and 1 x 100 MPa (measured 95.3
    MPa, elastically unloaded from the flow by the settling); the soft half yields (measured up
    to 0.024 near the grip) and every particle of the hard one keeps exactly zero plastic strain;
    and the plastic elongation, sum of V eps_p / A over the soft half, is the pull less the
    elastic stretch, 0.12 mm - sigma L / E (statics), within 3 % (measured -1.2 %)."""
    sim = _build(_scenario(tmp_path, HARD_SOFT, grip=LONG_PULL))
    _advance_to_end(sim, SETTLE["end_time"])
    p = sim.particles
    plastic = sim.per_particle(p.eq_plastic)
    soft = p.material == 1
    _, sigma_hard = _strain_and_stress(sim, 0.015, 0.045)
    _, sigma_soft = _strain_and_stress(sim, 0.075, 0.105)
    assert sigma_soft == pytest.approx(sigma_hard, rel=0.01)
    assert 0.9 * 100e6 < sigma_hard <= 100e6
    assert np.all(plastic[~soft] == 0.0) and plastic[soft].max() > 1e-3
    elongation = np.sum(p.volume[soft] * plastic[soft]) / (0.006 * 0.002)
    assert elongation == pytest.approx(1.2e-4 - sigma_hard * 0.12 / 200e9, rel=0.03)


# Two steels, breaking at 3 x 30 MPa (left, the weak one) and 3 x 300 MPa, elastic.
WEAK_STRONG = f"""
[materials.weak]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
tensile_strength = 30e6

[materials.strong]
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
tensile_strength = 300e6
{RIGHT_HALF}
"""


def test_the_weaker_half_breaks_alone_and_the_outputs_say_so(tmp_path):
    """Steel halves breaking at 3 x 30 MPa (left, held) and 3 x 300 MPa (right, pulled at 1.4 m/s,
    no damping), through the command line to 40 us: the pull sends a wave of rho c v = 55 MPa
    (c = sqrt(E / rho), the bar's) through both halves (one impedance: nothing reflects at the
    interface) that breaks nothing, and its reflection at the held end doubles it to 110 MPa,
    above the weak half's 90 MPa: the first failure is at the held end (x < 5 mm) when the
    reflection reaches it, (L + x) / c, within 5 % (measured +2.7 %: the front rises over a few
    spacings). summary.json's failures_by_material counts the failed particles, all weak
    (measured 20), its material_names say which index is which, and the VTU's `material` is 1
    on the right half and 0 on every failed particle; events.csv names each failure's material."""
    out = tmp_path / "out"
    path = _scenario(tmp_path, WEAK_STRONG, grip="speed = 1.4\ndirection = [1.0, 0.0, 0.0]", end_time=4e-5,
                     damping=0.0)
    assert main(["run", path, "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["material_names"] == ["weak", "strong"]
    assert s["failed_particles"] > 0 and s["failures_by_material"] == {"weak": s["failed_particles"]}
    events = read_events_csv(out / "events.csv")
    assert set(events["material"]) == {"weak"} and len(events["material"]) == s["failed_particles"]
    events = np.stack([events["time"], events["x"]], axis=1)
    first = events[np.argmin(events[:, 0])]
    c = np.sqrt(200e9 / 7800.0)
    assert first[1] < 0.005 and first[0] == pytest.approx((0.12 + first[1]) / c, rel=0.05)
    mesh = meshio.read(read_pvd(out / "fields.pvd")[-1][1])
    X = mesh.points - mesh.point_data["displacement"]
    material = mesh.point_data["material"]
    assert np.array_equal(material, (X[:, 0] >= 0.06 - 1e-9).astype(material.dtype))
    assert np.all(material[mesh.point_data["failed"] > 0] == 0)


# A stiff, light material (c = sqrt(400e9 / 2000) = 14.1 km/s) beside aluminium (5.1 km/s).
LIGHT = """
[{table}]
density = 2000.0
youngs_modulus = 400e9
poissons_ratio = 0.3
"""
ALUMINIUM = """
[{table}]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3
"""


def test_the_stable_step_follows_the_stiffest_lightest_material(tmp_path):
    """The stable step (Lanczos on the whole step, per-particle masses and laws) of the strip half
    aluminium, half a stiff light material is that of the stiff material alone within 5 %
    (measured -0.3 %), and far below aluminium's (the wave speeds' ratio 2.8: below 0.5 x;
    measured 0.37)."""
    def stable_dt(materials, name):
        return _build(_scenario(tmp_path, materials, name=name)).stable_dt

    two = stable_dt(ALUMINIUM.format(table="materials.aluminium") + LIGHT.format(table="materials.light")
                    + RIGHT_HALF, "two")
    light = stable_dt(LIGHT.format(table="material"), "light")
    aluminium = stable_dt(ALUMINIUM.format(table="material"), "aluminium")
    assert two == pytest.approx(light, rel=0.05)
    assert two < 0.5 * aluminium


def test_materials_by_the_mesh_files_groups(tmp_path):
    """A tet mesh file (an Abaqus .inp) with two *Elset groups, the halves x < 20 mm and x > 20 mm
    of a 40 x 10 x 10 mm bar: each material fills its group's particles (a node takes the group
    holding the most of its cell: every node off the plane x = 20 mm its side's), and the nodes on
    the plane whose cell is half in each (most of them: measured 36 of 41) take the later
    material's, as where two zones overlap."""
    mesh = structured_box((0.04, 0.01, 0.01), 0.0025)
    centroid = mesh.points[mesh.tets].mean(axis=1)[:, 0]
    meshio.Mesh(mesh.points, [("tetra", mesh.tets)],
                cell_sets={"left": [np.flatnonzero(centroid < 0.02)],
                           "right": [np.flatnonzero(centroid >= 0.02)]}).write(tmp_path / "bar.inp")
    path = tmp_path / "bar.toml"
    path.write_text('''
method = "meshfree"
[specimen]
shape = "mesh"
file = "bar.inp"
[materials.steel]
group = "right"
density = 7800.0
youngs_modulus = 200e9
poissons_ratio = 0.3
[materials.aluminium]
group = "left"
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3
[run]
end_time = 1e-6
''')
    sim = _build(path)
    X = sim.particles.X
    mesh = read_mesh(tmp_path / "bar.inp")  # as the set-up read it (its numbering)
    centroid = mesh.points[mesh.tets].mean(axis=1)[:, 0]
    # Each node's share of its cell (a quarter of each tet around it) on either side.
    quarter = np.abs(np.linalg.det(mesh.points[mesh.tets[:, 1:]] - mesh.points[mesh.tets[:, :1]])) / 24.0
    right = centroid >= 0.02
    share_right, share_left = (np.bincount(mesh.tets[side].ravel(), weights=np.repeat(quarter[side], 4),
                                           minlength=len(X)) for side in (right, ~right))
    tie = np.abs(share_right - share_left) <= 1e-9 * (share_right + share_left)
    expected = np.where((share_right > share_left) & ~tie, 0, 1)  # a tie: aluminium, the later
    on_plane = np.abs(X[:, 0] - 0.02) < 1e-9
    assert np.array_equal(expected[~on_plane], (X[~on_plane, 0] < 0.02).astype(int))
    assert np.sum(on_plane & tie) > 0.5 * on_plane.sum()  # most on the plane tie
    assert np.array_equal(sim.particles.material, expected) and sim.material_names == ["steel", "aluminium"]


@pytest.mark.parametrize("materials, message", [
    (ALUMINIUM_STEEL + ALUMINIUM.format(table="material"), "not both"),
    (ALUMINIUM_STEEL.replace(RIGHT_HALF, ""), "only one material may fill the rest"),
    (ALUMINIUM_STEEL.replace("[materials.aluminium]", "[materials.aluminium]\n" + RIGHT_HALF.replace("0.06", "0.03")),
     "lie in no material's group or zones"),
    (ALUMINIUM_STEEL.replace(RIGHT_HALF, 'group = "right"'), "materials.steel.group: groups come from a mesh file"),
    ("", "[material] is missing"),
])
def test_bad_material_tables_exit_2_with_the_fix(tmp_path, capsys, materials, message):
    """[material] beside [materials], two materials filling the rest, particles in no material
    (x < 30 mm: both claim half-spaces, none the rest), a group on a box, no material at all:
    exit 2 before the run, the message naming the table and the fix."""
    out = tmp_path / "out"
    assert main(["run", _scenario(tmp_path, materials), "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "history.csv").exists()


# The threads check: aluminium with a J2 law (hardening) and failure by plastic strain drawn per
# particle (lognormal), steel with the thermo law (yielding at 400 MPa), pulled fast (4 m/s).
MIXED = f"""
[materials.aluminium]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3
yield_stress = 100e6
hardening_exponent = 1.0
reference_plastic_strain = 0.1
failure_plastic_strain = 0.004
[materials.aluminium.random.failure_plastic_strain]
distribution = "lognormal"
cv = 0.3

[materials.steel]
model = "thermo"
density = 7800.0
youngs_modulus = 210e9
poissons_ratio = 0.3
yield_stress = 400e6
tensile_strength = 200e6
{RIGHT_HALF}
"""


def test_two_materials_identical_for_1_and_2_threads(tmp_path):
    """The strip of a J2 aluminium whose failure plastic strains are drawn per particle and a thermo
    steel, pulled at 4 m/s: after 700 steps positions, velocities, plastic strain, temperature,
    failed particles and removed links bit-identical with 1 and 2 numba threads; the compared run
    yields and breaks in the aluminium only, and draws a failure strain for each aluminium particle
    and none for the steel's (their plain inf)."""
    path = _scenario(tmp_path, MIXED, grip="speed = 4.0\ndirection = [1.0, 0.0, 0.0]", damping=0.0, name="mixed")
    script = (
        "import sys, hashlib, numpy as np; sys.path.insert(0, %r); import test_meshfree_materials as t; "
        "sim = t._build(%r); dt = 0.7 * sim.stable_dt; sim.advance(350, dt); sim.advance(350, dt); "
        "p = sim.particles; b = sim.breaking; h = hashlib.sha256(); "
        "[h.update(np.ascontiguousarray(a).tobytes()) for a in (p.x, p.v, p.eq_plastic, p.thermal, b.failed, "
        "b.blocked, np.array([b.damage]))]; al = p.material == 0; drawn = b.failure_strain; "
        "print(h.hexdigest(), float(p.eq_plastic.max()), int(b.failed[al].sum()), int(b.failed[~al].sum()), "
        "int(al.sum()), int(np.unique(drawn[al]).size), bool(np.all(np.isinf(drawn[~al]))))"
    ) % (os.path.dirname(__file__), path)
    digests = outputs_with_1_and_2_threads(script)
    assert digests[0][0] == digests[1][0]
    _, plastic, failed_al, failed_steel, n_al, distinct, steel_plain = digests[0]
    assert float(plastic) > 0.0 and int(failed_al) > 0, "the compared run must yield and break"
    assert int(failed_steel) == 0 and int(distinct) == int(n_al) and steel_plain == "True"

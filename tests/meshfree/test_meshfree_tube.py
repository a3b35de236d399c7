"""The meshfree method on a tube and under pressures (crackle.meshfree, paper 000 section 4.3):
the tube's particles and polyhedral cells, the patch tests on them, the follower pressure on
the wall faces (Nanson), the travelling detonation front and the tube-detonation example.
Small particle counts: seconds once the kernels are compiled."""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from crackle.cli import main
from crackle.loading import History, Pressure, Selection
from crackle.meshfree.build import build_meshfree_simulation
from crackle.meshfree.material import J2Law
from crackle.meshfree.particles import plate_particles, tube_particles
from crackle.meshfree.shape import FULL_BASIS
from meshfree_fields import ROUNDING, linear_field_errors
from threads import outputs_with_1_and_2_threads

E_AL, NU, RHO_AL = 70e9, 0.3, 2700.0
EVERYWHERE = Selection(box_min=(-1.0, -1.0, -1.0), box_max=(1.0, 1.0, 1.0))
# A short thick tube along z: 44 particles around, 7 along, 3 through the 2 mm wall (924).
RI, WALL, LENGTH, SPACING = 0.02, 0.002, 0.018, 0.003


def _tube(origin=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), length=LENGTH):
    return tube_particles(origin, axis, RI, WALL, length, SPACING, 3)


def test_tube_cells_are_closed_and_share_their_faces():
    """A tube along a skew axis (1, 2, 2) from (0.1, 0.2, 0.3): 44 x 7 x 3 particles; every cell's
    area vectors sum to zero (closed; below 1e-12 of a face's), every face inside the wall is
    used by exactly two cells with exactly opposite area vectors, and the cells fill the faceted
    tube: their volumes sum to (n / 2) sin(2 pi / n) (ro^2 - ri^2) L (the annulus between two
    regular n-gons, n = 44) within 1e-12."""
    tube = _tube((0.1, 0.2, 0.3), (1.0, 2.0, 2.0))
    n = len(tube.X)
    assert n == 44 * 7 * 3
    area = tube.cells.weight.reshape(n, 6, 3)  # one quadrature row a face: its area vector
    assert np.abs(area.sum(axis=1)).max() < 1e-12 * np.abs(area).max()
    faces = {}
    for centre, a in zip(tube.cells.points[tube.cells.point], tube.cells.weight):
        faces.setdefault(centre.tobytes(), []).append(a)
    shared = [pair for pair in faces.values() if len(pair) == 2]
    assert max(len(pair) for pair in faces.values()) == 2
    assert all(np.array_equal(a, -b) for a, b in shared)
    # Faces inside the wall: 2 radial per column, 3 around per ring... counted directly.
    assert len(shared) == 44 * 7 * 2 + 44 * 7 * 3 + 44 * 6 * 3
    ro = RI + WALL
    faceted = 22 * math.sin(2 * math.pi / 44) * (ro**2 - RI**2) * LENGTH
    assert tube.volume.sum() == pytest.approx(faceted, rel=1e-12)


def test_tube_patch_test_linear_field():
    """On the skew tube, a linear field u = A X + b: the MLS shape functions reproduce its values
    at every particle (1e-10 of |u|; measured 4e-14) and the gradients smoothed over the
    polyhedral cells (SCNI) are exact at every particle, ends and walls included (1e-10 of |A|;
    measured 2e-12)."""
    tube = _tube((0.1, 0.2, 0.3), (1.0, 2.0, 2.0))
    value_error, gradient_error = linear_field_errors(tube.X, tube.volume, tube.cells, 2.5 * float(np.max(tube.spacing)),
                                                      FULL_BASIS)
    assert value_error < 1e-10 and gradient_error < 1e-10


def test_tube_uniform_axial_stress_leaves_the_inside_in_equilibrium():
    """The integration constraint on the tube's cells: uniaxial stress along the axis (Green strain
    e = 1e-3 along z, -nu e across: S = E e along z only) loads no wall face (their normals are
    radial), so only the particles the ends' traction reaches feel a force; every particle
    farther than R + a/2 from both ends (R the support radius, a the axial step) is in
    equilibrium to ROUNDING of E e a^2, while the ends do pull (> 1e-2 of it;
    measured 0.38)."""
    tube = _tube(length=0.03)
    sim = build_meshfree_simulation(tube, RHO_AL, J2Law(E_AL, NU))
    p = sim.particles
    e = 1e-3
    p.x[:] = p.X * np.sqrt(1.0 + 2.0 * np.array([-NU * e, -NU * e, e]))
    dt = 1e-10
    sim.advance(1, dt)  # from rest: v = dt f / m
    force = p.v * p.mass[:, None] / dt
    assert p.stress[:, 2] == pytest.approx(E_AL * e, rel=ROUNDING)
    a = tube.spacing[1]
    z = p.X[:, 2]
    far = np.minimum(z, 0.03 - z) >= sim.support_radius + 0.5 * a - 1e-9
    assert far.sum() == 3 * 44 * 3
    scale = E_AL * e * a**2
    assert np.max(np.abs(force[far])) < ROUNDING * scale
    assert np.max(np.abs(force[~far])) > 1e-2 * scale


def _hoop_stress(sim):
    """Per particle, the Cauchy hoop stress of a tube along z through the origin."""
    X = sim.particles.X
    radial = X * np.array([1.0, 1.0, 0.0])
    radial /= np.linalg.norm(radial, axis=1)[:, None]
    hoop = np.stack([-radial[:, 1], radial[:, 0], np.zeros(len(X))], axis=1)
    s = sim.cauchy_stress()
    S = np.stack([s[:, [0, 3, 5]], s[:, [3, 1, 4]], s[:, [5, 4, 2]]], axis=1)
    return np.einsum("na,nab,nb->n", hoop, S, hoop)


def test_static_internal_pressure_gives_the_hoop_stress():
    """An open tube (ri = 20 mm, wall 2 mm, free ends, 12 mm long) under an internal pressure
    p = 1 MPa ramped over one breathing period 2 pi r / c, with mass-proportional damping at twice
    the breathing frequency (critical for that mode) to reach the static state in 70 us (kinetic
    energy below 1e-6 of the elastic): the hoop stress at mid-length, averaged through the wall
    with the layers' shares (1/4, 1/2, 1/4), converges to the force balance p ri / t = 10 MPa
    (Lame's mean): within 2 % at a 2 mm spacing (66 x 7 x 3 particles; measured -1.5 %), and
    its error at 3 mm (44 x 5 x 3; measured -5.3 %) is at least (3/2)^2 times that (second order
    in the spacing over the radius; measured 3.6 x). At both it falls through the wall as Lame's
    sigma = A (1 + ro^2 / r^2) does (inner > middle > outer; measured 10.36, 9.83, 9.40 MPa at
    2 mm for Lame's 10.52, 9.99, 9.52) and is the same all around (scatter below 1e-6 of it;
    the tube's particles are axisymmetric)."""
    c = math.sqrt(E_AL / (RHO_AL * (1.0 - NU**2)))
    omega = c / (RI + 0.5 * WALL)
    p0 = 1e6
    errors = []
    for spacing, around in ((0.003, 44), (0.002, 66)):
        tube = tube_particles((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), RI, WALL, 0.012, spacing, 3)
        load = Pressure(History.ramp(p0, 2.0 * math.pi / omega), EVERYWHERE, wall="inner")
        sim = build_meshfree_simulation(tube, RHO_AL, J2Law(E_AL, NU), pressures=[load], damping=2.0 * omega)
        dt = 0.7 * sim.stable_dt
        sim.advance(int(7e-5 / dt), dt)
        terms = sim.energies(dt)
        assert terms["energy.kinetic"] < 1e-6 * terms["energy.elastic"]
        hoop = _hoop_stress(sim)
        X = sim.particles.X
        r = np.linalg.norm(X[:, :2], axis=1)
        mid = np.abs(X[:, 2] - 0.006) < 1e-9
        layers = [hoop[mid & np.isclose(r, RI + 0.5 * WALL * k)] for k in range(3)]
        assert all(len(layer) == around for layer in layers)
        mean = 0.25 * layers[0].mean() + 0.5 * layers[1].mean() + 0.25 * layers[2].mean()
        errors.append(mean / (p0 * RI / WALL) - 1.0)
        assert layers[0].mean() > layers[1].mean() > layers[2].mean()
        assert all(layer.std() < 1e-6 * mean for layer in layers)
    assert abs(errors[1]) < 0.02
    assert abs(errors[0]) > 1.5**2 * abs(errors[1])


def test_pressurised_tube_energy_audit():
    """The same tube under a sudden internal pressure of 1 MPa, undamped (it rings): the work of
    the follower pressure (-p J F^-T A0 N on the inner wall's faces, counted with the step's
    velocities) equals the kinetic, elastic and stabilisation energy within 1 % (measured
    -1.2e-4) after 300 steps (44 x 5 x 3 particles)."""
    load = Pressure(History.constant(1e6), EVERYWHERE, wall="inner")
    sim = build_meshfree_simulation(_tube(length=0.012), RHO_AL, J2Law(E_AL, NU), pressures=[load])
    dt = 0.7 * sim.stable_dt
    sim.advance(300, dt)
    terms = sim.energies(dt)
    external = terms.pop("energy.external")
    assert external > 0.0 and terms["energy.elastic"] > 0.1 * external
    assert abs(external - sum(terms.values())) < 0.01 * external


def test_plate_pressure_force_is_p_times_the_face():
    """A plate 20 x 16 x 2 mm: a pressure p = 2 MPa on its outer (upper, +z) face pushes it
    with p Lx Ly along -z at the first step (from rest: sum m v / dt, within 1e-12), only on the
    upper layer's particles; on both faces the forces cancel (below 1e-12 of p Lx Ly)."""
    plate = plate_particles((0.0, 0.0, 0.0), (0.02, 0.016, 0.002), 0.002, 3)
    p0, dt = 2e6, 1e-9
    for wall, expected in (("outer", -p0 * 0.02 * 0.016), (None, 0.0)):
        load = Pressure(History.constant(p0), EVERYWHERE, wall=wall)
        sim = build_meshfree_simulation(plate, RHO_AL, J2Law(E_AL, NU), pressures=[load])
        sim.advance(1, dt)
        momentum = (sim.particles.mass[:, None] * sim.particles.v).sum(axis=0) / dt
        assert np.abs(momentum - [0.0, 0.0, expected]).max() < 1e-12 * p0 * 0.02 * 0.016
        if wall == "outer":
            moved = np.flatnonzero(np.any(sim.particles.v != 0.0, axis=1))
            assert np.all(np.isclose(plate.X[moved, 2], 0.002))


def test_detonation_front_arrives_at_s_over_d():
    """A Taylor-wave detonation (p_CJ = 6.1 MPa at the front, decay time 20 us to 0.4 p_CJ)
    running along a 24 mm tube at D = 2350 m/s from its first end: each inner-wall face first
    pushes (its particle's external work turns nonzero) at the first step at or after s / D,
    s the face centre's distance along the axis (to one step: 0 <= t - s / D < dt), the outer
    wall never; and the audit with the detonation's work closes within 1 % (measured -4.3e-4)."""
    D = 2350.0
    load = Pressure(History.taylor_wave(6.1e6, 0.4, 2e-5), EVERYWHERE, wall="inner", front_speed=D)
    tube = _tube(length=0.024)
    sim = build_meshfree_simulation(tube, RHO_AL, J2Law(E_AL, NU), pressures=[load])
    dt = 0.7 * sim.stable_dt
    n = len(tube.X)
    first = np.full(n, np.inf)
    while sim.time < 0.024 / D + 2 * dt:
        t = sim.time
        sim.advance(1, dt)
        first[(sim.particles.w_external != 0.0) & np.isinf(first)] = t
    surface = tube.surface
    inner = surface.particle[surface.side == 0]
    arrival = surface.centre[surface.side == 0, 2] / D
    assert np.all(first[inner] >= arrival - 1e-15) and np.all(first[inner] - arrival < dt)
    assert np.all(np.isinf(first[np.setdiff1d(np.arange(n), inner)]))
    terms = sim.energies(dt)
    external = terms.pop("energy.external")
    assert abs(external - sum(terms.values())) < 0.01 * external


def test_taylor_wave_history():
    """History.taylor_wave: p_CJ at the front, plateau + (1 - plateau) exp(-t / T) behind it,
    linear between samples within 2e-4 of the peak, held at the value of 10 T after."""
    h = History.taylor_wave(6.1e6, 0.4, 2e-5)
    t = np.linspace(0.0, 3e-4, 1001)
    exact = 6.1e6 * (0.4 + 0.6 * np.exp(-np.minimum(t, 2e-4) / 2e-5))
    assert h(0.0) == 6.1e6
    assert np.max(np.abs(h(t) - exact)) < 2e-4 * 6.1e6


TUBE = """
name = "mf-tube"
method = "meshfree"

[specimen]
shape = "tube"
inner_radius = 0.02
thickness = 0.002
length = 0.018

[particles]
spacing = 0.003

[material]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3

[[pressures]]
faces = "where"
where = { box_min = [-1.0, -1.0, -1.0], box_max = [1.0, 1.0, 1.0] }
wall = "inner"
value = 6.1e6
profile = "taylor"
decay_time = 2e-5
front_speed = 2350.0

[run]
end_time = 1e-5
history_samples = 10
field_frames = 0
"""


@pytest.mark.parametrize("overrides, field", [
    (['specimen.shape="box"', "specimen.size=[0.04, 0.04, 0.002]", "specimen.inner_radius=0.02"], "inner_radius"),
    (["particles.layers=2"], "particles.layers"),
    (['pressures.0.faces="precrack"'], "pressures.0.faces"),
    (["pressures.0.where.box_min=[2.0, 2.0, 2.0]", "pressures.0.where.box_max=[3.0, 3.0, 3.0]"], "pressures.0.where"),
    (['pressures.0.profile="history"'], "decay_time"),
    (["pressures.0.front_direction=[0.0, 0.0, 0.0]"], "front_direction"),
])
def test_bad_tube_and_pressure_input_exits_2(tmp_path, capsys, overrides, field):
    path = tmp_path / "tube.toml"
    path.write_text(TUBE)
    args = ["run", str(path), "--out", str(tmp_path / "o")]
    for o in overrides:
        args += ["--set", o]
    assert main(args) == 2
    assert field in capsys.readouterr().err


def test_front_on_a_plate_or_fdem_exits_2(tmp_path, capsys):
    """A travelling front needs a meshfree tube: on a plate the message names
    pressures.0.front_speed; the FDEM method refuses front_speed and wall by name."""
    plate = TUBE.replace('shape = "tube"\ninner_radius = 0.02\nthickness = 0.002\nlength = 0.018',
                         'shape = "box"\nsize = [0.04, 0.04, 0.002]\norigin = [-0.02, -0.02, 0.0]')
    path = tmp_path / "plate.toml"
    path.write_text(plate)
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "pressures.0.front_speed" in capsys.readouterr().err
    fdem = """
method = "fdem"
[specimen]
shape = "box"
size = [0.01, 0.01, 0.01]
element_size = 0.005
[material]
density = 2700.0
youngs_modulus = 70e9
poissons_ratio = 0.3
[material.interface]
law = "guo-munjiza"
tensile_strength = 3e6
cohesion = 15e6
friction_angle = 30.0
fracture_energy = 10.0
[[pressures]]
faces = "where"
where = { plane_point = [0.0, 0.0, 0.0], plane_normal = [0.0, 0.0, 1.0] }
value = 1e6
front_speed = 2350.0
[run]
end_time = 1e-6
"""
    path = tmp_path / "fdem.toml"
    path.write_text(fdem)
    assert main(["run", str(path), "--out", str(tmp_path / "f")]) == 2
    assert "pressures.0.front_speed" in capsys.readouterr().err


def test_tube_scenario_runs_with_the_detonation(tmp_path):
    """The scenario above through the command line (a Taylor-wave detonation entering the tube):
    it completes, the output contract holds (method, particles 924) and the audit closes within
    1 % (measured -2.7e-4)."""
    path = tmp_path / "tube.toml"
    path.write_text(TUBE)
    out = tmp_path / "o"
    assert main(["run", str(path), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["method"] == "meshfree" and s["particles"] == 924 and s["status"] == "completed"
    assert abs(s["energy_error"]) < 0.01


def test_tube_detonation_example_quick(tmp_path):
    """The shipped example tube-detonation --quick (paper 000 section 4.3's tube: ri 19.75 mm,
    wall 0.89 mm, 3 layers, 4 mm spacing, 60 mm long, clamped ends, shot 1's 25.4 mm axial notch
    at mid-length; a Taylor wave of p_CJ = 6.1 MPa at D = 2350 m/s on the inner wall, 30 us): the
    notch cuts links (measured 990 pairs), the run completes with the audit within 3 % (measured
    -0.007 %), and the wall yields (the front's step load overshoots the static hoop stress
    p r / t = 138 MPa about twice; the notch tips concentrate it: measured peak plastic strain
    0.015 there, below 0.1)."""
    out = tmp_path / "o"
    assert main(["run", "tube-detonation", "--quick", "--out", str(out), "--set", "run.field_frames=1"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["particles"] == 32 * 16 * 3
    assert s["precrack_links"] > 100
    assert abs(s["energy_error"]) < 0.03
    assert 0.0 < s["max_plastic_strain"] < 0.1


def test_pressurised_tube_identical_for_1_and_2_threads():
    """The detonation on the tube (follower pressure behind a travelling front, gathered per
    particle): its state after 200 steps (positions, velocities, external work per particle)
    bit-identical with 1 and 2 numba threads (subprocesses, as tests/core/test_determinism.py)."""
    script = (
        "import sys, hashlib, numpy as np; sys.path.insert(0, %r); import test_meshfree_tube as t; "
        "from crackle.loading import History, Pressure; "
        "from crackle.meshfree.build import build_meshfree_simulation; from crackle.meshfree.material import J2Law; "
        "load = Pressure(History.taylor_wave(6.1e6, 0.4, 2e-5), t.EVERYWHERE, wall='inner', front_speed=2350.0); "
        "sim = build_meshfree_simulation(t._tube(), t.RHO_AL, J2Law(t.E_AL, t.NU), pressures=[load]); "
        "dt = 0.7 * sim.stable_dt; sim.advance(200, dt); p = sim.particles; h = hashlib.sha256(); "
        "[h.update(np.ascontiguousarray(a).tobytes()) for a in (p.x, p.v, p.w_external)]; "
        "print(h.hexdigest(), float(np.abs(p.w_external).sum()))"
    ) % os.path.dirname(__file__)
    digests = outputs_with_1_and_2_threads(script)
    assert digests[0][0] == digests[1][0]
    assert float(digests[0][1]) > 0.0, "the pressure must have worked"

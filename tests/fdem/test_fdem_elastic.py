"""Elastic response of the assembled FDEM solver (exploded mesh + intact penalty interfaces).

Checks against closed forms: the static Young's modulus in uniaxial tension, the dilatational
wave speed and particle velocity of a step pulse in 1D strain, the discrete energy balance, and
conservation of linear / angular momentum under rigid motion.

Material: paper 001 Table 1 rock (E = 26 GPa, nu = 0.2, rho = 2340 kg/m^3, default interface
penalty factor 200). Time step: 0.8 of the model's stable step.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from crackle.fdem.model import build_fdem_model
from crackle.fdem.simulation import FdemSimulation
from crackle.geometry import gmsh_box, structured_box
from crackle.loading import History, Pressure, Selection, Support

from fdem_helpers import E, FT, NU, RHO, bar_wave_speed, energy_error, p_wave_speed, rock, rotation


def build(mesh, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # element-size advice for fracture: irrelevant here
        return build_fdem_model(mesh, rock(), **kwargs)


def roller(point, normal):
    return Support("roller", Selection(plane_point=point, plane_normal=normal), normal=normal)


# ---------------------------------------------------------------------------------------------
# Static Young's modulus
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mesher", ["structured", "gmsh"])
def test_effective_youngs_modulus(mesher):
    """Quasi-static uniaxial tension of a 60 x 20 x 20 mm block (h = 10 mm) below f_t.

    Rollers on x = 0, y = 0, z = 0 (symmetry planes), tension sigma = 1 MPa on x = L ramped over
    half a period of the first mode, mass-proportional damping 2 omega_1 (critical for that
    mode, omega_1 = pi c / (2L), c = sqrt(E/rho)), 3 periods: every mode then decays as
    exp(-omega_1 t) < 1e-8. E_eff = sigma / (mean u_x on x = L / L).

    Checks: E_eff / E within 3 % of 1 and below 1 (the interfaces are compliant springs in series
    with exact constant-strain tets; ~1.4 % soft at the default penalty); lateral strain
    -nu_eff sigma / E_eff with nu_eff within 0.05 of nu = 0.2 (absolute); kinetic / elastic energy
    < 1e-6 at the end (static); no interface damaged (sigma < f_t); energy error < 1e-3.
    """
    L, W = 0.06, 0.02
    mesh = (structured_box if mesher == "structured" else gmsh_box)((L, W, W), 0.01)
    sigma = 1e6
    w1 = math.pi * bar_wave_speed() / (2.0 * L)
    period = 2.0 * math.pi / w1
    supports = [roller((0, 0, 0), n) for n in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    load = Pressure(History.ramp(-sigma, 0.5 * period), Selection(plane_point=(L, 0, 0), plane_normal=(1, 0, 0)))
    model = build(mesh, supports=supports, pressures=[load], damping=2.0 * w1)
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    sim.advance(int(math.ceil(3.0 * period / dt)), dt)

    u = model.nodes.x - model.x0
    end = np.abs(model.x0[:, 0] - L) < 1e-9
    side = np.abs(model.x0[:, 1] - W) < 1e-9
    e_eff = sigma / (u[end, 0].mean() / L)
    nu_eff = -(u[side, 1].mean() / W) / (u[end, 0].mean() / L)
    en = sim.energies(dt)
    print(
        f"{mesher}: {model.n_tets} tets, {sim.steps} steps, E_eff/E = {e_eff / E:.5f}, "
        f"nu_eff = {nu_eff:.4f}, KE/elastic = {en['energy.kinetic'] / en['energy.elastic']:.2g}, "
        f"energy error = {energy_error(en):.2g}"
    )
    assert e_eff / E == pytest.approx(1.0, abs=0.03)
    assert e_eff < E
    assert nu_eff == pytest.approx(NU, abs=0.05)
    assert en["energy.kinetic"] < 1e-6 * en["energy.elastic"]
    assert np.all(model.ifs.damage == 0.0)
    assert abs(energy_error(en)) < 1e-3


# ---------------------------------------------------------------------------------------------
# Dilatational wave
# ---------------------------------------------------------------------------------------------
def test_p_wave_speed_plateau_and_energy():
    """Step pressure p = 1 MPa on x = 0 of a 200 x 10 x 10 mm bar (h = 5 mm) with rollers on its
    four long faces (1D strain): a front at c_p = sqrt((lambda + 2 mu)/rho) = 3514 m/s carrying
    the particle velocity v = p / (rho c_p). Run to t = 0.85 L / c_p.

    Checks: the time of flight between the half-amplitude arrivals (mean x-velocity of the node
    planes x = L/4 and 3L/4) is (L/2) / c_p within 3 % (measured ~1.5 % slow); the velocity
    plateau behind the front at x = L/4 (time mean from 0.05 L/c_p after arrival) is p/(rho c_p)
    within 3 %; total x-momentum = p A t within 1e-6 relative (the only x-force); energy error
    (external - others) / external within 1 %.
    """
    L, W, h = 0.2, 0.01, 0.005
    supports = [roller((0, y, 0), (0, 1, 0)) for y in (0.0, W)]
    supports += [roller((0, 0, z), (0, 0, 1)) for z in (0.0, W)]
    p = 1e6
    load = Pressure(History.constant(p), Selection(plane_point=(0, 0, 0), plane_normal=(1, 0, 0)))
    model = build(structured_box((L, W, W), h), supports=supports, pressures=[load])
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    cp = p_wave_speed()
    assert cp == pytest.approx(rock().p_wave_speed, rel=1e-12)
    vp = p / (RHO * cp)
    planes = [np.abs(model.x0[:, 0] - x) < 1e-9 for x in (0.25 * L, 0.75 * L)]
    times, vel = [], []
    while sim.time < 0.85 * L / cp:
        sim.advance(2, dt)
        times.append(sim.time)
        vel.append([model.nodes.v[s, 0].mean() for s in planes])
    times, vel = np.array(times), np.array(vel)

    arrival = []
    for k in range(2):
        i = int(np.argmax(vel[:, k] > 0.5 * vp))
        assert i > 0, "the front must reach both planes, after the start"
        w = (0.5 * vp - vel[i - 1, k]) / (vel[i, k] - vel[i - 1, k])
        arrival.append(times[i - 1] + w * (times[i] - times[i - 1]))
    speed_ratio = (0.5 * L) / (arrival[1] - arrival[0]) / cp
    behind = times > arrival[0] + 0.05 * L / cp
    plateau = vel[behind, 0].mean() / vp
    momentum = float(np.sum(model.nodes.mass * model.nodes.v[:, 0]))
    en = sim.energies(dt)
    err = energy_error(en)
    print(
        f"P-wave: {model.n_tets} tets, {sim.steps} steps, speed/c_p = {speed_ratio:.4f}, "
        f"plateau/(p/rho c_p) = {plateau:.4f}, momentum/(pAt) = {momentum / (p * W * W * sim.time):.8f}, "
        f"energy error = {err:.2g}"
    )
    assert speed_ratio == pytest.approx(1.0, abs=0.03)
    assert plateau == pytest.approx(1.0, abs=0.03)
    assert momentum == pytest.approx(p * W * W * sim.time, rel=1e-6)
    assert abs(err) < 0.01
    assert np.all(model.ifs.damage == 0.0)


# ---------------------------------------------------------------------------------------------
# Rigid motion
# ---------------------------------------------------------------------------------------------
BLOCK = (0.02, 0.02, 0.02)


def test_uniform_velocity_is_kept():
    """A free 20 mm block (h = 10 mm, 192 tets) moving at v = (1, 2, 3) m/s for 100 steps.

    Checks: every position is x0 + v t within 1e-12 of the block size; internal forces stay at
    round-off, < 1e-9 E h^2; every node velocity equals v within 1e-9 relative (the round-off
    floor: position ulps ~3e-18 m over 2.5 mm tet edges are strains ~1e-15, whose forces drift
    the velocities by ~1e-10 relative in 100 steps; 1e-12 is not reachable in float64); the
    interface forces stay at round-off too (< 1e-9 E h^2); no damage; the energy error < 1e-12
    (the initial kinetic energy counts as external work).
    """
    v0 = np.array([1.0, 2.0, 3.0])
    model = build(structured_box(BLOCK, 0.01), initial_velocity=tuple(v0))
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    sim.advance(100, dt)
    dv = np.abs(model.nodes.v - v0).max() / np.linalg.norm(v0)
    dx = np.abs(model.nodes.x - (model.x0 + v0 * sim.time)).max() / max(BLOCK)
    f = np.abs(model.nodes.force).max() / (E * 0.01**2)
    f_if = np.abs(model.ifs.force).max() / (E * 0.01**2)
    en = sim.energies(dt)
    print(
        f"uniform motion: max |dv|/|v| = {dv:.2g}, max |dx|/L = {dx:.2g}, "
        f"max |f|/(E h^2) = {f:.2g} (tets), {f_if:.2g} (interfaces)"
    )
    assert dv < 1e-9
    assert dx < 1e-12
    assert f < 1e-9
    assert f_if < 1e-9
    assert np.all(model.ifs.damage == 0.0)
    assert abs(energy_error(en)) < 1e-12


def test_rigid_spin_conserves_angular_momentum():
    """A free 20 mm block spinning at omega = 1000 rad/s about the oblique axis (1, 2, 2)/3
    through its centre (initial velocity omega x r, rim speed ~17 m/s), 200 steps.

    Checks: total angular momentum sum m x × v conserved within 1e-6 relative (objective St
    Venant-Kirchhoff bulk and interface law: no spurious torque); linear momentum stays 0
    (< 1e-9 of m |omega| L); kinetic energy within 1e-3 of the initial one; no interface damage;
    energy error < 1e-3.
    """
    mesh = structured_box(BLOCK, 0.01)
    centre = 0.5 * np.asarray(BLOCK)
    omega = 1000.0 * np.array([1.0, 2.0, 2.0]) / 3.0
    v_points = np.cross(omega, mesh.points - centre)
    model = build(mesh, initial_velocity=v_points)
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    m = model.nodes.mass

    def angular_momentum():
        return np.sum(m[:, None] * np.cross(model.nodes.x - centre, model.nodes.v), axis=0)

    j0 = angular_momentum()
    ke0 = sim.energies(dt)["energy.kinetic"]
    sim.advance(200, dt)
    j1 = angular_momentum()
    en = sim.energies(dt)
    dj = np.linalg.norm(j1 - j0) / np.linalg.norm(j0)
    p = np.linalg.norm(np.sum(m[:, None] * model.nodes.v, axis=0)) / (m.sum() * 1000.0 * max(BLOCK))
    print(
        f"rigid spin: {sim.steps} steps, rotation {1000.0 * sim.time:.3g} rad, |dJ|/|J| = {dj:.2g}, "
        f"|P| = {p:.2g}, KE/KE0 = {en['energy.kinetic'] / ke0:.6f}, energy error = {energy_error(en):.2g}"
    )
    assert dj < 1e-6
    assert p < 1e-9
    assert en["energy.kinetic"] == pytest.approx(ke0, rel=1e-3)
    assert np.all(model.ifs.damage == 0.0)
    assert abs(energy_error(en)) < 1e-3


def test_rigidly_rotated_configuration_is_stress_free():
    """The block (192 tets, 336 interfaces) placed rigidly rotated by 60 degrees about (1, -2, 3)
    and shifted, at rest, then 10 steps: F = R gives E = 0 in St Venant-Kirchhoff, and the
    interface openings are 0, so tet and interface forces stay at round-off (< 1e-9 E h^2,
    i.e. < 1e-3 f_t h^2 for the interfaces), the nodes stay put (|v| < 1e-9 m/s) and nothing
    is damaged."""
    model = build(structured_box(BLOCK, 0.01))
    R = rotation((1.0, -2.0, 3.0), 60.0)
    model.nodes.x[:] = model.x0 @ R.T + np.array([0.01, -0.02, 0.03])
    placed = model.nodes.x.copy()
    sim = FdemSimulation(model)
    dt = 0.8 * model.stable_dt
    sim.advance(10, dt)
    f = np.abs(model.nodes.force).max() / (E * 0.01**2)
    f_if = np.abs(model.ifs.force).max() / (FT * 0.01**2)
    v = np.abs(model.nodes.v).max()
    print(f"rotated block: max |f|/(E h^2) = {f:.2g}, interfaces/(ft h^2) = {f_if:.2g}, max |v| = {v:.2g}")
    assert f < 1e-9
    assert f_if < 1e-3
    assert v < 1e-9
    assert np.abs(model.nodes.x - placed).max() < 1e-15
    assert np.all(model.ifs.damage == 0.0)


def test_scenario_angular_velocity_spins_about_the_centre_of_mass():
    """[specimen] angular_velocity = (0, 0, 100) rad/s with initial_velocity (1, 0, 0) m/s on the
    3PB quick beam (500 x 50 x 20 mm): linear momentum M v0 (to 1e-12), angular momentum about
    the centre of mass Iz omega with Iz = M (a^2 + b^2) / 12 of the solid beam, within 1 %
    (measured +0.37 %: the lumped masses sit at the tet corners)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    scenario, base = load_scenario(
        "three-point-bending", ["specimen.angular_velocity=[0.0, 0.0, 100.0]", "specimen.initial_velocity=[1.0, 0.0, 0.0]"],
        quick=True,
    )
    sim, _ = build_simulation(scenario, base)
    nodes, x0 = sim.model.nodes, sim.model.x0
    m = nodes.mass
    total = m.sum()
    momentum = (m[:, None] * nodes.v).sum(axis=0) / total
    assert momentum == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    centre = m @ x0 / total
    spin = (m[:, None] * np.cross(x0 - centre, nodes.v - [1.0, 0.0, 0.0])).sum(axis=0)
    a, b = scenario.specimen.size[0], scenario.specimen.size[1]
    assert spin[2] == pytest.approx(total * (a * a + b * b) / 12.0 * 100.0, rel=0.01)
    assert abs(spin[0]) + abs(spin[1]) < 1e-9 * abs(spin[2])

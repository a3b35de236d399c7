"""Bonded-particle DEM (paper 003): two bonded spheres against the closed forms of the JCFpm
law (stiffness, tensile and shear strength, friction after failure), the energy audit, and
thread-count independence."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crackle.dem.build import build_dem_simulation
from crackle.dem.kernels import BONDED, BROKEN, GONE
from crackle.dem.membrane import no_membrane
from crackle.dem.model import BondLaw
from crackle.loading import History, Selection, Support, Tool
from crackle.scenario import ScenarioError, load_scenario
from crackle.analysis.energy import energy_error
from crackle.solver.failures import MODE_SHEAR, MODE_TENSION

R = 1e-3  # m
RHO = 2500.0
# Paper 003 Table 1: Y = 50 GPa, P = 1/3, phi = 18 deg, c = 45 MPa, t = 4.5 MPa.
LAW = BondLaw(50e9, 1.0 / 3.0, 4.5e6, 45e6, math.radians(18.0), math.radians(18.0))
KN = 2.0 * 50e9 * R * R / (2 * R)  # eq. 3 with Ra = Rb = R: Y R
KT = KN / 3.0
AINT = math.pi * R * R


def _pair(gap=0.0, **kw):
    """Two spheres of radius R on the x axis, centres 2R + gap apart, bonded."""
    return build_dem_simulation([[0.0, 0.0, 0.0], [2 * R + gap, 0.0, 0.0]], [R, R], RHO, LAW, gamma=1.05, **kw)


def _force_after(sim, shift, velocity=(0.0, 0.0, 0.0), dt=1e-12):
    """The interaction force on b after b is put at its rest place + shift (m) and moving at
    `velocity` over one tiny step (its tangential motion v dt loads the shear spring)."""
    p = sim.particles
    p.x[1] = sim.x0[1] + np.asarray(shift)
    p.x[0] = sim.x0[0]
    p.v[:] = 0.0
    p.v[1] = velocity
    sim.advance(1, dt)
    return sim.inter.transfer[0, :3].copy()


def test_two_spheres_elastic_stiffness():
    """Normal force kn un (kn = 2 Y Ra Rb / (Ra + Rb)) and shear force kt us (kt = P kn), both
    within 1e-9 of the formulas, on both sides of the rest distance."""
    sim = _pair()
    assert sim.n_bonds == 1 and sim.inter.kn[0] == pytest.approx(KN, rel=1e-12)
    delta = 1e-8
    f = _force_after(sim, (-delta, 0.0, 0.0))  # pushed together: b pushed away along +x
    assert f[0] == pytest.approx(KN * delta, rel=1e-9)
    sim = _pair()
    f = _force_after(sim, (delta, 0.0, 0.0))  # pulled apart, within the strength: b pulled back
    assert f[0] == pytest.approx(-KN * delta, rel=1e-9)
    sim = _pair()
    dt = 1e-12
    us = 1e-9
    f = _force_after(sim, (0.0, 0.0, 0.0), velocity=(0.0, us / dt, 0.0), dt=dt)
    assert f[1] == pytest.approx(-KT * us, rel=1e-9) and abs(f[0]) < 1e-9 * KT * us


@pytest.mark.parametrize("side", [1.0 - 1e-6, 1.0 + 1e-6])
def test_tensile_failure_at_t_aint(side):
    """The bond holds up to Fn = -t Aint and breaks beyond it (1e-6 either side), in tension,
    and the interaction is then gone."""
    sim = _pair()
    stretch = side * LAW.tensile_strength * AINT / KN
    _force_after(sim, (stretch, 0.0, 0.0))
    if side < 1.0:
        assert sim.inter.state[0] == BONDED
    else:
        assert sim.inter.state[0] == GONE and sim.inter.fail_mode[0] == MODE_TENSION
        assert np.all(sim.inter.transfer[0, :3] == 0.0)


@pytest.mark.parametrize("side", [1.0 - 1e-6, 1.0 + 1e-6])
def test_shear_failure_at_cohesion_plus_friction(side):
    """Under a compressive Fn the bond holds a shear force up to c Aint + Fn tan(phi) and breaks
    in shear beyond it (1e-6 either side); in compression it then rubs at Fn tan(phi)."""
    sim = _pair()
    squeeze = 2e-6
    fn = KN * squeeze
    strength = LAW.cohesion * AINT + fn * math.tan(LAW.friction_angle)
    dt = 1e-12
    us = side * strength / KT
    f = _force_after(sim, (-squeeze, 0.0, 0.0), velocity=(0.0, us / dt, 0.0), dt=dt)
    if side < 1.0:
        assert sim.inter.state[0] == BONDED
        assert -f[1] == pytest.approx(strength * side, rel=1e-9)
    else:
        assert sim.inter.state[0] == BROKEN and sim.inter.fail_mode[0] == MODE_SHEAR
        assert -f[1] == pytest.approx(fn * math.tan(LAW.friction_angle), rel=1e-9)
        # More sliding: still Coulomb (the normal force unchanged, the shear at its cap).
        f = _force_after(sim, (-squeeze, 0.0, 0.0), velocity=(0.0, 1e-3 / dt, 0.0), dt=dt)
        assert sim.inter.state[0] == BROKEN
        assert f[0] == pytest.approx(fn, rel=1e-6)
        assert math.hypot(f[1], f[2]) == pytest.approx(fn * math.tan(LAW.friction_angle), rel=1e-6)


def test_a_rigidly_turning_pair_carries_its_shear_force_along():
    """Objectivity: a bonded pair turning as a rigid body (spins equal to the orbit's rate, so
    the contact point does not slide) keeps its shear force, turned with the pair. A quarter
    turn about z at 1e-4 rad a step (a fragment spinning at 1e4 rad/s at a 10 ns step): the
    force along +y on the pair along +x ends along -x, its magnitude within 1e-4 and its
    direction within 1e-4 rad, and stays in the tangent plane (normal part below 1e-9 of it)."""
    from crackle.dem.kernels import advance

    sim = _pair()
    p, inter = sim.particles, sim.inter
    shear = 0.1 * LAW.cohesion * AINT
    inter.shear[0] = (0.0, shear, 0.0)
    turn, n_steps = 0.5 * math.pi, 15708
    rate, dt = 1e4, 1e-8
    half = 0.5 * (sim.x0[1] - sim.x0[0])
    centre = sim.x0[0] + half
    for step in range(1, n_steps + 1):
        angle = turn * step / n_steps
        c, s = math.cos(angle), math.sin(angle)
        arm = np.array([c * half[0] - s * half[1], s * half[0] + c * half[1], 0.0])
        p.x[0], p.x[1] = centre - arm, centre + arm
        p.v[0], p.v[1] = -np.cross((0.0, 0.0, rate), arm), np.cross((0.0, 0.0, rate), arm)
        p.spin[:] = (0.0, 0.0, rate)
        advance(1, step, dt, p, inter, sim.tools, sim.gravity, 0.0, *no_membrane(2))
    f = inter.shear[0]
    assert np.linalg.norm(f) == pytest.approx(shear, rel=1e-4)
    assert math.atan2(abs(f[1]), -f[0]) < 1e-4 and abs(f[2]) < 1e-9 * shear
    assert abs(f @ arm) / np.linalg.norm(arm) < 1e-9 * shear


def test_velocity_support_pulls_a_bond_to_t_aint():
    """Sphere a held by a fixed support, sphere b by a fixed support moving along +x (a velocity
    boundary condition, its reaction read by its grip's load cell). Started at 0.999 of the
    failure stretch and pulled 1e-7 of it per step, the bond breaks in tension, and the largest
    reaction the grip read is t Aint within 1e-6 (measured -2.7e-9): at constant speed the
    reaction is the bond's force exactly. The grip's displacement is speed x time."""
    fixed = Support("fixed", Selection(box_min=(-0.5 * R,) * 3, box_max=(0.5 * R,) * 3))
    moving = Support("fixed", Selection(box_min=(1.5 * R, -0.5 * R, -0.5 * R), box_max=(2.5 * R, 0.5 * R, 0.5 * R)),
                     tool=0)
    fail = LAW.tensile_strength * AINT / KN
    sim = _pair(tools=[Tool("pull", "support", (1.0, 0.0, 0.0), History.constant(1.0))], supports=[fixed, moving])
    dt = 0.5 * sim.stable_dt
    speed = 1e-7 * fail / dt
    sim.tools.speeds[:] = speed
    p = sim.particles
    p.x[1] = sim.x0[1] + (0.999 * fail, 0.0, 0.0)
    p.v[1] = (speed, 0.0, 0.0)  # already at speed: no start-up impulse
    steps = 20_000
    sim.advance(steps, dt)
    assert sim.inter.state[0] == GONE and sim.inter.fail_mode[0] == MODE_TENSION
    peak = sim.load_cell.peaks()[0][0]
    print(f"peak reaction {peak:.9g} N against t Aint = {LAW.tensile_strength * AINT:.9g} N")
    assert peak == pytest.approx(LAW.tensile_strength * AINT, rel=1e-6)
    assert sim.tools.disp[0, 0] == pytest.approx(speed * steps * dt, rel=1e-9)
    assert np.all(p.x[0] == sim.x0[0])  # the fixed sphere stays put


def _history(sim, dt, steps, rows):
    out = []
    per = steps // rows
    for _ in range(rows):
        sim.advance(per, dt)
        out.append(sim.energies(dt))
    return {k: np.array([r[k] for r in out]) for k in out[0]}


def test_energy_closes_through_oscillation_and_break():
    """Two bonded spheres flying apart (spin included, off-axis): they oscillate, the bond breaks
    in tension, and they separate. The audit (kinetic + elastic + damage + friction = initial
    kinetic energy) closes to < 0.1 % of the largest energy, and the energy booked as damage is
    what the bond held at failure (kinetic after = before - damage, 0.1 %)."""
    v_break = LAW.tensile_strength * AINT / math.sqrt(KN * RHO * 4 / 3 * math.pi * R**3 / 2)
    sim = _pair(velocity=None)
    p = sim.particles
    p.v[0] = (-0.6 * v_break, 0.05 * v_break, 0.0)
    p.v[1] = (0.6 * v_break, -0.02 * v_break, 0.01 * v_break)
    p.spin[0] = (0.0, 0.0, 3.0 * v_break / R)
    sim._initial_energy = sim.kinetic_energy()
    dt = 0.05 * sim.stable_dt
    history = _history(sim, dt, 40_000, 400)
    assert sim.inter.state[0] == GONE and sim.inter.fail_mode[0] == MODE_TENSION
    assert abs(energy_error(history)) < 1e-3
    damage = history["energy.damage"][-1]
    assert damage > 0.0
    assert history["energy.kinetic"][-1] + damage + history["energy.friction"][-1] == pytest.approx(
        sim._initial_energy, rel=1e-3)


def _max_imbalance(fraction):
    """Largest audit imbalance over a run of an intact bond vibrating in stretch, shear and spin,
    as a fraction of the energy put in, at `fraction` of the stable step."""
    sim = _pair()
    p = sim.particles
    p.v[1] = (0.01, 0.02, -0.01)
    p.spin[1] = (5.0, -3.0, 8.0)
    sim._initial_energy = sim.kinetic_energy()
    dt = fraction * sim.stable_dt
    h = _history(sim, dt, int(4000 / fraction), 200)
    assert sim.inter.state[0] == BONDED
    held = h["energy.kinetic"] + h["energy.elastic"] + h["energy.damage"] + h["energy.friction"]
    return float(np.max(np.abs(h["energy.external"] - held)) / sim._initial_energy)


def test_elastic_pair_energy_converges_at_second_order():
    """The audit pairs half-step velocities with mid-step potentials (solver.integrator): its
    imbalance is the scheme's own, k (v dt)^2 / 8, so it falls as dt^2. Measured: < 0.1 % at
    0.175 of the stable step, and 4.0x smaller (3.5-4.5) when the step is halved."""
    coarse, fine = _max_imbalance(0.35), _max_imbalance(0.175)
    assert fine < 1e-3
    assert 3.5 < coarse / fine < 4.5


def _shaken(seed=3):
    """~300 bonded particles in a 6 mm cube, flung about fast enough to break bonds and make
    contacts (and the contact list rebuilt)."""
    from crackle.dem.domains import Box
    from crackle.dem.packing import pack_spheres

    packing = pack_spheres(Box(np.zeros(3), np.full(3, 6e-3)), porosity=0.45, mean_radius=4e-4, seed=seed)
    rng = np.random.default_rng(seed)
    sim = build_dem_simulation(packing.centers, packing.radii, RHO, LAW, bonds_per_particle=12)
    sim.particles.v[:] = rng.normal(0.0, 2.0, sim.particles.v.shape)
    sim._initial_energy = sim.kinetic_energy()
    return sim


def test_state_does_not_depend_on_how_steps_are_split():
    """advance(37) + advance(163) gives bit for bit the state of advance(200) (contact-list
    rebuilds fall on a fixed grid of steps), with bonds breaking on the way."""
    whole, split = _shaken(), _shaken()
    dt = 0.7 * whole.stable_dt
    whole.advance(200, dt)
    split.advance(37, dt)
    split.advance(163, dt)
    assert whole.broken > 0
    for name in ("x", "v", "spin"):
        assert np.array_equal(getattr(whole.particles, name), getattr(split.particles, name))
    assert np.array_equal(whole.inter.state, split.inter.state)


def _ucs_quick(tmp_path, *overrides, scenario="dem-ucs", cli=False):
    """(history, summary) of `scenario` --quick with `overrides`, no field frames: through
    `crackle run` (cli) or through run_scenario without plots/ (the CLI's runs draw them, a few
    seconds each, and nothing else differs: the same steps, history and summary)."""
    import json

    from crackle.api import run_scenario
    from crackle.cli import main

    out = tmp_path / "-".join([scenario, *[o.split("=")[-1] for o in overrides]])
    if cli:
        args = ["run", scenario, "--quick", "--out", str(out), "--set", "run.field_frames=0"]
        for o in overrides:
            args += ["--set", o]
        assert main(args) == 0
    else:
        run_scenario(scenario, out, ["run.field_frames=0", *overrides], quick=True, progress=False, plots=False)
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    return history, json.loads((out / "summary.json").read_text())


# The quick UCS sample with unbreakable bonds (t and c x 100) to 0.22 ms: elastic throughout (the
# top platen alone at 0.2 m/s reaches 0.063 % strain).
UNBREAKABLE = ("material.tensile_strength=4.5e8", "material.cohesion=4.5e9", "run.end_time=2.2e-4")


@pytest.fixture(scope="module")
def elastic_ucs(tmp_path_factory):
    """One run of UNBREAKABLE, the top platen alone at 0.2 m/s, on packing seed 1 (the example's),
    for the tests that read it: the modulus's first packing, the top platen alone against both
    platens moving, and the Love-Weber stress of its last state (the simulation kept, one field
    frame at the end: the frames fall on history rows, so the history is the one of a run
    without). Returns (history, summary, sim, output folder)."""
    import json

    from crackle.api import build_simulation
    from crackle.solver import run

    out = tmp_path_factory.mktemp("elastic-ucs")
    scenario, base = load_scenario("dem-ucs", quick=True, overrides=["tools.0.speed=0.2", *UNBREAKABLE,
                                                                      "run.field_frames=1"])
    sim, control = build_simulation(scenario, base)
    control.plots = False
    run(sim, control, out)
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    return history, json.loads((out / "summary.json").read_text()), sim, out


@pytest.mark.slow
def test_elastic_modulus_is_reproducible_across_packings(tmp_path, elastic_ucs):
    """Three random packings (seeds 1-3) of the quick UCS sample, 3,215 particles (mean radius
    1 mm, paper 003's density), bonds made unbreakable (t and c x 100) so that the response
    stays elastic, loaded to 0.06 % strain: the slope of platen stress against strain over
    0.02-0.06 % (Young's modulus) is within 2 % of the three's mean (measured: 58.21, 57.52,
    57.96 GPa, 12 s a run; with 7,620 particles, mean radius 0.75 mm, 56.88, 56.31, 56.44 GPa,
    31 s a run; the paper's sample: ~55 GPa; 48.85, 48.88, 48.70 GPa with 5,266 particles at
    porosity 0.40 without overlaps). Seed 1 is the module's elastic_ucs run."""
    moduli = []
    for seed in (1, 2, 3):
        if seed == 1:
            h, summary = elastic_ucs[:2]
        else:
            h, summary = _ucs_quick(tmp_path, f"packing.seed={seed}", "tools.0.speed=0.2", *UNBREAKABLE)
        assert summary["broken"] == 0
        stress, strain = h["platenstress"], h["platenstrain"]
        window = (strain > 2e-4) & (strain < 6e-4)
        moduli.append(np.polyfit(strain[window], stress[window], 1)[0])
    mean = np.mean(moduli)
    print("moduli (GPa):", [f"{m * 1e-9:.2f}" for m in moduli])
    assert 30e9 < mean < 80e9
    assert np.max(np.abs(np.array(moduli) / mean - 1.0)) < 0.02, moduli


@pytest.mark.slow
def test_platen_strain_is_the_platens_approach_when_both_move(tmp_path, elastic_ucs):
    """Issue 43: both platens moving towards each other at v = 0.1 m/s (ramped over 0.1 ms), bonds
    unbreakable: platen.strain is the sum of both platens' travels over the sample's extent H at
    every row (1e-12; H = 54 mm to 1e-3), 2 v (t - 0.05 ms) / H after the ramp (1e-6: the step's
    integral of the ramp), and the modulus in the summary (the stress-strain slope over 20-50 % of
    the peak) is the slope of the history's own columns over that window (1e-9) and the one of
    the same approach made by the top platen alone at 2 v, within 2 % (measured 57.9 and 57.4 GPa;
    the strain of the top platen alone read it 2 x). The top platen alone is the module's
    elastic_ucs run."""
    h2, both = _ucs_quick(tmp_path, *UNBREAKABLE, "tools.0.speed=0.1", "tools.1.speed=0.1", "tools.1.ramp_time=1e-4")
    alone = elastic_ucs[1]
    travels = h2["tooltopuz"] * -1.0 + h2["toolbottomuz"]
    height = travels[-1] / h2["platenstrain"][-1]
    assert height == pytest.approx(0.054, rel=1e-3)
    assert np.allclose(h2["platenstrain"], travels / height, rtol=1e-12, atol=0.0)
    after = h2["time"] > 1e-4
    assert np.allclose(h2["platenstrain"][after], 2.0 * 0.1 * (h2["time"][after] - 0.5e-4) / height, rtol=1e-6, atol=0.0)
    stress, strain = h2["platenstress"], h2["platenstrain"]
    window = (stress >= 0.2 * stress.max()) & (stress <= 0.5 * stress.max())
    assert both["platen_modulus"] == pytest.approx(np.polyfit(strain[window], stress[window], 1)[0], rel=1e-9)
    print(f"modulus: both platens {both['platen_modulus'] * 1e-9:.1f} GPa, top alone {alone['platen_modulus'] * 1e-9:.1f}")
    assert both["platen_modulus"] == pytest.approx(alone["platen_modulus"], rel=0.02)
    assert both["platen_modulus"] == pytest.approx(55e9, rel=0.15)


def test_a_user_step_is_accepted_up_to_the_proven_stable_step(tmp_path):
    """Issue 43: the DEM proves a bound on its stable step at set-up (Gershgorin, over each
    particle's bonds, contacts and tools, translation and spin), so a given run.dt is accepted up
    to it, not only up to the default's 0.7 x the stable step with room for 6 later contacts per
    particle: the DEM codes' rule 0.5 Rmin / sqrt(Y / rho) (0.5 x 0.70 mm / 4,472 m/s = 78.2 ns
    on the quick sample) is above that stable step (72.3 ns) and below the bound (81.0 ns), and is
    accepted with a warning; 1.001 x the bound is refused before the run, naming run.dt, the bound
    and how it is proven."""
    from crackle.api import build_simulation

    scenario, base = load_scenario("dem-ucs", quick=True)
    sim, _ = build_simulation(scenario, base)
    rule = 0.5 * float(sim.particles.radius.min()) / math.sqrt(50e9 / 2500.0)
    assert sim.stable_dt < rule < sim.proven_dt
    for dt in (rule, sim.proven_dt):
        scenario, base = load_scenario("dem-ucs", quick=True, overrides=[f"run.dt={dt!r}"])
        sim, control = build_simulation(scenario, base)
        assert control.dt == dt and any("new contacts can make the run unstable" in w for w in sim.warnings)
    scenario, base = load_scenario("dem-ucs", quick=True, overrides=[f"run.dt={1.001 * sim.proven_dt!r}"])
    with pytest.raises(ScenarioError, match=r"run.dt = .* larger than the step crackle can prove stable.*Gershgorin"):
        build_simulation(scenario, base)


@pytest.mark.slow
def test_dem_ucs_quick_breaks_the_sample(tmp_path):
    """`crackle run dem-ucs --quick` (3,215 particles at paper 003's packing density, 1.47 per
    cubed mean diameter): bonds break (most of them in tension), the run stops after the peak,
    the energy audit closes within 1 %, and the sample has the paper's strength and stiffness
    with Table 1 unchanged: UCS within 15 % of ~70 MPa (measured 65.5 MPa; twelve runs with the
    platens moved by round-offs: 59.4-73.8, mean 65.8, sd 3.4, the peak being chaotic; 38.4 MPa at
    porosity 0.42 without overlaps) and the modulus over 0.02-0.04 % strain within 15 % of ~55 GPa
    (measured 58.2 GPa, 57.4-58.1 over those runs; 50.1 before); `platen_modulus` (20-50 % of the
    peak) within 3 % of it."""
    h, summary = _ucs_quick(tmp_path, cli=True)
    assert summary["method"] == "dem" and summary["status"] == "stopped"
    # The history's UCS curve: platen stress = top platen force / loaded area (its largest row
    # within 2 % of the load cell's peak, which sees every step), platen strain = travel / the
    # sample's height (54 mm, to the particles' extent: 1e-3) at 0.1 m/s.
    assert np.max(h["platenstress"]) == pytest.approx(summary["peak_stress"], rel=0.02)
    assert h["platenstress"][-1] < 0.2 * summary["peak_stress"]
    assert h["platenstrain"][-1] == pytest.approx(0.1 * (h["time"][-1] - 0.5e-4) / 0.054, rel=1e-2)  # ramp 0.1 ms
    assert summary["broken"] > 1000 and summary["broken_by_mode"]["tension"] > summary["broken"] / 2
    assert summary["peak_stress"] == pytest.approx(70e6, rel=0.15)
    window = (h["platenstrain"] > 2e-4) & (h["platenstrain"] < 4e-4)
    modulus = np.polyfit(h["platenstrain"][window], h["platenstress"][window], 1)[0]
    print(f"quick UCS {summary['peak_stress'] * 1e-6:.1f} MPa, modulus {modulus * 1e-9:.1f} GPa")
    assert modulus == pytest.approx(55e9, rel=0.15)
    assert summary["platen_modulus"] == pytest.approx(modulus, rel=0.03)
    assert summary["particles"] == 3215 and summary["bonds_per_particle"] == pytest.approx(12.0, abs=0.01)
    assert abs(summary["energy_error"]) < 0.01


def test_dem_tension_quick_breaks_in_tension(tmp_path):
    """`crackle run dem-tension --quick` (3,215 particles at paper 003's density) pulled by its top
    layer, a roller support moving up: bonds break in tension, the run stops once the support's
    reaction has dropped, the energy audit closes within 1 % (measured -0.013 %), and the summary
    reports the nominal strength over the 27 x 12 mm section: tensile_strength_ratio (over the
    bond's t = 4.5 MPa) between 0.8 and 1.5 (measured 1.115: 5.02 MPa; paper 003's UTS ~6 MPa)."""
    h, summary = _ucs_quick(tmp_path, scenario="dem-tension", cli=True)
    assert summary["status"] == "stopped"
    assert summary["broken"] > 500 and summary["broken_by_mode"]["tension"] > 0.9 * summary["broken"]
    assert abs(summary["energy_error"]) < 0.01
    assert summary["loaded_area"] == pytest.approx(0.027 * 0.012, rel=0.02)
    assert summary["nominal_strength"] == pytest.approx(summary["peak_forces"]["top"] / summary["loaded_area"], rel=1e-9)
    print(f"quick tension: {summary['nominal_strength'] * 1e-6:.2f} MPa, ratio {summary['tensile_strength_ratio']:.3f}")
    assert 0.8 < summary["tensile_strength_ratio"] < 1.5
    assert np.max(h["platenstress"]) == pytest.approx(summary["nominal_strength"], rel=0.02)


def test_dem_brazilian_quick_splits_along_the_loading_axis(tmp_path):
    """`crackle run dem-brazilian --quick` (the FDEM disc's [specimen], filled with 2,004
    particles at paper 003's density): the disc splits within 15 deg of the loading axis (summary
    `splitting_angle` within 2 deg of the events' reading), the Brazilian strength 2F/(pi D t) is reported (quick: 4.18 MPa, 3.05 MPa before the dense
    packing; paper 003: UTS ~6 MPa), and the energy audit closes within 1 %."""
    import json

    from crackle.analysis.brazilian import loading_direction, splitting_angle
    from crackle.cli import main
    from crackle.io import read_events_csv

    out = tmp_path / "bz"
    assert main(["run", "dem-brazilian", "--quick", "--out", str(out), "--set", "run.field_frames=0"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["brazilian_strength"] == pytest.approx(2 * summary["peak_force"] / (math.pi * 0.04 * 0.015), rel=1e-12)
    assert 1e6 < summary["brazilian_strength"] < 10e6
    angle, count = splitting_angle(read_events_csv(out / "events.csv"), loading_direction(0.0), radius=0.02)
    assert count > 100 and angle < 15.0
    # summary.json's own, as FDEM's disc reports it (the bonds' midpoints: 0.51 deg measured)
    assert summary["splitting_angle"] == pytest.approx(angle, abs=2.0)
    assert abs(summary["energy_error"]) < 0.01


# A flaw test reads the strength (the load cell's peak) and the energy audit: its run stops once the
# platen force has stayed below 80 % of the peak for 10 us instead of the example's 50 % for 0.1 ms
# (the force falls from the peak to 80 % of it within 50-75 us and never dipped more than 0.5 %
# below its running peak before it: measured on the four runs of these tests, whose peak_stress
# is the same to the bit as with the example's rule, in 12-14 % fewer steps).
PAST_THE_PEAK = ("run.stop.force_drop=0.8", "run.stop.force_drop_hold=1e-5")


@pytest.mark.slow
def test_open_flaw_strength_rises_with_its_inclination(tmp_path):
    """Paper 003 section 4.1: with an open flaw the uniaxial strength rises with the flaw's
    inclination theta, UCS(90)/UCS(0) ~ 2 (experiments 1.3-1.7). Quick sample at the paper's
    density: 40.5 and 64.9 MPa at 0 and 90 deg (ratio 1.60, 2026-12-06; 37.2 and 60.6 before;
    paper 29 and 56 MPa; each a draw with a ~5 % round-off scatter: 38.6 and 58.9 with the platens
    2e-18 m lower); the test asks for a ratio of 1.3-2.5. Each run stops past its peak
    (PAST_THE_PEAK)."""
    strength = {}
    for angle in (0, 90):
        _, summary = _ucs_quick(tmp_path, f"flaw.angle={angle}", *PAST_THE_PEAK, scenario="dem-flaw")
        strength[angle] = summary["peak_stress"]
        assert summary["particles"] < 3215  # the slot's particles are gone from the quick sample's
    assert 1.3 < strength[90] / strength[0] < 2.5


def test_flaw_outside_the_specimen_is_refused(tmp_path, capsys):
    from crackle.cli import main

    code = main(["run", "dem-flaw", "--quick", "--set", "flaw.center=[0.1,0,0]", "--out", str(tmp_path / "o")])
    assert code == 2 and "flaw.center" in capsys.readouterr().err
    code = main(["run", "dem-flaw", "--quick", "--set", "flaw.length=0.1", "--out", str(tmp_path / "o")])
    assert code == 2 and "flaw.length" in capsys.readouterr().err


def test_smooth_joint_takes_the_flaw_normal_friction_and_dilatancy():
    """Two spheres on the x axis joined across a flaw whose plane is inclined 30 deg (normal
    n_j = (cos 30, sin 30, 0)): squeezed by delta along n_j the joint pushes b with Kn_j Aint
    delta along n_j (1e-9); slid along the flaw's plane it rubs at Fn tan(phi_j) and, with
    dilatancy psi_j, the normal force grows by kn tan(psi_j) per unit of plastic slip (1e-6)."""
    from crackle.dem.kernels import JOINT
    from crackle.dem.model import Joint, with_joints

    theta = math.radians(30.0)
    normal = np.array([math.cos(theta), math.sin(theta), 0.0])
    along = np.array([-math.sin(theta), math.cos(theta), 0.0])
    kn_j, phi, psi = 1e12, math.radians(20.0), math.radians(10.0)
    sim = _pair()
    joint = Joint(np.array([R, 0.0, 0.0]), normal, along, 4 * R, kn_j, kn_j, phi, psi)
    sim.inter = with_joints(sim.particles, sim.inter, joint)
    assert sim.inter.state[0] == JOINT
    k = kn_j * AINT
    dt = 1e-12
    delta = 1e-8
    f = _force_after(sim, np.zeros(3), velocity=-delta / dt * normal, dt=dt)  # b approaches along n_j
    np.testing.assert_allclose(f, k * delta * normal, rtol=1e-9, atol=1e-9 * k * delta)
    slide = 1e-6  # far beyond the elastic shear k_t u < Fn tan(phi)
    f = _force_after(sim, np.zeros(3), velocity=slide / dt * along, dt=dt)
    cap = k * delta * math.tan(phi)
    slip = sim.inter.joint_slip[0]
    assert slip == pytest.approx(slide - cap / k, rel=1e-9)  # kt = kn here
    assert f @ normal == pytest.approx(k * delta, rel=1e-9)
    assert f @ along == pytest.approx(-cap, rel=1e-9)  # against the sliding
    # The next step, no motion: the slip has opened the joint by tan(psi) slip against its normal.
    f = _force_after(sim, np.zeros(3), dt=dt)
    assert f @ normal == pytest.approx(k * (delta + math.tan(psi) * slip), rel=1e-6)
    assert f @ along == pytest.approx(-cap, rel=1e-6)


@pytest.mark.slow
def test_closed_flaw_weakest_beyond_its_friction_angle(tmp_path):
    """Paper 003 section 5.1 (Fig. 14): with a closed flaw of smooth joints (phi_j = 18 deg) the
    strength at theta = 0 is kept, and it falls once theta exceeds phi_j. Quick sample at the
    paper's density: 61.9 MPa at 0 deg, 45.6 MPa at 30 deg (2026-12-06; 57.9 and 42.5 before;
    paper: 71 and ~45 MPa; 65.1 and 47.5 with the platens 2e-18 m lower: single draws); the test
    asks for the 30-deg strength at most 0.9 of the 0-deg one, and the energy audit within 1 %
    (joints apply their normal force off the line of centres: the torques must do work the
    springs store) at the end of each run, past its peak (PAST_THE_PEAK; measured 0.016 and
    0.026 %; 0.070 and 0.057 % at the example's later stop)."""
    out = {}
    for angle in (0, 30):
        _, summary = _ucs_quick(tmp_path, "flaw.kind=closed", f"flaw.angle={angle}", *PAST_THE_PEAK,
                                scenario="dem-flaw")
        out[angle] = summary["peak_stress"]
        assert abs(summary["energy_error"]) < 0.01
    assert out[30] < 0.9 * out[0]


def test_love_weber_stress_matches_the_platen_stress(elastic_ucs):
    """Paper 003 section 2.2: in a quasi-static compression the platen stress and the Love-Weber
    stress of the assembly (the particles' internal moments over the sample volume, appendix A
    with one cell) agree. The internal moments leave out the platen forces' lever arms in the
    particles that touch them, a radius at each end: sigma_zz = platen stress x (1 - 2 R / H)
    (0.963 for the quick sample) within 3 %; the lateral stresses below 5 % of it; the grid of
    cells of one mean diameter sums back to the same tensor (1e-9). The module's elastic_ucs
    run: the quick UCS sample at 0.22 ms, top platen at 0.2 m/s, unbreakable bonds (about
    36 MPa; measured ratio 0.967, lateral 6e-5 of it; the quick UCS at 0.1 m/s with Table 1's
    bonds at 0.3 ms, 27 MPa and 93 bonds broken, read 0.958 and 9e-4)."""
    h, _, sim, out = elastic_ucs
    platen = h["tooltopfz"][-1] / sim.loaded_area  # the force on the sample, down: sigma_zz < 0
    stress = sim.love_weber_stress()
    assert platen < -5e6
    lever = 1.0 - 2.0 * np.mean(sim.particles.radius) / 0.054
    assert stress[2] / platen == pytest.approx(lever, abs=0.03)
    assert np.max(np.abs(stress[[0, 1, 3, 4, 5]])) < 0.05 * abs(platen)
    lo, cell, grid = sim.homogenised_stress()
    np.testing.assert_allclose(grid.sum(axis=(0, 1, 2)) * cell**3 / sim.sample_volume, stress, rtol=1e-9,
                               atol=1e-9 * abs(platen))
    # The grid as ParaView reads it (the run's last frame): hexahedra of one cell each, whose
    # stresses times their volumes sum to the same tensor, and each holding its particles.
    import meshio

    frame = meshio.read(sorted((out / "fields").glob("step_*.vtu"))[-1])
    hexes = frame.cells_dict["hexahedron"]
    cell_stress = frame.cell_data_dict["homogenised_stress"]["hexahedron"]
    corners = frame.points[hexes]
    np.testing.assert_allclose(np.ptp(corners, axis=1), cell, rtol=1e-9)
    np.testing.assert_allclose(cell_stress.sum(axis=0) * cell**3 / sim.sample_volume, stress, rtol=1e-6,
                               atol=1e-6 * abs(platen))
    n = len(sim.particles.radius)
    first = corners[:, 0]  # the lower corner of each cell
    holder = np.all((sim.particles.x[:, None, :] >= first[None] - 1e-12) & (sim.particles.x[:, None, :] < first[None] + cell), axis=2)
    assert np.all(holder.sum(axis=1) == 1)  # every particle in exactly one cell
    assert np.all(frame.point_data["radius"][n:] == 0.0)


def test_clamped_supports_are_refused_for_particles():
    """A DEM particle's spin has no support: kind = "clamped" exits with the field and the fix."""
    with pytest.raises(ScenarioError, match=r'supports\.0\.kind: "clamped" is not available for DEM.*use "fixed"'):
        load_scenario("dem-ucs", overrides=['supports=[{kind="clamped", where={plane_point=[0, 0, 0], '
                                            'plane_normal=[0, 0, 1]}}]'])


def test_bond_force_fields_of_a_stretched_pair():
    """The bond lines' `normal_force` (tension positive) is kn x stretch within 1e-9 and their
    `shear_force` 0 for a pure stretch; pushed together, -kn x overlap (issue 44)."""
    delta = 1e-8
    for sign in (1.0, -1.0):
        sim = _pair()
        _force_after(sim, (sign * delta, 0.0, 0.0))
        fields = sim.fields()
        name, cells, data = fields["blocks"][0]
        assert name == "line" and cells.tolist() == [[0, 1]]
        assert data["normal_force"][0] == pytest.approx(sign * KN * delta, rel=1e-9)
        assert data["shear_force"][0] <= 1e-9 * KN * delta
        assert fields["point_data"]["id"][:2].tolist() == [0, 1]

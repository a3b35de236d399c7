"""One-element tests of the bilinear cohesive law (paper 004; Camanho-Davila mixed mode).

The two-tet `Cell` of tests/fdem/test_fdem_law.py: one interface, openings prescribed by moving the
B face, the law evaluated by `interface_forces` (no time stepping). The expected numbers are
written out here from the law's definition, independently of src:

* tractions kn dn, ks ds up to initiation at (<tn>/tn0)^2 + (ts/ts0)^2 = 1 (the default), or
  max(<tn>/tn0, ts/ts0) = 1 (initiation = "maximum");
* effective opening dm = sqrt(<dn>^2 + ds^2), K = (kn <dn>^2 + ks ds^2) / dm^2,
  d0 = initiation opening on the path, df = 2 Gc / (K d0); a full failure dissipates Gc per area;
* mixed mode from B = G_II / G_T = ks ds^2 / (kn dn^2 + ks ds^2): BK Gc = GIc + (GIIc - GIc) B^eta,
  power law ((1-B) Gc / GIc)^alpha + (B Gc / GIIc)^alpha = 1.

Parameters: paper 004 Table 1 (face: 7 MPa, 0.77 N/mm, 636.36 N/mm^3, in SI), with a distinct
shear strength, mode-II energy and shear stiffness so that a swapped mode would show.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from crackle.cli import main
from crackle.fdem.kernels import interface_energy
from crackle.fdem.laws import BilinearLaw
from crackle.materials import Material
from crackle.scenario import examples_dir

from fdem_helpers import E, NU, RHO
from test_fdem_law import Cell

TN0 = 7e6  # Pa
TS0 = 10e6  # Pa
GIC = 770.0  # J/m^2 (0.77 N/mm)
GIIC = 1500.0  # J/m^2
KN = 636.36e9  # N/m^3 (636.36 N/mm^3)
KS = 300e9  # N/m^3
BK_ETA = 1.45


def shell(**overrides) -> Material:
    law = dict(
        tensile_strength=TN0, shear_strength=TS0, fracture_energy=GIC, fracture_energy_shear=GIIC,
        normal_stiffness=KN, shear_stiffness=KS, friction=0.3,
    )
    law.update(overrides)
    return Material(RHO, E, NU, BilinearLaw(**law), name="shell")


def path_to(d0, df, n_fine=400, n_coarse=4000):
    """0 -> 1.1 df: fine steps up to 2 d0, then n_coarse steps."""
    fine = np.linspace(0.0, 2.0 * d0, n_fine + 1)
    coarse = np.linspace(2.0 * d0, 1.1 * df, n_coarse + 1)[1:]
    return np.concatenate([fine, coarse])


def drive(cell, path, direction):
    """Open along (cos, sin) of `direction` in the (dn, ds) plane; returns the tractions and the
    traction work (trapezoid) per unit area up to the failure step, and that step's index."""
    c, s = direction
    sig = np.empty_like(path)
    tau = np.empty_like(path)
    k_fail = None
    for k, d in enumerate(path):
        sig[k], tau[k] = cell.set(dn=c * d, ds=s * d)
        if k_fail is None and cell.state == 1:
            k_fail = k
    assert k_fail is not None, "the interface must fail within the path"
    dwork = 0.5 * (sig[1:] + sig[:-1]) * c * np.diff(path) + 0.5 * (tau[1:] + tau[:-1]) * s * np.diff(path)
    return sig, tau, float(np.sum(dwork[:k_fail])), k_fail


def test_stiffnesses_are_the_interface_penalties():
    """pn = kn and ps = ks exactly (they replace penalty_factor E / h), and the stable step
    sees them: 2 / sqrt(omega^2) with the pair spring 2 max(kn, ks) A / 3 on the nodes."""
    cell = Cell(shell())
    assert cell.pn == KN and cell.ps == KS
    stiff = Cell(shell(normal_stiffness=100.0 * KN))
    assert stiff.model.stable_dt < cell.model.stable_dt


def test_stiffness_per_element_scales_with_the_altitude():
    """stiffness_per = "element" (issue 38's second reading of Table 1's kn): every face's kn and
    ks are the given values times reference_altitude / h, h the smaller altitude of its two tets, to
    1e-12: on the two-tet cell and on each of a structured box's faces (pn h and ps h the same
    everywhere: the factor x E / h reading, factor = kn reference_altitude / E). Per area (the
    default, Abaqus's traction elasticity with a constitutive thickness of 1 mm) the cell's pn is
    kn itself; one of the two keys without the other is refused."""
    import warnings

    from crackle.fdem.model import build_fdem_model
    from crackle.geometry import structured_box

    reference = 0.00095
    cell = Cell(shell(stiffness_per="element", reference_altitude=reference))
    altitude = float(np.min(3.0 * cell.model.tets.vol / cell.A))  # each tet's altitude onto the shared face
    assert cell.pn == pytest.approx(KN * reference / altitude, rel=1e-12)
    assert cell.ps == pytest.approx(KS * reference / altitude, rel=1e-12)
    assert Cell(shell()).pn == KN
    mesh = structured_box((0.02, 0.02, 0.02), 0.004)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = build_fdem_model(mesh, shell(stiffness_per="element", reference_altitude=reference))
    pairs_h = KN * reference / model.ifs.pn
    assert np.ptp(pairs_h) > 0.0  # the box's tets have two altitudes
    assert np.allclose(model.ifs.ps * pairs_h, KS * reference, rtol=1e-12, atol=0.0)
    with pytest.raises(ValueError, match="reference_altitude"):
        shell(stiffness_per="element")
    with pytest.raises(ValueError, match="reference_altitude"):
        shell(reference_altitude=reference)


@pytest.mark.parametrize("mode", ["I", "II"])
def test_pure_mode_peak_and_energy(mode):
    """Pure mode I (dn only) and pure mode II (ds only), monotonic to 1.1 df.

    Checks: initial slope = kn (ks) within 1e-9; no damage below d0 = t0 / k; peak traction
    = tn0 = 7 MPa (ts0 = 10 MPa) within 1 %; failure (state 1) with fail_mode 1 (2); e_damage at
    failure = Gc A (770 / 1500 J/m^2) within 2 %; traction work up to failure = Gc A within 2 %;
    no traction after failure (opening: no contact; sliding at zero normal stress: no friction).
    """
    cell = Cell(shell())
    t0, k, gc, direction, fail_mode = {
        "I": (TN0, KN, GIC, (1.0, 0.0), 1),
        "II": (TS0, KS, GIIC, (0.0, 1.0), 2),
    }[mode]
    d0 = t0 / k
    df = 2.0 * gc / t0
    path = path_to(d0, df)
    sig, tau, work, k_fail = drive(cell, path, direction)
    trac = sig if mode == "I" else tau
    other = tau if mode == "I" else sig
    assert np.all(np.abs(other) <= 1e-9 * t0)
    assert trac[1] / path[1] == pytest.approx(k, rel=1e-9)
    peak = trac.max()
    ratio = cell.e_damage / (gc * cell.A)
    print(f"mode {mode}: peak/t0 = {peak / t0:.6f}, e_damage/(Gc A) = {ratio:.6f}, work/Gc = {work / gc:.6f}")
    assert peak == pytest.approx(t0, rel=0.01)
    assert cell.ifs.fail_mode[0] == fail_mode
    assert path[k_fail] >= df * (1.0 - 1e-9) and path[k_fail - 1] < df
    assert ratio == pytest.approx(1.0, rel=0.02)
    assert work / gc == pytest.approx(1.0, rel=0.02)
    assert np.all(trac[k_fail:] == 0.0)


def test_unload_reload_keeps_damage_and_secant_slope():
    """Mode I to D ~ 0.5, unload to 0 in 50 steps, reload to the same opening, then on.

    Checks: D unchanged (exactly) after the unload and after the reload to the same opening;
    unloading and reloading are linear with slope (1 - D) kn within 1 %; no dissipation over the
    cycle (e_damage unchanged exactly); the stored energy from interface_energy equals
    (1 - D) kn dn^2 / 2 A within 1e-9 and traction work = stored + e_damage within 0.5 %
    (the element-level energy balance); past the old maximum, damage grows again.
    """
    cell = Cell(shell())
    d0 = TN0 / KN
    df = 2.0 * GIC / TN0
    path = path_to(d0, df)
    work = 0.0
    prev_d, prev_s = 0.0, 0.0
    dn_max = None
    for d in path:
        s, _ = cell.set(dn=d)
        work += 0.5 * (s + prev_s) * (d - prev_d)
        prev_d, prev_s = d, s
        if cell.damage >= 0.5:
            dn_max = d
            break
    assert dn_max is not None
    D = cell.damage
    e_dmg = cell.e_damage
    cohesive = np.zeros(1)
    contact = np.zeros(1)
    x = cell.model.x0.copy()
    x[cell.nb] += dn_max * cell.n
    interface_energy(x, cell.ifs, cohesive, contact)
    stored = 0.5 * (1.0 - D) * KN * dn_max**2 * cell.A
    print(f"D = {D:.4f}: stored/expected = {cohesive[0] / stored:.12f}, "
          f"work/(stored + e_damage) = {work * cell.A / (cohesive[0] + e_dmg):.6f}")
    assert cohesive[0] == pytest.approx(stored, rel=1e-9)
    assert work * cell.A == pytest.approx(cohesive[0] + e_dmg, rel=0.005)

    down = np.linspace(dn_max, 0.0, 51)[1:]
    for d in down:
        s, _ = cell.set(dn=d)
        if d > 0.0:
            assert s / d == pytest.approx((1.0 - D) * KN, rel=0.01)
    assert cell.damage == D
    up = np.linspace(0.0, dn_max, 51)[1:]
    slopes = []
    for d in up:
        s, _ = cell.set(dn=d)
        slopes.append(s / d)
    print(f"reload slope / ((1-D) kn) = {slopes[0] / ((1 - D) * KN):.9f} .. {slopes[-1] / ((1 - D) * KN):.9f}")
    assert np.allclose(slopes, (1.0 - D) * KN, rtol=0.01)
    assert cell.damage == D, "reloading to the old maximum must not heal or grow damage"
    assert cell.e_damage == e_dmg
    cell.set(dn=1.05 * dn_max)
    assert cell.damage > D


def test_compression_is_carried_undamaged():
    """Closing to -50 MPa / kn: traction -50 MPa (kn dn) within 1e-9, D = 0, e_damage = 0; after
    pre-damage to D ~ 0.5 in opening the same closure still gives kn dn (D not applied) and D
    unchanged; a shear slip under the compression gives (1 - D) ks ds (no friction while intact)."""
    dn = -50e6 / KN
    cell = Cell(shell())
    s, t = cell.set(dn=dn)
    print(f"compression: sigma = {s / 1e6:.9f} MPa")
    assert s == pytest.approx(-50e6, rel=1e-9) and abs(t) < 1e-6
    assert cell.damage == 0.0 and cell.e_damage == 0.0

    cell = Cell(shell())
    df = 2.0 * GIC / TN0
    for d in np.linspace(0.0, 0.5 * df, 2001)[1:]:
        cell.set(dn=d)
    D = cell.damage
    assert 0.3 < D < 0.99
    s, _ = cell.set(dn=dn)
    assert s == pytest.approx(-50e6, rel=1e-9)
    assert cell.damage == D
    ds = 0.5 * TS0 / KS
    s, t = cell.set(dn=dn, ds=ds)
    assert s == pytest.approx(-50e6, rel=1e-9)
    assert t == pytest.approx((1.0 - D) * KS * ds, rel=1e-9)


def gc_bk(b, eta=BK_ETA):
    return GIC + (GIIC - GIC) * b**eta


def gc_power(b, alpha=2.0):
    return (((1.0 - b) / GIC) ** alpha + (b / GIIC) ** alpha) ** (-1.0 / alpha)


@pytest.mark.parametrize("rule, initiation", [("bk", "quadratic"), ("power", "quadratic"), ("bk", "maximum"),
                                              ("power", "maximum")])
def test_mixed_mode_45_degrees_dissipates_mixed_gc(rule, initiation):
    """dn = ds (45 degrees), monotonic to failure, BK (eta 1.45) and power law (alpha 2), each
    with both initiation criteria.

    Energy ratio B = ks / (kn + ks) = 0.3204; Gc = 910.1 J/m^2 (BK) or 1101.2 J/m^2 (power).
    d0 from sqrt((kn d / tn0)^2 + (ks d / ts0)^2) = 1 (quadratic: the peak normal traction is then
    0.9496 tn0) or max(kn d / tn0, ks d / ts0) = 1 (maximum: tn0, the normal criterion governs),
    K = (kn + ks) / 2 per unit dm^2, df = 2 Gc / (K d0). Checks: e_damage at failure and traction
    work = Gc A within 2 %; failure at dm = df (within a step); fail_mode 3 (mixed); the peak
    normal traction kn c d0 within 1 %.
    """
    cell = Cell(shell(mixed_mode=rule, initiation=initiation))
    b = KS / (KN + KS)
    gc = gc_bk(b) if rule == "bk" else gc_power(b)
    # along the path d = dm: dn = ds = dm / sqrt(2)
    c = 1.0 / math.sqrt(2.0)
    f_n, f_s = KN * c / TN0, KS * c / TS0
    f_per_dm = max(f_n, f_s) if initiation == "maximum" else math.hypot(f_n, f_s)
    d0 = 1.0 / f_per_dm
    k_eff = 0.5 * (KN + KS)
    df = 2.0 * gc / (k_eff * d0)
    path = path_to(d0, df)
    sig, tau, work, k_fail = drive(cell, path, (c, c))
    ratio = cell.e_damage / (gc * cell.A)
    print(f"mixed {rule}: B = {b:.4f}, Gc = {gc:.1f}, e_damage/(Gc A) = {ratio:.6f}, work/Gc = {work / gc:.6f}, "
          f"peak sigma/tn0 = {sig.max() / TN0:.6f}")
    assert ratio == pytest.approx(1.0, rel=0.02)
    assert work / gc == pytest.approx(1.0, rel=0.02)
    assert path[k_fail] >= df * (1.0 - 1e-9) and path[k_fail - 1] < df
    assert cell.ifs.fail_mode[0] == 3
    assert sig.max() == pytest.approx(KN * c * d0, rel=0.01)


def test_friction_after_failure_uses_ks_and_mu():
    """After a mode-I failure, closing to -20 MPa / kn and sliding: normal traction kn dn (within
    1e-9), and the shear traction reaches mu |sigma| = 0.3 x 20 MPa (within 1 %) and never
    exceeds it: the failed pair is the existing penalty contact with Coulomb friction, its
    penalties the law's kn and ks."""
    cell = Cell(shell())
    df = 2.0 * GIC / TN0
    cell.set(dn=0.5 * df)
    cell.set(dn=1.01 * df)
    assert cell.state == 1
    dn = -20e6 / KN
    s, t = cell.set(dn=dn)
    assert s == pytest.approx(-20e6, rel=1e-9)
    dt = 1e-7
    rate = 1.0
    taus = [cell.set(dn=dn, ds=k * rate * dt, slip_rate=rate, dt=dt)[1] for k in range(1, 400)]
    assert taus[0] == pytest.approx(KS * rate * dt, rel=1e-9)
    assert max(taus) <= 0.3 * 20e6 * (1 + 1e-9)
    assert taus[-1] == pytest.approx(0.3 * 20e6, rel=0.01)


BASE = (examples_dir() / "three-point-bending.toml").read_text()
GM_BLOCK = """law = "guo-munjiza"
tensile_strength = 3e6            # Pa (3 MPa)
cohesion = 15e6                   # Pa (15 MPa)
friction_angle = 30.0             # degrees
fracture_energy = 10.0            # J/m^2
"""
BILINEAR_BLOCK = """law = "bilinear"
tensile_strength = 7e6
shear_strength = 7e6
fracture_energy = 770.0
normal_stiffness = 636.36e9
shear_stiffness = 636.36e9
"""


@pytest.mark.parametrize(
    "edit, expected",
    [
        (lambda t: t.replace("normal_stiffness = 636.36e9\n", ""), "material.interface.normal_stiffness"),
        (lambda t: t.replace("shear_strength = 7e6\n", ""), "material.interface.shear_strength"),
        (lambda t: t.replace("shear_stiffness = 636.36e9", "shear_stiffness = -1.0"), "material.interface.shear_stiffness"),
        (lambda t: t.replace('law = "bilinear"', 'law = "bilinear"\nmixed_mode = "quadratic"'), "material.interface.mixed_mode"),
        (lambda t: t.replace('law = "bilinear"', 'law = "bilinear"\ncohesion = 1e6'), "material.interface.cohesion"),
        (lambda t: t.replace("fracture_energy = 770.0", "fracture_energy = 1.0"), "snap back"),
    ],
)
def test_bad_bilinear_scenario_exits_2_naming_the_field(tmp_path, capsys, edit, expected):
    """law = "bilinear" without normal_stiffness (and other mistakes): exit code 2, one line
    naming the field (`expected`), nothing written."""
    assert GM_BLOCK in BASE
    text = edit(BASE.replace(GM_BLOCK, BILINEAR_BLOCK))
    path = tmp_path / "s.toml"
    path.write_text(text)
    code = main(["run", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    print(err)
    assert code == 2
    assert expected in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_bilinear_scenario_builds():
    """The same block, complete, validates and builds a model whose interfaces have pn = kn."""
    from crackle.fdem.setup import Scenario, build_material
    import tomllib

    data = tomllib.loads(BASE.replace(GM_BLOCK, BILINEAR_BLOCK))
    scenario = Scenario.model_validate(data)
    mat = build_material(scenario.material)
    assert isinstance(mat.interface, BilinearLaw)
    assert mat.interface.mixed_mode == "bk" and mat.interface.gf_shear == 770.0
    assert Cell(mat).pn == 636.36e9


def test_energy_balance_closes_in_a_run():
    """A 20 mm cube of 750 tets with bilinear interfaces (tn0 3 MPa, kn 2e13 N/m^3), torn by an
    initial velocity field (4 m/s stretch, 2 m/s shear over its height), 300 steps at 0.3 of the
    stable step: interfaces damage and fail (checked > 100 failed) and the energy audit closes:
    |external - (kinetic + strain + cohesive + contact + damage + friction ...)| / external
    < 1e-3 (measured -2.7e-4; second order in dt: -3.0e-5 at 0.1 of the step)."""
    import warnings

    from crackle.fdem.model import build_fdem_model
    from crackle.fdem.simulation import FdemSimulation
    from crackle.geometry import structured_box

    from fdem_helpers import energy_error

    mesh = structured_box((0.02, 0.02, 0.02), 0.004)
    v0 = np.zeros_like(mesh.points)
    v0[:, 2] = 4.0 * (mesh.points[:, 2] - 0.01) / 0.01
    v0[:, 0] = 2.0 * (mesh.points[:, 2] - 0.01) / 0.01
    law = BilinearLaw(3e6, 4e6, 10.0, 2e13, 1e13, fracture_energy_shear=20.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = build_fdem_model(mesh, Material(RHO, E, NU, law), initial_velocity=v0)
    assert np.all(model.ifs.pn == 2e13) and np.all(model.ifs.ps == 1e13)
    sim = FdemSimulation(model)
    dt = 0.3 * model.stable_dt
    sim.advance(300, dt)
    err = energy_error(sim.energies(dt))
    failed = int((model.ifs.state == 1).sum())
    print(f"run: failed {failed}, energy error {err:.3e}")
    assert failed > 100
    assert abs(err) < 1e-3

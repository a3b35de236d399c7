"""The triaxial test (FDEM): a core confined by a pressure on its side ([[pressures]] on the faces
a cylinder selection takes), then loaded between platens; and the strength envelopes a sweep fits
to the peaks (analysis.envelope, sweep.table.write_envelopes)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crackle.analysis.envelope import hoek_brown, hoek_brown_sigma_1, mohr_coulomb
from crackle.api import build_simulation, run_scenario
from crackle.scenario import load_scenario
from crackle.sweep.table import write_envelopes

R, L, E, NU = 0.01, 0.04, 26e9, 0.2


def _boundary_faces(model):
    """(tet, face, unit outward normal, area) of every outer face of the exploded mesh."""
    tets, x = model.tets, model.nodes.x  # at set-up: the reference positions
    tet, face = np.nonzero(tets.face_iface < 0)
    corners = np.array([[k for k in range(4) if k != f] for f in face])
    p = x[4 * tet[:, None] + corners]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    return tet, face, normal, tets.face_area[tet, face]


def test_the_cylinders_side_takes_every_side_face_and_no_end_face():
    """The quick core's confinement (`where` a cylinder of radius 10 mm about z): the faces it
    loads are exactly the outer faces whose normal is not along the axis (every one of them, none
    of the ends' faces, whose rim triangles have all three corners on the cylinder too), and
    their area is the side's, 2 pi R L, within 1 % (the inscribed polygon's facets: measured
    -0.5 %)."""
    scenario, base = load_scenario("triaxial", quick=True)
    sim, _ = build_simulation(scenario, base)
    tet, face, normal, area = _boundary_faces(sim.model)
    pressed = sim.model.tets.face_pressure[tet, face] == 0
    side = np.abs(normal[:, 2]) < 0.5
    assert np.array_equal(pressed, side)
    assert (~side).sum() > 0
    assert area[pressed].sum() == pytest.approx(2.0 * math.pi * R * L, rel=0.01)


def test_a_confined_elastic_core_carries_the_closed_form_stresses(tmp_path):
    """The quick core with unbreakable faces and frictionless platens, sigma_3 = 10 MPa on its
    side (ramped over 0.04 ms, held) while the platens hold still (to 0.07 ms), then closing (at
    0.05 m/s each from 0.12 ms, to 0.26 ms): with the ends held the confinement's Poisson squeeze
    leaves the platens an axial stress 2 nu sigma_3 = 4 MPa (within 5 %, the mean over 0.05-0.07
    ms, about one axial ringing period, 2 L / c = 24 us: the core rings about it; measured 3.847
    MPa, -3.8 %; 3.854 MPa with the example's 0.1 ms ramp, held to 0.15 ms); once they close, the
    axial stress rises with the platens' strain at E (the lateral pressure stays: within 5 %, over
    0.01-0.04 % strain; measured 25.42 GPa, -2.2 %: the faces' penalty springs add compliance). The summary's confining_pressure is sigma_3 at the peak (the run's last
    row, elastic throughout) and deviator_at_peak the peak less it (1e-12)."""
    out = tmp_path / "elastic"
    result = run_scenario("triaxial", out, quick=True, progress=False, plots=False, overrides=[
        "material.interface.tensile_strength=1e9", "material.interface.cohesion=1e10", "tools.0.friction=0",
        "tools.1.friction=0", "pressures.0.ramp_time=4e-5", *[f"tools.{k}.speed_table={{time=[0.0, 7e-5, 1.2e-4], "
        "speed=[0.0, 0.0, 0.05]}" for k in (0, 1)], "run.end_time=2.6e-4", "run.field_frames=0"])
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    s = result.summary
    held = (h["time"] > 5e-5) & (h["time"] < 7e-5)
    print(f"axial stress while held {np.mean(h['platenstress'][held]) / 1e6:.3f} MPa")
    assert np.mean(h["platenstress"][held]) == pytest.approx(2.0 * NU * 10e6, rel=0.05)
    loading = (h["platenstrain"] > 1e-4) & (h["platenstrain"] < 4e-4)
    modulus = np.polyfit(h["platenstrain"][loading], h["platenstress"][loading], 1)[0]
    print(f"axial modulus {modulus / 1e9:.2f} GPa")
    assert modulus == pytest.approx(E, rel=0.05)
    assert s["broken"] == 0
    assert s["confining_pressure"] == 10e6
    assert s["deviator_at_peak"] == pytest.approx(s["peak_stress"] - 10e6, rel=1e-12)
    assert s["peak_stress"] == pytest.approx(np.max(np.abs(h["platenstress"])), rel=0.02)


def test_envelopes_recover_the_criteria_they_are_fitted_to():
    """Peaks on an exact Mohr-Coulomb line (c = 15 MPa, phi = 30 deg: UCS 51.96 MPa, slope 3)
    give back c and phi (1e-9); peaks on an exact Hoek-Brown curve (sigma_ci = 100 MPa, m_i = 10)
    give back sigma_ci and m_i (1e-9); one confinement gives no envelope; a slope below 1 (no
    friction) no Mohr-Coulomb one."""
    s3 = np.array([0.0, 5e6, 10e6, 20e6])
    c, phi = 15e6, math.radians(30.0)
    ucs = 2.0 * c * math.cos(phi) / (1.0 - math.sin(phi))
    fit = mohr_coulomb(s3, ucs + 3.0 * s3)
    assert fit["cohesion"] == pytest.approx(c, rel=1e-9)
    assert fit["friction_angle"] == pytest.approx(30.0, rel=1e-9)
    assert fit["ucs"] == pytest.approx(ucs, rel=1e-9) and fit["r2"] == pytest.approx(1.0)
    hoek = {"sigma_ci": 100e6, "m_i": 10.0}
    got = hoek_brown(s3, hoek_brown_sigma_1(hoek, s3))
    assert got["sigma_ci"] == pytest.approx(100e6, rel=1e-9) and got["m_i"] == pytest.approx(10.0, rel=1e-9)
    assert mohr_coulomb([5e6, 5e6], [60e6, 61e6]) is None and hoek_brown([5e6], [60e6]) is None
    assert mohr_coulomb(s3, 50e6 + 0.5 * s3) is None


def test_a_sweeps_triaxial_runs_get_their_envelopes(tmp_path):
    """write_envelopes over a sweep's rows: the finished runs with confining_pressure and
    peak_stress (a failed run and one without them left out) in envelope.json, with both fits,
    and plots/strength_envelope.png; rows at one confinement write nothing."""
    def row(s3, s1, status="stopped"):
        return {"status": status, "summary": {"confining_pressure": s3, "peak_stress": s1}}

    rows = [row(0.0, 52e6), row(10e6, 82e6), row(20e6, 112e6), row(30e6, 1.0, "failed"), {"status": "stopped",
                                                                                        "summary": {}}]
    lines = write_envelopes(tmp_path, rows, "triaxial")
    saved = json.loads((tmp_path / "envelope.json").read_text())
    assert saved["sigma_3"] == [0.0, 10e6, 20e6]
    assert saved["mohr_coulomb"]["friction_angle"] == pytest.approx(30.0) and len(lines) == 2
    assert (tmp_path / "plots" / "strength_envelope.png").stat().st_size > 0
    other = tmp_path / "one"
    other.mkdir()
    assert write_envelopes(other, [row(10e6, 82e6), row(10e6, 83e6)]) == [] and not (other / "envelope.json").exists()

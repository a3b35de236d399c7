"""energy_error: the imbalance at the end of a run over the largest energy seen, so that it means
the same for a loaded run, a run with no loads and a run stopped before its first step."""

import json

import numpy as np
import pytest

from crackle.cli import main
from crackle.analysis.energy import created_fraction, energy_error, imbalance_growth


def _history(external, kinetic, elastic):
    return {
        "energy.external": np.asarray(external, float),
        "energy.kinetic": np.asarray(kinetic, float),
        "energy.elastic": np.asarray(elastic, float),
    }


def test_relative_to_the_largest_energy_seen():
    """10 J put in, 9.5 J accounted for at the end: -0.5 / 10 = 5 %, whatever came before."""
    h = _history([0.0, 4.0, 10.0], [0.0, 3.0, 6.0], [0.0, 1.0, 3.5])
    assert energy_error(h) == pytest.approx(0.05, rel=1e-12)


def test_initial_kinetic_energy_counts_as_work_put_in():
    """A body flying freely: external = its initial kinetic energy, kinetic unchanged: 0."""
    h = _history([2.0, 2.0, 2.0], [2.0, 2.0, 2.0], [0.0, 0.0, 0.0])
    assert energy_error(h) == 0.0


@pytest.mark.parametrize("rows", [1, 5])
def test_no_energy_at_all_is_no_error(rows):
    """A run with no loads, or one stopped at step 0 (a single row of zeros): 0, not -100 %."""
    zeros = np.zeros(rows)
    assert energy_error(_history(zeros, zeros, zeros)) == 0.0


def test_the_growth_of_the_imbalance_is_located_and_its_term_named():
    """A run whose friction is booked 10 % too high from 0.5 to 1 s (energy from nothing, as on
    the walnut's sliding crushed faces before the turning forces), beside a kinetic energy that
    oscillates and a damage term that grows over the whole run: the imbalance went from 10 to
    90 % of its final value between 0.55 and 0.95 s (+-1 row of 0.01 s), in proportion to
    energy.friction at -0.1 / 1.1 of it (R^2 > 0.999), and its description says so."""
    t = np.linspace(0.0, 1.0, 101)
    friction = np.clip(t - 0.5, 0.0, None)  # J truly dissipated by friction
    damage = 0.3 * t
    kinetic = 0.05 * (1.0 + np.sin(40.0 * t))
    elastic = 0.2 * t
    external = friction + damage + kinetic + elastic
    history = {"time": t, **_history(external, kinetic, elastic), "energy.damage": damage,
               "energy.friction": 1.1 * friction}
    growth = imbalance_growth(history)
    assert growth.start == pytest.approx(0.55, abs=0.011)
    assert growth.end == pytest.approx(0.95, abs=0.011)
    assert growth.term == "energy.friction"
    assert growth.ratio == pytest.approx(-0.1 / 1.1, rel=1e-9)
    assert growth.r2 > 0.999
    text = growth.describe(1.0, "s")
    assert f"between {growth.start:.4g} and {growth.end:.4g} s" in text and "energy.friction (-9.1%" in text
    # No imbalance: nothing to locate.
    history["energy.friction"] = friction
    assert imbalance_growth(history) is None


def test_a_run_without_loads_reports_zero_and_no_warning(tmp_path):
    """A specimen at rest with no tool, support, pressure or gravity: its energies stay at
    rounding noise (~1e-27 J), which is no imbalance (it read -100 % before)."""
    path = tmp_path / "rest.toml"
    path.write_text(
        """
method = "fdem"
[specimen]
shape = "box"
size = [0.02, 0.02, 0.02]
element_size = 0.01
mesh = "structured"
[material]
density = 2340.0
youngs_modulus = 26e9
poissons_ratio = 0.2
[material.interface]
law = "guo-munjiza"
tensile_strength = 3e6
cohesion = 15e6
friction_angle = 30.0
fracture_energy = 10.0
[run]
end_time = 1e-6
field_frames = 0
"""
    )
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["energy_error"] == 0.0
    assert not any("energy balance" in w for w in summary.get("warnings", []))


def test_instability_check_leaves_out_the_contact_springs_one_step_lag():
    """created_fraction (the driver's instability check): a tool that reaches the specimen after
    a gap stores contact energy in the step before its work is booked (first contact: 0 J put in,
    1e-6 J in the springs) - not an instability (0); energy created in the body is one: 2 J of
    kinetic energy for 1 J put in is (2 - 1) / 2 = 0.5 of the larger."""
    first_contact = {"energy.external": 0.0, "energy.kinetic": 0.0, "energy.contact": 1e-6}
    assert created_fraction(first_contact) == 0.0
    unstable = {"energy.external": 1.0, "energy.kinetic": 2.0, "energy.contact": 1e-6}
    assert created_fraction(unstable) == pytest.approx(0.5, rel=1e-12)


def test_the_audit_warning_says_when_the_imbalance_grew(tmp_path, monkeypatch):
    """The summary's energy warning (here forced with a threshold of 0) names the span where the
    imbalance grew and the term it grew with, in the run's time unit."""
    import crackle.solver.driver as driver

    monkeypatch.setattr(driver, "ENERGY_WARNING", 0.0)
    out = tmp_path / "out"
    assert main(["run", "single-fracture", "--quick", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    [warning] = [w for w in summary["warnings"] if "energy balance" in w]
    assert "it went from 10% to 90% of its final value between" in warning and " µs, in proportion to energy." in warning

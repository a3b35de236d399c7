"""energy_error: the imbalance at the end of a run over the largest energy seen, so that it means
the same for a loaded run, a run with no loads and a run stopped before its first step."""

import json

import numpy as np
import pytest

from crackle.cli import main
from crackle.analysis.energy import created_fraction, energy_error


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

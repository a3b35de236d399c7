"""Paper 001 Fig. 1: a breakable sphere hitting a rigid base, slow (10 m/s) and fast (100 m/s),
quick forms (672 tets) with surface contact on."""

from __future__ import annotations

import json

import pytest

from crackle.api import run_scenario


def _summary(tmp_path, name):
    # plots/ left out: seconds a run, and no test here reads it
    run_scenario(name, tmp_path / name, overrides=["run.field_frames=0"], quick=True, plots=False)
    return json.loads((tmp_path / name / "summary.json").read_text())


def test_slow_impact_stays_nearly_whole_and_rebounds(tmp_path):
    """10 m/s: the largest fragment keeps >= 95 % of the mass (measured 100 %: 2 interfaces
    broken), bounces back up at more than half the impact speed (measured 9.85 m/s), and energy
    balances within 3 %."""
    s = _summary(tmp_path, "sphere-impact-slow")
    assert s["largest_fragment_mass_fraction"] >= 0.95
    assert s["largest_fragment_velocity"][2] > 5.0
    assert abs(s["energy_error"]) < 0.03


@pytest.mark.slow
def test_fast_impact_fragments_with_energy_balance(tmp_path):
    """100 m/s: many fragments (>= 50; measured 409 of 672 tets), none holding half the mass, and
    |energy_error| < 3 % (the contact issue's acceptance; measured +0.30 %, 2026-12-06; +0.69 % before
    the turning forces of failed faces)."""
    s = _summary(tmp_path, "sphere-impact-fast")
    assert s["fragments"] >= 50
    assert s["largest_fragment_mass_fraction"] < 0.5
    assert abs(s["energy_error"]) < 0.03

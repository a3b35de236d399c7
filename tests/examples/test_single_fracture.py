"""Paper 001 section 3.1: a single fracture driven by pressure on a central pre-crack, and the
plastic-zone measurement behind its validation rows."""

from __future__ import annotations

import json

import numpy as np
import pytest

from crackle.analysis import FracturePlane, propagating_plastic_zone, tip_and_plastic_zone
from crackle.api import run_scenario
from crackle.io import read_events_csv


def test_tip_and_plastic_zone_on_a_line_of_interfaces():
    """Interfaces every 5 mm along x on the plane y = 0 (and one off it): failed up to x = 30 mm,
    softening (0 < D < 1) up to 45 mm, intact beyond: tip 30 mm, plastic zone 15 mm exactly.
    The damaged interface off the plane and the one behind the tip do not count."""
    x = np.arange(0.0, 0.1, 0.005)
    centroids = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.01)])
    failed = x <= 0.030 + 1e-12
    damage = np.where(failed, 1.0, np.where(x <= 0.045 + 1e-12, 0.5, 0.0))
    damage[2] = 0.7  # behind the tip: failed anyway
    off = np.array([[0.08, 0.004, 0.01]])  # damaged, but 4 mm off the plane
    plane = FracturePlane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0), tol=1e-6)
    tip, zone = tip_and_plastic_zone(
        plane, np.vstack([centroids, off]), np.append(damage, 0.9), np.append(failed, False)
    )
    assert tip == pytest.approx(0.030, abs=1e-12)
    assert zone == pytest.approx(0.015, abs=1e-12)
    # Median over the samples while the tip moves: the first sample (tip at rest) is skipped.
    assert propagating_plastic_zone([0.01, 0.01, 0.02, 0.03], [0.0, 0.004, 0.015, 0.017]) == pytest.approx(0.016)


def test_quick_single_fracture_splits_along_the_precrack_plane(tmp_path):
    """Quick form (h = 20 mm, 432 tets, the paper's Model 1): every failure lies on the pre-crack
    plane y = 60 mm (one fracture plane through the pre-crack), the fracture runs to the far
    boundary (the last failed centroid within one element of x = 60 mm), the body ends in 2
    pieces, the energy balances within 1 % (measured -0.0006 %), and the plastic zone spans one
    to two elements as the paper finds at this size (measured 26.7 mm)."""
    out = tmp_path / "sf"
    result = run_scenario("single-fracture", out, overrides=["run.field_frames=0"], quick=True, progress=False,
                          plots=False)  # plots/: seconds, read by no test here
    s = json.loads((out / "summary.json").read_text())
    ev = read_events_csv(out / "events.csv")
    assert len(ev["y"]) >= 4
    assert np.allclose(ev["y"], 0.06, atol=1e-6)
    assert s["fracture_tip_final"] >= 0.06 - 0.02
    assert s["fragments"] == 2
    assert abs(s["energy_error"]) < 0.01
    assert 0.0 < s["plastic_zone_length"] <= 2 * 0.02
    assert result.summary["status"] == "completed"

"""The shipped brazilian-disc example (paper 001, section 4) in its quick form (1,650 tets,
element_size 4 mm), at loading angles theta = 0 and 30 degrees (`loading.angle`).

Measured (NUMBA_NUM_THREADS=1, ~37-40 s each): peak platen force 2572 N (theta = 0) and
2073 N (theta = 30); the first failures are shear failures under the platens (~407 us), then
the crushing zones spread and the run's energy balance breaks down (energy_error -98 %, more
dissipated and kinetic energy than the platens' work), and the disc ends up broken across the
loading axis rather than split along it: splitting_angle 89.7 deg (theta = 0) and 84.5 deg
(theta = 30). So the splitting test is an expected failure until the crushing-zone energy
creation is fixed; the peak-force band holds.
"""

from __future__ import annotations

import math

import pytest

from crackle.analysis.brazilian import loading_direction, splitting_angle
from crackle.api import run_scenario
from crackle.io import read_events_csv

D, T, FT = 0.04, 0.015, 3e6
ELASTIC_PEAK = FT * math.pi * D * T / 2  # 2827 N


@pytest.fixture(scope="module", params=[0.0, 30.0], ids=["theta0", "theta30"])
def quick_run(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(f"bd{int(request.param)}")
    result = run_scenario(
        "brazilian-disc", out, overrides=[f"loading.angle={request.param}", "run.field_frames=0"], quick=True, progress=False
    )
    return request.param, result


def test_peak_force_near_elastic_brazilian_relation(quick_run):
    """Peak force within 0.6-1.2 x ft pi D t / 2 (= 1696-3393 N). Measured 0.91 (theta = 0) and
    0.73 (theta = 30). The band is wide because the 4 mm quick mesh resolves neither the
    contact zone (a line of 1-2 nodes under each platen) nor the plastic zone, and the peak is
    set by crushing under the platens; the paper's fine-mesh mean (2220 N) is 0.79 x."""
    _, result = quick_run
    assert 0.6 * ELASTIC_PEAK <= result.summary["peak_force"] <= 1.2 * ELASTIC_PEAK
    assert result.summary["broken"] > 0


@pytest.mark.xfail(strict=True, reason="crushing at the platens creates energy (energy_error -98 %) and the disc breaks across the load axis; see the module docstring")
def test_splitting_fracture_along_loading_axis(quick_run):
    """Paper 001 Fig. 17: one tensile splitting fracture along the loading axis. The principal
    direction of the tension/mixed failures in the central 60 % of the diameter along the load
    axis lies within 15 degrees of it, and the energy balances within 5 %."""
    theta, result = quick_run
    ev = read_events_csv(result.out_dir / "events.csv")
    angle, used = splitting_angle(ev, loading_direction(theta), 0.5 * D)
    assert used >= 5
    assert angle <= 15.0
    assert abs(result.summary["energy_error"]) < 0.05

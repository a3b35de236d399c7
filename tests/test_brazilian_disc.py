"""The shipped brazilian-disc example (paper 001, section 4) in its quick form (1,650 tets,
element_size 4 mm), at loading angles theta = 0 and 30 degrees (`loading.angle`).

Measured at theta = 0 (2 threads, ~2 min): shear failures under the platens from ~0.65 ms, peak
platen force 4450 N, then one splitting fracture through the centre at ~1.14 ms, 7 degrees
from the loading axis (theta = 30: 5906 N, 5 degrees); energy error -0.03 %. The peak is
1.6-2.1 x the elastic Brazilian relation: with Gf = 50 J/m^2 the characteristic length E Gf / ft^2 = 144 mm is 3.6 disc
diameters, and the 4 mm mesh (about 3 tets through the thickness) does not resolve the process
zone, which the paper reports over-estimates peak loads on coarse meshes.
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
    """Peak force within 0.6-2.5 x ft pi D t / 2 (= 1696-7069 N); measured 1.57 x (4450 N,
    theta = 0) and 2.09 x (5906 N, theta = 30). A sanity band, not a validation: on the quick
    mesh the peak depends on how the faceted disc meets the (rotated) flat platens, and the
    process zone is not resolved (module docstring); the paper's fine-mesh mean, 2220 N, is
    0.79 x."""
    _, result = quick_run
    assert 0.6 * ELASTIC_PEAK <= result.summary["peak_force"] <= 2.5 * ELASTIC_PEAK
    assert result.summary["broken"] > 0


def test_splitting_fracture_along_loading_axis(quick_run):
    """Paper 001 Fig. 17: one splitting fracture along the loading axis. The principal direction
    of the tension/mixed failures in the central 60 % of the diameter along the load axis lies
    within 15 degrees of it (measured 6 degrees at theta = 0), and the energy balances within
    3 % (measured -0.03 %)."""
    theta, result = quick_run
    ev = read_events_csv(result.out_dir / "events.csv")
    angle, used = splitting_angle(ev, loading_direction(theta), 0.5 * D)
    print(f"theta = {theta}: splitting angle {angle:.1f} deg from {used} failures, peak {result.summary['peak_force']:.0f} N")
    assert used >= 5
    assert angle <= 15.0
    assert abs(result.summary["energy_error"]) < 0.03

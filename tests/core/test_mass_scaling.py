"""Mass scaling (run.target_dt, run.max_added_mass): only elements whose step is below the
target get heavier, by (target / their step)^2; the added mass is reported and capped; the
energy audit stays closed."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from crackle.api import build_simulation
from crackle.cli import main
from crackle.scenario import load_scenario

# The quick Brazilian disc (gmsh, 1,650 tets): its run step without scaling is 7.6 ns, a few
# small elements near 7-10 ns, the median element 18 ns (0.7 x 26 ns stable).
DISC = ["specimen.element_size=0.004", "run.end_time=2e-5"]


def _sim(*overrides):
    scenario, base = load_scenario("brazilian-disc", [*DISC, *overrides])
    return build_simulation(scenario, base)[0]


def test_only_elements_below_the_target_get_heavier_and_the_step_reaches_it():
    plain, scaled = _sim(), _sim("run.target_dt=1e-8")
    safety = 0.7
    before = safety * plain.model.time_step.element_dt
    factor = np.maximum(1.0, (1e-8 / before) ** 2)
    tet_mass = plain.model.nodes.mass.reshape(-1, 4).sum(axis=1)
    expected = np.sum((factor - 1.0) * tet_mass) / tet_mass.sum()
    ms = scaled.model.mass_scaling
    assert ms.added_mass == pytest.approx(expected, rel=1e-12) and 0 < ms.added_mass < 0.01
    assert ms.elements == np.count_nonzero(factor > 1.0) < len(factor) // 10
    np.testing.assert_allclose(scaled.model.nodes.mass, plain.model.nodes.mass * np.repeat(factor, 4), rtol=1e-14)
    # The element bound reaches the target; the run's step (the assembled step's, by Lanczos) is
    # at least that.
    assert safety * scaled.model.time_step.bound_dt == pytest.approx(1e-8, rel=1e-9)
    assert safety * scaled.stable_dt >= 1e-8
    assert np.all(safety * scaled.model.time_step.element_dt >= 1e-8 * (1 - 1e-9))
    # Elements already above the target keep their mass and their step.
    kept = factor == 1.0
    np.testing.assert_array_equal(scaled.model.time_step.element_dt[kept], plain.model.time_step.element_dt[kept])


def test_target_above_the_cap_is_refused_naming_the_largest_allowed(capsys, tmp_path):
    """3e-8 s would make nearly every element heavier (exit 2); the target the message offers
    runs, within run.max_added_mass."""
    code = main(["run", "brazilian-disc", *sum((["--set", o] for o in DISC), []), "--set", "run.target_dt=3e-8",
                 "--out", str(tmp_path / "no")])
    err = capsys.readouterr().err
    assert code == 2 and "more than run.max_added_mass = 1.0%" in err and not (tmp_path / "no").exists()
    offered = float(re.search(r"at most ([0-9.e+-]+) s", err).group(1))
    assert _sim(f"run.target_dt={offered!r}").model.mass_scaling.added_mass <= 0.01


@pytest.mark.slow
def test_scaled_run_keeps_the_energy_balance(tmp_path):
    out = tmp_path / "run"
    args = ["run", "brazilian-disc", "--quick", "--out", str(out), "--set", "run.target_dt=1.2e-8",
            "--set", "run.end_time=2e-4", "--set", "run.field_frames=0"]
    assert main(args) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["dt"] >= 1.2e-8 and s["dt_limit"]["bound_dt"] * 0.7 == pytest.approx(1.2e-8, rel=1e-9)
    assert 0 < s["added_mass"] <= 0.01
    assert abs(s["energy_error"]) < 0.01

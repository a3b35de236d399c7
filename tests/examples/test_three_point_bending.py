"""The shipped three-point-bending example (paper 001, section 3.2) in its quick form."""

from __future__ import annotations

import json

import numpy as np
import pytest

from crackle.api import run_scenario
from crackle.io import read_events_csv, read_history_csv


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("3pb")
    return run_scenario("three-point-bending", out, quick=True, progress=False)


def test_single_fracture_near_mid_span(quick_run):
    """Paper 001 Fig. 14e: one fracture at mid-span. Every failed interface lies within one
    element (25 mm) of x = 250 mm, and the crack runs through at least 80 % of the 50 mm height."""
    ev = read_events_csv(quick_run.out_dir / "events.csv")
    assert len(ev["time"]) >= 3
    assert np.all(np.abs(ev["x"] - 0.25) <= 0.025)
    assert np.ptp(ev["y"]) >= 0.8 * 0.05 * (1 - 2 / 6)  # failure points sit at face centroids
    # It starts on the tension side (bottom) and ends on the compression side (top).
    first, last = np.argmin(ev["time"]), np.argmax(ev["time"])
    assert ev["y"][first] < 0.025 < ev["y"][last]
    assert set(ev["mode"]) <= {"tension", "mixed"}


def test_energy_audited_with_fracture_and_friction(quick_run):
    """|energy_error| < 3 % in a run with fracture (damage > 0) and platen friction (> 0)."""
    s = quick_run.summary
    h = quick_run.history
    assert h["energy.damage"][-1] > 0
    assert h["energy.friction"][-1] > 0
    assert abs(s["energy_error"]) < 0.03


def test_outputs_follow_the_contract(quick_run):
    out = quick_run.out_dir
    summary = json.loads((out / "summary.json").read_text())
    for key in ("method", "scenario", "steps", "dt", "wall_time", "elements", "broken", "peak_force", "peak_force_tool", "energy_error", "crackle_version"):
        assert key in summary, key
    assert summary["method"] == "fdem" and summary["elements"] == 960
    # Every tool's peak over every step is reported; the overall one names its tool. In the quick
    # form the loading platen's peak is the fracture load (693 N, as the first interfaces fail at ~0.63 ms);
    # the beam halves then rebound on the supports, whose windowed force peaks later (761 N).
    assert set(summary["peak_forces"]) == {"top", "left", "right"}
    assert summary["peak_force"] == max(summary["peak_forces"].values())
    assert summary["peak_forces"][summary["peak_force_tool"]] == summary["peak_force"]
    assert summary["peak_forces"]["top"] == pytest.approx(693.0, rel=0.05)
    assert summary["broken"] == len(read_events_csv(out / "events.csv")["time"])
    hist = read_history_csv(out / "history.csv")
    for col in ["time", "broken"] + [f"tool.top.{c}" for c in ("fx", "fy", "fz", "ux", "uy", "uz")] + [
        f"energy.{e}" for e in ("kinetic", "elastic", "cohesive", "damage", "friction", "damping", "external")
    ]:
        assert col in hist, col
    # The top platen moves down at 0.1 m/s after a 0.1 ms ramp: uy(t) = -0.1 (t - 0.05 ms).
    t, uy = hist["time"][-1], hist["tool.top.uy"][-1]
    assert uy == pytest.approx(-0.1 * (t - 0.5e-4), rel=1e-6)
    assert (out / "fields.pvd").exists() and len(list((out / "fields").glob("*.vtu"))) >= 2
    for plot in ("load_displacement.png", "energies.png", "crack_pattern.png"):
        assert (out / "plots" / plot).stat().st_size > 1000
    # Peak load is the largest interval-mean platen force, and it was reached before the break.
    assert summary["peak_force"] > 100.0


def test_unstable_run_stops_with_message_and_keeps_outputs(tmp_path):
    """A step 30x above the stable one blows up: UnstableRunError naming the time, and the
    history written so far plus summary.json (status 'unstable') stay on disk."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario
    from crackle.solver import UnstableRunError, run

    scenario, _ = load_scenario("three-point-bending", quick=True)
    sim, control = build_simulation(scenario)
    control.dt = 30 * sim.model.stable_dt
    sim.model.time_step.dt *= 100  # bypass the guard to force the blow-up (stable_dt derives from it)
    control.plots = False
    with pytest.raises(UnstableRunError, match="unstable (at|before) t ="):
        run(sim, control, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "unstable"
    assert len((tmp_path / "history.csv").read_text().splitlines()) >= 2


def test_energy_created_stops_the_run_before_it_overflows(tmp_path):
    """A step 1.5x above the stable one grows slowly: the run is stopped as unstable once the
    model holds more than UNSTABLE_CREATED (25 %) more energy than the work put in, long before
    the overflow guard (1e6 x the work); a sound run stays below 1 % (docs/validation.md)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario
    from crackle.solver import UnstableRunError, run

    scenario, _ = load_scenario("three-point-bending", quick=True)
    sim, control = build_simulation(scenario)
    control.dt = 1.5 * sim.model.stable_dt
    sim.model.time_step.dt *= 3  # bypass the up-front refusal of a step above the stable one
    control.plots = False
    with pytest.raises(UnstableRunError, match=r"holds \d+% more energy"):
        run(sim, control, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "unstable"
    assert summary["energy_error"] < -0.25

"""The load cell: a tool's force is the mean over a fixed window of steps, its peak taken over
every step, so neither depends on how often history.csv is sampled."""

import json

import numpy as np
import pytest

from crackle.cli import main
from crackle.io import read_history_csv
from crackle.loading import History, Tool
from crackle.loading.arrays import LOAD_CELL_RING, tool_arrays
from crackle.loading.loadcell import LoadCell
from crackle.loading.tools import load_cell_step

RHO, E = 2340.0, 26e9
SPEED = 1.0  # m/s
SIDE, LENGTH = 0.01, 0.06  # m

BAR = f"""
name = "bar-hits-wall"
method = "fdem"

[specimen]
shape = "box"
size = [{SIDE}, {SIDE}, {LENGTH}]
origin = [0.0, 0.0, 1e-6]           # touches the wall after 1 us
element_size = 0.005
mesh = "structured"
initial_velocity = [0.0, 0.0, -{SPEED}]

[material]
density = {RHO}
youngs_modulus = {E}
poissons_ratio = 0.0

[material.interface]
law = "guo-munjiza"
tensile_strength = 30e6             # 4 x rho c v: no fracture
cohesion = 150e6
friction_angle = 30.0
fracture_energy = 100.0

[[tools]]
name = "wall"
shape = "plane"
center = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
direction = [0.0, 0.0, 1.0]
speed = 0.0

[run]
end_time = 4.5e-5
field_frames = 0
"""


def test_moving_mean_and_peak_of_a_known_force_sequence():
    """Per step forces 0, 1, ..., 9 N (x) and 0 (y, z) with a 4-step window: after step k the
    cell reads the mean of the last min(k + 1, 4) forces; the peak is the largest such mean over
    every step (7.5 N after the last step, at its time)."""
    tools = tool_arrays([Tool("plate", "plane", (0, 0, 1), History.constant(0.0))], 1.0, 1.0, 3)
    cell = LoadCell(tools)
    cell.set_window(4)
    for k in range(10):
        tools.force_slots[0, k % 3, 0] = float(k)  # any slot: the step's forces are summed
        load_cell_step(1e-3 * (k + 1), tools)
        expected = np.mean(np.arange(max(0, k - 3), k + 1))
        assert cell.forces(None)[0, 0] == pytest.approx(expected, rel=1e-14)
        assert np.all(tools.force_slots == 0.0)
    magnitude, time = cell.peaks()
    assert magnitude[0] == pytest.approx(7.5, rel=1e-14) and time[0] == pytest.approx(1e-2)


def test_window_longer_than_the_ring_is_refused():
    tools = tool_arrays([], 1.0, 1.0, 1)
    with pytest.raises(ValueError, match="window"):
        LoadCell(tools).set_window(LOAD_CELL_RING + 1)


def _run(tmp_path, samples, window=None):
    path = tmp_path / "bar.toml"
    path.write_text(BAR)
    out = tmp_path / f"out{samples}"
    args = ["run", str(path), "--out", str(out), "--set", f"run.history_samples={samples}"]
    if window is not None:
        args += ["--set", f"run.load_cell_window={window}"]
    assert main(args) == 0
    return json.loads((out / "summary.json").read_text()), read_history_csv(out / "history.csv")


def test_bar_hitting_a_wall_reads_the_impedance_force(tmp_path):
    """A bar (nu = 0, so c = sqrt(E / rho) exactly) hitting a rigid wall at v: while the wave runs
    up the bar and back (2 L / c = 36 us) the wall carries rho c v A = 780 N. The mean force over
    the plateau within 5 %, the peak within 15 % of it (before the fix the peak read 2.7-3.5 x
    the plateau and moved with history_samples), and the peak and its time identical with 40 and
    150 history rows."""
    plateau = RHO * np.sqrt(E / RHO) * SPEED * SIDE * SIDE
    coarse, _ = _run(tmp_path, 40)
    fine, h = _run(tmp_path, 150)
    assert coarse["peak_force"] == fine["peak_force"]
    assert coarse["peak_force_time"] == fine["peak_force_time"]
    assert fine["peak_force_tool"] == "wall"
    assert fine["peak_force"] == pytest.approx(plateau, rel=0.15)
    c = np.sqrt(E / RHO)
    window = (h["time"] > 8e-6) & (h["time"] < 2 * LENGTH / c - 4e-6)
    assert h["tool.wall.fz"][window].mean() == pytest.approx(plateau, rel=0.05)

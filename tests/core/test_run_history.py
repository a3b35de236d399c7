"""The history as arrays (io.outputs.RunHistory): the numbers history.csv holds, bit for bit,
without reading the file back; each column with the unit it was registered with."""

from __future__ import annotations

import math

import numpy as np

from crackle.analysis.columns import column_unit, tool_column_units
from crackle.io.outputs import HistoryWriter, RunHistory, read_history_csv


def test_the_arrays_are_the_file_s_numbers_bit_for_bit(tmp_path):
    """Values repr cannot shorten (1/3, 0.1 + 0.2), -0.0, nan, an int, a bool and a missing
    column (nan in both) read back from history.csv as the arrays hold them."""
    units = {"time": "s", "energy.kinetic": "J", "broken": "1", "tool.top.fx": "N"}
    rows = [{"time": 0.0, "energy.kinetic": 1.0 / 3.0, "broken": 0, "tool.top.fx": -0.0},
            {"time": 1e-7, "energy.kinetic": 0.1 + 0.2, "broken": True, "tool.top.fx": math.nan},
            {"time": 2e-7, "broken": 12}]
    table = RunHistory(units)
    with HistoryWriter(tmp_path / "history.csv", list(units)) as writer:
        for row in rows:
            writer.append(row)
            table.append(row)
    read = read_history_csv(tmp_path / "history.csv")
    assert list(table) == list(read)
    for name in read:
        assert table[name].tobytes() == read[name].tobytes(), name
    # A resumed run's table starts from the rows it keeps, and goes on.
    resumed = RunHistory(units, read)
    resumed.append({"time": 3e-7, "broken": 13})
    assert resumed["broken"].tolist() == [0.0, 1.0, 12.0, 13.0]
    assert np.isnan(resumed["energy.kinetic"][2:]).all()


def test_a_unit_per_column_from_where_it_was_registered():
    units = {"time": "s", "j.tip*": "J/m^2", **tool_column_units(["platen"])}
    assert column_unit(units, "tool.platen.uy") == "m" and column_unit(units, "tool.platen.fz") == "N"
    assert column_unit(units, "tool.platen.vx") == "m/s"
    assert column_unit(units, "j.tip3") == "J/m^2"  # a family: one column per crack tip
    assert column_unit(units, "g.tip0") == ""  # registered nowhere

"""crackle sweep: the plan (product, zip, values), runs on a local Dask cluster of 2 workers equal
to the same runs made one by one, resuming an interrupted sweep, and bad input."""

from __future__ import annotations

import csv
import json

import pyarrow.parquet as pq
import pytest

from crackle.cli import main
from crackle.scenario import ScenarioError
from crackle.sweep import list_sweeps, make_plan
from crackle.sweep.plan import parse_vary
from crackle.sweep.runner import check_runs
from crackle.sweep.table import summary_scalars

pytestmark = pytest.mark.filterwarnings("ignore:element size")

# The quick three-point beam (960 tets) for 20 us: about a second a run.
SHORT = ["three-point-bending", "--quick", "--set", "run.end_time=2e-5"]


def test_vary_values_are_toml_and_split_at_top_level_commas():
    vary = parse_vary(["loading.angle=0,30.5", 'plates.polar=[90, 90],[60, 120]', "material.name=a,\"b, c\""])
    assert vary == {"loading.angle": [0, 30.5], "plates.polar": [[90, 90], [60, 120]], "material.name": ["a", "b, c"]}


def test_product_has_the_last_key_fastest_and_zip_pairs_positions():
    plan = make_plan("three-point-bending", ["a.x=1,2", "b.y=3,4,5"], [], False, False)
    assert [r.varied for r in plan.runs()] == [
        {"a.x": 1, "b.y": 3}, {"a.x": 1, "b.y": 4}, {"a.x": 1, "b.y": 5},
        {"a.x": 2, "b.y": 3}, {"a.x": 2, "b.y": 4}, {"a.x": 2, "b.y": 5},
    ]
    zipped = make_plan("three-point-bending", ["a.x=1,2", "b.y=3,4"], [], True, False)
    assert [r.varied for r in zipped.runs()] == [{"a.x": 1, "b.y": 3}, {"a.x": 2, "b.y": 4}]
    assert [r.folder for r in zipped.runs()] == ["000_x=1_y=3", "001_x=2_y=4"]


@pytest.mark.parametrize(
    "vary, zip_, message",
    [
        (["a.x="], False, "at least one value"),
        (["a.x"], False, "write key=v1,v2"),
        ([], False, "nothing to vary"),
        (["a.x=1,2", "b.y=1"], True, "--zip: every varied key needs as many values"),
        (["a.x=1", "a.x=2"], False, "given twice"),
    ],
)
def test_bad_plans_are_refused_naming_the_problem(vary, zip_, message):
    with pytest.raises(ScenarioError, match=message):
        make_plan("three-point-bending", vary, [], zip_, False)


def test_every_shipped_sweep_is_a_valid_family_of_scenarios():
    """brazilian-angles (4 runs), walnut-layouts (4 zipped layouts), mesh-ladder (3 sizes): every
    run's scenario validates."""
    assert set(list_sweeps()) == {"brazilian-angles", "walnut-layouts", "mesh-ladder"}
    sizes = {}
    for name in list_sweeps():
        plan = make_plan(name, [], [], False, False)
        assert check_runs(plan, plan.runs()) == {}
        sizes[name] = len(plan.runs())
    assert sizes == {"brazilian-angles": 4, "walnut-layouts": 4, "mesh-ladder": 3}


def test_sweep_on_two_workers_equals_the_runs_one_by_one_and_resumes(tmp_path):
    """A 2 x 2 sweep on a local cluster of 2 workers: 4 run folders whose histories are
    byte-identical to the same runs made one by one with `crackle run`, and a table whose rows
    are their summaries. Then 2 runs are made unfinished (one folder's summary gone, one marked
    interrupted): a rerun makes those 2 only and leaves the others' files as they were."""
    out = tmp_path / "sweep"
    vary = ["--vary", "material.interface.tensile_strength=2e6,3e6", "--vary", "tools.top.speed=0.5,1.0"]
    assert main(["sweep", *SHORT, *vary, "--workers", "2", "--out", str(out)]) == 0
    folders = sorted(p.name for p in out.iterdir() if p.is_dir() and p.name != "plots")
    assert folders == ["000_tensile_strength=2e+06_speed=0.5", "001_tensile_strength=2e+06_speed=1",
                       "002_tensile_strength=3e+06_speed=0.5", "003_tensile_strength=3e+06_speed=1"]
    with open(out / "sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    parquet = pq.read_table(out / "sweep.parquet").to_pylist()
    assert list(rows[0])[:5] == ["material.interface.tensile_strength", "tools.top.speed", "run", "status", "message"]
    for folder, row, prow, (ft, speed) in zip(folders, rows, parquet, [(2e6, 0.5), (2e6, 1.0), (3e6, 0.5), (3e6, 1.0)]):
        alone = tmp_path / f"alone-{folder}"
        assert main(["run", *SHORT, "--set", f"material.interface.tensile_strength={ft:g}",
                     "--set", f"tools.top.speed={speed}", "--out", str(alone)]) == 0
        assert (out / folder / "history.csv").read_bytes() == (alone / "history.csv").read_bytes()
        summary = json.loads((out / folder / "summary.json").read_text())
        assert row["status"] == "completed" and float(row["tools.top.speed"]) == speed
        for key, value in summary_scalars(summary).items():
            if isinstance(value, float):
                assert float(row[key]) == value and prow[key] == value  # csv keeps repr's 17 digits
    for key in ("material.interface.tensile_strength", "tools.top.speed"):
        assert (out / "plots" / f"sweep_{key}.png").stat().st_size > 0

    kept = {f: (out / f / "history.csv").stat().st_mtime_ns for f in folders}
    (out / folders[1] / "summary.json").unlink()
    interrupted = json.loads((out / folders[2] / "summary.json").read_text())
    (out / folders[2] / "summary.json").write_text(json.dumps({**interrupted, "status": "interrupted"}))
    assert main(["sweep", *SHORT, *vary, "--workers", "2", "--out", str(out)]) == 0
    again = {f: (out / f / "history.csv").stat().st_mtime_ns for f in folders}
    assert [f for f in folders if again[f] != kept[f]] == [folders[1], folders[2]]
    assert (out / folders[1] / "history.csv").read_bytes() == (tmp_path / f"alone-{folders[1]}" / "history.csv").read_bytes()


def test_a_value_one_run_refuses_is_its_row_and_the_others_run(tmp_path, capsys):
    out = tmp_path / "sweep"
    code = main(["sweep", *SHORT, "--vary", "material.interface.tensile_strength=3e6,-1", "--workers", "1", "--out", str(out)])
    assert code == 1  # not every run completed
    with open(out / "sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["completed", "invalid"]
    assert "tensile_strength" in rows[1]["message"]
    assert "1 completed, 1 invalid" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["--vary", "material.interface.no_such_key=1,2"], "every run of the sweep is refused"),
        (["--vary", "run.end_time="], "at least one value"),
        (["--vary", "run.end_time=1e-5,2e-5", "--scheduler", "tcp://127.0.0.1:9"], "--scheduler tcp://127.0.0.1:9: cannot reach it"),
        (["--vary", "run.end_time=1e-5", "--workers", "0"], "--workers must be at least 1"),
    ],
)
def test_bad_sweep_input_exits_2_with_a_message(tmp_path, capsys, args, message):
    assert main(["sweep", "three-point-bending", "--quick", *args, "--out", str(tmp_path / "s")]) == 2
    assert message in capsys.readouterr().err


def test_a_folder_holding_another_sweep_is_refused(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "sweep.json").write_text(json.dumps({"scenario": "single-fracture"}))
    assert main(["sweep", *SHORT, "--vary", "material.interface.tensile_strength=3e6", "--out", str(out)]) == 2
    assert "holds another sweep" in capsys.readouterr().err

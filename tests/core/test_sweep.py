"""crackle sweep and calibrate: the plan (product, zip, values), runs on a local Dask cluster of 2
workers equal to the same runs made one by one, a killed sweep finished by a rerun, the curve distance
and a calibration that recovers its own curve's strength, and bad input."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from crackle.cli import main
from crackle.io import read_history_csv
from crackle.io.plots import tool_curves
from crackle.scenario import ScenarioError
from crackle.sweep import list_sweeps, make_plan
from crackle.sweep.calibrate import curve_distance, quadratic_minimum, read_target
from crackle.sweep.plan import parse_vary
from crackle.sweep.runner import check_runs, finished_summary, run_one
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
    """brazilian-angles (4 runs), walnut-layouts (6 zipped layouts), mesh-ladder (3 sizes),
    tube-shots (3 zipped notches), tension-size-effect (3 zipped sizes x 10 seeds), layered-longmaxi
    (7 angles), triaxial-envelope and dem-triaxial-envelope (4 confinements each): every run's scenario
    validates."""
    assert set(list_sweeps()) == {"brazilian-angles", "walnut-layouts", "mesh-ladder", "tube-shots",
                                  "tension-size-effect", "layered-longmaxi", "triaxial-envelope",
                                  "dem-triaxial-envelope"}
    sizes = {}
    for name in list_sweeps():
        plan = make_plan(name, [], [], False, False)
        assert check_runs(plan, plan.runs()) == {}
        sizes[name] = len(plan.runs())
    assert sizes == {"brazilian-angles": 4, "walnut-layouts": 6, "mesh-ladder": 3, "tube-shots": 3,
                     "tension-size-effect": 30, "layered-longmaxi": 7, "triaxial-envelope": 4,
                     "dem-triaxial-envelope": 4}


def test_seeds_repeat_every_run_with_each_seed():
    """--seeds N adds run.seed = 0 .. N-1: a product with the other keys, and with --zip every
    zipped position N times (the seed varying fastest); varying or setting run.seed as well is
    refused."""
    plan = make_plan("three-point-bending", ["a.x=1,2"], [], False, False, seeds=3)
    assert [r.varied for r in plan.runs()] == [{"a.x": x, "run.seed": s} for x in (1, 2) for s in range(3)]
    zipped = make_plan("three-point-bending", ["a.x=1,2", "b.y=3,4"], [], True, False, seeds=2)
    assert [tuple(r.varied.values()) for r in zipped.runs()] == [(1, 3, 0), (1, 3, 1), (2, 4, 0), (2, 4, 1)]
    assert len(make_plan("three-point-bending", [], [], False, False, seeds=4).runs()) == 4
    for vary, fixed in ((["run.seed=1,2"], []), ([], ["run.seed=3"])):
        with pytest.raises(ScenarioError, match="run.seed"):
            make_plan("three-point-bending", vary, fixed, False, False, seeds=2)


def test_seed_statistics_are_the_mean_and_deviation_over_seeds(tmp_path):
    """sweep_seeds.csv: per value of the other keys, a scalar's mean and sample standard
    deviation (n - 1) over the finished seeds; a failed run is left out."""
    from crackle.sweep.table import write_seed_statistics

    peaks = {1: [10.0, 12.0, 14.0], 2: [20.0, 20.0, 26.0]}
    rows = [{"a.x": x, "run.seed": s, "run": f"{x}-{s}", "status": "completed", "message": "",
             "summary": {"peak_force": peak}} for x, values in peaks.items() for s, peak in enumerate(values)]
    rows.append({"a.x": 1, "run.seed": 3, "run": "1-3", "status": "unstable", "message": "", "summary": {"peak_force": 1e9}})
    lines = write_seed_statistics(tmp_path, ["a.x", "run.seed"], rows)
    with open(tmp_path / "sweep_seeds.csv", newline="") as fh:
        table = {(r["a.x"], r["quantity"]): r for r in csv.DictReader(fh)}
    assert float(table["1", "peak_force"]["mean"]) == 12.0 and float(table["1", "peak_force"]["sd"]) == 2.0
    assert float(table["2", "peak_force"]["mean"]) == 22.0 and float(table["2", "peak_force"]["sd"]) == pytest.approx(12.0**0.5)
    assert table["1", "peak_force"]["runs"] == "3"
    assert len(lines) == 2 and "over 3 seeds at x=1: peak_force 12 +- 2" in lines[0]


@pytest.mark.slow
def test_sweep_on_two_workers_equals_the_runs_one_by_one(tmp_path):
    """A 2 x 2 sweep on a local cluster of 2 workers: 4 run folders whose histories are
    byte-identical to the same runs made one by one with `crackle run`, and a table whose rows
    are their summaries."""
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


@pytest.mark.slow
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
    if "--scheduler" not in args:
        assert not (tmp_path / "s").exists()  # nothing written


def test_a_folder_holding_another_sweep_is_refused(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "sweep.json").write_text(json.dumps({"scenario": "single-fracture"}))
    assert main(["sweep", *SHORT, "--vary", "material.interface.tensile_strength=3e6", "--out", str(out)]) == 2
    assert "holds another sweep" in capsys.readouterr().err


# The bonded-particle Brazilian disc, coarse and fast (574 particles, ~1.5 s a run): its peak
# force grows with the bonds' tensile strength t (2.76 / 3.56 / 4.02 kN at t = 3 / 4 / 4.5 MPa).
DEM_DISC = ["--quick", "--set", "packing.mean_radius=1.6e-3", "--set", "run.end_time=4e-4", "--set", "run.field_frames=0"] + [
    f"--set=tools.{tool}.{key}={value}" for tool in ("top", "bottom") for key, value in (("speed", 0.2), ("ramp_time", 5e-5))
]


def test_curve_distance_of_a_scaled_and_a_shifted_curve():
    """F_run = 1.1 F: distance = 0.1 x rms(F) / max(F) (closed form, 1e-12); the run's curve read
    between its points linearly and past its end at its last force."""
    u = np.linspace(0.0, 1e-3, 11)
    f = 1e3 * np.sin(np.pi * u / 1e-3) + 10.0
    assert curve_distance(u, f, u, 1.1 * f) == pytest.approx(0.1 * np.sqrt(np.mean(f**2)) / f.max(), rel=1e-12)
    assert curve_distance(u, f, u, f) == 0.0
    short = u <= 5e-4  # the run stops half-way at its peak force f(5e-4)
    expected = np.where(short, 0.0, f[5] - f)
    assert curve_distance(u, f, u[short], f[short]) == pytest.approx(np.sqrt(np.mean(expected**2)) / f.max(), rel=1e-12)


def test_quadratic_minimum_of_noisy_squared_distances():
    """Distances |x - 3| / 4 (x in MPa) with +-10 % noise at 40 points in [1, 6]: the fitted
    quadratic's minimum within 2 % of 3; a linear trend (no minimum) gives None."""
    rng = np.random.default_rng(1)
    x = rng.uniform(1e6, 6e6, 40)
    d = np.abs(x - 3e6) / 4e6 * (1.0 + 0.1 * rng.uniform(-1.0, 1.0, 40))
    best = quadratic_minimum(x[:, None], d, np.array([[1e6, 6e6]]))
    assert best[0] == pytest.approx(3e6, rel=0.02)
    assert quadratic_minimum(x[:, None], x / 6e6, np.array([[1e6, 6e6]])) is None


@pytest.mark.slow
def test_calibration_recovers_the_tensile_strength_of_its_own_curve(tmp_path):
    """The disc's top-platen curve made with t = 3 MPa is the target; from t = 2 MPa within
    [1, 6] MPa, 5 candidates a generation for 4 generations on 2 workers (26 runs with the
    quadratic fit's): t within 2 % of 3 MPa (measured 2.987 MPa)."""
    made = tmp_path / "made"
    assert main(["run", "dem-brazilian", *DEM_DISC, "--set", "material.tensile_strength=3e6", "--out", str(made)]) == 0
    u, f, _ = tool_curves(read_history_csv(made / "history.csv"))["top"]
    target = tmp_path / "measured.csv"
    target.write_text("displacement,force\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(u.tolist(), f.tolist())))
    out = tmp_path / "cal"
    assert main(["calibrate", "dem-brazilian", *DEM_DISC, "--target", str(target), "--tool", "top",
                 "--fit", "material.tensile_strength=1e6:6e6", "--start", "material.tensile_strength=2e6",
                 "--population", "5", "--generations", "4", "--workers", "2", "--out", str(out)]) == 0
    record = json.loads((out / "calibration.json").read_text())
    assert record["fitted"]["material.tensile_strength"] == pytest.approx(3e6, rel=0.02)
    assert record["start"] == {"material.tensile_strength": 2e6}
    with open(out / "calibration.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[0]["material.tensile_strength"]) == 2e6 and len(rows) == record["runs"]
    assert record["distance"] < float(rows[0]["distance"])  # closer than the start
    assert (out / "calibration.png").stat().st_size > 0


@pytest.mark.parametrize(
    "args, message",
    [
        (["--fit", "material.tensile_strength=6e6:1e6"], "lo < hi"),
        (["--fit", "material.tensile_strength=1e6:6e6", "--start", "material.tensile_strength=9e6"], "within its --fit range"),
        (["--fit", "material.tensile_strength=1e6:6e6", "--start", "material.cohesion=9e6"], "not a fitted key"),
        (["--fit", "material.tensile_strength=-1:6e6"], "tensile_strength"),  # a bound the scenario refuses
    ],
)
def test_bad_calibration_input_exits_2(tmp_path, capsys, args, message):
    target = tmp_path / "t.csv"
    target.write_text("displacement,force\n0,0\n1e-4,100\n2e-4,150\n")
    assert main(["calibrate", "dem-brazilian", "--quick", "--target", str(target), *args, "--out", str(tmp_path / "c")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize(
    "text, message",
    [("", "empty"), ("a,b,c\n1,2,3\n", "name the columns"), ("displacement,force\n0,0\n1,x\n2,3\n", "a number"),
     ("displacement,force\n0,0\n2,1\n1,3\n", "must not decrease"), ("displacement,force\n0,0\n1,1\n", "at least 3")],
)
def test_a_bad_target_curve_is_refused(tmp_path, text, message):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=message):
        read_target(path)


def test_a_run_is_finished_when_its_summary_says_completed_stopped_or_unstable(tmp_path):
    for status, finished in (("completed", True), ("stopped", True), ("unstable", True), ("interrupted", False)):
        (tmp_path / "summary.json").write_text(json.dumps({"status": status}))
        assert (finished_summary(tmp_path) is not None) == finished
    (tmp_path / "summary.json").write_text("{\"status\": ")  # cut short by a kill
    assert finished_summary(tmp_path) is None


def test_an_interrupted_run_of_a_sweep_continues_from_its_checkpoint(tmp_path):
    """A sweep's run that was interrupted with a checkpoint (here: one left at 10 us, its summary
    not finished) continues from it when the sweep runs it again: its history is the one an
    uninterrupted run writes, byte for byte, and the steps before the checkpoint are not run
    again (summary.json: resumed_from the checkpoint's time)."""
    folder = tmp_path / "run"
    overrides = {"run.end_time": 2e-5}
    assert run_one("three-point-bending", str(folder), {"run.end_time": 1e-5}, True, 1)["status"] == "completed"
    (folder / "summary.json").write_text(json.dumps({"status": "interrupted"}))
    before = (folder / "history.csv").read_text()
    assert run_one("three-point-bending", str(folder), overrides, True, 1)["status"] == "completed"
    straight = tmp_path / "straight"
    assert run_one("three-point-bending", str(straight), overrides, True, 1)["status"] == "completed"
    resumed = (folder / "history.csv").read_text()
    assert resumed.startswith(before) and len(resumed) > len(before)
    assert json.loads((folder / "summary.json").read_text())["resumed_from"] == pytest.approx(1e-5, rel=0.01)
    assert resumed == (straight / "history.csv").read_text()


@pytest.mark.slow
def test_a_killed_sweep_finishes_only_its_missing_runs(tmp_path, capsys):
    """`crackle sweep` killed (SIGKILL to its process group: client, scheduler and workers) once
    its first run has finished; the same command again runs exactly the runs without a finished
    summary and leaves the finished ones' files as they were."""
    out = tmp_path / "sweep"
    args = ["sweep", *SHORT, "--vary", "tools.top.speed=0.5,0.6,0.7,0.8,0.9,1.0", "--workers", "1", "--out", str(out)]
    process = subprocess.Popen([sys.executable, "-m", "crackle.cli", *args], start_new_session=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300

    def finished():
        return sorted(p.parent.name for p in out.glob("*/summary.json") if finished_summary(p.parent))

    while not finished() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    done = finished()
    assert 1 <= len(done) < 6
    kept = {f: (out / f / "history.csv").stat().st_mtime_ns for f in done}
    assert main(args) == 0
    assert f"; {6 - len(done)} run now" in capsys.readouterr().out
    assert sorted(finished()) == sorted(p.name for p in out.iterdir() if p.is_dir() and p.name != "plots")
    assert len(finished()) == 6
    assert {f: (out / f / "history.csv").stat().st_mtime_ns for f in done} == kept
    with open(out / "sweep.csv", newline="") as fh:
        assert [r["status"] for r in csv.DictReader(fh)] == ["completed"] * 6


LATTICE = Path(__file__).parents[1] / "data" / "lattice-platen.toml"


def _lattice_elastic(tmp_path) -> Path:
    """The lattice platen test stopped before any spring breaks: its force follows E alone."""
    path = tmp_path / "lattice-elastic.toml"
    path.write_text(LATTICE.read_text().replace("end_time = 4e-5", "end_time = 1e-5"))
    return path


@pytest.mark.slow
def test_two_value_targets_of_two_scenarios(tmp_path):
    """A candidate's distance over two value targets, each of another scenario's run: the crushed
    lattice's peak_force and the same lattice's elastic force (a second scenario file), both made
    with E = 26 GPa. A candidate with those values is at distance 0 exactly (the runs are
    deterministic); one with E = 30 GPa at sqrt(mean d^2) of its two runs' relative misfits."""
    from crackle.sweep.calibrate import evaluate, parse_target, target_folder

    elastic = _lattice_elastic(tmp_path)
    made = {}
    for source in (LATTICE, elastic):
        out = tmp_path / f"made-{source.stem}"
        assert main(["run", str(source), "--set", "run.field_frames=0", "--out", str(out)]) == 0
        made[source] = json.loads((out / "summary.json").read_text())["peak_force"]
    targets = [parse_target(f"peak_force={made[LATTICE]!r}"), parse_target(f"{elastic}:peak_force={made[elastic]!r}")]
    assert targets[0].scenario is None and targets[1].scenario == str(elastic.resolve())
    at = evaluate(str(LATTICE), str(tmp_path / "c0"), {}, False, 1, None, targets)
    assert at["status"] == "completed" and at["distance"] == 0.0
    off = evaluate(str(LATTICE), str(tmp_path / "c1"), {"material.youngs_modulus": 30e9}, False, 1, None, targets)
    runs = [json.loads((Path(target_folder(str(tmp_path / "c1"), s, str(LATTICE))) / "summary.json").read_text())
            for s in (str(LATTICE), str(elastic.resolve()))]
    misfits = [(r["peak_force"] - made[s]) / made[s] for r, s in zip(runs, (LATTICE, elastic))]
    print(f"relative misfits at E = 30 GPa: {misfits}")
    assert off["distance"] == pytest.approx(np.sqrt(np.mean(np.square(misfits))), rel=1e-12)
    assert off["distance"] > 0.02
    assert off["values"] == {targets[0].text: runs[0]["peak_force"], targets[1].text: runs[1]["peak_force"]}


@pytest.mark.slow
def test_calibration_to_two_values_recovers_the_modulus(tmp_path):
    """`crackle calibrate` to two value targets of two scenarios (the lattice's crushing peak and
    its elastic force, made with E = 26 GPa) from E = 20 GPa within [18, 34] GPa: E within 3 % of
    26 GPa; calibration.json names the targets and the fitted run's values, calibration.csv has a
    column per value target."""
    elastic = _lattice_elastic(tmp_path)
    made = []
    for source in (LATTICE, elastic):
        out = tmp_path / f"made-{source.stem}"
        assert main(["run", str(source), "--set", "run.field_frames=0", "--out", str(out)]) == 0
        made.append(json.loads((out / "summary.json").read_text())["peak_force"])
    out = tmp_path / "cal"
    targets = [f"peak_force={made[0]!r}", f"{elastic}:peak_force={made[1]!r}"]
    assert main(["calibrate", str(LATTICE), "--target", targets[0], "--target", targets[1],
                 "--fit", "material.youngs_modulus=18e9:34e9", "--start", "material.youngs_modulus=20e9",
                 "--population", "4", "--generations", "3", "--workers", "2", "--set", "run.field_frames=0",
                 "--out", str(out)]) == 0
    record = json.loads((out / "calibration.json").read_text())
    print(record["fitted"], record["distance"], record["runs"])
    assert record["targets"] == targets
    assert record["fitted"]["material.youngs_modulus"] == pytest.approx(26e9, rel=0.03)
    assert set(record["fitted_values"]) == set(targets)
    with open(out / "calibration.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(float(rows[-1][t]) > 0 for t in targets) and len(rows) == record["runs"]


@pytest.mark.parametrize("target", ["peak_stress", "peak_stress=high", "peak_stress=0"])
def test_bad_value_target_exits_2(tmp_path, capsys, target):
    """A target that is neither a CSV nor KEY=VALUE with a non-zero number: exit 2, saying what to give."""
    assert main(["calibrate", "dem-brazilian", "--quick", "--target", target, "--fit",
                 "material.tensile_strength=1e6:6e6", "--out", str(tmp_path / "c")]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err


def test_a_calibration_to_a_missing_tool_exits_2_before_any_run(tmp_path, capsys):
    target = tmp_path / "t.csv"
    target.write_text("displacement,force\n0,0\n1e-4,100\n2e-4,150\n")
    out = tmp_path / "c"
    assert main(["calibrate", str(LATTICE), "--target", str(target), "--tool", "plattern",
                 "--fit", "material.youngs_modulus=18e9:34e9", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--tool plattern: no such tool" in err and "Traceback" not in err
    assert not (out / "candidates").exists()


@pytest.mark.parametrize("target, message", [
    ("peak_force=KN", "misses the targets by"),  # the lattice's peak force given in kN
    ("no_such_value=1.0", "every one of the"),  # no run can give it: every candidate invalid
])
@pytest.mark.slow
def test_a_calibration_that_failed_exits_1_and_says_why(tmp_path, capsys, target, message):
    """A target in kN where the run gives N (misfit ~1000, read as FAILED_DISTANCE = 10; beyond
    USEFUL_MISFIT = 0.5), or one no
    run can meet: exit 1 with the reason; calibration.json is written and says `usable`: false with
    the relative misfit."""
    made = tmp_path / "made"
    assert main(["run", str(LATTICE), "--set", "run.field_frames=0", "--out", str(made)]) == 0
    peak = json.loads((made / "summary.json").read_text())["peak_force"]
    target = target.replace("KN", repr(peak / 1000.0))
    out = tmp_path / "c"
    assert main(["calibrate", str(LATTICE), "--target", target, "--fit", "material.youngs_modulus=18e9:34e9",
                 "--population", "2", "--generations", "1", "--workers", "1", "--set", "run.field_frames=0",
                 "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    record = json.loads((out / "calibration.json").read_text())
    assert record["usable"] is False and record["converged"] in (True, False)
    if message.startswith("misses"):
        assert record["relative_misfit"] >= 10.0  # 999, capped at FAILED_DISTANCE


@pytest.mark.slow
def test_a_misspelt_plot_scalar_exits_2_after_the_table_is_written(tmp_path, capsys):
    """--plot peak_forse: the runs and the table are kept, the exit is 2 naming the name and the
    nearest scalar; the same command with the right name plots it without running again."""
    out = tmp_path / "sweep"
    args = ["sweep", *SHORT, "--vary", "tools.top.speed=0.5", "--workers", "1", "--out", str(out)]
    assert main([*args, "--plot", "peak_forse"]) == 2
    err = capsys.readouterr().err
    assert "--plot peak_forse (did you mean peak_force?)" in err and "Traceback" not in err
    assert (out / "sweep.csv").is_file()
    assert main([*args, "--plot", "stable_dt"]) == 0
    assert "0 to run" in capsys.readouterr().out


@pytest.mark.slow
def test_ctrl_c_during_a_sweep_stops_it_in_one_line(tmp_path):
    """SIGINT to the sweep's process group (as a terminal's Ctrl-C) while its runs go on: exit
    130, one line of ours saying what is kept and how to finish, no KeyboardInterrupt tracebacks
    (the workers ignore SIGINT; the sweep's process stops them); a traceback Dask's comms log as
    the cluster closes (seen once in five CI runs) is Dask's, inside distributed."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "sweep"
    proc = subprocess.Popen(
        [sys.executable, "-m", "crackle.cli", "sweep", "three-point-bending", "--quick", "--vary",
         "tools.top.speed=0.5,0.6,0.7,0.8", "--workers", "2", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    deadline = time.time() + 120
    while time.time() < deadline and not list(out.glob("*/history.csv")):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    # No interrupt traceback from any process; Dask's own comms may still log a closed connection
    # while the cluster shuts down (a traceback inside distributed, timing-dependent).
    assert "KeyboardInterrupt" not in err
    assert all("site-packages/distributed" in tb for tb in err.split("Traceback")[1:]), err
    assert f"sweep interrupted: the finished runs are kept in {out}" in err
    # The runs in progress stopped as Ctrl-C stops a run: summary, plots, checkpoint, lock released,
    # status.json final; the runs not started have no folder.
    members = [folder for folder in out.iterdir() if folder.is_dir()]
    assert 1 <= len(members) < 4, members
    for folder in members:
        assert json.loads((folder / "summary.json").read_text())["status"] in ("interrupted", "completed", "stopped")
        assert json.loads((folder / "status.json").read_text())["state"] != "running"
        assert (folder / "checkpoint.pkl").is_file() and not (folder / ".crackle.lock").exists()
        assert all((folder / "plots" / f"{name}.png").is_file() for name in ("load_displacement", "energies", "crack_pattern"))


def test_a_run_on_the_callers_thread_gives_its_thread_count_back(tmp_path):
    """run_one sets numba's thread count for its run; afterwards the caller has its own count
    again, whether the run finished or was refused (here: an unknown scenario, status
    "invalid"), so a sweep run on the caller's thread leaves the caller's later work as it was."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        row = run_one("no-such-scenario", str(tmp_path / "run"), {}, quick=True, threads=2)
        assert row["status"] == "invalid"
        assert numba.get_num_threads() == 1
    finally:
        numba.set_num_threads(before)

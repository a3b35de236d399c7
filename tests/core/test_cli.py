"""Command line and scenario validation: bad input ends before any work with exit code 2 and one
message naming the field or file and the fix (no traceback)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from crackle.cli import main
from crackle.scenario import examples_dir

BASE = (examples_dir() / "three-point-bending.toml").read_text()


def _as_mesh_file(text, name):
    """The scenario with its [specimen] a mesh file (the beam's keys, which a mesh does not read, left out)."""
    start, end = text.index("[specimen]"), text.index("[material]")
    return text[:start] + f'[specimen]\nshape = "mesh"\nfile = "{name}"\n\n' + text[end:]


def _write(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _run(capsys, *argv):
    code = main(["run", *argv])
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize(
    "edit, expected",
    [
        # unknown key
        (lambda t: t.replace('name = "top"', 'name = "top"\ncolour = "red"', 1), "tools.0.colour"),
        # missing key
        (lambda t: t.replace("density = 2340.0", ""), "material.density"),
        # non-physical values
        (lambda t: t.replace("youngs_modulus = 26e9", "youngs_modulus = -1.0"), "material.youngs_modulus"),
        (lambda t: t.replace("poissons_ratio = 0.2", "poissons_ratio = 0.5"), "material.poissons_ratio"),
        (lambda t: t.replace("density = 2340.0", "density = 0.0"), "material.density"),
        (lambda t: t.replace("tensile_strength = 3e6", "tensile_strength = -3e6"), "material.interface.tensile_strength"),
        (lambda t: t.replace("fracture_energy = 10.0", "fracture_energy = -1.0"), "material.interface.fracture_energy"),
        # broken TOML
        (lambda t: t.replace("[run]", "[run"), "broken TOML"),
        # a stop condition naming a tool that does not exist
        (lambda t: t.replace("force_drop = 0.1", 'force_drop = 0.1\ntool = "middle"'), "run.stop.tool"),
        # wrong type
        (lambda t: t.replace('shape = "beam"', 'shape = "banana"'), "specimen.shape"),
    ],
)
def test_malformed_scenario_exits_2_naming_the_field(tmp_path, capsys, edit, expected):
    """Each malformed scenario: exit code 2, one line naming the field (`expected`), no traceback."""
    code, err = _run(capsys, _write(tmp_path, edit(BASE)), "--out", str(tmp_path / "out"))
    assert code == 2
    assert expected in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists(), "nothing may be written before validation passes"


def test_missing_mesh_file(tmp_path, capsys):
    text = _as_mesh_file(BASE, "nowhere.msh")
    code, err = _run(capsys, _write(tmp_path, text), "--out", str(tmp_path / "out"))
    assert code == 2 and "nowhere.msh" in err and "does not exist" in err


def test_inverted_tets_in_mesh_file(tmp_path, capsys):
    import meshio

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) * 0.01
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(points, [("tetra", np.array([[0, 2, 1, 3]]))]))
    text = _as_mesh_file(BASE, "bad.vtu")
    code, err = _run(capsys, _write(tmp_path, text), "--out", str(tmp_path / "out"))
    assert code == 2 and "bad.vtu" in err and "inverted" in err
    assert "first is tet 1 (counting the file's tetrahedra from 1), centroid (0.0025, 0.0025, 0.0025) m" in err


def test_bad_element_named_by_its_abaqus_label(tmp_path, capsys):
    """An Abaqus file's inverted element is named by the file's own label (here 1002, the second
    tet of a block whose labels start at 1001)."""
    inp = tmp_path / "bad.inp"
    inp.write_text(
        "*NODE\n1, 0, 0, 0\n2, 0.01, 0, 0\n3, 0, 0.01, 0\n4, 0, 0, 0.01\n5, 0.01, 0.01, 0.01\n"
        "*ELEMENT, TYPE=C3D4, ELSET=rock\n1001, 1, 2, 3, 4\n1002, 2, 3, 5, 4\n"
    )
    text = _as_mesh_file(BASE, "bad.inp")
    code, err = _run(capsys, _write(tmp_path, text), "--out", str(tmp_path / "out"))
    assert code == 2 and "1 inverted (negative-volume) tets, first is element 1002" in err, err


def test_unknown_example_and_bad_override(tmp_path, capsys):
    code, err = _run(capsys, "no-such-example")
    assert code == 2 and "no-such-example" in err and "three-point-bending" in err
    code, err = _run(capsys, "three-point-bending", "--set", "run.end_time", "--out", str(tmp_path / "o"))
    assert code == 2 and "key=value" in err
    code, err = _run(capsys, "three-point-bending", "--set", "run.end_time=-1", "--out", str(tmp_path / "o"))
    assert code == 2 and "run.end_time" in err


def test_time_step_larger_than_stable_is_refused(tmp_path, capsys):
    """A user dt above safety x stable step is refused before the run, naming run.dt."""
    code, err = _run(capsys, "three-point-bending", "--quick", "--set", "run.dt=1e-5", "--out", str(tmp_path / "o"))
    assert code == 2 and "run.dt" in err and "stable" in err


def test_real_process_exit_code(tmp_path):
    """The installed entry point returns exit code 2 for a broken file, with no traceback."""
    path = _write(tmp_path, "this is [not toml")
    proc = subprocess.run([sys.executable, "-m", "crackle.cli", "run", path], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "broken TOML" in proc.stderr and "Traceback" not in proc.stderr


def test_examples_listed_and_valid(capsys):
    """Every shipped example validates, with and without its quick form."""
    from crackle.scenario import list_examples, load_scenario

    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    names = list_examples()
    assert "three-point-bending" in names and "three-point-bending" in out
    for name in names:
        load_scenario(name)
        load_scenario(name, quick=True)
    # Each description's whole first sentence on its line (five were cut mid-sentence at the TOML's
    # line break, issue 71 item 10), not cut at an abbreviation ("Fig. 1a").
    for name, text in names.items():
        assert text.endswith(".") and f"{name:24s} {text}\n" in out, (name, text)
    assert "(paper 001, Fig. 1b): it should break into many fragments" in names["sphere-impact-fast"]


def test_fpz_json_matches_paper_001():
    """Paper 001 eqs 13-14 for Table 1 (E 26 GPa, Gf 10 J/m2, ft 3 MPa): 8.5 mm and 21.7 mm."""
    proc = subprocess.run(
        [sys.executable, "-m", "crackle.cli", "fpz", "--E", "26e9", "--Gf", "10", "--ft", "3e6", "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    data = json.loads(proc.stdout)
    assert data["plastic_zone_long"] == pytest.approx(8.5e-3, rel=0.01)
    assert data["plastic_zone_short"] == pytest.approx(21.7e-3, rel=0.01)
    assert data["advised_element_size"] == pytest.approx(data["plastic_zone_long"] / 3, rel=1e-12)


def _mistakes(tmp_path):
    """(argv, text the one-line message must hold) for the mistakes a new user makes."""
    scenario = _write(tmp_path, BASE)
    a_file = tmp_path / "a-file.txt"
    a_file.write_text("x")
    no_quick = _write(tmp_path, BASE[: BASE.index("[quick]")], "no-quick.toml")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + BASE.replace("[material]", "[materail]", 1).encode())
    return [
        ([str(tmp_path)], "is a folder"),
        ([scenario, "--set", "specimen.element_size.x.y=1"], "'specimen.element_size' is a value"),
        ([scenario, "--set", "run.end_time=inf"], "run.end_time"),
        ([scenario, "--set", "run.end_time=nan"], "run.end_time: nan"),
        ([scenario, "--set", "tools.0.center=[nan, 0.0, 0.0]"], "tools.0.center.0: nan"),
        ([scenario, "--out", str(a_file)], "is a file"),
        ([scenario, "--out", str(a_file / "run1")], "lies under"),
        ([scenario, "--out", "/sys/crackle-out"], "cannot write"),
        ([str(bom)], "unknown section materail; did you mean material?"),
        ([scenario, "--set", "tools.middle.speed=1.0"], "0 (top), 1 (left), 2 (right)"),
        ([no_quick, "--quick"], "no [quick] section"),
        # unit slips: mm for m, GPa for Pa, g/cm^3 for kg/m^3
        ([scenario, "--set", "specimen.element_size=10"], "larger than the specimen"),
        ([scenario, "--set", "specimen.element_size=1e-9"], "below 1e-5 of the specimen"),
        ([scenario, "--set", "material.youngs_modulus=26"], "if that is GPa, write 26e9"),
        ([scenario, "--set", "material.density=2.34"], "2.34 g/cm^3 is 2340 kg/m^3"),
        ([scenario, "--set", "run.load_cell_window=1.0"], "more than the 4096 the load cell holds"),
    ]


def test_mistakes_exit_2_with_one_message(tmp_path, capsys):
    """Each mistake: exit code 2, one line that names what is wrong, no traceback, nothing
    written (the output folder is tmp_path/out unless the case names its own)."""
    for argv, expected in _mistakes(tmp_path):
        if "--out" not in argv:
            argv = argv + ["--out", str(tmp_path / "out")]
        code, err = _run(capsys, *argv)
        assert code == 2, (argv, err)
        assert expected in err, (argv, err)
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "out").exists()


def test_tools_set_by_name():
    """--set tools.NAME.key is the same as tools.NUMBER.key."""
    from crackle.scenario import load_scenario

    by_name, _ = load_scenario("three-point-bending", ["tools.left.friction=0.25"])
    by_number, _ = load_scenario("three-point-bending", ["tools.1.friction=0.25"])
    assert by_name.tools[1].friction == 0.25 and by_name == by_number


def test_rerun_clears_only_crackles_outputs(tmp_path):
    """A rerun into a folder that holds an earlier run leaves none of its frames (fewer frames
    the second time) nor a figure another method drew there (a DEM run's stress-strain curve
    beside an FDEM run's figures), and keeps files of the user's, in plots/ too."""
    from crackle.io import read_pvd

    out = tmp_path / "out"
    args = ["run", "single-fracture", "--quick", "--out", str(out)]
    assert main(args + ["--set", "run.field_frames=6"]) == 0
    first = len(list((out / "fields").glob("*.vtu")))
    (out / "notes.txt").write_text("mine")
    (out / "plots" / "stress_strain.png").write_bytes(b"a DEM run's figure")
    (out / "plots" / "my_figure.png").write_bytes(b"mine")
    assert main(args + ["--set", "run.field_frames=2", "--set", "run.history_samples=20"]) == 0
    frames = sorted((out / "fields").glob("*.vtu"))
    assert len(frames) < first and frames == sorted(path for _, path in read_pvd(out / "fields.pvd"))
    assert (out / "notes.txt").read_text() == "mine" and (out / "plots" / "my_figure.png").read_bytes() == b"mine"
    assert not (out / "plots" / "stress_strain.png").exists()


def test_a_folder_with_a_users_own_history_is_not_overwritten(tmp_path, capsys):
    """Issue 71 item 10: --out pointed at a folder holding a history.csv, or a plots/*.png, that no
    crackle run wrote (a lab's own test record and figure): exit 2 naming the file, which is left
    as it was; a folder of an earlier crackle run (status.json beside its files) is rerun into as
    before."""
    out = tmp_path / "lab"
    out.mkdir()
    (out / "history.csv").write_text("t_s,force_kN\n0,0\n")
    args = ["run", "single-fracture", "--quick", "--set", "run.end_time=2e-6", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "it holds history.csv that no crackle run wrote" in err and "choose another --out" in err
    assert (out / "history.csv").read_text() == "t_s,force_kN\n0,0\n"
    (out / "history.csv").unlink()
    # A figure of the user's own under a name a run draws (it was overwritten, exit 0).
    (out / "plots").mkdir()
    (out / "plots" / "load_displacement.png").write_bytes(b"their figure")
    assert main(args) == 2
    assert "it holds plots/load_displacement.png that no crackle run wrote" in capsys.readouterr().err
    assert (out / "plots" / "load_displacement.png").read_bytes() == b"their figure"
    (out / "plots" / "load_displacement.png").unlink()
    assert main(args) == 0 and main(args) == 0  # the second into the first's folder


def test_ctrl_c_stops_consistently_with_exit_130(tmp_path):
    """SIGINT during a run: exit 130, status "interrupted", and summary, history and events end
    at the same state (one event row per failure counted in the summary)."""
    import signal
    import time

    from crackle.io import read_events_csv, read_history_csv

    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "crackle.cli", "run", "sphere-impact-fast", "--quick", "--out", str(out),
         "--set", "run.field_frames=0", "--set", "run.history_samples=2000"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    deadline = time.time() + 120
    while time.time() < deadline and not ((out / "history.csv").exists() and len((out / "history.csv").read_text().splitlines()) > 40):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted"
    assert len(read_events_csv(out / "events.csv")["id"]) == s["broken"]
    h = read_history_csv(out / "history.csv")
    assert h["time"][-1] == s["end_time"] and h["broken"][-1] == s["broken"]


def test_setup_lines_and_coarse_mesh_advice_before_the_run(tmp_path, capsys):
    """Before the first step: one line with the size and the steps, then the coarse-mesh advice
    (paper-001 rock at 17.9 mm against the advised 2.84 mm); the advice is left out when the loads
    cannot reach the strength (ft = 10 GPa: the platen's 0.1 m/s over 40 us squeezed into one
    element gives at most E u / h = 5.8 MPa)."""
    args = ["run", "three-point-bending", "--quick", "--set", "run.end_time=4e-5", "--set", "run.field_frames=0"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("three-point-bending: 960 tets, 1,672 interfaces; 619 steps of")
    assert lines[1].startswith("  warning: element size 17.9 mm is coarser than the advised 2.84 mm")
    assert lines[2].startswith("three-point-bending: completed")
    strong = ["--set", "material.interface.tensile_strength=1e10", "--set", "material.interface.cohesion=5e10"]
    assert main(args + strong + ["--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "warning" not in out
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["warnings"] == []


def test_threads_sleep_unless_the_user_chose():
    """import crackle sets OMP_WAIT_POLICY=PASSIVE (benchmarks/shared_machine.py: no 3x slowdown
    beside a busy process), but never over the user's OMP_WAIT_POLICY or GOMP_SPINCOUNT."""
    import os

    code = "import os, crackle; print(os.environ.get('OMP_WAIT_POLICY'))"
    clean = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    for extra, expected in (({}, "PASSIVE"), ({"OMP_WAIT_POLICY": "ACTIVE"}, "ACTIVE"), ({"GOMP_SPINCOUNT": "1000"}, "None")):
        out = subprocess.run([sys.executable, "-c", code], env={**clean, **extra}, capture_output=True, text=True, check=True)
        assert out.stdout.strip() == expected, extra


def test_gmsh_clamped_size_is_said():
    """A disc (40 x 15 mm) asked at 30 mm is meshed by gmsh at ~6.6 mm mean edge: the set-up says
    so (the mean edge is within 0.95-1.25 of a size gmsh honours: 4 mm gives no such warning)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    def warnings_for(size):
        scenario, base = load_scenario("brazilian-disc", [f"specimen.element_size={size}", "run.end_time=1e-6"])
        return build_simulation(scenario, base)[0].warnings

    clamped = warnings_for(0.03)
    assert clamped and "gmsh meshed it at 6.6" in clamped[0] and "element_size <= 6.6 mm" in clamped[0]
    assert not any("gmsh meshed" in w for w in warnings_for(0.004))


def test_key_reference_is_current_and_complete():
    """docs/keys.md is `crackle keys` (regenerate it with `crackle keys > docs/keys.md`), and every
    key of every schema has its unit or meaning, those of tables by name ([materials.NAME] and
    its zones) included."""
    from pathlib import Path

    from crackle.keys import reference_document

    text = reference_document()
    assert (Path(__file__).parents[2] / "docs" / "keys.md").read_text() == text
    rows = [line for line in text.splitlines() if line.startswith("| `")]
    assert len(rows) > 100
    undocumented = [row.split("|")[1] for row in rows if not row.rstrip(" |").split("|")[-1].strip()]
    assert not undocumented, undocumented
    assert "| `run.end_time` | number | required | > 0 | s, simulated time |" in text
    assert "| `materials.NAME.zones[].min_diameter` | number |" in text


def test_ctrl_c_during_set_up_exits_130_without_a_traceback(capsys, monkeypatch):
    """Ctrl-C while the scenario is read or meshed (before the driver's own handler is in place):
    exit 130 and one line, as an interrupted run."""
    import crackle.api

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(crackle.api, "run_scenario", interrupted)
    code, err = _run(capsys, "three-point-bending", "--quick")
    assert code == 130 and err.strip() == "crackle: interrupted during set-up, before the first step: no results written"

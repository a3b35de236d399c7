import json
import math
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from crackle.io import (
    EventWriter,
    FieldWriter,
    HistoryWriter,
    Progress,
    plot_crack_pattern,
    plot_energies,
    plot_load_displacement,
    read_events_csv,
    read_history_csv,
    read_pvd,
    write_standard_plots,
    write_summary,
)

ENERGIES = ["kinetic", "elastic", "cohesive", "contact", "damage",
            "friction", "damping", "external"]


def bits(a):
    return np.asarray(a, dtype=np.float64).view(np.uint64)


# --- history.csv -----------------------------------------------------------

def test_history_round_trip_is_bit_exact(tmp_path):
    path = tmp_path / "history.csv"
    tricky = [0.1 + 0.2, 1e-300, -0.0, 5e-324, 1.7976931348623157e308,
              np.float32(0.1), np.pi, -1 / 3]
    columns = ["time", "tool.punch.fx", "broken"]
    with HistoryWriter(path, columns) as writer:
        for i, v in enumerate(tricky):
            writer.append({"time": i * 1e-7 + 1e-9, "tool.punch.fx": v, "broken": i})
        writer.append([1.0, math.inf, np.int64(7)])
        writer.append({"time": 2.0})  # missing columns -> nan

    with open(path) as f:
        assert f.readline() == "time,tool.punch.fx,broken\n"

    h = read_history_csv(path)
    assert list(h) == columns
    expected = [float(v) for v in tricky] + [math.inf, math.nan]
    np.testing.assert_array_equal(bits(h["tool.punch.fx"][:-1]), bits(expected[:-1]))
    assert math.isnan(h["tool.punch.fx"][-1])
    assert math.copysign(1.0, h["tool.punch.fx"][2]) == -1.0  # -0.0 keeps its sign
    np.testing.assert_array_equal(
        bits(h["time"][: len(tricky)]), bits([i * 1e-7 + 1e-9 for i in range(len(tricky))])
    )
    assert h["broken"][:-1].tolist() == list(range(len(tricky))) + [7]


def test_history_rows_are_on_disk_before_close(tmp_path):
    path = tmp_path / "history.csv"
    writer = HistoryWriter(path, ["time", "energy.kinetic"])
    writer.append([0.5, 1.25])
    # Without close(): another reader must already see the row (crash safety).
    h = read_history_csv(path)
    assert h["time"].tolist() == [0.5] and h["energy.kinetic"].tolist() == [1.25]
    writer.close()


def test_history_ignores_torn_last_line_and_reads_empty(tmp_path):
    path = tmp_path / "history.csv"
    path.write_text("time,a\n0.1,2.0\n0.2,")
    h = read_history_csv(path)
    assert h["time"].tolist() == [0.1] and h["a"].tolist() == [2.0]

    with HistoryWriter(tmp_path / "empty.csv", ["time", "a"]):
        pass
    h = read_history_csv(tmp_path / "empty.csv")
    assert list(h) == ["time", "a"] and h["time"].size == 0


def test_history_rejects_bad_rows(tmp_path):
    with pytest.raises(ValueError):
        HistoryWriter(tmp_path / "h.csv", ["energy.kinetic", "time"])
    with HistoryWriter(tmp_path / "h.csv", ["time", "a"]) as writer:
        with pytest.raises(KeyError):
            writer.append({"time": 0.0, "typo": 1.0})
        with pytest.raises(ValueError):
            writer.append([0.0, 1.0, 2.0])


# --- summary.json -------------------------------------------------------------

def test_summary_converts_numpy_and_nonfinite(tmp_path):
    path = tmp_path / "summary.json"
    write_summary(path, {
        "steps": np.int64(1200),
        "dt": np.float32(0.5),
        "peak_force": np.float64(3.25e4),
        "residual": float("nan"),
        "limit": np.inf,
        "ok": np.bool_(True),
        "forces": np.array([1.0, np.nan, -np.inf]),
        "grid": np.arange(4).reshape(2, 2),
        "nested": {"b": (1, 2), "a": [np.float64(np.nan), None]},
        "name": "beam",
    })
    text = path.read_text()
    data = json.loads(text)  # strict parse: NaN would be rejected below
    assert "NaN" not in text and "Infinity" not in text
    assert data == {
        "steps": 1200, "dt": 0.5, "peak_force": 3.25e4, "residual": None,
        "limit": None, "ok": True, "forces": [1.0, None, None],
        "grid": [[0, 1], [2, 3]], "nested": {"a": [None, None], "b": [1, 2]},
        "name": "beam",
    }
    assert text == json.dumps(data, indent=2, sort_keys=True) + "\n"


def test_summary_rejects_unknown_types(tmp_path):
    with pytest.raises(TypeError):
        write_summary(tmp_path / "summary.json", {"x": object()})


# --- events.csv ---------------------------------------------------------------

def test_events_round_trip(tmp_path):
    path = tmp_path / "events.csv"
    with EventWriter(path) as writer:
        writer.append_many([1e-6, 0.1 + 0.2], [[0.0, -0.0, 1e-300], [1.5, 2.5, 3.5]],
                           ["tension", "shear"], np.array([4, 9]))
        writer.append_many([], np.zeros((0, 3)), [], [])
        writer.append_many(np.array([2e-6]), np.array([[1.0, 2.0, 3.0]]), "mixed", [11])
    assert path.read_text().splitlines()[0] == "time,x,y,z,mode,id"

    ev = read_events_csv(path)
    np.testing.assert_array_equal(bits(ev["time"]), bits([1e-6, 0.1 + 0.2, 2e-6]))
    np.testing.assert_array_equal(bits(ev["y"]), bits([-0.0, 2.5, 2.0]))
    np.testing.assert_array_equal(bits(ev["z"]), bits([1e-300, 3.5, 3.0]))
    assert ev["mode"].tolist() == ["tension", "shear", "mixed"]
    assert ev["id"].tolist() == [4, 9, 11]


def test_events_reject_unknown_mode_and_length_mismatch(tmp_path):
    with EventWriter(tmp_path / "events.csv") as writer:
        with pytest.raises(ValueError):
            writer.append_many([0.0], [[0, 0, 0]], ["crushing"], [1])
        with pytest.raises(ValueError):
            writer.append_many([0.0, 1.0], [[0, 0, 0]], ["shear"], [1])
    assert read_events_csv(tmp_path / "events.csv")["time"].size == 0


# --- fields.pvd + fields/*.vtu ----------------------------------------------------

def two_tet_mesh():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    triangles = np.array([[1, 2, 3]])  # the shared face, as an interface element
    return points, tets, triangles


def test_field_writer_series_with_interface_triangles(tmp_path):
    points, tets, triangles = two_tet_mesh()
    rng = np.random.default_rng(0)
    writer = FieldWriter(tmp_path)
    steps = []
    for time in (0.0, 1.0e-6 / 3):
        data = {
            "displacement": rng.normal(size=(5, 3)) * 1e-7,
            "velocity": rng.normal(size=(5, 3)),
            "stress": rng.normal(size=(2, 6)) * 1e6,
            "damage": np.array([0.0, 0.25]),
            "opening": np.array([3e-5]),
        }
        path = writer.write(
            time, points, tets,
            point_data={"displacement": data["displacement"], "velocity": data["velocity"]},
            cell_data={"stress": data["stress"], "damage": data["damage"]},
            triangles=triangles,
            triangle_data={"damage": np.array([0.75]), "opening": data["opening"]},
        )
        steps.append((time, path, data))
        # The pvd must be valid after every step, listing the steps so far.
        assert len(read_pvd(tmp_path / "fields.pvd")) == len(steps)

    root = ET.parse(tmp_path / "fields.pvd").getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    datasets = root.find("Collection").findall("DataSet")
    assert [d.get("file") for d in datasets] == [
        "fields/step_000000.vtu", "fields/step_000001.vtu"]
    assert [float(d.get("timestep")) for d in datasets] == [0.0, 1.0e-6 / 3]

    for time, path, data in steps:
        assert path == tmp_path / "fields" / path.name and path.exists()
        mesh = meshio.read(path)
        np.testing.assert_array_equal(mesh.points, points)
        assert [c.type for c in mesh.cells] == ["tetra", "triangle"]
        np.testing.assert_array_equal(mesh.cells[0].data, tets)
        np.testing.assert_array_equal(mesh.cells[1].data, triangles)
        for name in ("displacement", "velocity"):
            np.testing.assert_array_equal(mesh.point_data[name], data[name])  # exact
        stress = mesh.cell_data["stress"]
        np.testing.assert_array_equal(stress[0], data["stress"])
        np.testing.assert_array_equal(stress[1], np.zeros((1, 6)))  # padded
        opening = mesh.cell_data["opening"]
        np.testing.assert_array_equal(opening[0], [0.0, 0.0])  # padded
        np.testing.assert_array_equal(opening[1], data["opening"])
        damage = mesh.cell_data["damage"]  # same name on both blocks: merged
        np.testing.assert_array_equal(damage[0], [0.0, 0.25])
        np.testing.assert_array_equal(damage[1], [0.75])
        kind = mesh.cell_data["cell_kind"]
        assert np.issubdtype(kind[0].dtype, np.integer)
        np.testing.assert_array_equal(kind[0], [0, 0])
        np.testing.assert_array_equal(kind[1], [1])


def test_field_writer_tets_only_and_full_stress_tensor(tmp_path):
    points, tets, _ = two_tet_mesh()
    stress = np.arange(18, dtype=float).reshape(2, 3, 3)
    path = FieldWriter(tmp_path).write(0.5, points, tets, cell_data={"stress": stress})
    mesh = meshio.read(path)
    assert [c.type for c in mesh.cells] == ["tetra"]
    np.testing.assert_array_equal(mesh.cell_data["stress"][0], stress.reshape(2, 9))
    with pytest.raises(ValueError):
        FieldWriter(tmp_path).write(0.0, points, tets, cell_data={"damage": np.zeros(3)})


# --- plots --------------------------------------------------------------------------

def synthetic_history(n=50):
    t = np.linspace(0, 20e-6, n)
    u = 1e-3 * t / t[-1]
    h = {"time": t}
    for tool, sign in (("punch", -1.0), ("support", 1.0)):
        h[f"tool.{tool}.fx"] = np.zeros(n)
        h[f"tool.{tool}.fy"] = np.zeros(n)
        h[f"tool.{tool}.fz"] = sign * 5e4 * np.sin(np.pi * t / t[-1])
        h[f"tool.{tool}.ux"] = np.zeros(n)
        h[f"tool.{tool}.uy"] = np.zeros(n)
        h[f"tool.{tool}.uz"] = sign * u
    for i, name in enumerate(ENERGIES):
        h[f"energy.{name}"] = (i + 1) * t / t[-1]
    h["broken"] = np.floor(np.linspace(0, 30, n))
    return h


def synthetic_events(k=40):
    rng = np.random.default_rng(1)
    return {
        "time": np.sort(rng.uniform(0, 20e-6, k)),
        "x": rng.uniform(0, 0.1, k), "y": rng.uniform(0, 0.02, k),
        "z": rng.uniform(0, 0.01, k),
        "mode": rng.choice(["tension", "shear", "mixed"], k),
    }


def assert_png(path):
    assert path.exists() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


BOUNDS = ((0.0, 0.0, 0.0), (0.1, 0.02, 0.01))


def test_individual_plots(tmp_path):
    history = synthetic_history()
    assert_png(plot_load_displacement(history, tmp_path / "ld.png"))
    assert_png(plot_energies(history, tmp_path / "e.png"))
    assert_png(plot_crack_pattern(synthetic_events(), BOUNDS, tmp_path / "c.png"))
    assert_png(plot_crack_pattern({}, BOUNDS, tmp_path / "c0.png"))


def test_standard_plots_from_files_with_zero_events(tmp_path):
    history = synthetic_history()
    columns = list(history)
    with HistoryWriter(tmp_path / "history.csv", columns) as writer:
        for row in zip(*history.values()):
            writer.append(row)
    EventWriter(tmp_path / "events.csv").close()

    paths = write_standard_plots(tmp_path, read_history_csv(tmp_path / "history.csv"),
                                 read_events_csv(tmp_path / "events.csv"), BOUNDS)
    assert [p.name for p in paths] == [
        "load_displacement.png", "energies.png", "crack_pattern.png"]
    for p in paths:
        assert p.parent == tmp_path / "plots"
        assert_png(p)


def test_standard_plots_skip_load_displacement_without_tools(tmp_path):
    history = {k: v for k, v in synthetic_history().items() if not k.startswith("tool.")}
    paths = write_standard_plots(tmp_path, history, synthetic_events(3), BOUNDS)
    assert [p.name for p in paths] == ["energies.png", "crack_pattern.png"]
    assert not (tmp_path / "plots" / "load_displacement.png").exists()


# --- progress -------------------------------------------------------------------------

def test_progress_disabled_prints_nothing(capsys):
    with Progress(1e-3, enabled=False) as progress:
        for i in range(1000):
            progress.update(i * 1e-6, i, i // 10)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""


def test_progress_auto_is_off_when_not_a_terminal(capsys):
    # Under pytest stdout is captured, i.e. not a terminal.
    with Progress(1e-3, delay=0.0) as progress:
        assert not progress.enabled
        progress.update(5e-4, 10, 1)
    assert capsys.readouterr().out == ""


def test_progress_enabled_draws_after_delay(capsys):
    with Progress(1e-3, enabled=True, delay=0.0) as progress:
        for i in range(100):
            progress.update(i * 1e-5, i, 3)
    assert "broken 3" in capsys.readouterr().out


def test_progress_enabled_stays_silent_for_short_runs(capsys):
    with Progress(1e-3, enabled=True) as progress:  # default delay of 1 s
        progress.update(5e-4, 10, 1)
    assert capsys.readouterr().out == ""


def test_progress_stage_shows_at_once(capsys):
    """Before the first step (compiling kernels) the bar is drawn at once with what is going on."""
    with Progress(1e-3, enabled=True, delay=60.0) as progress:
        progress.stage("compiling kernels")
    assert "compiling kernels" in capsys.readouterr().out


def test_field_component_names(tmp_path):
    """Named columns (stress xx .. xz) are labelled in the VTU for ParaView and read back intact."""
    points, tets, _ = two_tet_mesh()
    stress = np.arange(12.0).reshape(2, 6)
    path = FieldWriter(tmp_path).write_blocks(
        0.0, points, [("tetra", tets, {"stress": stress})],
        component_names={"stress": ("xx", "yy", "zz", "xy", "yz", "xz")},
    )
    text = path.read_text()
    assert 'ComponentName0="xx"' in text and 'ComponentName5="xz"' in text
    np.testing.assert_array_equal(meshio.read(path).cell_data["stress"][0], stress)

"""The DEM's confining pressure: [[pressures]] on faces of the sample's box as a flexible membrane
on the outermost particles (dem.membrane), and the triaxial test (dem-triaxial)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from crackle.scenario import ScenarioError, load_scenario

SRC = Path(__file__).resolve().parents[2] / "src"

# An elastic 10 mm cube (bonds 1000 x paper 003's strengths: none breaks) of ~1,470 particles.
CUBE = """
name = "membrane-cube"
method = "dem"

[specimen]
shape = "box"
size = [0.01, 0.01, 0.01]
origin = [0.0, 0.0, 0.0]

[packing]
mean_radius = 5e-4
particle_density = 1.47
seed = 1

[material]
density = 2500.0
bond_modulus = 50e9
stiffness_ratio = 0.3333333333333333
tensile_strength = 4.5e9
cohesion = 45e9
friction_angle = 18.0
bonds_per_particle = 12.0
local_damping = 0.2

[[pressures]]
faces = "where"
value = 10e6
ramp_time = 2e-5
[pressures.where]                  # every face: their centres lie in this box
box_min = [-0.001, -0.001, -0.001]
box_max = [0.011, 0.011, 0.011]

[run]
end_time = 1e-4
history_samples = 50
field_frames = 0
"""

# The quick dem-triaxial on a coarse packing (about 950 particles), stopped past the peak.
COARSE = ("packing.mean_radius=1.5e-3", "run.stop.force_drop=0.8", "run.stop.force_drop_hold=1e-5",
          "run.field_frames=0")


def _write(tmp_path, text=CUBE, name="cube.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def hydrostatic(tmp_path_factory):
    """The cube under 10 MPa on all six faces (ramped over 20 us), run to 100 us: (sim, summary)."""
    from crackle.api import build_simulation
    from crackle.solver import run

    tmp = tmp_path_factory.mktemp("membrane")
    scenario, base = load_scenario(str(_write(tmp)))
    sim, control = build_simulation(scenario, base)
    control.plots = False
    run(sim, control, tmp / "out")
    return sim, json.loads((tmp / "out" / "summary.json").read_text())


def test_membrane_areas_tile_each_face(hydrostatic):
    """Each face's rasterised areas sum to the face's area: the membrane's resultant on each of
    the six faces equals p x face area (1e-4 m^2 x 10 MPa = 1,000 N) within 1e-9 relative, along
    the face's inward normal, and the six cancel (net force below 1e-9 of one face's)."""
    from crackle.dem.membrane import exposed_areas

    sim, _ = hydrostatic
    m = sim.membrane
    assert len(m.faces[0]) == 6
    p = 10e6
    for face in m.faces[0]:
        area = exposed_areas(sim.particles.x, sim.particles.radius, face, m.cell)
        assert area.sum() * p == pytest.approx(p * face.area, rel=1e-9)
        assert face.area == pytest.approx(1e-4, rel=1e-12)
    forces = m.forces(sim.time)
    assert np.abs(forces).sum(axis=0) == pytest.approx(np.full(3, 2.0 * p * 1e-4), rel=1e-9)
    assert np.abs(forces.sum(axis=0)).max() < 1e-9 * p * 1e-4


def test_hydrostatic_pressure_gives_its_stress(hydrostatic):
    """The elastic cube under 10 MPa on all six faces, settled (local damping 0.2, 100 us, 5 x the
    ramp): the Love-Weber stress's normal components (the membrane's forces counted where each
    cell's force meets its sphere) each equal -10 MPa within 6 % (measured: -9.570, -9.582,
    -9.570 MPa: the sphere surfaces the cells meet lie ~0.4 R inside the faces, and the virial's
    lever arms are short by 2 x that over the 10 mm side), the shear ones below 1 % of p; the
    kinetic energy below 1e-6 of the stored one (measured 5e-13); the energy audit, with the
    membrane's work as the input, closes within 1 % (measured 2e-9)."""
    sim, summary = hydrostatic
    p = 10e6
    lw = sim.love_weber_stress()
    assert lw[:3] == pytest.approx(np.full(3, -p), rel=0.06)
    assert np.abs(lw[3:]).max() < 0.01 * p
    assert sim.kinetic_energy() < 1e-6 * sim.interaction_energy(0.0)
    assert abs(summary["energy_error"]) < 0.01
    assert summary["membrane_rasters"] >= 1


@pytest.fixture(scope="module")
def triaxial(tmp_path_factory):
    """Coarse quick runs (COARSE) of dem-ucs, of dem-triaxial without [[pressures]] and of
    dem-triaxial at sigma_3 = 0, 2 and 5 MPa: {"ucs" | "none" | sigma_3: (summary, history bytes)}.
    Each stops once the platen force has stayed below 95 % of its peak for 10 us (COARSE's 80 %
    raised): the five peaks are the same to the bit as with 80 %, in 6 % fewer steps (94,480
    against 100,670)."""
    from crackle.api import run_scenario

    tmp = tmp_path_factory.mktemp("triaxial")
    out = {}
    runs = [("ucs", "dem-ucs", []), ("none", "dem-triaxial", ["pressures=[]"]),
            *[(p, "dem-triaxial", [f"pressures.0.value={p}"]) for p in (0.0, 2e6, 5e6)]]
    for key, name, extra in runs:
        folder = tmp / f"{name}-{key}"
        run_scenario(name, folder, [*COARSE, "run.stop.force_drop=0.95", *extra], quick=True, progress=False,
                     plots=False)
        out[key] = json.loads((folder / "summary.json").read_text()), (folder / "history.csv").read_bytes()
    return out


def test_unconfined_triaxial_is_the_ucs(triaxial):
    """dem-triaxial --quick on a coarse packing (mean radius 1.5 mm, ~950 particles) at sigma_3 =
    0: the zero membrane adds nothing, so its peak is that of the same run without [[pressures]]
    to the bit (a UCS test with the triaxial's platen schedule); and it equals dem-ucs's peak on the
    same packing within the quick UCS's round-off scatter, 15 % (twelve draws of the quick UCS
    read 59.4-73.8 MPa, docs/validation.md; measured here 62.0 MPa against 70.9 MPa, -12.6 %:
    the two differ only in when the platen starts, which draws another chain of bond failures;
    on the 1.25 mm packing of the example's quick form 73.7 against 66.6 MPa, +10.7 %)."""
    free, none, ucs = (triaxial[k][0] for k in (0.0, "none", "ucs"))
    assert free["peak_stress"] == none["peak_stress"]
    assert free["steps"] == none["steps"]
    assert free["peak_stress"] == pytest.approx(ucs["peak_stress"], rel=0.15)
    assert free["confining_pressure"] == 0.0


def test_triaxial_peak_rises_with_confinement(triaxial):
    """dem-triaxial --quick on the coarse packing: the peak axial stress rises with sigma_3 (measured
    62.0, 128.3 and 147.7 MPa at 0, 2 and 5 MPa; 197.6 and 265.0 MPa at 10 and 20 MPa, not run
    here); confining_pressure reports sigma_3 (1e-6 Pa) and deviator_at_peak = peak_stress -
    sigma_3 (1e-12); every run's energy audit, with the membrane's work, closes within 1 %
    (measured at most 0.0064 %; 0.016 % at COARSE's later stop)."""
    free, low, high = (triaxial[k][0]["peak_stress"] for k in (0.0, 2e6, 5e6))
    assert free < low < high
    assert low > 1.2 * free
    for sigma3 in (0.0, 2e6, 5e6):
        s = triaxial[sigma3][0]
        assert s["confining_pressure"] == pytest.approx(sigma3, abs=1e-6)
        assert s["deviator_at_peak"] == pytest.approx(s["peak_stress"] - sigma3, rel=1e-12)
    for s, _ in triaxial.values():
        assert abs(s["energy_error"]) < 0.01


def test_membrane_is_thread_count_independent(tmp_path):
    """dem-triaxial --quick, coarse packing, sigma_3 = 5 MPa, to 0.5 ms (the confinement, the
    platen's start), the membrane redrawn once a particle has moved 0.01 R (membrane.MOVE, 0.25
    in a run: here 3 rasters as the platen starts): history.csv byte-identical with
    NUMBA_NUM_THREADS = 1 and 2."""
    code = textwrap.dedent("""
        import sys
        import crackle.dem.membrane
        crackle.dem.membrane.MOVE = 0.01
        from crackle.api import run_scenario
        run_scenario("dem-triaxial", sys.argv[1], [*sys.argv[2:]], quick=True, progress=False, plots=False)
    """)
    texts = []
    for threads in (1, 2):
        out = tmp_path / f"t{threads}"
        env = {**os.environ, "NUMBA_NUM_THREADS": str(threads), "PYTHONPATH": str(SRC)}
        subprocess.run([sys.executable, "-c", code, str(out), *COARSE, "pressures.0.value=5e6",
                        "run.end_time=5e-4"], check=True, env=env)
        texts.append((out / "history.csv").read_bytes())
        summary = json.loads((out / "summary.json").read_text())
        assert summary["membrane_rasters"] > 1
    assert texts[0] == texts[1]


@pytest.mark.parametrize("change, message", [
    ('box_min = [-0.001, -0.001, -0.001]\nbox_max = [0.011, 0.011, 0.011]',
     "pressures.0.where selects no face"),
    ('faces = "where"', 'pressures.0.faces: the DEM has no pre-cracks'),
])
def test_bad_pressures_exit_2(tmp_path, capsys, change, message):
    """A where that selects no face (a plane through the cube's middle) and faces = "precrack"
    stop before the run with exit code 2 and a message naming the field."""
    from crackle.cli import main

    replacement = {"pressures.0.where selects no face":
                   'plane_point = [0.005, 0.005, 0.005]\nplane_normal = [1.0, 0.0, 0.0]',
                   "pressures.0.faces: the DEM has no pre-cracks": 'faces = "precrack"'}[message]
    path = _write(tmp_path, CUBE.replace(change, replacement))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err


def test_non_box_specimen_refused(tmp_path):
    """Pressures on a disc: a ScenarioError naming the box faces the DEM loads."""
    from crackle.api import build_simulation

    text = CUBE.replace('shape = "box"\nsize = [0.01, 0.01, 0.01]\norigin = [0.0, 0.0, 0.0]',
                        'shape = "disc"\ndiameter = 0.01\nthickness = 0.004')
    scenario, base = load_scenario(str(_write(tmp_path, text)))
    with pytest.raises(ScenarioError, match="box specimen"):
        build_simulation(scenario, base)


def test_where_names_faces_of_the_box():
    """A plane names the face lying in it (all four corners on it); a box the faces whose centres
    it holds: dem-triaxial's box around the prism's middle gives the four lateral faces, not the
    top and bottom; the quick example's membrane tiles them (27 x 54 and 12 x 54 mm, twice each:
    the |force| per unit pressure sums to 2 x 12 x 54 mm^2 along x, 2 x 27 x 54 along y, within 1e-12)."""
    from crackle.api import build_simulation
    from crackle.dem.membrane import box_faces, selected_faces
    from crackle.loading import Selection

    faces = box_faces((0.0, 0.0, 0.0), (0.027, 0.012, 0.054))
    where = Selection(plane_point=(0.027, 0.0, 0.0), plane_normal=(1.0, 0.0, 0.0))
    plane = selected_faces(where, faces, 0.054)
    assert [f.name for f in plane] == ["x = 0.027"]
    scenario, base = load_scenario("dem-triaxial", quick=True)
    sim, _ = build_simulation(scenario, base)
    assert [f.name for f in sim.membrane.faces[0]] == ["x = 0", "x = 0.027", "y = 0", "y = 0.012"]
    total = np.abs(sim.membrane.area[0]).sum(axis=0)
    assert total == pytest.approx([2 * 0.012 * 0.054, 2 * 0.027 * 0.054, 0.0], rel=1e-12, abs=1e-18)


def test_confined_run_resumed_is_bit_identical(tmp_path, monkeypatch):
    """dem-triaxial --quick on the coarse packing at 5 MPa, the membrane redrawn at 0.01 R
    (membrane.MOVE): run to 0.25 ms (the platen at speed since 0.2 ms), then resumed to 0.5 ms
    (the checkpoint holds the membrane's raster and positions; bonds break after it: 0 then 22):
    history.csv's rows after 0.25 ms and the peak equal, bit for bit, those of the run to 0.5 ms
    never stopped."""
    from crackle.cli import main
    import crackle.dem.membrane

    monkeypatch.setattr(crackle.dem.membrane, "MOVE", 0.01)
    args = ["dem-triaxial", "--quick", *[a for o in COARSE for a in ("--set", o)],
            "--set", "pressures.0.value=5e6"]
    whole, half = tmp_path / "whole", tmp_path / "half"
    rows = ["--set", "run.history_samples=100"]
    assert main(["run", *args, *rows, "--set", "run.end_time=5e-4", "--out", str(whole)]) == 0
    # the first half on the same grid of rows (the half run's rows are its own end time's samples)
    first = ["--set", "run.history_samples=50", "--set", "run.end_time=2.5e-4"]
    assert main(["run", *args, *first, "--out", str(half)]) == 0
    assert main(["run", *args, *rows, "--set", "run.end_time=5e-4", "--resume", str(half)]) == 0
    a, b = (np.genfromtxt(out / "history.csv", delimiter=",", names=True) for out in (whole, half))
    late_a, late_b = a[a["time"] > 2.501e-4], b[b["time"] > 2.501e-4]  # past the half run's last row
    assert len(late_a) == len(late_b) > 10
    assert late_b["broken"][-1] > late_b["broken"][0]  # bonds break in the resumed part
    for name in a.dtype.names:
        assert np.array_equal(late_a[name], late_b[name]), name
    sa, sb = (json.loads((out / "summary.json").read_text()) for out in (whole, half))
    assert sa["peak_stress"] == sb["peak_stress"] and sa["steps"] == sb["steps"]
    assert sb["membrane_rasters"] > 2

"""Several particle groups in one DEM packing ([materials.NAME], [interfaces."A-B"]): a
two-material sample in direct tension against each material alone on the same packing."""

from __future__ import annotations

import json
from collections import Counter
from importlib import resources
from pathlib import Path

import meshio
import numpy as np
import pytest

from crackle.api import run_scenario
from crackle.cli import main
from crackle.io import read_events_csv, read_pvd

# The quick dem-tension sample (27 x 12 x 54 mm, ~3,200 spheres, pulled along z), its lower half
# soft (Y = 25 GPa, t = 3 MPa), its upper half stiff and strong (50 GPa, 6 MPa).
TWO = """
[materials.soft]
density = 2500.0
bond_modulus = 25e9
tensile_strength = 3e6
cohesion = 30e6

[materials.stiff]
density = 2500.0
bond_modulus = 50e9
tensile_strength = 6e6
cohesion = 60e6
zones = [{shape = "half-space", point = [0.0, 0.0, 0.027], normal = [0.0, 0.0, 1.0]}]
{pair}"""
ONE = """
[material]
density = 2500.0
bond_modulus = {Y}
tensile_strength = {t}
cohesion = {c}
"""


def _scenario(tmp_path, name: str, materials: str) -> str:
    src = (resources.files("crackle") / "examples" / "dem-tension.toml").read_text()
    start = src.index("\n[material]\n")
    end = src.index("\n[[supports]]\n", start)
    path = tmp_path / f"{name}.toml"
    path.write_text(src[:start] + materials + src[end:])
    return str(path)


def _run(tmp_path, name, materials, *sets):
    """`crackle run` of the scenario --quick, 10 field frames, without plots/ (seconds a run,
    read by no test here): run_scenario."""
    out = tmp_path / name
    run_scenario(_scenario(tmp_path, name, materials), out, ["run.field_frames=10", *sets], quick=True, progress=False,
                 plots=False)
    return json.loads((out / "summary.json").read_text()), out


def _halves(out, frame: int):
    """(strain, mean Love-Weber sigma_zz) of the lower and the upper half (slabs 5-22 and 32-49 mm)."""
    _, path = read_pvd(out / "fields.pvd")[frame]
    mesh = meshio.read(path)
    keep = mesh.point_data["radius"] > 0  # the particles, not the stress grid's corners
    u = mesh.point_data["displacement"][keep]
    x = mesh.points[keep] - u
    szz = mesh.point_data["stress"][keep][:, 2]

    def mean_z(lo, hi):
        sel = (x[:, 2] > lo) & (x[:, 2] < hi)
        return u[sel, 2].mean(), x[sel, 2].mean()

    out = []
    for (a, b), (lo, hi) in [(((0.005, 0.008), (0.019, 0.022)), (0.005, 0.022)),
                              (((0.032, 0.035), (0.046, 0.049)), (0.032, 0.049))]:
        (ua, za), (ub, zb) = mean_z(*a), mean_z(*b)
        out.append(((ub - ua) / (zb - za), szz[(x[:, 2] > lo) & (x[:, 2] < hi)].mean()))
    return out


def test_two_particle_groups_in_series_and_the_weaker_breaks(tmp_path):
    """At 0.2 ms (elastic, before the peak at ~0.3 ms): each half's compliance (strain over its
    mean sigma_zz) is that of the same half of the packing made all of its material, within 1 %
    (the springs in series: each half strains as its own material, the junction's bonds the two
    half-springs in series), and the halves carry the same stress within 2 % (the Love-Weber means
    scatter by about 1 %). The sample breaks at the soft material's strength (the soft sample's
    nominal strength) within 10 %, nine in ten broken bonds or more in the soft half.
    Measured: the compliances -0.04 % (soft) and -0.02 % (stiff) off, the stresses 1.2 % apart,
    3.42 against 3.37 MPa. The stiff sample runs to 0.2 ms, its one field frame there (its
    frame 2 of 10 over 0.25 ms fell at 0.05 ms before, the ramp's end: -0.22 %); the soft one
    stops once its force has stayed below 80 % of the peak for 10 us (the example's rule: 30 %
    for 50 us), past the peak (at 0.41 ms; the force falls to 80 % in 45 us and never dipped 1 %
    below its running peak before it: measured), the same nominal strength to the bit."""
    two, out_two = _run(tmp_path, "two", TWO.replace("{pair}", ""))
    soft, out_soft = _run(tmp_path, "soft", ONE.replace("{Y}", "25e9").replace("{t}", "3e6").replace("{c}", "30e6"),
                          "run.stop.force_drop=0.8", "run.stop.force_drop_hold=1e-5")
    _, out_stiff = _run(tmp_path, "stiff", ONE.replace("{Y}", "50e9").replace("{t}", "6e6").replace("{c}", "60e6"),
                        "run.end_time=2e-4", "run.field_frames=1")
    (e_soft, s_soft), (e_stiff, s_stiff) = _halves(out_two, 2)
    alone_soft, alone_stiff = _halves(out_soft, 2)[0], _halves(out_stiff, 1)[1]
    assert e_soft / s_soft == pytest.approx(alone_soft[0] / alone_soft[1], rel=0.01)
    assert e_stiff / s_stiff == pytest.approx(alone_stiff[0] / alone_stiff[1], rel=0.01)
    assert e_soft / e_stiff == pytest.approx(2.0, rel=0.1)
    assert s_soft == pytest.approx(s_stiff, rel=0.02)

    assert two["nominal_strength"] == pytest.approx(soft["nominal_strength"], rel=0.10)
    counts = two["failures_by_material"]
    assert counts.get("soft", 0) >= 0.9 * sum(counts.values()) > 0
    assert soft["failures_by_material"] is None
    # events.csv names each broken bond's material (pair), a one-material run has no such column
    assert Counter(read_events_csv(out_two / "events.csv")["material"]) == counts
    assert "material" not in read_events_csv(out_soft / "events.csv")


def test_bad_particle_groups_are_refused(tmp_path, capsys):
    """Two groups without zones, and a local damping that differs between groups: exit 2 naming it."""
    no_zone = TWO.replace("{pair}", "").replace(
        'zones = [{shape = "half-space", point = [0.0, 0.0, 0.027], normal = [0.0, 0.0, 1.0]}]', "")
    assert main(["run", _scenario(tmp_path, "a", no_zone), "--out", str(tmp_path / "a")]) == 2
    assert "only one material may fill the rest" in capsys.readouterr().err
    damped = TWO.replace("{pair}", "").replace("cohesion = 60e6", "cohesion = 60e6\nlocal_damping = 0.1")
    assert main(["run", _scenario(tmp_path, "b", damped), "--out", str(tmp_path / "b")]) == 2
    assert "local_damping" in capsys.readouterr().err



def test_a_weak_pair_law_breaks_the_junction_alike_on_1_and_2_threads(tmp_path):
    """[interfaces."soft-stiff"] with t = 1 MPa (a weak joint between the two halves): the
    sample breaks below the soft material's strength (3.37 MPa), most broken bonds between the
    two; the same run with 1 and with 2 numba threads gives byte-identical history and events.
    On the quick sample packed coarser (mean radius 1.5 mm: 953 particles, 4 blocks of particles
    and 23 of interactions for the threads to share), without plots/: measured 1.97 MPa, all 178
    broken bonds in the junction (the quick sample's 3,215 particles: 1.89 MPa, all 386)."""
    import os
    import subprocess
    import sys

    pair = '\n[interfaces."soft-stiff"]\ntensile_strength = 1e6\ncohesion = 10e6\n'
    scenario = _scenario(tmp_path, "joint", TWO.replace("{pair}", pair))
    outs = []
    for threads in (1, 2):
        out = tmp_path / f"t{threads}"
        run = ("import sys; from crackle.api import run_scenario; "
               "run_scenario(sys.argv[1], sys.argv[2], sys.argv[3:], quick=True, plots=False)")
        subprocess.run([sys.executable, "-c", run, scenario, str(out), "run.field_frames=0", "packing.mean_radius=1.5e-3"],
                       env=dict(os.environ, NUMBA_NUM_THREADS=str(threads)), check=True, capture_output=True)
        outs.append(out)
    assert (outs[0] / "history.csv").read_bytes() == (outs[1] / "history.csv").read_bytes()
    assert (outs[0] / "events.csv").read_bytes() == (outs[1] / "events.csv").read_bytes()
    summary = json.loads((outs[0] / "summary.json").read_text())
    counts = summary["failures_by_material"]
    assert counts.get("soft-stiff", 0) > 0.5 * sum(counts.values())
    assert summary["nominal_strength"] < 0.7 * 3.37e6


def test_groups_from_a_sphere_files_column_are_the_zones_groups(tmp_path, capsys):
    """The quick two-group sample's packing written as a text sphere list with a fifth column
    ("granite" below z = 27 mm, "marble" above, as another code would export each sphere's
    material) and [materials.NAME] taking theirs by `group`: the same particles in each group as
    the half-space zone gives, so the same run bit for bit (history and events over 50 us, bonds
    breaking in neither). A label no material names stops the run (exit 2) naming it."""
    zoned = _scenario(tmp_path, "zoned", TWO.replace("{pair}", ""))
    from crackle.dem.setup import build_simulation as build_dem
    from crackle.scenario import load_scenario

    packing = build_dem(*load_scenario(zoned, quick=True)).packing
    label = np.where(packing.centers[:, 2] >= 0.027, "marble", "granite")
    lines = [" ".join(repr(float(v)) for v in (*c, r)) + f" {g}" for c, r, g in zip(packing.centers, packing.radii, label)]
    (tmp_path / "spheres.txt").write_text("# x y z r material\n" + "\n".join(lines) + "\n")
    grouped = TWO.replace("{pair}", "").replace(
        'zones = [{shape = "half-space", point = [0.0, 0.0, 0.027], normal = [0.0, 0.0, 1.0]}]', 'group = "marble"')
    grouped = grouped.replace("cohesion = 30e6\n", 'cohesion = 30e6\ngroup = "granite"\n', 1)
    src = Path(_scenario(tmp_path, "grouped", grouped)).read_text()
    start = src.index("\n[packing]\n")
    end = src.index("\n[", start + 1)
    Path(tmp_path / "grouped.toml").write_text(
        src[:start] + '\n[packing]\nfile = "spheres.txt"\ngroup_column = 5\n' + src[end:])
    outs = []
    for name in ("zoned", "grouped"):
        out = tmp_path / f"out-{name}"
        assert main(["run", str(tmp_path / f"{name}.toml"), "--quick", "--out", str(out), "--set", "run.end_time=5e-5",
                     "--set", "run.field_frames=0"]) == 0
        outs.append(out)
    assert (outs[0] / "history.csv").read_bytes() == (outs[1] / "history.csv").read_bytes()
    assert (outs[0] / "events.csv").read_bytes() == (outs[1] / "events.csv").read_bytes()

    (tmp_path / "spheres.txt").write_text((tmp_path / "spheres.txt").read_text().replace(" marble\n", " basalt\n", 1))
    assert main(["run", str(tmp_path / "grouped.toml"), "--quick", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert "named by no material: basalt" in err

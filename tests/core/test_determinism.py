"""Bit-identical results with 1 and 2 numba threads (gather, never racing scatter)."""

from __future__ import annotations

import os
import subprocess
import sys


# Each case: a shipped example (its quick form) and the overrides of its run.
BENDING = ["three-point-bending", "run.end_time=7.5e-4", "run.stop.force_drop=0.5"]
# Fragmentation with surface contact on: failures, rebuilds of the surface and candidate lists.
IMPACT = ["sphere-impact-fast", "run.end_time=4e-5"]
# Extrinsic interfaces: insertions, the regrouping of clusters (their mesh points in parallel), the
# node pass over points.
EXTRINSIC = ["three-point-bending", "run.end_time=1e-3", "material.interface.insertion=extrinsic"]
# Glued grips pulling a bar apart, faces inserted by either tet's traction, the effective mixed mode
# (the example's), Weibull face strengths in a random field (one law row per face); the bar
# separates before 1 ms.
TENSION = ["direct-tension", "material.interface.insertion=extrinsic", "run.end_time=1e-3",
           'material.random.tensile_strength={distribution="weibull", modulus=6, correlation_length=0.005}']
# Bonded-particle DEM: bonds breaking, the sample pulled by a moving support (its reaction summed
# from every block's slot) against a still one; bond strengths drawn per bond. A coarser packing
# than the quick one (mean radius 1.5 mm: 953 particles, 4 blocks of particles and 23 of
# interactions for the 2 threads to share; 478 bonds broken by 0.35 ms, the first at 0.15 ms):
# the same kernels at a third of the quick sample's cost. (Neither sample relists its contacts
# after the first step within 0.35 ms: measured.)
DEM = ["dem-tension", "run.end_time=3.5e-4", "packing.mean_radius=1.5e-3",
       'material.random.tensile_strength={distribution="lognormal", cv=0.3}',
       'material.random.cohesion={distribution="normal", cv=0.2, correlation_length=0.004}']

# A run as `crackle run NAME --quick --set ...` makes it, without plots/ (seconds a run, and
# not compared): run_scenario in a process of its own (the thread count is fixed when numba starts).
RUN = ("import sys; from crackle.api import run_scenario; "
       "run_scenario(sys.argv[1], sys.argv[2], sys.argv[3:], quick=True, plots=False)")


def _run(tmp_path, threads, case=BENDING):
    out = tmp_path / f"{case[0]}-t{threads}"
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    subprocess.run(
        [sys.executable, "-c", RUN, case[0], str(out), *case[1:], "run.field_frames=0"],
        env=env,
        check=True,
        capture_output=True,
    )
    return out


def test_history_and_events_identical_for_1_and_2_threads(tmp_path):
    """history.csv and events.csv are byte-identical; the run includes interface failures and
    platen contact with friction, so every kernel path is exercised."""
    one, two = _run(tmp_path, 1), _run(tmp_path, 2)
    h1, h2 = (one / "history.csv").read_bytes(), (two / "history.csv").read_bytes()
    assert h1 == h2
    e1 = (one / "events.csv").read_text()
    assert e1 == (two / "events.csv").read_text()
    assert len(e1.strip().splitlines()) > 1, "the compared run must include failures"


def test_identical_for_1_and_2_threads_with_surface_contact(tmp_path):
    """The fast sphere impact (quick form, first 40 us) with surface contact on: byte-identical
    history and events with 1 and 2 threads, and the run does fragment."""
    one, two = _run(tmp_path, 1, IMPACT), _run(tmp_path, 2, IMPACT)
    assert (one / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
    e1 = (one / "events.csv").read_text()
    assert e1 == (two / "events.csv").read_text()
    assert len(e1.strip().splitlines()) > 50, "the compared run must fragment"


def test_identical_for_1_and_2_threads_with_extrinsic_interfaces(tmp_path):
    """The quick three-point bending with extrinsic interfaces to 1 ms (insertions and failures
    under the platen and at the notch): byte-identical history and events with 1 and 2 threads."""
    one, two = _run(tmp_path, 1, EXTRINSIC), _run(tmp_path, 2, EXTRINSIC)
    assert (one / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
    e1 = (one / "events.csv").read_text()
    assert e1 == (two / "events.csv").read_text()
    assert len(e1.strip().splitlines()) > 1, "the compared run must include failures"


def test_identical_for_1_and_2_threads_with_dem_bonds_breaking(tmp_path):
    """The DEM direct tension (DEM: the quick sample, coarser) to 0.35 ms (hundreds of bonds
    broken, the moving support's reaction): byte-identical history and events with 1 and 2
    threads."""
    one, two = _run(tmp_path, 1, DEM), _run(tmp_path, 2, DEM)
    assert (one / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
    e1 = (one / "events.csv").read_text()
    assert e1 == (two / "events.csv").read_text()
    assert len(e1.strip().splitlines()) > 100, "the compared run must break bonds"


def test_identical_for_1_and_2_threads_with_glued_grips(tmp_path):
    """The quick direct tension bar (glued grips, extrinsic faces, the effective mixed mode) to
    its break: byte-identical history and events with 1 and 2 threads, with failures."""
    one, two = _run(tmp_path, 1, TENSION), _run(tmp_path, 2, TENSION)
    assert (one / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
    e1 = (one / "events.csv").read_text()
    assert e1 == (two / "events.csv").read_text()
    assert len(e1.strip().splitlines()) > 1, "the compared run must include failures"

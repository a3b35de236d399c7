"""Bit-identical results with 1 and 2 numba threads (gather, never racing scatter)."""

from __future__ import annotations

import os
import subprocess
import sys


BENDING = ["three-point-bending", "--set", "run.end_time=7.5e-4", "--set", "run.stop.force_drop=0.5"]
# Fragmentation with surface contact on: failures, rebuilds of the surface and candidate lists.
IMPACT = ["sphere-impact-fast", "--set", "run.end_time=4e-5"]
# Extrinsic interfaces: insertions, the serial regrouping of clusters, the node pass over points.
EXTRINSIC = ["three-point-bending", "--set", "run.end_time=1e-3", "--set", "material.interface.insertion=extrinsic"]
# Glued grips pulling a bar apart, faces inserted by either tet's traction, the effective mixed mode
# (the example's), Weibull face strengths in a random field (one law row per face); the bar
# separates before 1 ms.
TENSION = ["direct-tension", "--set", "material.interface.insertion=extrinsic", "--set", "run.end_time=1e-3",
           "--set", 'material.random.tensile_strength={distribution="weibull", modulus=6, correlation_length=0.005}']
# Bonded-particle DEM: bonds breaking, contact lists rebuilt, the sample pulled by a moving
# support (its reaction summed from every block's slot) against a still one; bond strengths
# drawn per bond.
DEM = ["dem-tension", "--set", "run.end_time=3.5e-4",
       "--set", 'material.random.tensile_strength={distribution="lognormal", cv=0.3}',
       "--set", 'material.random.cohesion={distribution="normal", cv=0.2, correlation_length=0.004}']


def _run(tmp_path, threads, case=BENDING):
    out = tmp_path / f"{case[0]}-t{threads}"
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    subprocess.run(
        [sys.executable, "-m", "crackle.cli", "run", *case, "--quick", "--out", str(out), "--set", "run.field_frames=0"],
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
    """The quick DEM direct tension to 0.35 ms (hundreds of bonds broken, the contact list
    rebuilt, the moving support's reaction): byte-identical history and events with 1 and 2
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

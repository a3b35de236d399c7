"""Suite-wide settings, applied before any test imports crackle."""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    # The suite runs in worker processes (pyproject's addopts: -n auto), one per core: each steps
    # with one numba thread and lets it sleep between parallel loops, so they never fight for a
    # core (the thread-count comparisons start their own processes with 1 and 2 threads). Set, not
    # defaulted: a worker inherits the controller's ACTIVE (below), and two workers spinning two
    # threads each on two cores made every test ~3x slower (a 1,307 s suite).
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
    import numba

    numba.set_num_threads(1)
else:
    # crackle makes numba's OpenMP threads sleep between parallel loops (OMP_WAIT_POLICY=PASSIVE,
    # src/crackle/__init__.py): robust on a shared machine, but a single process's small models
    # step ~1.5x slower that way on a machine of their own (tests/examples/test_brazilian_disc.py +
    # test_sphere_impact.py: 169 s against 118 s spinning), so it lets the threads spin; results
    # do not depend on the wait policy. test_cli.py checks crackle's own default.
    os.environ.setdefault("OMP_WAIT_POLICY", "ACTIVE")


# The slow tests (`pytest -m "not slow"` leaves them out: the inner loop of a few minutes; the full
# suite, what CI runs, keeps them): the 1-and-2-thread comparisons (two subprocesses each), the
# golden and determinism files, runs on a Dask cluster, and the runs of 25 s or more in a
# fresh-clone suite (their test names, or a name's start for a parametrised family).
SLOW_FILES = {"test_determinism.py", "test_golden.py"}
SLOW_TESTS = {
    # Dask: a local cluster per sweep or calibration
    "test_sweep_on_two_workers_equals_the_runs_one_by_one", "test_a_value_one_run_refuses_is_its_row_and_the_others_run",
    "test_calibration_recovers_the_tensile_strength_of_its_own_curve", "test_a_killed_sweep_finishes_only_its_missing_runs",
    "test_two_value_targets_of_two_scenarios", "test_calibration_to_two_values_recovers_the_modulus",
    "test_a_calibration_that_failed_exits_1_and_says_why", "test_a_misspelt_plot_scalar_exits_2_after_the_table_is_written",
    "test_ctrl_c_during_a_sweep_stops_it_in_one_line",
    # example-sized runs
    "test_peak_force_near_elastic_brazilian_relation", "test_rotated_platens_load_the_disc_as_unrotated_ones",
    "test_extrinsic_insertion_peaks_as_intrinsic", "test_quick_walnut_crush_cracks_through_the_suture",
    "test_closed_flaw_weakest_beyond_its_friction_angle", "test_open_flaw_strength_rises_with_its_inclination",
    "test_seated_platens_start_unloaded_on_a_packing_that_overlaps_them",
    "test_paper_density_packing_overlaps_and_starts_unloaded", "test_elastic_modulus_is_reproducible_across_packings",
    "test_dem_ucs_quick_breaks_the_sample", "test_platen_strain_is_the_platens_approach_when_both_move",
    "test_structured_bar_breaks_at_the_tensile_strength", "test_quick_bar_breaks_at_ft_in_both_insertion_modes",
    "test_paper_law_carries_the_face_orientation_bias", "test_quick_multipoint_crushing",
    "test_fast_impact_fragments_with_energy_balance", "test_scaled_run_keeps_the_energy_balance",
    "test_interrupted_run_resumed_is_bit_identical",
}


# Compiled once before the workers start (pytest_configure): a fresh clone's workers would each
# compile every kernel family at once (about 215 s of one core: FDEM 86 s, meshfree 66, shell 34,
# DEM 29), the same work twice. Two processes, one family list each, fill numba's cache
# instead; the workers then load it. Each a shipped example's quick form for a few steps.
PRECOMPILE = (("three-point-bending", "shell-tear"), ("plate-impact", "dem-ucs"))


def pytest_configure(config):
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", None):
        return  # a worker, or a run without workers: each kernel compiles where it is first used
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as out:
        jobs = [subprocess.Popen(
            [sys.executable, "-c", "import sys; from crackle.cli import main; sys.exit(max(main(['run', name, "
             f"'--quick', '--set', 'run.end_time=1e-5', '--out', '{out}/' + name]) for name in {list(names)!r}))"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
            for names in PRECOMPILE]
        for job in jobs:
            job.wait()  # a failure shows again, with its message, in the tests that run it


def pytest_runtest_teardown(item):
    # A test that sets numba's thread count (a sweep's run on this thread, a 1-and-2-thread
    # comparison) leaves the worker on one thread again, for the tests after it.
    if os.environ.get("PYTEST_XDIST_WORKER"):
        import numba

        numba.set_num_threads(1)


def pytest_collection_modifyitems(config, items):
    import pytest

    for item in items:
        name = item.originalname or item.name
        if "1_and_2_threads" in name or item.path.name in SLOW_FILES or name in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)

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
# suite, what CI runs, keeps them): the 1-and-2-thread comparisons (two subprocesses each, by
# their names), the golden and determinism files, and each test marked @pytest.mark.slow where it
# is defined (runs on a Dask cluster, runs of 25 s or more in a fresh-clone suite).
SLOW_FILES = {"test_determinism.py", "test_golden.py"}


# Compiled once before the workers start (pytest_configure): in a fresh clone each worker would
# compile every kernel family where it first meets it (about 215 s of one core: FDEM 86 s,
# meshfree 66, shell 34, DEM 29), most of it twice, once per worker (a fresh clone's suite on
# 2026-12-07 without this: its first FDEM test 125 s and its first meshfree one 94 s, each
# compiling). Two processes, one family list each, fill numba's cache instead; the workers then
# load it. Each runs a shipped example's quick form for a few steps.
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
        if "1_and_2_threads" in name or item.path.name in SLOW_FILES:
            item.add_marker(pytest.mark.slow)

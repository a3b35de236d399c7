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

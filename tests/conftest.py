"""Suite-wide settings, applied before any test imports crackle."""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    # The suite runs in two worker processes (pyproject's addopts: -n 2), one per core: each steps
    # with one numba thread and lets it sleep between parallel loops, so the two never fight for a
    # core (the thread-count comparisons start their own processes with 1 and 2 threads).
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import numba

    numba.set_num_threads(1)
else:
    # crackle makes numba's OpenMP threads sleep between parallel loops (OMP_WAIT_POLICY=PASSIVE,
    # src/crackle/__init__.py): robust on a shared machine, but a single process's small models
    # step ~1.5x slower that way on a machine of their own (tests/test_brazilian_disc.py +
    # test_sphere_impact.py: 169 s against 118 s spinning), so it lets the threads spin; results
    # do not depend on the wait policy. test_cli.py checks crackle's own default.
    os.environ.setdefault("OMP_WAIT_POLICY", "ACTIVE")

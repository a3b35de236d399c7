"""Suite-wide settings, applied before any test imports crackle."""

import os

# crackle makes numba's OpenMP threads sleep between parallel loops (OMP_WAIT_POLICY=PASSIVE,
# src/crackle/__init__.py): robust on a shared machine, but the suite's small models step ~1.5x
# slower that way on a machine of their own (tests/test_brazilian_disc.py + test_sphere_impact.py:
# 169 s against 118 s spinning). The suite runs on a dedicated CI machine, so it lets the threads
# spin; results do not depend on the wait policy. test_cli.py checks crackle's own default.
os.environ.setdefault("OMP_WAIT_POLICY", "ACTIVE")

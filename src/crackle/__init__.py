"""crackle: dynamic fracture of brittle solids (FDEM today; DEM and shell methods planned)."""

import os

__version__ = "0.1.0"

# numba's OpenMP threads spin between two parallel loops by default. On a machine shared with
# other work a spinning thread takes the core the working one needs: with one busy process beside
# it, a 960-tet run on 2 threads is 3x slower spinning and unchanged sleeping (measured with
# benchmarks/shared_machine.py, docs/validation.md). Sleeping costs ~0.1 ms per step on tiny models
# on an idle machine and nothing from ~20,000 tets. Set before numba loads libgomp; a user's own
# OMP_WAIT_POLICY or GOMP_SPINCOUNT wins.
if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"

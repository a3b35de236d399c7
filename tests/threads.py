"""Running one script under 1 and 2 numba threads (subprocesses: the thread count is fixed when
numba starts), for the bit-identity tests of the methods' kernels."""

from __future__ import annotations

import os
import subprocess
import sys


def outputs_with_1_and_2_threads(script: str) -> list[list[str]]:
    """The whitespace-separated words `python -c script` prints, with 1 and with 2 threads."""
    outputs = []
    # The tests' shared helpers (this folder) importable by the script, as pytest makes them for the tests.
    path = os.pathsep.join(filter(None, [os.path.dirname(os.path.abspath(__file__)), os.environ.get("PYTHONPATH")]))
    for threads in (1, 2):
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), PYTHONPATH=path)
        done = subprocess.run([sys.executable, "-c", script], env=env, check=True, capture_output=True, text=True)
        outputs.append(done.stdout.split())
    return outputs

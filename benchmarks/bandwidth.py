"""This machine's memory bandwidth, measured the way the throughput scripts compare against it.

A STREAM-style triad a = b + s c over three arrays far larger than the caches (256 MB each by
default), in a numba parallel loop with the threads the caller has set: 24 bytes moved per
element (two reads and a write; the write-allocate read the hardware may add is not counted, as
STREAM does not). The best of `repeats` runs, in bytes/s.

    python benchmarks/bandwidth.py --threads 2
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def _triad(a, b, c, s):
    for i in numba.prange(a.shape[0]):
        a[i] = b[i] + s * c[i]


def memory_bandwidth(megabytes: int = 256, repeats: int = 5) -> float:
    """Bytes/s of the triad with numba's current thread count (the best of `repeats`)."""
    n = megabytes * (1 << 20) // 8
    a, b, c = np.zeros(n), np.ones(n), np.full(n, 2.0)
    _triad(a, b, c, 3.0)  # compile, and touch every page
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        _triad(a, b, c, 3.0)
        best = min(best, time.perf_counter() - t0)
    return 24.0 * n / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--megabytes", type=int, default=256)
    args = parser.parse_args()
    if args.threads:
        numba.set_num_threads(args.threads)
    print(f"{memory_bandwidth(args.megabytes) / 1e9:.2f} GB/s triad, {numba.get_num_threads()} threads")


if __name__ == "__main__":
    main()

"""What a sweep on Dask costs beyond its runs (issue 16: a sweep of N quick runs on 2 workers within
the sum of the runs / 2 + 10 %, the scheduler's overhead per run < 1 s).

    python benchmarks/sweep_overhead.py [--runs 6] [--example three-point-bending] [--end-time T]

The same N quick runs (the example's quick form, its first tool's speed varied so that no two
are the same run) three ways: (1) a shell loop of `crackle run`, one process per run (each pays
Python's start, the imports and loading the compiled kernels from numba's cache); (2) a loop in
one warm process, 1 numba thread (the kernels loaded once, before the timing); (3) `crackle
sweep` on a local cluster of 2 workers with 1 thread each, the cluster's start included. Prints
each, sweep / (loop / 2) for both loops, and the overhead per run against the warm loop,
(sweep - warm / 2) x 2 / N: what a worker spends per run on anything but the runs (its share of
the cluster's start, the imports and kernel loading in each worker, the scheduler)."""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--example", default="three-point-bending")
    parser.add_argument("--end-time", type=float, help="s, each run's end time (default the quick form's)")
    args = parser.parse_args()

    import numba

    from crackle.api import run_scenario
    from crackle.sweep import make_plan, run_sweep
    from crackle.sweep.runner import COMPLETED

    speeds = [round(0.1 + 0.01 * i, 4) for i in range(args.runs)]
    fixed = ["run.field_frames=0"] + ([f"run.end_time={args.end_time}"] if args.end_time else [])
    work = Path(tempfile.mkdtemp(prefix="crackle-sweep-bench-"))
    try:
        numba.set_num_threads(1)
        run_scenario(args.example, work / "warm", fixed, True, progress=False)  # compile or load the kernels
        started = time.perf_counter()
        for i, speed in enumerate(speeds):
            subprocess.run(["crackle", "run", args.example, "--quick", *(f"--set={s}" for s in fixed),
                            f"--set=tools.0.speed={speed}", "--out", str(work / f"shell-{i}")],
                           check=True, capture_output=True, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
        shell = time.perf_counter() - started
        started = time.perf_counter()
        for i, speed in enumerate(speeds):
            run_scenario(args.example, work / f"alone-{i}", [*fixed, f"tools.0.speed={speed}"], True, progress=False)
        alone = time.perf_counter() - started

        plan = make_plan(args.example, ["tools.0.speed=" + ",".join(str(s) for s in speeds)], fixed, False, True)
        started = time.perf_counter()
        result = run_sweep(plan, work / "sweep", workers=2, threads_per_run=1, report=lambda text: None)
        swept = time.perf_counter() - started
        assert all(row["status"] in COMPLETED for row in result.rows), result.rows
    finally:
        shutil.rmtree(work, ignore_errors=True)
    ideal = alone / 2.0
    print(f"{args.runs} quick {args.example} runs" + (f" to t = {args.end_time:g} s" if args.end_time else ""))
    print(f"  shell loop of crackle run, 1 thread: {shell:.1f} s ({shell / args.runs:.2f} s a run)")
    print(f"  loop in one warm process, 1 thread: {alone:.1f} s ({alone / args.runs:.2f} s a run)")
    print(f"  sweep, 2 workers x 1 thread (cluster start included): {swept:.1f} s")
    print(f"  sweep / (shell loop / 2) = {swept / (shell / 2.0):.3f}; sweep / (warm loop / 2) = {swept / ideal:.3f}; "
          f"overhead per run {(swept - ideal) * 2.0 / args.runs:.2f} s")
    print(f"  peak RSS of this process {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()

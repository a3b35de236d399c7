"""What a sweep on Dask costs beyond its runs (issue 16: a sweep of N quick runs on 2 workers within
the sum of the runs / 2 + 10 %, the scheduler's overhead per run < 1 s).

    python benchmarks/sweep_overhead.py [--runs 8] [--example three-point-bending] [--end-time 2e-4]

Runs the same N quick runs (the example's quick form, its tool speed varied so no two are the
same run) one after the other in this process with 1 numba thread (each run's set-up, steps and
outputs: `sum`), then as `crackle sweep` on a local cluster of 2 workers with 1 thread each,
cluster start-up included (`sweep`). Prints both, sweep / (sum / 2), and the overhead per run,
(sweep - sum / 2) x 2 / N: what each worker spends per run on anything but the run. The numba
cache is warmed first (one run) so that neither side pays the compilation."""

from __future__ import annotations

import argparse
import resource
import shutil
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--example", default="three-point-bending")
    parser.add_argument("--end-time", type=float, default=2e-4, help="s, each run's end time")
    args = parser.parse_args()

    import numba

    from crackle.api import run_scenario
    from crackle.sweep import make_plan, run_sweep

    speeds = [round(0.1 + 0.01 * i, 4) for i in range(args.runs)]
    fixed = [f"run.end_time={args.end_time}", "run.field_frames=0"]
    work = Path(tempfile.mkdtemp(prefix="crackle-sweep-bench-"))
    try:
        numba.set_num_threads(1)
        run_scenario(args.example, work / "warm", fixed, True, progress=False)  # compile or load the kernels
        started = time.perf_counter()
        for i, speed in enumerate(speeds):
            run_scenario(args.example, work / f"alone-{i}", [*fixed, f"tools.0.speed={speed}"], True, progress=False)
        alone = time.perf_counter() - started

        plan = make_plan(args.example, ["tools.0.speed=" + ",".join(str(s) for s in speeds)], fixed, False, True)
        started = time.perf_counter()
        result = run_sweep(plan, work / "sweep", workers=2, threads_per_run=1, report=lambda text: None)
        swept = time.perf_counter() - started
        assert all(row["status"] in ("completed", "stopped") for row in result.rows), result.rows
    finally:
        shutil.rmtree(work, ignore_errors=True)
    ideal = alone / 2.0
    print(f"{args.runs} quick {args.example} runs to t = {args.end_time:g} s")
    print(f"  one by one, 1 thread: {alone:.1f} s ({alone / args.runs:.2f} s a run)")
    print(f"  sweep, 2 workers x 1 thread (cluster start included): {swept:.1f} s")
    print(f"  sweep / (sum / 2) = {swept / ideal:.3f}; overhead per run {(swept - ideal) * 2.0 / args.runs:.2f} s")
    print(f"  peak RSS of this process {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()

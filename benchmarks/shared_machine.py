"""FDEM throughput on a shared machine: numba threading layer and OpenMP wait policy.

numba's parallel loops hand work to a pool of threads; between two parallel loops an OpenMP
thread spins (by default) waiting for the next one. On a machine where another process holds a
core, a spinning thread steals the time slice the thread doing the work needs, and a 2-thread run
can become many times slower than a 1-thread run. This script measures, for each configuration
(threading layer, OMP_WAIT_POLICY), the step time of benchmarks/fdem_throughput.py alone and with
one busy process per `--competitors` running beside it.

Output: one line per configuration and condition (ms per step, M tet-steps/s), then LAST one JSON
object on one line: {"tets": ..., "results": [{"config": ..., "competitors": ..., "seconds_per_step": ...}, ...]}.

    python benchmarks/shared_machine.py --tets 20000 --threads 2
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).parent
CONFIGS = {
    # libgomp's own default (OMP_WAIT_POLICY unset: spin 300,000 times, then sleep)
    "omp, GOMP_SPINCOUNT=300000": {"NUMBA_THREADING_LAYER": "omp", "OMP_WAIT_POLICY": None, "GOMP_SPINCOUNT": "300000"},
    "omp, OMP_WAIT_POLICY=PASSIVE": {"NUMBA_THREADING_LAYER": "omp", "OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": None},
    "workqueue": {"NUMBA_THREADING_LAYER": "workqueue", "OMP_WAIT_POLICY": None, "GOMP_SPINCOUNT": None},
}
BUSY = "while True: pass"


def measure(env_changes: dict, tets: int, threads: int, seconds: float) -> float:
    env = dict(os.environ)
    for key, value in env_changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    proc = subprocess.run(
        [sys.executable, str(HERE / "fdem_throughput.py"), "--sizes", str(tets), "--threads", str(threads),
         "--seconds", str(seconds), "--repeats", "3", "--in-process"],
        env=env, capture_output=True, text=True, check=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])["sizes"][0]["seconds_per_step"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tets", type=int, default=20000)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--competitors", type=int, nargs="+", default=[0, 1], help="busy processes beside the run")
    p.add_argument("--seconds", type=float, default=2.0, help="timed seconds per repeat")
    args = p.parse_args(argv)
    results = []
    for name, env_changes in CONFIGS.items():
        for n_busy in args.competitors:
            busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(n_busy)]
            try:
                seconds = measure(env_changes, args.tets, args.threads, args.seconds)
            finally:
                for proc in busy:
                    proc.kill()
            results.append({"config": name, "competitors": n_busy, "seconds_per_step": seconds})
            print(f"{name:40s} competitors {n_busy}: {seconds * 1e3:8.2f} ms/step, "
                  f"{args.tets / seconds / 1e6:6.2f} M tet-steps/s", flush=True)
    print(json.dumps({"tets": args.tets, "threads": args.threads, "results": results}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

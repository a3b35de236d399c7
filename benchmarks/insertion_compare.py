"""Intrinsic against extrinsic interfaces on the paper examples: time to solution and results.

Runs each example (quick form by default) twice, `material.interface.insertion` = "intrinsic"
and "extrinsic" (the Guo-Munjiza default penalty of each: 200 and 2 E / h), and prints per run
the stable step and what sets it, the steps, the wall time of the run (set-up and outputs
included), the peak tool force, the failed faces, the energy error and the example's own
result (plastic zone, split angle). The last line is one JSON object with every row.

    python benchmarks/insertion_compare.py                       # quick forms
    python benchmarks/insertion_compare.py --examples single-fracture --full
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

EXAMPLES = ("single-fracture", "three-point-bending", "brazilian-disc")


def _splitting_angle(out: Path):
    """Angle (degrees) between the Brazilian disc's splitting fracture and the loading axis."""
    from crackle.analysis.brazilian import loading_direction, splitting_angle
    from crackle.io import read_events_csv

    return splitting_angle(read_events_csv(out / "events.csv"), loading_direction(0.0), radius=0.02)[0]


# The example's own result: a key of summary.json, or a function of the output folder.
RESULTS = {"single-fracture": "plastic_zone_length", "three-point-bending": "fragments",
           "brazilian-disc": _splitting_angle}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--examples", nargs="+", default=list(EXAMPLES))
    p.add_argument("--full", action="store_true", help="the full examples, not their quick forms")
    p.add_argument("--set", action="append", default=[], help="extra overrides for every run")
    args = p.parse_args(argv)

    from crackle.api import run_scenario

    rows = []
    print(f"{'example':22s} {'insertion':10s} {'dt (ns)':>9s} {'set by':18s} {'steps':>8s} {'wall (s)':>9s} "
          f"{'peak (N)':>10s} {'failed':>7s} {'energy err':>10s}  result")
    for example in args.examples:
        for insertion in ("intrinsic", "extrinsic"):
            with tempfile.TemporaryDirectory() as tmp:
                overrides = [f"material.interface.insertion={insertion}", "run.field_frames=0", *args.set]
                start = time.perf_counter()
                out = Path(tmp) / "out"
                result = run_scenario(example, out, overrides=overrides, quick=not args.full, progress=False)
                wall = time.perf_counter() - start
                s = result.summary
                key = RESULTS.get(example)
                value = key(out) if callable(key) else s.get(key)
                key = getattr(key, "__name__", key).lstrip("_")
            row = {
                "example": example, "insertion": insertion, "dt": s["dt"], "dt_limit": s["dt_limit"]["kind"],
                "steps": s["steps"], "wall_s": wall, "peak_force": s.get("peak_force"), "broken": s["broken"],
                "energy_error": s["energy_error"], "result": key, "value": value,
            }
            rows.append(row)
            print(f"{example:22s} {insertion:10s} {row['dt'] * 1e9:9.3g} {row['dt_limit']:18s} {row['steps']:8d} "
                  f"{wall:9.1f} {row['peak_force'] or 0:10.4g} {row['broken']:7d} {row['energy_error']:10.2e}  "
                  f"{key} = {row['value']}", flush=True)
    print(json.dumps({"rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

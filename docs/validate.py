"""Regenerate the numbers in docs/validation.md that come from the shipped examples' quick forms.

Each such number sits between two markers in the Markdown (invisible when rendered):

    <!--q:CASE:VALUE:FORMAT-->4450<!--/q-->

CASE names a run in CASES below (its `crackle run` arguments, exactly what the table's command
column says), VALUE a number of that run: a summary.json key, dotted into dicts and lists
(`peak_forces.top`, `largest_fragment_velocity.2`), optionally scaled (`plastic_zone_length*1e3`
for mm), or one of DERIVED; FORMAT is a Python format spec (`,.0f`, `.2%`), optionally followed
by `|` and a suffix written after the number (` deg`); a missing value (none, nan) reads "none".

    python docs/validate.py --quick              # run every case, rewrite the numbers
    python docs/validate.py --quick --check      # run, report what differs, exit 1 if anything does
    python docs/validate.py --quick --cases 3pb brazilian-0

About 20 minutes on 2 cores (33 runs). Rows that need the full examples or longer runs carry no
markers: their commands and wall times are stated beside them.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

DOC = Path(__file__).with_name("validation.md")
MARKER = re.compile(r"<!--q:(?P<case>[\w.-]+):(?P<value>[\w.*-]+):(?P<format>[^>]*?)-->(?P<text>.*?)<!--/q-->")

MULTIPOINT = ["walnut-multipoint", "--quick"]
CASES = {
    "single-fracture": ["single-fracture", "--quick"],
    "3pb": ["three-point-bending", "--quick"],
    "sphere-slow": ["sphere-impact-slow", "--quick"],
    "sphere-fast": ["sphere-impact-fast", "--quick"],
    "brazilian-0": ["brazilian-disc", "--quick"],
    "brazilian-30": ["brazilian-disc", "--quick", "--set", "loading.angle=30"],
    "brazilian-60": ["brazilian-disc", "--quick", "--set", "loading.angle=60"],
    "brazilian-90": ["brazilian-disc", "--quick", "--set", "loading.angle=90"],
    "brazilian-0-half-speed": ["brazilian-disc", "--quick", "--set", "tools.0.speed=0.025", "--set", "tools.1.speed=0.025",
                               "--set", "run.end_time=3e-3"],
    "walnut-crush": ["walnut-crush", "--quick"],
    "multipoint-2": [*MULTIPOINT, "--set", "plates.polar=[90,90]", "--set", "plates.azimuth=[0,180]"],
    "multipoint-3": [*MULTIPOINT, "--set", "plates.polar=[90,90,90]", "--set", "plates.azimuth=[0,120,240]"],
    "multipoint-4": MULTIPOINT,
    "multipoint-tetrahedron": [*MULTIPOINT, "--set", "plates.polar=[0,109.47,109.47,109.47]",
                               "--set", "plates.azimuth=[0,0,120,240]"],
    "multipoint-5": [*MULTIPOINT, "--set", "plates.polar=[90,90,90,90,90]", "--set", "plates.azimuth=[0,72,144,216,288]"],
    "multipoint-6": [*MULTIPOINT, "--set", "plates.polar=[90,90,90,90,90,90]",
                     "--set", "plates.azimuth=[0,60,120,180,240,300]"],
    "dem-ucs": ["dem-ucs", "--quick"],
    "dem-brazilian": ["dem-brazilian", "--quick"],
    "dem-tension": ["dem-tension", "--quick"],
    "dem-triaxial": ["dem-triaxial", "--quick"],
    **{f"dem-damping-{a}": ["dem-ucs", "--quick", "--set", f"material.local_damping={a}"] for a in ("0.1", "0.4", "0.8")},
    **{f"dem-damping-{a}-slow": ["dem-ucs", "--quick", "--set", f"material.local_damping={a}", "--set", "tools.0.speed=0.025",
                                 "--set", "run.end_time=8e-3"] for a in ("0.1", "0.2", "0.4", "0.8")},
    **{f"dem-flaw-{a}": ["dem-flaw", "--quick", "--set", f"flaw.angle={a}"] for a in (0, 30, 60, 90)},
    **{f"dem-closed-{a}": ["dem-flaw", "--quick", "--set", "flaw.kind=closed", "--set", f"flaw.angle={a}"]
       for a in (0, 30, 60, 90)},
}

# Brazilian disc (paper 001 section 4): F = ft pi D t / 2 for ft = 3 MPa, D = 40 mm, t = 15 mm.
ELASTIC_BRAZILIAN_PEAK = 3e6 * math.pi * 0.04 * 0.015 / 2


def _splitting_angle(run) -> float:
    from crackle.analysis.brazilian import loading_direction, splitting_angle

    angle = next((float(a.split("=")[1]) for a in run["args"] if a.startswith("loading.angle=")), 0.0)
    value, _ = splitting_angle(run["events"], loading_direction(angle), radius=0.02)
    return value


def _failure_time(which):
    def value(run) -> float:
        t = run["events"]["time"]
        return float(which(t)) * 1e6 if len(t) else math.nan  # us
    return value


def _platen_modulus(run) -> float:
    """GPa: the slope of platen stress against platen strain over 0.02-0.04 % (DEM)."""
    h = run["history"]
    stress, strain = h["platenstress"], h["platenstrain"]
    window = (strain > 2e-4) & (strain < 4e-4)
    return float(np.polyfit(strain[window], stress[window], 1)[0]) * 1e-9


DERIVED = {
    "peak_over_elastic": lambda run: run["summary"]["peak_force"] / ELASTIC_BRAZILIAN_PEAK,
    "splitting_angle": _splitting_angle,
    "first_failure_us": _failure_time(min),
    "last_failure_us": _failure_time(max),
    "platen_modulus_gpa": _platen_modulus,
}


def value_of(run, path: str):
    """A number of a run: a derived value or a dotted summary path, times an optional scale."""
    path, _, scale = path.partition("*")
    if path in DERIVED:
        value = DERIVED[path](run)
    else:
        value = run["summary"]
        for part in path.split("."):
            value = value[int(part)] if isinstance(value, list) else value[part]
    return value * float(scale) if scale else value


def run_case(name: str, out_root: Path) -> dict:
    from crackle.api import run_scenario
    from crackle.io import read_events_csv

    args = CASES[name]
    source, quick, overrides = args[0], "--quick" in args, [a for i, a in enumerate(args) if i and args[i - 1] == "--set"]
    result = run_scenario(source, out_root / name, overrides=overrides, quick=quick, progress=False)
    print(f"  {name}: {result.summary['status']}, {result.summary['wall_time']:.0f} s", flush=True)
    history = np.genfromtxt(result.out_dir / "history.csv", delimiter=",", names=True)
    return {"args": overrides, "summary": result.summary, "events": read_events_csv(result.out_dir / "events.csv"),
            "history": history}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", required=True, help="the quick-form rows (the only ones generated)")
    p.add_argument("--check", action="store_true", help="report differences, do not write")
    p.add_argument("--cases", nargs="+", choices=sorted(CASES), help="only these runs (default: every case the document uses)")
    args = p.parse_args(argv)

    text = DOC.read_text(encoding="utf-8")
    used = sorted({m["case"] for m in MARKER.finditer(text)})
    unknown = [c for c in used if c not in CASES]
    if unknown:
        print(f"validate.py: {DOC.name} names unknown cases {unknown}", file=sys.stderr)
        return 2
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases or used:
            runs[name] = run_case(name, Path(tmp))

    changes = []

    def rewrite(m):
        if m["case"] not in runs:
            return m[0]
        value = value_of(runs[m["case"]], m["value"])
        spec, _, suffix = m["format"].partition("|")
        missing = value is None or (isinstance(value, float) and math.isnan(value))
        new = "none" if missing else format(value, spec) + suffix
        if new != m["text"]:
            changes.append(f"{m['case']}:{m['value']}: {m['text']} -> {new}")
        return f"<!--q:{m['case']}:{m['value']}:{m['format']}-->{new}<!--/q-->"

    updated = MARKER.sub(rewrite, text)
    print("\n".join(changes) or "every generated number matches")
    if args.check:
        return 1 if changes else 0
    DOC.write_text(updated, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Hashes of the shipped examples' histories: the byte-identity check of a refactor.

    python tests/golden/quick_examples.py            # run, compare with quick_examples.json
    python tests/golden/quick_examples.py --short    # only the short forms (what the suite runs)
    python tests/golden/quick_examples.py --update   # run and store (after an intended change)

Each case runs one example's quick form (the "full" table) or a short form of it (fewer steps,
the "short" table) in a fresh output folder, and hashes history.csv and events.csv. Bit-identity
holds on one machine with one numpy/numba build: the store keeps one set of hashes per platform
(`platform_key`); on a platform without its set the comparison is skipped (store one with
--update there first, on the code before the change).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
STORE = HERE / "quick_examples.json"

# Short forms: the first part of each quick run, with failures where that is cheap.
SHORT = {
    "three-point-bending": ["run.end_time=6e-4", "run.history_samples=100"],
    "single-fracture": [],
    "brazilian-disc": ["run.end_time=3e-4", "run.history_samples=60"],
    "sphere-impact-slow": ["run.end_time=2e-5", "run.history_samples=40"],
    "sphere-impact-fast": ["run.end_time=2e-5", "run.history_samples=40"],
    "walnut-crush": ["run.end_time=4e-4", "run.history_samples=60"],
    "walnut-multipoint": ["run.end_time=4e-4", "run.history_samples=60"],
}


def short_overrides(name: str) -> list[str]:
    """The --set overrides of an example's short form (no field output)."""
    return SHORT[name] + ["run.field_frames=0"]


def platform_key() -> str:
    import numba
    import numpy

    from crackle.validation.runner import cpu_model

    cpu = cpu_model()
    # The model name alone ("AMD EPYC") hides the generation, and numba compiles for the host's
    # (e.g. znver3 against znver4 with AVX-512): results differ in the last bits.
    from llvmlite.binding import get_host_cpu_name

    return (f"{cpu} ({get_host_cpu_name()}) | numpy {numpy.__version__} | numba {numba.__version__} | "
            f"{platform.machine()}")


def run_case(name: str, overrides: list[str]) -> dict:
    from crackle.api import run_scenario

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / name
        run_scenario(name, out, overrides=overrides, quick=True)
        return {f: hashlib.sha256((out / f).read_bytes()).hexdigest()[:16] for f in ("history.csv", "events.csv")}


def cases(short_only: bool):
    for name in SHORT:
        if not short_only:
            yield "full", name, []
        yield "short", name, short_overrides(name)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--short", action="store_true", help="only the short forms")
    p.add_argument("--update", action="store_true", help="store the hashes instead of comparing")
    args = p.parse_args(argv)
    here = platform_key()
    store = read_store()
    if here not in store and not args.update:
        print(f"no hashes stored for '{here}' (only for {', '.join(repr(k) for k in store) or 'none'}): nothing to compare")
        return 0
    stored = store.setdefault(here, {"full": {}, "short": {}})
    failed = 0
    for table, name, overrides in cases(args.short):
        start = time.perf_counter()
        got = run_case(name, overrides)
        wall = time.perf_counter() - start
        if args.update:
            stored[table][name] = got
            print(f"{table:5s} {name:22s} {wall:6.1f} s  stored")
            continue
        ok = stored[table].get(name) == got
        failed += not ok
        print(f"{table:5s} {name:22s} {wall:6.1f} s  {'same' if ok else 'DIFFERENT'}")
    if args.update:
        STORE.write_text(json.dumps({"platforms": store}, indent=1) + "\n")
    return 1 if failed else 0


def read_store() -> dict:
    """{platform: {"full": {example: hashes}, "short": {...}}}; an older store of one platform
    ({"platform": ..., "full": ..., "short": ...}) is read as such."""
    if not STORE.exists():
        return {}
    data = json.loads(STORE.read_text())
    if "platforms" in data:
        return data["platforms"]
    return {data["platform"]: {"full": data["full"], "short": data["short"]}}


if __name__ == "__main__":
    sys.exit(main())

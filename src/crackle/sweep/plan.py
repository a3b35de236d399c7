"""What a sweep runs: the scenario, the fixed and the varied overrides, and one folder per run.

A sweep is given on the command line (`--vary key=v1,v2 --set key=v`) or in a sweep file, a
TOML file with a [sweep] table (shipped ones by name: `crackle sweep brazilian-angles`):

    [sweep]
    scenario = "brazilian-disc"        # a shipped example or a file (relative to this file)
    zip = false                        # true: the i-th values of every key together
    [sweep.set]                        # overrides every run gets
    "run.end_time" = 2e-3
    [sweep.vary]                       # the values each key takes
    "loading.angle" = [0, 30, 60, 90]

`seeds = N` in [sweep] (or `--seeds N`) varies run.seed over 0 .. N-1 as well (every combination
of the other keys N times, with random material properties drawn anew): the table then gets the
mean and standard deviation of every summary scalar over the seeds (sweep_seeds.csv).
"""

from __future__ import annotations

import itertools
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from ..scenario import ScenarioError, split_override

# The key a sweep over seeds varies: the seed of every random draw of a run ([run] seed).
SEED_KEY = "run.seed"


@dataclass
class SweepPlan:
    scenario: str  # a shipped example's name or an absolute path to a scenario file
    vary: dict[str, list[Any]]  # key -> its values, in the order given
    zip: bool = False
    fixed: dict[str, Any] = field(default_factory=dict)  # overrides every run gets
    quick: bool = False

    def runs(self) -> list["SweepRun"]:
        """One run per combination (the cartesian product, the last key varying fastest) or per
        position (zip)."""
        keys = list(self.vary)
        if self.zip:
            # Seeds (SEED_KEY, last) repeat every zipped position.
            zipped = [k for k in keys if k != SEED_KEY]
            seeds = [(v,) for v in self.vary[SEED_KEY]] if SEED_KEY in self.vary else [()]
            combos = [position + seed for position in zip(*(self.vary[k] for k in zipped)) for seed in seeds]
        else:
            combos = list(itertools.product(*self.vary.values()))
        return [SweepRun(i, dict(zip(keys, values))) for i, values in enumerate(combos)]

    def as_record(self) -> dict:
        """What sweep.json keeps, to tell whether a rerun into the same folder is the same sweep."""
        return {"scenario": self.scenario, "vary": self.vary, "zip": self.zip, "set": self.fixed, "quick": self.quick}


@dataclass
class SweepRun:
    index: int
    varied: dict[str, Any]  # this run's value of each varied key

    @property
    def folder(self) -> str:
        """`003_angle=30`: the index, then each varied key's last part and its value, in
        characters any file system takes."""
        parts = [f"{key.split('.')[-1]}={_plain(value)}" for key, value in self.varied.items()]
        name = re.sub(r"[^A-Za-z0-9._=+-]", "_", "_".join(parts))[:80]
        return f"{self.index:03d}_{name}"


def _plain(value) -> str:
    if isinstance(value, list):
        return "-".join(_plain(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def parse_vary(texts: list[str]) -> dict[str, list[Any]]:
    """`key=v1,v2,...` items into key -> values; each value is read as TOML (`30`, `"text"`,
    `[90, 90]`), a bare word as a string. Commas inside brackets or quotes do not split."""
    vary: dict[str, list[Any]] = {}
    for text in texts:
        if "=" not in text:
            raise ScenarioError(f"--vary {text!r}: write key=v1,v2,..., e.g. --vary loading.angle=0,30,60,90")
        key, raw = text.split("=", 1)
        key = key.strip()
        values = [split_override(f"{key}={item}")[1] for item in _top_level_items(raw)]
        if not key or not values:
            raise ScenarioError(f"--vary {text!r}: give a key and at least one value, e.g. --vary loading.angle=0,30")
        if key in vary:
            raise ScenarioError(f"--vary {key}: given twice; list all its values in one --vary")
        vary[key] = values
    return vary


def _top_level_items(raw: str) -> list[str]:
    items, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(raw):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            items.append(raw[start:i])
            start = i + 1
    items.append(raw[start:])
    return [item.strip() for item in items if item.strip()]


def sweeps_dir():
    return resources.files("crackle") / "examples" / "sweeps"


def list_sweeps() -> dict[str, str]:
    """Shipped sweep names and the first line of their description."""
    out = {}
    for entry in sorted(sweeps_dir().iterdir(), key=lambda p: p.name):
        if entry.name.endswith(".toml"):
            text = tomllib.loads(entry.read_text()).get("description", "").strip()
            out[entry.name[:-5]] = text.splitlines()[0] if text else ""
    return out


def is_sweep_file(source: str) -> bool:
    """A shipped sweep's name, or a TOML file with a [sweep] table."""
    if (sweeps_dir() / f"{source}.toml").is_file():
        return True
    path = Path(source)
    if path.suffix != ".toml" or not path.is_file():
        return False
    try:
        return "sweep" in tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except tomllib.TOMLDecodeError:
        return False


def read_sweep_file(source: str) -> tuple[str, dict[str, list[Any]], bool, dict[str, Any], int | None]:
    """(scenario, vary, zip, fixed overrides, seeds) of a sweep file or shipped sweep."""
    shipped = sweeps_dir() / f"{source}.toml"
    path, base = (shipped, None) if shipped.is_file() else (Path(source), Path(source).resolve().parent)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"{source}: broken TOML ({err}); fix the syntax at that line") from None
    sweep = data.get("sweep")
    if not isinstance(sweep, dict):
        raise ScenarioError(f"{source}: no [sweep] table; a sweep file names its scenario and [sweep.vary]")
    unknown = sorted(set(sweep) - {"scenario", "vary", "zip", "set", "seeds"})
    if unknown:
        raise ScenarioError(f"{source}: sweep.{unknown[0]}: not a sweep field (scenario, vary, zip, set, seeds)")
    seeds = sweep.get("seeds")
    if seeds is not None and (not isinstance(seeds, int) or isinstance(seeds, bool) or seeds < 1):
        raise ScenarioError(f"{source}: sweep.seeds: give the number of seeds, an integer >= 1 (e.g. 10)")
    scenario = sweep.get("scenario")
    if not isinstance(scenario, str):
        raise ScenarioError(f"{source}: sweep.scenario: give a shipped example's name or a scenario file")
    if base is not None and scenario.endswith(".toml") and not Path(scenario).is_absolute():
        scenario = str(base / scenario)
    vary = sweep.get("vary", {} if seeds else None)
    if not isinstance(vary, dict) or not (vary or seeds):
        raise ScenarioError(f"{source}: sweep.vary: give at least one key and its values, e.g. \"loading.angle\" = [0, 30]")
    for key, values in vary.items():
        if not isinstance(values, list):
            raise ScenarioError(f"{source}: sweep.vary.{key}: give a list of values, e.g. [0, 30]")
    return scenario, dict(vary), bool(sweep.get("zip", False)), dict(sweep.get("set", {})), seeds


def make_plan(source: str, vary_texts: list[str], set_texts: list[str], zip_: bool, quick: bool,
              seeds: int | None = None) -> SweepPlan:
    """The plan from a scenario (with --vary) or a sweep file (its own vary, to which --vary
    adds); `seeds` (or the file's): run.seed over 0 .. seeds-1 as well; every mistake a
    ScenarioError naming the field."""
    if is_sweep_file(source):
        scenario, vary, file_zip, fixed, file_seeds = read_sweep_file(source)
        zip_ = zip_ or file_zip
        seeds = seeds or file_seeds
    else:
        scenario, vary, fixed = source, {}, {}
    for key, values in parse_vary(vary_texts).items():
        vary[key] = values
    fixed.update(split_override(text) for text in set_texts)
    if seeds:
        if SEED_KEY in vary or SEED_KEY in fixed:
            raise ScenarioError(f"{SEED_KEY}: --seeds varies it; drop its --vary or --set")
        vary[SEED_KEY] = list(range(seeds))
    if not vary:
        raise ScenarioError("nothing to vary: give --vary key=v1,v2,... or --seeds N (or a sweep file with [sweep.vary])")
    for key, values in vary.items():
        if not values:
            raise ScenarioError(f"--vary {key}: the list of values is empty; give at least one")
        if key in fixed:
            raise ScenarioError(f"{key}: both varied and set; drop one")
    if zip_:
        lengths = {key: len(values) for key, values in vary.items() if key != SEED_KEY}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{k} ({n})" for k, n in lengths.items())
            raise ScenarioError(f"--zip: every varied key needs as many values; got {listed}")
    return SweepPlan(absolute_source(scenario), vary, zip_, fixed, quick)


def absolute_source(scenario: str) -> str:
    """A scenario file as an absolute path (the workers may run in another folder); an example's
    name as it is."""
    path = Path(scenario)
    return str(path.resolve()) if path.suffix == ".toml" or path.exists() else scenario

"""Reading a scenario: a TOML file or a shipped example, `--set` overrides and `--quick`, validated
against its method's schema (`load_scenario`)."""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..schema import ScenarioError, resolve_path
from .messages import _describe, _refuse_nan, _refuse_without_method
from .sections import ScenarioBase


def examples_dir():
    return resources.files("crackle") / "examples"


# The end of a description's first sentence: a full stop before a space or the end, not one of
# an abbreviation ("Fig. 1a", "e.g. a plate").
_SENTENCE_END = re.compile(r"(?<!\bFig)(?<!\bFigs)(?<!\be\.g)(?<!\bi\.e)(?<!\beq)(?<!\bEq)\.(?=\s|$)")


def list_examples() -> dict[str, str]:
    """Shipped example names and the first sentence of their descriptions (whole, on one line)."""
    out = {}
    for entry in sorted(examples_dir().iterdir(), key=lambda p: p.name):
        if entry.name.endswith(".toml"):
            text = " ".join(tomllib.loads(entry.read_text()).get("description", "").split())
            end = _SENTENCE_END.search(text)
            out[entry.name[:-5]] = text[: end.end()] if end else text
    return out


def read_scenario_data(source: str | Path) -> tuple[dict, Path | None]:
    """Raw TOML data of a file path or shipped example name, and the folder relative paths use."""
    path = Path(source)
    if path.is_dir():
        inside = sorted(p.name for p in path.glob("*.toml"))
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise ScenarioError(f"{path} is a folder{hint}: give a .toml scenario file or a shipped example name")
    if path.suffix == ".toml" or path.exists():
        if not path.exists():
            raise ScenarioError(f"scenario file {path} does not exist; check the path or run 'crackle examples'")
        try:
            # utf-8-sig: a byte-order mark (some Windows editors write one) is not TOML.
            text, base = path.read_text(encoding="utf-8-sig"), path.parent
        except UnicodeDecodeError as err:
            raise ScenarioError(f"{path}: not UTF-8 text ({err.reason} at byte {err.start}); save it as UTF-8") from None
    else:
        entry = examples_dir() / f"{source}.toml"
        if not entry.is_file():
            known = ", ".join(list_examples())
            raise ScenarioError(f"'{source}' is neither a scenario file nor a shipped example (examples: {known})")
        text, base = entry.read_text(), None
    try:
        return tomllib.loads(text), base
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"{source}: broken TOML ({err}); fix the syntax at that line") from None


def apply_overrides(data: dict, overrides: dict[str, Any] | list[str]) -> dict:
    """Set dotted keys (`run.end_time`, `tools.0.speed`) in a copy of the raw data.

    String overrides `key=value` parse their value as a TOML value (`1e-3`, `"text"`, `[1, 2]`);
    a bare word that is not TOML is taken as a string.
    """
    import copy

    data = copy.deepcopy(data)
    items = overrides.items() if isinstance(overrides, dict) else (split_override(s) for s in overrides)
    for key, value in items:
        parts = key.split(".")
        node = data
        for k, part in enumerate(parts[:-1]):
            if isinstance(node, list):
                node = node[_index(part, key, node)]
            elif isinstance(node, dict):
                node = node.setdefault(part, {})
            else:
                raise ScenarioError(f"--set {key}: '{'.'.join(parts[:k])}' is a value ({node!r}), not a table; set it directly")
        last = parts[-1]
        if isinstance(node, list):
            node[_index(last, key, node)] = value
        elif isinstance(node, dict):
            node[last] = value
        else:
            raise ScenarioError(f"--set {key}: '{'.'.join(parts[:-1])}' is a value ({node!r}), not a table; set it directly")
    return data


def split_override(text: str) -> tuple[str, Any]:
    if "=" not in text:
        raise ScenarioError(f"--set {text!r}: write key=value, e.g. --set run.end_time=1e-3")
    key, raw = text.split("=", 1)
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.strip(), value


def _index(part: str, key: str, items: list) -> int:
    """The position of `part` in a list of tables: its number, or the `name` of one of them."""
    if part.isdigit() and int(part) < len(items):
        return int(part)
    names = [item.get("name") if isinstance(item, dict) else None for item in items]
    if part in names:
        return names.index(part)
    listed = ", ".join(f"{i} ({n})" if n else str(i) for i, n in enumerate(names)) or "none"
    raise ScenarioError(f"--set {key}: '{part}' is neither the number nor the name of an entry; entries: {listed}")


def load_scenario(source: str | Path, overrides: list[str] | None = None, quick: bool = False) -> tuple[ScenarioBase, Path | None]:
    """Read, override and validate a scenario against its method's schema; raises ScenarioError
    with one clear message."""
    from ..methods import get_method

    data, base = read_scenario_data(source)
    written_method = data.get("method", "fdem")
    if quick:
        if not data.get("quick"):
            raise ScenarioError(f"--quick: {source} has no [quick] section; run it without --quick or add one")
        data = apply_overrides(data, data.get("quick", {}))
    if overrides:
        data = apply_overrides(data, overrides)
    try:
        schema = get_method(data.get("method", "fdem")).Scenario
    except KeyError as err:
        raise ScenarioError(f"{source}: method: {err.args[0]}") from None
    _refuse_nan(data, source)
    try:
        scenario = schema.model_validate(data)
    except ValidationError as err:
        if "method" not in data:
            _refuse_without_method(data, source)
        switched = data.get("method", "fdem") != written_method
        raise ScenarioError(_describe(err, source, schema) + (
            f". The scenario is written for method = \"{written_method}\", whose sections the {data.get('method')!r} "
            "method does not read: a method is chosen by a scenario written for it (crackle examples lists one of "
            "each), not by --set method" if switched else "")) from None
    for i, tool in enumerate(scenario.tools):
        if tool.shape == "surface":
            path = resolve_path(tool.file, base)
            if not path.is_file():
                raise ScenarioError(
                    f"{source}: tools.{i}.file: surface file {path} does not exist; give a path "
                    "relative to the scenario file's folder, or an absolute one"
                )
    return scenario, base


def no_such_file(key: str, path: Path) -> ScenarioError:
    """The error for a scenario's file (`key`, resolved to `path`) that is missing or a folder."""
    what = "is a folder, not a file" if path.is_dir() else "does not exist"
    return ScenarioError(f"{key}: {path.absolute()} {what}; check the path (a relative path is taken from the scenario "
                         "file's folder, or from the working folder for a shipped example)")

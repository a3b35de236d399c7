"""The scenario key reference (every key, its unit, default and range), generated from the
schemas: each method's pydantic Scenario, whose field docstrings give the unit and meaning.

`crackle keys [METHOD]` prints it; docs/keys.md is its output for every method (a test keeps it
current).
"""

from __future__ import annotations

import math

from .schema import schema_fields, section_schemas

# The units a field's description starts with (its first word), as the schemas write them.
UNITS = {"m", "s", "Pa", "N", "J", "K", "kg", "m/s", "rad/s", "1/s", "degrees", "J/m^2", "kg/m^3", "Pa/m", "N/m^3",
         "m^2", "m^3", "bytes", "Hz"}

HEADER = "| key | type | default | range | unit and meaning |\n|---|---|---|---|---|"
DOC_INTRO = """# Scenario keys

Generated from the scenario schemas by `crackle keys` (do not edit: a test compares this file with
its output). Sections in bold; `tools[].speed` is a key of each `[[tools]]` entry; a blank
default is a key left unset (its meaning says what then applies). Units are SI.
"""


def reference_document() -> str:
    """docs/keys.md: the introduction and every method's table."""
    from .methods import METHODS

    return DOC_INTRO + "".join("\n" + key_reference(name) for name in METHODS)


def key_reference(method: str) -> str:
    """Markdown: one table row per scenario key of `method`, sections as dotted prefixes
    (`tools[].speed` for a key of each [[tools]] entry)."""
    from .methods import get_method

    scenario = get_method(method).Scenario
    schema = scenario.model_json_schema(mode="validation")
    defs = schema.get("$defs", {})
    lines = [f"## method = \"{method}\"", "", HEADER]
    skip = set(scenario.unread_keys())
    lines += _rows(schema, defs, "", skip=skip)
    return "\n".join(lines) + "\n"


def _resolve(prop: dict, defs: dict) -> dict:
    """The schema a property stands for: through $ref, and `X | None` (anyOf with null)."""
    if "$ref" in prop:
        return {**defs[prop["$ref"].split("/")[-1]], **{k: v for k, v in prop.items() if k != "$ref"}}
    options = [p for p in prop.get("anyOf", []) if p.get("type") != "null"]
    if len(options) == 1:
        return {**_resolve(options[0], defs), **{k: v for k, v in prop.items() if k != "anyOf"}}
    return prop


def _rows(schema: dict, defs: dict, prefix: str, skip: set[str] = frozenset()) -> list[str]:
    """The table rows of a schema's keys, less those in `skip` (the keys the method does not read)."""
    rows = []
    required = set(schema.get("required", []))
    for name, raw in schema.get("properties", {}).items():
        prop = _resolve(raw, defs)
        key = prefix + name
        if key in skip:
            continue
        meaning = " ".join((raw.get("description") or prop.get("description") or "").split())
        if "properties" in prop:  # a section
            rows.append(f"| **{key}** | section | | | {meaning} |")
            rows += _rows(prop, defs, key + ".", skip)
        elif prop.get("type") == "array" and "properties" in _resolve(prop.get("items", {}), defs):
            rows.append(f"| **{key}** | list of sections | | | {meaning} |")
            rows += _rows(_resolve(prop["items"], defs), defs, key + "[].", skip)
        elif prop.get("type") == "object" and _is_section(prop.get("additionalProperties"), defs):
            # A table of sections by the user's names ([materials.NAME]): one NAME's keys.
            rows.append(f"| **{key}** | table of sections by name | | | {meaning} |")
            rows += _rows({"properties": {"NAME": prop["additionalProperties"]}}, defs, key + ".", skip)
        elif "oneOf" in prop or ("anyOf" in prop and all("$ref" in p for p in prop["anyOf"] if p.get("type") != "null")):
            rows.append(f"| **{key}** | section, by its kind | | | {meaning} |")
            for option in prop.get("oneOf") or [p for p in prop["anyOf"] if p.get("type") != "null"]:
                variant = _resolve(option, defs)
                rows.append(f"| *{key}: {variant.get('title', '')}* | | | | {_first_line(variant.get('description', ''))} |")
                rows += _rows(variant, defs, key + ".", skip)
        else:
            default = "required" if name in required else _value(prop.get("default"))
            rows.append(f"| `{key}` | {_type(prop, defs)} | {default} | {_range(prop)} | {meaning} |")
    return rows


def _is_section(prop, defs: dict) -> bool:
    """Whether a schema is a section (keys of its own) or a choice among sections."""
    if not isinstance(prop, dict):
        return False
    prop = _resolve(prop, defs)
    return "properties" in prop or "oneOf" in prop


def _first_line(text: str) -> str:
    return " ".join(text.strip().split("\n\n")[0].split())


def _type(prop: dict, defs: dict) -> str:
    if "enum" in prop:
        return " \\| ".join(f'"{v}"' for v in prop["enum"])
    if "const" in prop:
        return f'"{prop["const"]}"'
    kind = prop.get("type")
    if kind == "array":
        items = prop.get("prefixItems")
        if items:
            return f"[{', '.join(_type(_resolve(i, defs), defs) for i in items)}]"
        return f"list of {_type(_resolve(prop.get('items', {}), defs), defs)}"
    if kind == "object":
        return "table"
    if "anyOf" in prop:
        return " or ".join(_type(_resolve(p, defs), defs) for p in prop["anyOf"] if p.get("type") != "null")
    return {"number": "number", "integer": "integer", "string": "text", "boolean": "true/false"}.get(kind, kind or "any")


def _range(prop: dict) -> str:
    if prop.get("type") == "array" and prop.get("prefixItems"):
        prop = prop["prefixItems"][0]
    if "anyOf" in prop:
        prop = next((p for p in prop["anyOf"] if p.get("type") != "null"), prop)
    parts = []
    for key, symbol in (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"), ("maximum", "<=")):
        if key in prop:
            parts.append(f"{symbol} {_value(prop[key])}")
    return ", ".join(parts)


def _value(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"' if value else '""'
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def key_unit(source, dotted: str) -> str | None:
    """The unit of a scenario key (`tools.top.speed`, `material.interface.tensile_strength`) from
    its schema's description (the first word, when it is one of UNITS), for the scenario `source`
    (an example name or a file); None where the key has no unit or is not found."""
    from .methods import get_method
    from .scenario import load_scenario

    try:
        scenario, _ = load_scenario(source)
    except Exception:  # noqa: BLE001 - a label, not worth failing a sweep's plots for
        return None
    models = [get_method(scenario.method).Scenario]
    parts = dotted.split(".")
    for k, part in enumerate(parts):
        field = next((schema_fields(m)[part] for m in models if part in schema_fields(m)), None)
        if field is None:
            continue  # a list entry's number or name (tools.top)
        if k == len(parts) - 1:
            word = (field.description or "").replace(",", " ").split(" ")[0]
            return word if word in UNITS else None
        models = section_schemas(field.annotation)  # a choice among sections: look in each
    return None

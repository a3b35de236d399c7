"""The text of a scenario's errors: pydantic's validation errors said as the key, the value and
the fix (`_describe`, with did-you-mean hints), a missing `method`, a nan."""

from __future__ import annotations

import math

from pydantic import ValidationError

from ..schema import ScenarioError, schema_fields, section_schemas


# Fields whose value is one of several schemas chosen by a name (e.g. `law`).
TAGGED_CHOICES = ("interface",)


def _refuse_nan(data, source, where: str = "") -> None:
    """No value of a scenario may be nan (pydantic takes it for a float)."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for key, value in items:
        path = f"{where}.{key}" if where else str(key)
        if isinstance(value, float) and math.isnan(value):
            raise ScenarioError(f"{source}: {path}: nan is not a value; give a number")
        _refuse_nan(value, source, path)


def _field_names(model, seen=None) -> set[str]:
    """Every field name of a schema and the schemas nested in it (for did-you-mean hints)."""
    import typing

    seen = set() if seen is None else seen
    if model in seen or not hasattr(model, "model_fields"):
        return set()
    seen.add(model)
    names = set(model.model_fields)
    for field in model.model_fields.values():
        stack = [field.annotation]
        while stack:
            t = stack.pop()
            stack.extend(typing.get_args(t))
            names |= _field_names(t, seen)
    return names


def _refuse_without_method(data: dict, source) -> None:
    """A scenario without `method` is read as FDEM's; when it does not validate so but does as
    another method's, the error is the missing method, not FDEM's nearest key."""
    from ..methods import METHODS, get_method

    for name in METHODS:
        if name == "fdem":
            continue
        try:
            get_method(name).Scenario.model_validate({**data, "method": name})
        except ValidationError:
            continue
        raise ScenarioError(f"{source}: method: not given, so read as method = \"fdem\", which it is not; it is a "
                            f"{name} scenario: add method = \"{name}\"")


def _section_model(model, path):
    """The schema of the section at `path` (field names, list indices skipped), or None where the
    path leaves the schemas (a choice by kind, a dict)."""
    for part in path:
        if isinstance(part, int):
            continue
        field = schema_fields(model).get(part)
        models = section_schemas(field.annotation) if field is not None else []
        if len(models) != 1:  # not a field, a plain value, or a choice among sections
            return None
        model = models[0]
    return model


# The field that names which schema of a tagged choice a section is (material.interface.law).
_TAG_KEY = "law"


def _tagged_choice(schema, loc, tag):
    """For an unknown key loc[-1] in a section chosen by name (`tag`, e.g. "guo-munjiza"): the
    chosen schema, and the name of another choice that has the key (None if none does)."""
    parent = _section_model(schema, loc[:-2])
    field = schema_fields(parent).get(str(loc[-2])) if parent is not None else None
    choices = section_schemas(field.annotation) if field is not None else []
    named = {getattr(schema_fields(c).get(_TAG_KEY), "default", None): c for c in choices}
    other = next((name for name, c in named.items() if name != tag and str(loc[-1]) in schema_fields(c)), None)
    return named.get(tag), other


def _describe(err: ValidationError, source, schema=None) -> str:
    errors = err.errors()
    # A misspelt key also leaves the right one missing: name the unknown key first.
    errors.sort(key=lambda e: e["type"] not in ("extra_forbidden", "unexpected_keyword_argument"))
    first = errors[0]
    loc = first["loc"]
    # The tag of a choice by name that pydantic puts in the path (material.interface.bilinear.kn).
    tag = next((p for k, p in enumerate(loc) if 0 < k < len(loc) - 1 and loc[k - 1] in TAGGED_CHOICES), None)
    loc = [p for k, p in enumerate(loc) if not (0 < k < len(loc) - 1 and loc[k - 1] in TAGGED_CHOICES)]
    where = ".".join(str(p) for p in loc) or "(top level)"
    kind = first["type"]
    if kind in ("extra_forbidden", "unexpected_keyword_argument"):
        import difflib

        what = "section" if len(loc) == 1 else "key"
        section = _section_model(schema, loc[:-1]) if schema else None
        other = None
        if section is None and tag is not None and schema is not None:
            section, other = _tagged_choice(schema, loc, tag)
        names = set(schema_fields(section)) if section is not None else (_field_names(schema) if schema else set())
        close = difflib.get_close_matches(str(loc[-1]), sorted(names - {str(loc[-1])}), n=1)
        if other is not None:
            hint = (f"{loc[-1]} is a key of the {other} {loc[-2]}, not of the {tag} one this {loc[-2]} is; "
                    f"set {'.'.join(map(str, loc[:-1]))}.{_TAG_KEY} = \"{other}\" to use it, or remove it")
        else:
            hint = f"unknown {what} {loc[-1]}; " + (f"did you mean {close[0]}?" if close else "remove it or check its spelling")
    elif kind == "missing":
        hint = "required: add it"
    else:
        hint = first["msg"].removeprefix("Value error, ")
        if first.get("input") is not None and kind != "value_error":
            hint += f" (got {first['input']!r})"
    more = f" (and {len(err.errors()) - 1} more problem(s))" if len(err.errors()) > 1 else ""
    if not loc and kind == "value_error":  # a check across sections: its message names the keys
        return f"{source}: {hint}{more}"
    return f"{source}: {where}: {hint}{more}"

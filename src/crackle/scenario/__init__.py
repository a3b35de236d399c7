"""Scenario files: TOML validated against a schema before any work, then built into a run.

A scenario is data: it is parsed with tomllib and validated with pydantic; nothing in it is
evaluated. Errors name the field and say how to fix it (ScenarioError), and the command line
turns them into exit code 2.

  sections.py  what a scenario is: the shared sections and section schemas
  files.py     reading one: a file or a shipped example, --set and --quick (load_scenario)
  messages.py  the text of its errors (pydantic's said as the key, the value and the fix)
"""

from ..schema import ScenarioError, resolve_path
from .files import apply_overrides, examples_dir, list_examples, load_scenario, no_such_file, read_scenario_data, \
    split_override
from .sections import *  # noqa: F403 (the section schemas, each named in sections.__all__)
from .sections import __all__ as _SECTIONS

__all__ = ["ScenarioError", "apply_overrides", "examples_dir", "list_examples", "load_scenario", "no_such_file",
           "read_scenario_data", "resolve_path", "split_override", *_SECTIONS]

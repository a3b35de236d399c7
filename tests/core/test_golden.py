"""Byte-identity guard: the short forms of every shipped example (tests/golden/quick_examples.py)
give the stored history.csv and events.csv hashes. A refactor must not change them; a change of
the physics updates them on purpose (`python tests/golden/quick_examples.py --update`, and say
why in the commit). Hashes hold for one machine and numpy/numba build (the stored platform);
elsewhere the test is skipped, not passed."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "golden"))
from quick_examples import SHORT, STORE, platform_key, run_case, short_overrides  # noqa: E402

STORED = json.loads(STORE.read_text())


@pytest.mark.parametrize("name", sorted(SHORT))
def test_short_quick_history_unchanged(name):
    if STORED["platform"] != platform_key():
        pytest.skip(f"hashes stored on '{STORED['platform']}', this is '{platform_key()}'")
    assert run_case(name, short_overrides(name)) == STORED["short"][name]

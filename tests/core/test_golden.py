"""Byte-identity guard: the short forms of every shipped example (tests/golden/quick_examples.py)
give the stored history.csv and events.csv hashes. A refactor must not change them; a change of
the physics updates them on purpose (`python tests/golden/quick_examples.py --update`, and say
why in the commit). Hashes hold for one machine and numpy/numba build: one set per platform is
stored; on a platform without one the test is skipped, not passed."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "golden"))
from quick_examples import SHORT, platform_key, read_store, run_case, short_overrides  # noqa: E402

STORED = read_store()


@pytest.mark.parametrize("name", sorted(SHORT))
def test_short_quick_history_unchanged(name):
    here = platform_key()
    if here not in STORED:
        pytest.skip(f"no hashes stored for '{here}' (only for {', '.join(repr(k) for k in STORED)})")
    assert run_case(name, short_overrides(name)) == STORED[here]["short"][name]

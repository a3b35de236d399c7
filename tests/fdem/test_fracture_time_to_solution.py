"""benchmarks/fracture_time_to_solution.py on a tiny bar: every phase reported, the numbers
consistent with each other (no assertion on wall time)."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

BENCHMARK = Path(__file__).parents[2] / "benchmarks" / "fracture_time_to_solution.py"


@pytest.fixture(scope="module")
def fts():
    spec = importlib.util.spec_from_file_location("fracture_time_to_solution", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up by name
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def report(fts, tmp_path_factory):
    """The bar at 25 mm (a few hundred tets) pulled for 20 us, both insertion modes."""
    out = tmp_path_factory.mktemp("fts") / "bar.json"
    assert fts.main(["--case", "bar", "--size", "25", "--until-us", "20", "--chunk-us", "1", "--json", str(out)]) == 0
    return json.loads(out.read_text())


@pytest.mark.parametrize("insertion", ["intrinsic", "extrinsic"])
def test_the_phases_add_up_to_the_run(report, insertion):
    """The four phases in order, contiguous, their steps and simulated time adding up to the run's;
    the bar ties, inserts and fails within 20 us; the counts rise through the chunks."""
    r = next(r for r in report["results"] if r["insertion"] == insertion)
    phases = r["phases"]
    assert list(phases) == ["tied", "inserting", "failing", "contact"]
    driver_steps = round(r["end_us"] / r["dt_ns"] * 1e3)
    chunk_steps = sum(c["driver_steps"] for c in r["chunks"])
    assert sum(p["driver_steps"] for p in phases.values()) == driver_steps == chunk_steps
    assert sum(p["compiled_steps"] for p in phases.values()) == sum(c["compiled_steps"] for c in r["chunks"])
    simulated = 1e6 * r["chunks"][-1]["t_end"]
    assert sum(p["simulated_us"] for p in phases.values()) == pytest.approx(simulated, rel=1e-9)
    assert abs(simulated - r["end_us"]) <= 0.5e-3 * r["dt_ns"]  # the end time within half a step
    assert sum(p["wall_s"] for p in phases.values()) == pytest.approx(r["wall_s"], rel=1e-9)
    # Tied, then inserting, then failing: each present and starting where the one before ended.
    present = [p for p in phases.values() if p["driver_steps"]]
    assert [p["driver_steps"] > 0 for p in list(phases.values())[:3]] == [True, True, True]
    assert present[0]["start_us"] == 0.0
    for before, after in zip(present, present[1:]):
        assert after["start_us"] == pytest.approx(before["end_us"])
    for p in present:
        assert p["step_ns"] == pytest.approx(1e3 * p["simulated_us"] / p["compiled_steps"])
        assert p["tet_steps_per_s"] == pytest.approx(r["tets"] * p["compiled_steps"] / p["wall_s"])
    chunks = r["chunks"]
    assert all(b["reached"] >= a["reached"] and b["broken"] >= a["broken"] for a, b in zip(chunks, chunks[1:]))
    assert r["end"]["broken"] == chunks[-1]["broken"] > 0
    # Extrinsic: the tied phase's long step, then tied_substeps compiled steps per driver step.
    if insertion == "extrinsic":
        assert r["tied_substeps"] > 1
        assert phases["tied"]["compiled_steps"] == phases["tied"]["driver_steps"]
        assert r["end"]["tied_until_us"] is not None
    else:
        assert r["tied_substeps"] == 1
    # The end state's energies are reported (the run's audit is the simulation's, not tested here).
    assert {"kinetic", "elastic", "cohesive", "damage", "external"} <= set(r["end"]["energies"])


def test_classify_puts_a_chunk_in_the_later_phase(fts):
    """A chunk is sorted by its end state; contact is what follows the last rise of the broken count."""
    chunk = lambda t, reached, broken: fts.Chunk(t, 1.0, 1, 1, reached == 0, reached, broken)  # noqa: E731
    chunks = [chunk(1, 0, 0), chunk(2, 3, 0), chunk(3, 5, 2), chunk(4, 5, 2), chunk(5, 6, 4), chunk(6, 6, 4)]
    assert fts.classify(chunks) == ["tied", "inserting", "failing", "failing", "failing", "contact"]
    table = fts.phase_table(chunks, n_tets=10)
    assert [table[p]["driver_steps"] for p in fts.PHASES] == [1, 1, 3, 1]
    assert table["failing"]["start_us"] == pytest.approx(2e6) and table["failing"]["end_us"] == pytest.approx(5e6)
    # Repeats: the medians of the timed numbers, the steps of the first.
    slower = fts.phase_table([fts.Chunk(c.t_end, 3.0, 1, 1, c.tied, c.reached, c.broken) for c in chunks], 10)
    median = fts.median_phases([table, slower, slower])
    assert median["failing"]["wall_s"] == 9.0 and median["failing"]["driver_steps"] == 3

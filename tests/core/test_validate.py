"""`crackle validate`: cases read from runs, their bands, the report and the exit code.

The shipped cases are the papers' (validation.cases.CASES, minutes each); these tests put one
quick case in their place: the quick 10 m/s sphere impact (paper 001 section 5, 672 tets, about
12 s), whose ball rebounds at 9.85 m/s.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from crackle.cli import main
from crackle.validation import cases as case_registry
from crackle.validation import validate
from crackle.validation.cases import FAST_CASES, NUMBER, RUNS, Case, Run, select
from crackle.validation.runner import MARKER, STAMP, document_data, stamp_text, write_document

DOCUMENT = Path(__file__).resolve().parents[2] / "docs" / "validation.md"

REBOUND_RUN = Run("sphere-rebound", "001", "sphere-impact-slow")
REBOUND = Case("001-sphere-rebound", "001", "quick", REBOUND_RUN, "the ball's rebound speed",
               "largest_fragment_velocity.2", "m/s", (9.0, 10.5),
               "the ball's rebound at 10 m/s: nearly elastic, 9.85 m/s measured; +-7 %", "(slightly damaged, bounces)")


@pytest.fixture(scope="module")
def shared_out(tmp_path_factory):
    """One output folder for the module: a run finished by one test is read by the next."""
    return tmp_path_factory.mktemp("validate") / "report"


@pytest.fixture
def one_case(monkeypatch):
    def use(*cases):
        monkeypatch.setattr(case_registry, "CASES", tuple(cases))
    return use


def test_a_case_in_its_band_passes_and_a_broken_one_is_named(shared_out, one_case, capsys):
    """The rebound case passes (exit 0, report.md and report.json say so, with the commit);
    the same case stopped at 80 us (an override changed on purpose), the ball still pressing
    into the base (-8.5 m/s), reads no rebound: exit 1, the case named as outside its band. Rerun, the first run is read
    from its folder, not run again."""
    one_case(REBOUND)
    out = shared_out
    assert main(["validate", "001", "--out", str(out), "--jobs", "1"]) == 0
    report = json.loads((out / "report.json").read_text())
    (row,) = report["cases"]
    assert row["status"] == "pass" and 9.0 <= row["value"] <= 10.5 and report["commit"]
    assert "| 001-sphere-rebound |" in (out / "report.md").read_text()
    capsys.readouterr()
    assert main(["validate", "001", "--out", str(out), "--jobs", "1"]) == 0
    assert "1 finished before, 0 to run" in capsys.readouterr().out

    broken = Case(**{**REBOUND.__dict__, "run": Run("sphere-pressing", "001", "sphere-impact-slow",
                                                     overrides={"run.end_time": 8e-5})})
    one_case(broken)
    assert main(["validate", "001", "--out", str(out), "--jobs", "1"]) == 1
    said = capsys.readouterr().out
    assert "001-sphere-rebound: outside" in said
    (row,) = json.loads((out / "report.json").read_text())["cases"]
    assert row["status"] == "outside" and row["value"] < 0.0


def test_a_case_not_reproduced_says_why_and_does_not_fail(shared_out, one_case):
    """A case with a reason, inside its band: status "not reproduced", its reason in the report,
    exit 0 (its run, the same settings as the first test's, read from the shared folder when that
    test ran first). Given a curve (the base's load against its displacement), the report shows it
    as figures/CASE.png."""
    why = Case(**{**REBOUND.__dict__, "name": "001-sphere-why", "reason": "a stated reason", "curve": "load"})
    one_case(why)
    out = shared_out
    assert main(["validate", "--out", str(out), "--jobs", "1"]) == 0
    assert json.loads((out / "report.json").read_text())["cases"][0]["status"] == "not reproduced"
    report = (out / "report.md").read_text()
    assert "Not reproduced: a stated reason." in report
    assert "](figures/001-sphere-why.png)" in report and (out / "figures" / "001-sphere-why.png").stat().st_size > 1000


def test_bad_choices_are_refused(capsys):
    """An unknown paper, tier or case name: exit 2 naming it and the choices."""
    assert main(["validate", "007"]) == 2
    assert "unknown paper '007'" in capsys.readouterr().err
    assert main(["validate", "--tier", "huge"]) == 2
    assert "--tier huge: choose one of quick, full, paper" in capsys.readouterr().err
    assert main(["validate", "--cases", "nope"]) == 2
    assert "unknown case 'nope'" in capsys.readouterr().err


def test_shipped_cases_are_complete():
    """Every shipped case names a known paper and tier, a band low <= high with its source, and the
    paper's value; the quick tier has a case of papers 001, 003 and 004."""
    for case in case_registry.CASES:
        assert case.paper in case_registry.PAPERS and case.tier in case_registry.TIERS
        assert case.band[0] <= case.band[1] and case.band_source and case.paper_value
    assert {c.paper for c in select(None, "quick")} == set(case_registry.PAPERS)


def test_the_document_agrees_with_the_fast_cases(tmp_path):
    """docs/validation.md's validate block (written by crackle validate --document) has a row for
    every declared case, and the fast cases (runs of seconds) rerun now read each value the
    block records within 1 % (measured: equal on the machine that wrote it), inside their bands:
    the document and the code agree."""
    text = DOCUMENT.read_text()
    rows = document_data(text)["cases"]
    for case in case_registry.CASES:
        assert f"| {case.name} |" in text
    results = validate(select(None, "quick", list(FAST_CASES)), tmp_path, jobs=1, report=lambda *_: None)
    for r in results:
        assert r.status in ("pass", "not reproduced"), (r.case.name, r.status, r.message)
        assert r.value == pytest.approx(rows[r.case.name]["value"], rel=0.01, abs=1e-12), r.case.name


def test_the_documents_markers_name_declared_runs_and_each_line_its_commits():
    """Every number between markers in docs/validation.md names a declared run and a number of the
    form KEY[*|/FACTOR]; every line holding markers has one stamp, and it says the commits and dates
    the block records for those runs (none "not run yet"): no generated number without its commit."""
    text = DOCUMENT.read_text()
    runs = document_data(text)["runs"]
    lines = [line for line in text.splitlines() if MARKER.search(line)]
    assert len(lines) > 20
    for line in lines:
        names = list(dict.fromkeys(m["run"] for m in MARKER.finditer(line)))
        assert all(n in RUNS for n in names), names
        assert all(NUMBER.match(m["number"]) for m in MARKER.finditer(line))
        stamps = STAMP.findall(line)
        assert len(stamps) == 1, line[:120]
        assert stamps[0] == stamp_text(names, runs) and "not run" not in stamps[0], (names, stamps[0])


def test_write_document_fills_markers_and_stamps(shared_out, one_case, monkeypatch, tmp_path):
    """A document with a validate block and a line with a marker of the rebound run: --document
    runs that run too (read from the shared folder when the first test ran), writes the rebound
    speed with its format and suffix, stamps the line with the run's commit and date, and puts the
    case's row in the block; a marker of a run not declared is refused (exit 2)."""
    one_case(REBOUND)
    monkeypatch.setitem(RUNS, REBOUND_RUN.name, REBOUND_RUN)
    document = tmp_path / "doc.md"
    document.write_text("# doc\n\n<!--validate:begin--><!--validate:end-->\n\n| rebound | "
                        "<!--q:sphere-rebound:largest_fragment_velocity.2:.2f| m/s-->old<!--/q--> in "
                        "<!--q:sphere-rebound:steps:,-->old<!--/q--> steps (<!--q-stamp--><!--/q-->) |\n")
    assert main(["validate", "001", "--out", str(shared_out), "--jobs", "1", "--document", str(document)]) == 0
    text = document.read_text()
    speed, steps = (m["text"] for m in MARKER.finditer(text))
    assert 9.0 <= float(speed.removesuffix(" m/s")) <= 10.5
    assert re.fullmatch(r"\d{1,3}(,\d{3})*", steps)  # a count as written: "1,234", not "1234.0"
    commit = json.loads((shared_out / "report.json").read_text())["commit"]
    assert STAMP.search(text)["text"].startswith(f"run at commit {commit.split('-')[0]}")
    assert "| 001-sphere-rebound | quick |" in text and document_data(text)["runs"]["sphere-rebound"]
    document.write_text(text.replace("sphere-rebound:", "no-such-run:"))
    assert main(["validate", "001", "--out", str(shared_out), "--jobs", "1", "--document", str(document)]) == 2

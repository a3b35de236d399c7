"""docs/validation.md: no number in a table without the commit it came from.

A table row outside the generated `<!--validate:begin-->` block that holds a digit must name a
commit (a 7-40 hex-digit git hash) outside its HTML comments: "run at commit X" (that commit's
code ran) or "recorded at commit X" (the commit that wrote the number into the document). Left
out: header and separator rows, the rows whose numbers `crackle validate --document` writes
between `<!--q:...-->` markers (their stamps, tests/core/test_validate.py), and the short ALLOWED
list of rows that hold no crackle measurement at all. Every hash cited in a table row must be a
commit of this repository (checked where git and the history are at hand).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENT = ROOT / "docs" / "validation.md"

# A git hash, 7 to 40 hex digits, not the digits after a decimal point (1.1547005383792517) and
# not part of a longer word or number.
HASH = re.compile(r"(?<![\w.])[0-9a-f]{7,40}(?!\w)")
COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
SEPARATOR = re.compile(r"^\|\s*:?-{3,}")
BEGIN, END = "<!--validate:begin-->", "<!--validate:end-->"

# Rows with numbers but no crackle measurement, by a phrase found in that row alone.
ALLOWED = {
    # Single fracture: the theoretical band of plastic-zone lengths, the paper's eqs 13-14; the
    # crackle column of that row is empty (crackle's own values are in the rows above it).
    "| theory (eqs 13-14) |":
        "the paper's closed-form band, no crackle value",
    # Issue 42's summary: crackle's column says "reported"; the only digit is the item's number.
    "| bytes and bandwidth share in every throughput script (item 4) |":
        "crackle's column is 'reported', no number",
}

# Hashes of other repositories, cited where a row names a file taken from them.
FOREIGN = {
    "2286c55": "ThomasChauve/yade-code, the commit of the Yade packing file (paper 003's table)",
}


def table_rows(text: str):
    """(line number, line) of every table row outside the validate block, less the header and
    separator rows (a header is the row just above a separator)."""
    lines = text.split("\n")
    inside = False
    for i, line in enumerate(lines):
        if BEGIN in line:
            inside = True
        if END in line:
            inside = False
            continue
        if inside or not line.startswith("|") or SEPARATOR.match(line):
            continue
        if i + 1 < len(lines) and SEPARATOR.match(lines[i + 1]):
            continue
        yield i + 1, line


def cited_hashes(line: str) -> list[str]:
    """The hashes a row cites outside its HTML comments, other repositories' left out."""
    return [h for h in HASH.findall(COMMENT.sub("", line)) if h not in FOREIGN]


def unstamped_rows(text: str, allowed=()) -> list[tuple[int, str]]:
    """Table rows outside the validate block with a digit and no commit: (line number, line).
    Rows with `<!--q:` markers and rows holding one of the allowed phrases are left out."""
    found = []
    for number, line in table_rows(text):
        if "<!--q:" in line or any(phrase in line for phrase in allowed):
            continue
        visible = COMMENT.sub("", line)
        if re.search(r"\d", visible) and not cited_hashes(line):
            found.append((number, line))
    return found


def test_every_table_row_with_numbers_names_its_commit():
    text = DOCUMENT.read_text(encoding="utf-8")
    missing = unstamped_rows(text, ALLOWED)
    assert not missing, "rows of docs/validation.md with numbers and no commit:\n" + "\n".join(
        f"  line {number}: {line[:110]}" for number, line in missing)


def test_the_allowed_rows_exist_and_name_no_commit():
    """Each allowed phrase picks one table row, one that would fail without it: a stale entry
    (its row gone, or since stamped) is removed from the list rather than kept."""
    rows = list(table_rows(DOCUMENT.read_text(encoding="utf-8")))
    for phrase in ALLOWED:
        hits = [(number, line) for number, line in rows if phrase in line]
        assert len(hits) == 1, f"allowed phrase {phrase!r} matches {len(hits)} rows"
        ((number, line),) = hits
        assert not cited_hashes(line), f"line {number} names a commit: drop {phrase!r} from ALLOWED"


def test_the_check_names_an_unstamped_row():
    """The checker on a small document reports the unstamped row (line 6) and the row whose only
    hex-looking digits are a number's decimals (line 10), not the header (with a digit), the
    separator, the stamped row, the generated rows or the row without digits; an allowed phrase
    takes its row off the report."""
    text = "\n".join([
        "| case | paper 001 | crackle |",                                          # 1 header
        "|---|---|---|",                                                            # 2
        "| quick | 4 petals | 0 (recorded at commit 500f47a, 2026-11-29) |",          # 3 stamped
        "| full | 56 MPa | <!--q:x:peak:.1f-->64.9<!--/q--> MPa |",                  # 4 generated
        "| pattern | one fracture | one fracture |",                                 # 5 no digit
        "| h = 10 mm | converged | 743.2 N at 504 us |",                             # 6 unstamped
        BEGIN,                                                                      # 7
        "| 001-3pb | quick | 693 N |",                                               # 8 generated block
        END,                                                                        # 9
        "| index | 2/sqrt(3) | 1.1547005383792517 |",                                # 10 decimals
    ])
    found = unstamped_rows(text)
    assert [number for number, _ in found] == [6, 10]
    assert "743.2 N" in found[0][1]
    assert unstamped_rows(text, allowed=("| h = 10 mm |",)) == found[1:]


def test_the_cited_hashes_are_commits_of_this_repository():
    """Every hash cited in a table row (the validate block's included) is a commit here:
    `git cat-file -e HASH^{commit}`. Skipped without git, outside a checkout, or in a shallow one."""
    git = shutil.which("git")
    if git is None:
        pytest.skip("git is not installed")

    def run(*args):
        return subprocess.run([git, *args], cwd=ROOT, capture_output=True, text=True)

    inside = run("rev-parse", "--is-inside-work-tree")
    if inside.returncode != 0 or inside.stdout.strip() != "true":
        pytest.skip("not a git checkout")
    if run("rev-parse", "--is-shallow-repository").stdout.strip() == "true":
        pytest.skip("a shallow clone lacks the older commits")
    cited = {}
    for number, line in enumerate(DOCUMENT.read_text(encoding="utf-8").split("\n"), start=1):
        if line.startswith("|"):
            for h in cited_hashes(line):
                cited.setdefault(h, number)
    assert cited, "no commit cited in any table row"
    unknown = [f"{h} (line {number})" for h, number in sorted(cited.items(), key=lambda kv: kv[1])
               if run("cat-file", "-e", f"{h}^{{commit}}").returncode != 0]
    assert not unknown, "hashes in docs/validation.md's tables that are no commit here: " + ", ".join(unknown)

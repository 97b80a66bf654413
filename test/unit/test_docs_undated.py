"""The documentation describes the package as it is, not how it got there: no line of a page
under docs/ (docs/**/*.md, the generated results page and node reference included) carries
a date or a commit hash, and no figure is named by a date. Dates, run logs and commit hashes
belong in git. (That every relative link resolves is test_doc_links.py's.)"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))

_MONTH = "January|February|March|April|May|June|July|August|September|October|November|December"
#: 2026-12-05, 2026-12-05T04:46, a day and a month spelt out with a year.
DATE = re.compile(
    r"\b(?:19|20)\d\d-(?:0[1-9]|1[0-2])-(?:0[1-9]|[12]\d|3[01])(?!\d)"
    rf"|\b(?:{_MONTH}) \d{{1,2}}, (?:19|20)\d\d\b"
    rf"|\b\d{{1,2}} (?:{_MONTH}) (?:19|20)\d\d\b"
)
#: A commit hash: 7-40 hex digits alone in a code span (with a digit and a letter, so that a
#: number or a word is not one), or after "commit".
HASH = re.compile(
    r"`(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}`"
    r"|\bcommit(?:s|ted)?(?: at| of)?\s+`?[0-9a-f]{7,40}\b",
    re.IGNORECASE,
)


def dated_lines(text: str) -> list[str]:
    """``line: text`` of every line with a date or a commit hash."""
    return [
        f"{number}: {line.strip()}"
        for number, line in enumerate(text.splitlines(), start=1)
        if DATE.search(line) or HASH.search(line)
    ]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_page_carries_a_date_or_a_commit_hash(page):
    assert dated_lines(page.read_text(encoding="utf-8")) == []


def test_no_figure_is_named_by_a_date():
    figures = sorted(p.name for p in (DOCS / "figures").iterdir())
    assert figures, "no figures found"
    assert [name for name in figures if DATE.search(name.replace("_", " "))] == []


def test_the_pages_include_the_generated_ones():
    names = {p.relative_to(DOCS).as_posix() for p in PAGES}
    assert {"results.md", "safety.md", "reference/README.md"} <= names


def test_the_checker_finds_dates_and_hashes():
    text = "\n".join(
        [
            "The hour at 250 Hz, passed (2026-12-05 04:46-05:51).",  # 1
            "Measured 2026-11-23T03:17 UTC.",  # 2
            "Measured at commit 4d8b93b on the VM.",  # 3
            "The code of `f3277e5` and `97dc642`.",  # 4
            "Run on December 5, 2026.",  # 5
            "range `>= 0, <= 4294967295, step 1`, `1000000` steps, `deadbeef`, `sim_bridge`",
            "a sqlite3 commit) and 1e-15 rad; 2026 robots; version 2.14.5; 12-05",
        ]
    )
    assert [line.split(":")[0] for line in dated_lines(text)] == ["1", "2", "3", "4", "5"]
    assert DATE.search("fault_soak_hour_250hz_2026-12-05.png".replace("_", " "))

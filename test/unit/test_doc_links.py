"""Every relative link of README.md and of every page under docs/ (docs/**/*.md: the
tutorials and the generated node reference included) resolves.

A link is ``[text](target)`` or ``![alt](target)`` outside code (fenced blocks and inline code
spans are skipped). Links to http(s):// and mailto: are not followed. A relative target must
name an existing file or directory, resolved from the Markdown file that holds the link; an
anchor (``file.md#anchor`` or ``#anchor`` in the same file) must be the GitHub slug of a
heading of that Markdown file. Every page directly under docs/ is linked from the README, and
every page below it can be reached from the README by following links."""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
#: The pages directly under docs/ (each linked from the README) ...
DOCS = sorted((ROOT / "docs").glob("*.md"))
#: ... and every page under docs/, at any depth.
ALL_DOCS = sorted((ROOT / "docs").rglob("*.md"))

_FENCE = re.compile(r"^\s*(```|~~~)")
_CODE_SPAN = re.compile(r"(`+)(.+?)\1")
_LINK = re.compile(r"\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
_EXTERNAL = ("http://", "https://", "mailto:")


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code blocks."""
    lines, fence = [], None
    for number, line in enumerate(text.splitlines(), start=1):
        match = _FENCE.match(line)
        if match:
            if fence is None:
                fence = match.group(1)
            elif match.group(1) == fence:
                fence = None
            continue
        if fence is None:
            lines.append((number, line))
    return lines


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: the rendered text lowercased, punctuation other than
    '-' and '_' dropped, spaces turned into '-'."""
    text = _CODE_SPAN.sub(lambda m: m.group(2), heading)
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link keeps its text
    text = re.sub(r"[*~]", "", text)
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """The anchors of every heading of a Markdown file (duplicates get -1, -2, ...)."""
    seen: dict[str, int] = {}
    result = set()
    for _, line in _prose_lines(path.read_text(encoding="utf-8")):
        match = _HEADING.match(line)
        if not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        result.add(base if count == 0 else f"{base}-{count}")
    return result


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link and image outside code."""
    found = []
    for number, line in _prose_lines(path.read_text(encoding="utf-8")):
        line = _CODE_SPAN.sub("", line)
        found.extend((number, m.group(1)) for m in _LINK.finditer(line))
    return found


def broken_links(path: Path) -> list[str]:
    """Every relative link of a Markdown file that does not resolve, with the reason."""
    broken = []
    for number, target in links(path):
        if target.lower().startswith(_EXTERNAL):
            continue
        where = f"{path.name}:{number}: ({target})"
        file_part, _, anchor = target.partition("#")
        destination = (path.parent / unquote(file_part)).resolve() if file_part else path
        if not destination.exists():
            broken.append(f"{where}: no such file {destination}")
            continue
        if anchor and destination.suffix == ".md":
            if unquote(anchor) not in anchors(destination):
                broken.append(f"{where}: no heading with anchor #{anchor} in {destination.name}")
    return broken


@pytest.mark.parametrize("page", [README, *ALL_DOCS], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_relative_link_resolves(page):
    assert links(page) or page != README, "no links found in the README: parser broken?"
    assert broken_links(page) == []


def test_every_docs_page_is_linked_from_the_readme():
    linked = {
        (README.parent / unquote(target.partition("#")[0])).resolve()
        for _, target in links(README)
        if not target.startswith(("#", *_EXTERNAL))
    }
    assert DOCS, "no docs/*.md found"
    assert [p.name for p in DOCS if p.resolve() not in linked] == []


def linked_pages(page: Path) -> set[Path]:
    """The Markdown files (a folder: its README.md) a page links to, resolved."""
    found = set()
    for _, target in links(page):
        file_part = target.partition("#")[0]
        if not file_part or target.lower().startswith(_EXTERNAL):
            continue
        destination = (page.parent / unquote(file_part)).resolve()
        if destination.is_dir():
            destination = destination / "README.md"
        if destination.suffix == ".md" and destination.exists():
            found.add(destination)
    return found


def reachable(start: Path) -> set[Path]:
    """Every Markdown file reached from ``start`` by following relative links."""
    seen, todo = set(), [start.resolve()]
    while todo:
        page = todo.pop()
        if page not in seen:
            seen.add(page)
            todo.extend(linked_pages(page) - seen)
    return seen


def test_every_docs_page_can_be_reached_from_the_readme():
    found = reachable(README)
    assert any(p.parent.name != "docs" for p in ALL_DOCS), "no page below docs/: glob broken?"
    assert [p.relative_to(ROOT).as_posix() for p in ALL_DOCS if p.resolve() not in found] == []


def test_the_checker_finds_broken_files_and_anchors(tmp_path):
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "plot.png").write_bytes(b"")
    (tmp_path / "other.md").write_text(
        "# Other page\n\n## Gains, `kp` and K_D\n\n## Gains\n\n## Gains\n"
    )
    page = tmp_path / "page.md"
    page.write_text(
        "# Page: `jsc bench`\n\n"
        "[ok](other.md) [ok](other.md#gains-kp-and-k_d) [ok](other.md#gains-1)\n"
        "![ok](figures/plot.png) [ok](#page-jsc-bench) [web](https://example.org/x)\n"
        "`[code span](missing.md)`\n\n"
        "```\n[in a fence](missing.md)\n```\n\n"
        "[bad file](missing.md) ![bad image](figures/none.png)\n"
        "[bad anchor](other.md#gains-2) [bad local anchor](#trigger)\n"
    )
    assert [entry.split(": ")[1] for entry in broken_links(page)] == [
        "(missing.md)",
        "(figures/none.png)",
        "(other.md#gains-2)",
        "(#trigger)",
    ]

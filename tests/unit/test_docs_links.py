"""Every relative link in the README and docs/ leads somewhere: the file exists, and a #fragment
names a heading of it as GitHub anchors it. Figures move between docs/benchmarks.md and its
history page as sessions go by, and a link left behind fails quietly on GitHub. So does a table
whose header row an edit dropped: GitHub then shows its rows as plain text."""
import collections
import functools
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCUMENTS = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
LINK = re.compile(r"\]\(([^)\s]+)\)")
HEADING = re.compile(r"^#{1,6} (.+)$", re.MULTILINE)
FENCE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
TABLE_SEPARATOR = re.compile(r"^\|(\s*:?-+:?\s*\|)+$")


def without_code(document):
    """The document's text with its fenced code blocks blanked, line numbers kept."""
    return FENCE.sub(lambda block: "\n" * block.group().count("\n"), document.read_text())


def github_anchor(heading):
    """The id GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


@functools.lru_cache(maxsize=None)
def anchors(document):
    """Every heading's anchor; a repeated heading gets -1, -2, ... as on GitHub. Read once per
    document, however many links point into it."""
    found, repeats = set(), collections.Counter()
    for heading in HEADING.findall(without_code(document)):
        anchor = github_anchor(heading)
        found.add(f"{anchor}-{repeats[anchor]}" if repeats[anchor] else anchor)
        repeats[anchor] += 1
    return found


def relative_links(document):
    for target in LINK.findall(without_code(document)):
        if not re.match(r"[a-z]+:", target):
            yield target


def broken_links(document):
    broken = []
    for target in relative_links(document):
        path, _, fragment = target.partition("#")
        linked = (document.parent / path).resolve() if path else document
        if not linked.exists():
            broken.append(target)
        elif fragment and linked.suffix == ".md" and fragment not in anchors(linked):
            broken.append(target)
    return broken


def headless_tables(document):
    """Line numbers of table separators (|---|) with no header row above them."""
    lines = without_code(document).splitlines()
    return [number + 1 for number, line in enumerate(lines)
            if TABLE_SEPARATOR.match(line) and (number == 0 or not lines[number - 1].startswith("|"))]


def test_github_anchors_drop_punctuation_and_keep_hyphens():
    assert github_anchor("Session 32: every severity, after the wall-face rule") == \
        "session-32-every-severity-after-the-wall-face-rule"
    assert github_anchor("2026-11-26 (session 25), whose the gap is: `benchmarks/slam_gaps`") == \
        "2026-11-26-session-25-whose-the-gap-is-benchmarksslam_gaps"


def test_a_missing_heading_or_file_is_reported(tmp_path):
    document = tmp_path / "page.md"
    document.write_text("# Title\n\n[here](#title) [gone](#nothing) [file](other.md) [web](https://x.org)\n")
    assert broken_links(document) == ["#nothing", "other.md"]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda path: path.name)
def test_every_relative_link_leads_to_a_file_and_heading_that_exist(document):
    assert broken_links(document) == []


def test_a_table_without_its_header_row_is_reported(tmp_path):
    document = tmp_path / "page.md"
    document.write_text("| a | b |\n|---|---|\n| 1 | 2 |\n\n```\ncode\n```\nMild:\n\n|---|---|\n| 3 | 4 |\n")
    assert headless_tables(document) == [10]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda path: path.name)
def test_every_table_has_a_header_row(document):
    assert headless_tables(document) == []

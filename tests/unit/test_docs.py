"""The manual's pages hold together: every relative link points at a file that exists, and no page keeps a diary.

The README, CHANGELOG.md and every Markdown page under ``docs/`` are read as text (no process, no SUMO). A link
``[text](path)`` or ``[text](path#anchor)`` that is not a web address must name a file or folder relative to the page.
The manual speaks of the product only: the words of a work log ("session", "this round", "last round", "issue N")
belong nowhere in it; history goes to CHANGELOG.md by date and commit, measurements to ``docs/results/``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.helpers import ROOT

PAGES = sorted([ROOT / "README.md", ROOT / "CHANGELOG.md", *(ROOT / "docs").rglob("*.md")])
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
DIARY = re.compile(r"\bsessions?\b|\bthis round\b|\blast round\b|\bissue #?\d+", re.IGNORECASE)


def _id(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


@pytest.mark.parametrize("page", PAGES, ids=_id)
def test_relative_links_resolve(page: Path) -> None:
    broken = []
    for target in LINK.findall(page.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+://|mailto:|#", target):
            continue
        path = target.split("#", 1)[0]
        if not (page.parent / path).exists():
            broken.append(target)
    assert not broken, f"{_id(page)}: links to missing files {broken}"


@pytest.mark.parametrize("page", PAGES, ids=_id)
def test_no_diary_words(page: Path) -> None:
    hits = [
        f"line {n}: {line.strip()[:80]}"
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if DIARY.search(line)
    ]
    assert not hits, f"{_id(page)} speaks of how the project was worked on: {hits}"


def test_the_readme_is_a_front_door() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; the manual belongs in docs/guide/"
    measured = [line for line in lines if line.startswith("Measured on")]
    assert len(measured) == 1, "README.md needs exactly one line starting with 'Measured on' (today's times)"

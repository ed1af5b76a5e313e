"""The repository describes the tool as it is: no tracked text file tells the story of how it was
made. The story (periods of work, issue numbers, who did what, when) belongs in commit messages.

Each pattern is narrow on purpose, so that ordinary prose does not trip it:
- a numbered period of work: "session 9", "Session-8", "sessions 6 to 8", "round 4", "sprint 2"
  (pytest's ``scope="session"`` has no number);
- an issue or pull-request number: "issue 13", "Issues 13 and 14", "issue #7", "PR #12";
- the people who worked on it: "engineer", "the lead", "reviewer";
- a date of work (2026-11-24) anywhere but BENCHMARKS.md, whose tables each carry the date
  they were measured.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PATTERNS = {
    "a numbered period of work": re.compile(r"\b(sessions?|rounds?|sprints?)[ -]#?\d", re.I),
    "an issue number": re.compile(r"\b(issues?|pull requests?) #?\d|\bPR #?\d", re.I),
    "the people who worked on it": re.compile(r"\bengineers?\b|\bthe lead\b|\blead's\b|"
                                              r"\breviewers?\b", re.I),
    "a date of work": re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b"),
}
DATES_ALLOWED = {"BENCHMARKS.md"}
THIS_FILE = Path(__file__).resolve().relative_to(ROOT).as_posix()


def _tracked_text_files() -> list[str]:
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                                check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [name for name in listed.decode("utf-8", "surrogateescape").split("\0") if name]


def _findings(name: str, text: str) -> list[str]:
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for what, pattern in PATTERNS.items():
            if what == "a date of work" and name in DATES_ALLOWED:
                continue
            match = pattern.search(line)
            if match:
                found.append(f"{name}:{number}: {what} ({match.group(0)!r}): {line.strip()[:120]}")
    return found


def test_the_patterns_catch_history_and_spare_prose():
    caught = ["measured in session 9", "Session-8 defaults", "### Round 4: the seam", "sessions 6 "
              "to 8", "before issue 13", "Issues 13 and 14", "see issue #7", "(PR #12)",
              "as the lead asked", "the structure engineer's table", "on 2026-11-24"]
    spared = ['@pytest.fixture(scope="session")', "rounded to 2 decimals", "round(x, 3)",
              "period 8 px", "each iteration 4.81", "an issue with thin volumes",
              "leading edge", "Hua 2016", "engineered", "step 1: organise"]
    assert all(_findings("x.md", line) for line in caught)
    assert not [line for line in spared if _findings("x.md", line)]


def test_no_tracked_file_tells_the_history():
    found = []
    for name in _tracked_text_files():
        if name == THIS_FILE:
            continue
        try:
            data = (ROOT / name).read_bytes()
        except OSError:  # deleted in the working tree
            continue
        if b"\0" in data:
            continue  # binary
        found += _findings(name, data.decode("utf-8", "replace"))
    assert not found, "history in tracked files:\n" + "\n".join(found)

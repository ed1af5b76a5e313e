"""Every example in README.md runs as written, from a folder that holds the shipped samples.

Shell blocks (```sh): each command is run in order, in-process (osmap_cli.cli.main), and must
exit 0; later lines may read what earlier ones wrote. A line with a `# your files` comment needs the
user's own files and is not run; `make ...` lines are the set-up commands (`make test` runs
this suite). Any other command is an error of this test: the README shows only `osmap` lines.
Python blocks (```python) are run too.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
ILLUSTRATIVE = "# your files"


def _blocks(language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", README.read_text(), re.M | re.S)


def _commands(block: str) -> list[str]:
    """The block's command lines: continuations joined, illustrative lines left out."""
    joined = re.sub(r"\\\n\s*", " ", block)
    return [line for line in joined.splitlines()
            if line.strip() and not line.lstrip().startswith("#")
            and ILLUSTRATIVE not in line]


def test_the_readme_has_runnable_and_illustrative_examples():
    lines = [line for block in _blocks("sh") for line in _commands(block)]
    assert sum(line.startswith("osmap ") for line in lines) >= 10
    assert ILLUSTRATIVE in README.read_text()
    assert _blocks("python")


@pytest.fixture
def readme_folder(tmp_path, samples, monkeypatch):
    (tmp_path / "samples").symlink_to(samples)
    (tmp_path / "out").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_readme_examples_run(readme_folder, run_cli):
    for block in _blocks("sh"):
        for line in _commands(block):
            args = shlex.split(line, comments=True)
            if args[0] == "make":
                continue
            assert args[0] == "osmap", f"README: not an osmap command: {line}"
            result = run_cli(*args[1:])
            assert result.code == 0, f"README: {line}\n{result.err}"
    assert (readme_folder / "out" / "cells.png").exists()


def test_the_readme_python_runs(readme_folder, capsys):
    for block in _blocks("python"):
        exec(compile(block, "README.md", "exec"), {})
    assert "(192, 320, 2)" in capsys.readouterr().out

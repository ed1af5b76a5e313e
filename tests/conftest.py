"""Shared fixtures: where the repository, the samples and the installed `osmap` script are, and
a helper that runs the command line in-process."""

from __future__ import annotations

import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

# As `osmap` does (osmap_cli.cli.main): numpy's BLAS single-threaded. Multi-threaded OpenBLAS
# makes each small PCA call of the pipeline hundreds of times slower on a busy machine. This must
# run before numpy is imported.
for _variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
PRESETS = REPO / "presets"


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The repository root."""
    return REPO


@pytest.fixture(scope="session")
def samples() -> Path:
    """The folder of sample exemplars (samples/README.md lists them)."""
    return SAMPLES


@pytest.fixture(scope="session")
def small_samples(tmp_path_factory) -> Path:
    """64x64 crops of the samples, same names (cells.png, brick.png, weave.png, cells_rgba.png).

    Synthesis time is dominated by analysing the exemplar, so tests that only check plumbing
    (formats, channels, errors) run on these.
    """
    from osmap_cli.imageio import read_image, write_image

    folder = tmp_path_factory.mktemp("small_samples")
    for name in ("cells.png", "brick.png", "weave.png", "cells_rgba.png"):
        pixels = read_image(SAMPLES / name).pixels[:64, :64]
        write_image(folder / name, pixels, 8)
    return folder


@pytest.fixture(scope="session")
def osmap_exe() -> str:
    """Path of the installed `osmap` console script (next to this Python, else on PATH)."""
    candidate = Path(sys.executable).parent / ("osmap.exe" if os.name == "nt" else "osmap")
    if candidate.exists():
        return str(candidate)
    found = shutil.which("osmap")
    if found is None:
        pytest.skip("the osmap console script is not installed (pip install -e .)")
    return found


@dataclass
class CliResult:
    """Outcome of one in-process `osmap` run."""

    code: int
    out: str
    err: str

    @property
    def err_lines(self) -> list[str]:
        return self.err.splitlines()


@pytest.fixture
def run_cli(capsys):
    """Run `osmap ARGS...` in-process through osmap_cli.cli.main; returns a CliResult.

    stderr is not a terminal here, so no progress bar is drawn.
    """
    from osmap_cli.cli import main

    def run(*args) -> CliResult:
        capsys.readouterr()  # drop anything printed before
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliResult(code, captured.out, captured.err)

    return run


@pytest.fixture(scope="session")
def twenty(samples, tmp_path_factory):
    """20 small exemplars for batch tests: 32x32 crops of the shipped samples at different
    offsets."""
    from osmap_cli.imageio import read_image, write_image

    folder = tmp_path_factory.mktemp("twenty")
    names = ("cells.png", "brick.png", "weave.png", "grass.png", "gravel.png")
    paths = []
    for i in range(20):
        source = read_image(samples / names[i % 5]).pixels
        y, x = 8 * (i // 5), 16 * (i // 5)
        path = folder / f"ex{i:02d}_{names[i % 5]}"
        write_image(path, source[y:y + 32, x:x + 32], 8)
        paths.append(path)
    return paths


def json_lines(text: str) -> list[dict]:
    """The JSON objects of --json output, one per line."""
    import json

    return [json.loads(line) for line in text.splitlines()]


@pytest.fixture(scope="session", autouse=True)
def _synth_kernels_compiled():
    """Compile the synth kernels once, up front and two at a time, if Numba's cache lacks them:
    the tests then never see the first-run announcement on stderr."""
    from osmap_cli.synth.warm import ensure_compiled

    ensure_compiled()

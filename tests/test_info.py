"""Provenance in every output, `osmap info`, and re-running its command line byte for byte."""

from __future__ import annotations

import json
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from osmap_cli import __version__
from osmap_cli.imageio import write_image


@pytest.fixture
def workdir(small_samples, tmp_path, monkeypatch):
    """A folder holding an exemplar and a material map, as the current directory."""
    shutil.copy(small_samples / "cells.png", tmp_path / "cells.png")
    write_image(tmp_path / "cells_rough.png", np.linspace(0, 1, 64 * 64).reshape(64, 64, 1), 8)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _remake(run_cli, path, remove=()):
    """Run `osmap info PATH --command`, delete PATH (and `remove`), then run that command;
    returns the command."""
    result = run_cli("info", path, "--command")
    assert result.code == 0, result.err
    command = result.out.strip()
    for name in (path, *remove):
        Path(name).unlink(missing_ok=True)
    args = shlex.split(command)
    assert args[0] == "osmap"
    rerun = run_cli(*args[1:])
    assert rerun.code == 0, rerun.err
    return command


@pytest.mark.parametrize("output, extra", [
    ("out.png", ["--seed", "7", "--levels", "2", "--scale", "1.25"]),
    ("out.exr", ["--bit-depth", "32", "--orientation", "33.3", "--quality", "fast"]),
    ("out.tif", ["--preset", "stochastic", "--tileable", "--occupancy", "0.3"]),
])
def test_info_command_reproduces_the_bytes(run_cli, workdir, output, extra):
    result = run_cli("synth", "cells.png", "-o", output, "--size", "40x32", "--preset", "fast",
                     "--quiet", *extra)
    assert result.code == 0, result.err
    first = (workdir / output).read_bytes()
    command = _remake(run_cli, output)
    assert (workdir / output).read_bytes() == first, command


def test_info_reproduces_with_maps_uv_and_preset_files(run_cli, workdir):
    (workdir / "mine.toml").write_text('name = "mine"\n[synth]\nlevels = 2\nsweeps = 1\n')
    result = run_cli("synth", "cells.png", "-o", "m.png", "--size", "32", "--preset",
                     "mine.toml", "--with", "cells_rough.png", "--uv-out", "m_uv.exr", "--quiet")
    assert result.code == 0, result.err
    files = ("m.png", "m_cells_rough.png", "m_uv.exr")
    before = {name: (workdir / name).read_bytes() for name in files}
    for name in files:
        for other in files:
            (workdir / other).write_bytes(before[other])
        _remake(run_cli, name, remove=files)
        assert (workdir / name).read_bytes() == before[name], name


@pytest.mark.parametrize("name", ["soft", "fast"])
def test_info_reproduces_a_solid_made_with_a_preset_file(run_cli, workdir, name):
    """A preset file is recorded by its file name, whatever its `name` says: a name that is no
    built-in preset could not be re-run, and a built-in one ("fast") would stand for its own
    table instead of the file's."""
    # method osmap: what is recorded is under test, and it is the quicker method at 8^3
    (workdir / "soft.toml").write_text(f'name = "{name}"\n[solid]\nmethod = "osmap"\n'
                                       "iterations = 1\nknn = 1\nposition_weight = 2.0\n")
    result = run_cli("solid", "cells.png", "-o", "v.nrrd", "--size", "8", "--preset",
                     "soft.toml", "--quiet")
    assert result.code == 0, result.err
    first = (workdir / "v.nrrd").read_bytes()
    command = _remake(run_cli, "v.nrrd")
    assert "--preset soft.toml" in command
    assert (workdir / "v.nrrd").read_bytes() == first, command


def test_info_reproduces_a_solid_of_three_exemplars(run_cli, workdir):
    """--x, --y and --z are recorded by name and given again in their order."""
    from osmap_cli.imageio import read_image

    write_image(workdir / "turned.png", read_image(workdir / "cells.png").pixels[::-1].copy(), 8)
    result = run_cli("solid", "--x", "cells.png", "--y", "turned.png", "--z", "cells.png",
                     "-o", "v.nrrd", "--size", "8", "--preset", "fast", "--method", "osmap",
                     "--quiet")
    assert result.code == 0, result.err
    first = (workdir / "v.nrrd").read_bytes()
    command = _remake(run_cli, "v.nrrd")
    assert command.startswith("osmap solid --x cells.png --y turned.png --z cells.png -o v.nrrd")
    assert (workdir / "v.nrrd").read_bytes() == first, command


def test_info_prints_provenance(run_cli, workdir):
    assert run_cli("synth", "cells.png", "-o", "o.png", "--size", "32", "--seed", "3",
                   "--preset", "fast", "--quiet").code == 0
    result = run_cli("info", "o.png")
    assert result.code == 0, result.err
    fields = dict(line.split(None, 1) for line in result.out.splitlines())
    assert fields["file"] == "o.png" and fields["seed"] == "3"
    assert fields["software"] == f"osmap {__version__}" and fields["exemplar"] == "cells.png"
    assert fields["reproduce"].startswith("osmap synth cells.png -o o.png --size 32x32")
    data = json.loads(run_cli("info", "o.png", "--json").out)
    assert data["preset"] == "fast" and json.loads(data["options"])["seed"] == 3


def test_info_reads_nrrd_fields(run_cli, tmp_path):
    path = tmp_path / "v.nrrd"
    header = ("NRRD0004\n# comment\ntype: float\ndimension: 3\nsizes: 1 1 1\n"
              "endian: little\nencoding: raw\nosmap:command:=solid\nosmap:seed:=9\n"
              "osmap:exemplar:=marble.png\nosmap:args:=--size 1x1x1 --seed 9\n\n")
    path.write_bytes(header.encode() + np.zeros(1, "<f4").tobytes())
    result = run_cli("info", path)
    assert result.code == 0, result.err
    fields = dict(line.split(None, 1) for line in result.out.splitlines())
    assert fields["seed"] == "9" and fields["exemplar"] == "marble.png"
    assert fields["command"] == "solid" and fields["args"] == "--size 1x1x1 --seed 9"
    assert fields["reproduce"] == f"osmap solid marble.png -o {path} --size 1x1x1 --seed 9"


def test_info_errors(run_cli, small_samples, tmp_path):
    foreign = small_samples / "cells.png"  # not written by osmap
    result = run_cli("info", foreign)
    assert result.code == 1, result.err
    assert result.err_lines == [f"osmap: error: {foreign}: no osmap provenance in this file"]
    result = run_cli("info", tmp_path / "missing.png")
    assert result.code == 1, result.err
    assert result.err_lines == [f"osmap: error: {tmp_path / 'missing.png'}: no such file"]

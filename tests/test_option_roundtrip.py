"""Every option round-trips: a run with each option of a command at a value other than its
default writes files from which `osmap info FILE --command` writes the same bytes again.

The options are read from their declarations (the `option()` fields of SynthOptions,
FillOptions and SolidOptions, osmap_cli.options) and from the commands' click parameters, so an
option declared later is set here without a change to this file; a new flag that is neither an
option field nor listed below as not changing the output fails
`test_every_flag_is_covered`. Runs are tiny and group many options each."""

from __future__ import annotations

import dataclasses
import json
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from osmap_cli.commands.info import read_provenance
from osmap_cli.imageio import write_image
from osmap_cli.options import flag, number_text
from osmap_cli.solid.options import SolidOptions
from osmap_cli.synth.options import FillOptions, SynthOptions

# flags that name inputs and outputs or steer the run, not the bytes of a file
NOT_OPTIONS = {
    "exemplars", "images", "output", "out_dir", "name_template", "jobs", "fail_fast",
    "json_lines", "overwrite", "scheduler", "scheduler_file", "threads", "quiet", "verbose", "uv",
    "maps", "mask", "ex_x", "ex_y", "ex_z", "preview", "fmt",
}
# flags that change the bytes and are not option fields: --bit-depth, --normal, --nrrd-encoding
# and --target-guide are set by the runs below; tests/test_info.py round-trips --with, --uv-out
# and preset files, tests/test_guide.py --guide; --also and the control fields are recorded by
# file name and not round-tripped by any test yet
NOT_OPTIONS |= {"bit_depth", "normal", "nrrd_encoding", "preset", "with_maps", "uv_out",
                "also", "guide", "target_guide", "orientation_field", "scale_field"}
# osmap solid --analyse makes no volume: it prints the analysis and writes the segmentation
# (tests/test_solid_structure.py)
NOT_OPTIONS |= {"analyse"}
# free-text options (no choices): a valid value other than the default, given here so that a new
# free-text option fails this test until it is listed
TEXT_VALUES = {"lattice": "off"}
COMPOSED = {"width": "size", "height": "size", "depth": "size", "rotate_x": "orientation",
            "rotate_y": "orientation", "rotate_z": "orientation"}


def other_value(spec, value, name=""):
    """A valid value other than VALUE: the next choice, the other truth value, a nearby
    number (small steps keep every run cheap)."""
    if spec.kind is bool:
        return not value
    if spec.kind is str and not spec.choices:
        return TEXT_VALUES[name]
    if spec.kind is str:
        return next(c for c in spec.choices if c != value)
    step = 1 if spec.kind is int else max(abs(value) * 0.1, (spec.hi - spec.lo) * 0.01)
    candidate = value + step if value + step <= spec.hi else value - step
    return candidate if spec.kind is int else float(number_text(round(candidate, 4)))


def _fields(cls):
    return {f.name: f.metadata["spec"] for f in dataclasses.fields(cls)}


def _command_params(name):
    import click

    from osmap_cli.cli import cli

    command = cli.get_command(click.Context(cli), name)
    return {p.name for p in command.params}


def _args(cls, values: dict, command: str) -> list[str]:
    """Command-line flags setting VALUES (option fields of CLS) on osmap COMMAND."""
    params = _command_params(command)
    args = []
    for name, value in values.items():
        assert name in params or name in COMPOSED, (
            f"{cls.__name__}.{name} has no flag on osmap {command}: give it one (or list how it "
            "is set in tests/test_option_roundtrip.py COMPOSED)")
        if name in COMPOSED:
            continue
        if isinstance(value, bool):
            args += [flag(name)] if value else []
        else:
            args += [flag(name), number_text(value) if not isinstance(value, str) else value]
    return args


def _recorded(path) -> dict:
    return json.loads(read_provenance(str(path))["options"])


def _round_trip(run_cli, folder: Path, path: str, expected: dict):
    """The options recorded in PATH hold EXPECTED; `osmap info --command` writes it again, the
    same bytes."""
    recorded = _recorded(folder / path)
    wrong = {k: (recorded.get(k), v) for k, v in expected.items() if recorded.get(k) != v}
    assert not wrong, f"not recorded as set (recorded, set): {wrong}"
    info = run_cli("info", folder / path, "--command")
    assert info.code == 0, info.err
    command = shlex.split(info.out.strip())
    first = (folder / path).read_bytes()
    (folder / path).unlink()
    again = run_cli(*command[1:])
    assert again.code == 0, (info.out, again.err)
    if (folder / path).read_bytes() != first:
        rerun = _recorded(folder / path)
        lost = {k: (v, rerun.get(k)) for k, v in recorded.items() if rerun.get(k) != v}
        pytest.fail(f"{path}: `{info.out.strip()}` writes other bytes; options not carried "
                    f"(first, again): {lost}")


@pytest.fixture
def workdir(small_samples, tmp_path, monkeypatch):
    shutil.copy(small_samples / "cells.png", tmp_path / "ex.png")
    rng = np.random.default_rng(0)
    write_image(tmp_path / "guide.png", rng.random((16, 16, 1)), 8)
    mask = np.zeros((64, 64, 1), np.float32)
    mask[20:36, 24:40] = 1.0
    write_image(tmp_path / "mask.png", mask, 8)
    write_image(tmp_path / "bump.png", rng.random((64, 64, 3)), 8)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _synth_values(skip=()):
    """Every option field of SynthOptions at another value (sizes, seed and the method set by
    the caller)."""
    defaults = SynthOptions()
    return {name: other_value(spec, getattr(defaults, name), name)
            for name, spec in _fields(SynthOptions).items()
            if name not in ("width", "height", "seed", "method", *skip)}


def test_synth_options_round_trip(run_cli, workdir):
    """Every tunable and plain option at once, guided (so guide_weight plays a part), with
    --uv-out; then `osmap apply` with its options on those positions; then --method paper."""
    values = _synth_values()
    size = {"width": 24, "height": 16, "seed": 3}
    result = run_cli("synth", "ex.png", "-o", "s.png", "--size", "24x16", "--seed", "3",
                     "--target-guide", "guide.png", "--uv-out", "s_uv.exr", "--bit-depth", "16",
                     *_args(SynthOptions, values, "synth"))
    assert result.code == 0, result.err
    _round_trip(run_cli, workdir, "s.png", {**values, **size})
    result = run_cli("apply", "s_uv.exr", "bump.png", "-o", "a.tif", "--normal",
                     "--bit-depth", "32")
    assert result.code == 0, result.err
    first = (workdir / "a.tif").read_bytes()
    info = run_cli("info", "a.tif", "--command")
    assert "--normal" in info.out and "--bit-depth 32" in info.out, info.out
    (workdir / "a.tif").unlink()
    assert run_cli(*shlex.split(info.out)[1:]).code == 0
    assert (workdir / "a.tif").read_bytes() == first

    paper = {"method": "paper", "quality": "high", "scale": 1.5, "window_scale": 1.5,
             "som_anisotropy": 0.5}
    result = run_cli("synth", "ex.png", "-o", "p.png", "--size", "24", "--seed", "2",
                     *_args(SynthOptions, paper, "synth"))
    assert result.code == 0, result.err
    _round_trip(run_cli, workdir, "p.png", paper)


@pytest.mark.parametrize("command", ["inpaint", "tileable"])
def test_fill_options_round_trip(run_cli, workdir, command):
    from osmap_cli.commands.fill_common import OSMAP_ONLY

    params = _command_params(command)
    values = {k: v for k, v in _synth_values().items()
              if k in params and k not in OSMAP_ONLY}
    extra = ["--mask", "mask.png"] if command == "inpaint" else []
    if command == "tileable":
        border = _fields(FillOptions)["border"]
        extra = ["--border", str(other_value(border, 12))]
    result = run_cli(command, "ex.png", "-o", "f.png", "--seed", "4", *extra,
                     *_args(SynthOptions, values, command))
    assert result.code == 0, result.err
    _round_trip(run_cli, workdir, "f.png", values)


def _solid_values(**fixed):
    defaults = SolidOptions()
    values = {name: other_value(spec, getattr(defaults, name), name)
              for name, spec in _fields(SolidOptions).items()
              if name not in ("width", "height", "depth", "seed", *COMPOSED)}
    values.update(fixed)
    return values


@pytest.mark.parametrize("output, turned", [("v.nrrd", False), ("slices", True)])
def test_solid_options_round_trip(run_cli, workdir, output, turned):
    """Every solid option at another value: tileable, or turned (the two exclude each other),
    written as NRRD or a folder of slices."""
    values = _solid_values(tileable=not turned)
    extra = ["--orientation", "10,0,5"] if turned else []
    if turned:
        values.update(rotate_x=10.0, rotate_z=5.0)
    result = run_cli("solid", "ex.png", "-o", output, "--size", "8", "--seed", "5",
                     "--nrrd-encoding", "gzip", *extra, *_args(SolidOptions, values, "solid"))
    assert result.code == 0, result.err
    path = "v.nrrd" if output == "v.nrrd" else "slices/slice_0003.png"
    _round_trip(run_cli, workdir, path, values)


@pytest.mark.parametrize("command, classes", [
    ("synth", (SynthOptions,)), ("inpaint", (SynthOptions,)),
    ("tileable", (SynthOptions, FillOptions)), ("solid", (SolidOptions,)), ("apply", ())])
def test_every_flag_is_covered(command, classes):
    """Each flag of the command sets an option field (set by the tests above) or is listed in
    NOT_OPTIONS; each option field has a flag (or is COMPOSED into one)."""
    fields = set().union(*(_fields(c) for c in classes)) if classes else set()
    params = _command_params(command)
    composed = {COMPOSED[f] for f in fields if f in COMPOSED}
    stray = params - fields - NOT_OPTIONS - composed
    assert not stray, (f"osmap {command}: flags {sorted(stray)} are not option fields; declare "
                       "them with option() or list them in NOT_OPTIONS with a reason")

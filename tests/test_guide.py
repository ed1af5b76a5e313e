"""Guided synthesis (--guide, --target-guide, --guide-weight; docs/guide.md): the output follows
the target guide where the exemplar follows its guide, coherently, and every bad input is one
clear line."""

from __future__ import annotations

import json
import os
import shlex
from pathlib import Path

import numpy as np
import pytest
from texture_stats import coherence

from osmap_cli.imageio import read_image, write_image
from osmap_cli.synth.guide import auto_guide, guide_levels
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.pipeline import synthesize

SIZE = 96  # output side
MARGIN = 4  # output columns kept off the guide's boundary when measuring coherence


@pytest.fixture(scope="module")
def materials(samples):
    """(exemplar 128x64: gravel | brick, its guide 0 | 1, gravel, brick)."""
    a = read_image(samples / "gravel.png").pixels[:64, :64]
    b = read_image(samples / "brick.png").pixels[:64, :64]
    exemplar = np.concatenate([a, b], axis=1)
    guide = np.zeros((64, 128), np.float32)
    guide[:, 64:] = 1.0
    return exemplar, guide, a, b


def _halves(shape=(SIZE, SIZE)):
    target = np.zeros(shape, np.float32)
    target[:, shape[1] // 2:] = 1.0
    return target


def test_each_output_half_comes_from_its_material(materials):
    exemplar, guide, a, b = materials
    result = synthesize(exemplar, SynthOptions(width=SIZE, height=SIZE, seed=1), guide=guide,
                        target_guide=_halves())
    from_b = result.positions[..., 1] >= 63.5
    left, right = 1 - from_b[:, :SIZE // 2].mean(), from_b[:, SIZE // 2:].mean()
    assert left >= 0.9 and right >= 0.9, (left, right)
    # each half's patches against its material, next to an unguided synthesis of that material
    ratios = []
    for material, half in ((a, result.pixels[:, :SIZE // 2 - MARGIN]),
                           (b, result.pixels[:, SIZE // 2 + MARGIN:])):
        alone = synthesize(material, SynthOptions(width=SIZE // 2, height=SIZE, seed=1)).pixels
        ratios.append(coherence(material, half) / coherence(material, alone[:, :half.shape[1]]))
    assert np.mean(ratios) < 1.3, ratios


def test_each_painted_material_keeps_its_own_lattice(samples):
    """A guide painted in a few values gives each material the lattice read from its own
    pixels: the weave beside gravel keeps its 2D lattice, the gravel none. (The two-material
    exemplar's autocorrelation reads vertical stripes 8 px apart, which, applied to the whole
    output, would put every gravel copy on an 8 px column.)"""
    from osmap_cli.synth.regular import lattice_text

    gravel = np.repeat(read_image(samples / "gravel.png").pixels[:64, :64], 3, axis=2)
    weave = read_image(samples / "weave.png").pixels[:64, :64, :3]
    exemplar = np.concatenate([gravel, weave], axis=1)
    guide = np.zeros((64, 128), np.float32)
    guide[:, 64:] = 1.0
    result = synthesize(exemplar, SynthOptions(width=SIZE, height=SIZE, seed=1), guide=guide,
                        target_guide=_halves())
    gravel_lattice, weave_lattice = result.lattice.lattices
    assert gravel_lattice is None and len(weave_lattice.vectors) == 2
    assert lattice_text(result.lattice).startswith("guide 0: none; guide 1: ")
    ys, xs = np.mgrid[:SIZE, :SIZE].astype(np.float64)
    offset = result.positions - np.stack([ys, xs], axis=-1)
    # the weave half: every copy on the weave's lattice, in one phase
    right = offset[:, SIZE // 2 + MARGIN:] @ weave_lattice.dual().T
    assert np.abs(np.exp(2j * np.pi * right).mean(axis=(0, 1))).min() > 0.95


def test_a_small_painted_region_and_a_tileable_output(samples):
    """The smallest region a painted guide may have (32x32) and a tileable output, which keeps
    each region's lattice fitted to its size (the weave's 8 px diagonal period fits 64 px
    whole)."""
    weave = read_image(samples / "weave.png").pixels[:64, :128, :3]
    guide = np.zeros((64, 128), np.float32)
    guide[16:48, 40:72] = 1.0  # 32x32
    target = np.zeros((64, 64), np.float32)
    target[20:44, 20:44] = 1.0
    result = synthesize(weave, SynthOptions(width=64, height=64, seed=1), guide=guide,
                        target_guide=target)
    assert result.pixels.shape == (64, 64, 3)
    guide[:] = 0.0
    guide[:, 64:] = 1.0
    result = synthesize(weave, SynthOptions(width=64, height=64, seed=1, tileable=True),
                        guide=guide, target_guide=target)
    assert all(out is not None for out in result.lattice.outputs)


def test_only_a_guide_of_a_few_large_regions_is_a_map_of_materials():
    from osmap_cli.synth.regular import guide_regions

    two = np.zeros((64, 64), np.float32)
    two[:, 32:] = 1.0
    values, labels = guide_regions(two)
    assert values == (0.0, 1.0) and labels[0, 0] == 0 and labels[0, 63] == 1
    assert guide_regions(np.tile(np.linspace(0, 1, 64, dtype=np.float32), (64, 1))) is None
    assert guide_regions(np.zeros((64, 64), np.float32)) is None  # one value: nothing to map
    speck = two.copy()
    speck[:8, :8] = 0.5  # a third value on 64 pixels: not a material
    assert guide_regions(speck) is None
    nine = np.repeat(np.arange(9, dtype=np.float32), 64 * 64 // 9 + 1)[:64 * 64]
    assert guide_regions(nine.reshape(64, 64) / 8) is None


def test_a_painted_guide_starts_each_region_from_its_own_material():
    """The coarsest level of a painted guide starts from an OS-Map layout of each region's own
    positions: every output pixel at a position of the region its target guide picks (a
    layout of the whole exemplar mixes the two: about half of each side elsewhere)."""
    from osmap_cli.synth.pipeline import _regional_start
    from osmap_cli.synth.regular import guide_regions

    guide = np.zeros((32, 64), np.float32)
    guide[:, 32:] = 1.0  # left half region 0, right half region 1; three horizontal bands
    target = np.zeros((24, 24), np.float32)
    target[8:16] = 1.0
    lo, hi = np.array([2.0, 2.0]), np.array([29.0, 61.0])
    opts = SynthOptions(width=24, height=24, seed=3).validated()
    pos = _regional_start(guide_regions(guide), (32, 64), target, 1, np.eye(2), lo, hi, opts)
    right = pos[..., 1] >= 31.5
    assert (right == (target == 1.0)).all()
    assert (pos[..., 0] >= lo[0]).all() and (pos[..., 1] <= hi[1]).all()
    assert len(np.unique(np.rint(pos).reshape(-1, 2), axis=0)) > 100  # a layout, not a point
    # a region too narrow at this level for a window of its own: the whole exemplar's layout
    labels = np.zeros((32, 64), np.int32)
    labels[:, 30:32] = 1
    pos = _regional_start(((0.0, 1.0), labels), (32, 64), target, 1, np.eye(2), lo, hi, opts)
    assert np.isfinite(pos).all() and (pos[..., 1] <= hi[1]).all()


def test_the_target_guide_is_resized_to_the_output(materials):
    exemplar, guide, _, _ = materials
    small = _halves((10, 30))  # another size and aspect: stretched to the output
    result = synthesize(exemplar, SynthOptions(width=48, height=32, seed=2), guide=guide,
                        target_guide=small)
    from_b = result.positions[..., 1] >= 63.5
    assert from_b[:, :20].mean() < 0.1 and from_b[:, 28:].mean() > 0.9


def test_a_painted_guide_keeps_its_values_at_every_level():
    """Halving blurs a border between two painted materials into values between theirs; with
    the painted values given, every level keeps only those (the nearest), so a material's
    copies cannot spill across the border at the coarse levels at little cost."""
    step = np.zeros((24, 40), np.float32)
    step[:, 19:] = 1.0  # a border not on an even column: halving mixes the two values
    blurred = guide_levels(step, (24, 40), 3)
    assert any(np.any((g > 0.01) & (g < 0.99)) for g in blurred)
    crisp = guide_levels(step, (24, 40), 3, values=(0.0, 1.0))
    for level, g in zip(blurred, crisp):
        assert set(np.unique(g)) <= {0.0, 1.0}
        assert np.array_equal(g, (level >= 0.5).astype(np.float32))
    assert np.array_equal(crisp[0], step)
    ramp = np.tile(np.linspace(0, 1, 40, dtype=np.float32), (24, 1))  # between the materials
    for kept, free in zip(guide_levels(ramp, (24, 40), 3, values=(0.0, 1.0)),
                          guide_levels(ramp, (24, 40), 3)):
        assert np.array_equal(kept, free)


@pytest.mark.parametrize("left", ["gravel", "cells"])
def test_a_painted_border_stays_where_the_target_puts_it(samples, left):
    """Planks beside gravel or cells: no output pixel 2 px or more past the target's border
    comes from the other material (with guides blurred by the pyramid's halving, 26 to 50
    pixels of one material spilled 2 to 5 px into the other's half)."""
    def material(name):
        pixels = read_image(samples / f"{name}.png").pixels[:64, :64]
        return pixels[..., :3] if pixels.shape[2] >= 3 else np.repeat(pixels[..., :1], 3, 2)

    exemplar = np.concatenate([material(left), material("wood_side")], axis=1)
    guide = np.zeros((64, 128), np.float32)
    guide[:, 64:] = 1.0
    result = synthesize(exemplar, SynthOptions(width=SIZE, height=SIZE, seed=1), guide=guide,
                        target_guide=_halves())
    from_wood = result.positions[..., 1] >= 63.5
    columns = np.arange(SIZE)
    wrong = np.where(columns < SIZE // 2, from_wood, ~from_wood)
    past = np.where(columns < SIZE // 2, SIZE // 2 - 1 - columns, columns - SIZE // 2)
    assert not np.any(wrong & (past >= 2)[None, :]), int((wrong & (past >= 2)[None, :]).sum())


def test_guide_levels_and_auto_guide():
    ramp = np.tile(np.linspace(0, 1, 40, dtype=np.float32), (20, 1))
    levels = guide_levels(ramp, (20, 40), 3)
    assert [g.shape for g in levels] == [(20, 40), (10, 20), (5, 10)]
    assert levels[0] is not ramp and np.array_equal(levels[0], ramp)
    auto = auto_guide(np.stack([ramp] * 3, -1))
    assert auto.min() == 0.0 and auto.max() == 1.0 and auto.shape == (20, 40)
    assert np.all(np.diff(auto[10]) >= -1e-6)  # a blurred ramp still rises


def test_the_library_refuses_mismatched_guides(materials):
    exemplar, guide, _, _ = materials
    opts = SynthOptions(width=32, height=32)
    with pytest.raises(ValueError, match="target_guide"):
        synthesize(exemplar, opts, guide=guide)
    with pytest.raises(ValueError, match="must match"):
        synthesize(exemplar, opts, guide=guide[:, :64], target_guide=_halves())
    with pytest.raises(ValueError, match="method 'osmap'"):
        synthesize(exemplar, opts.replace(method="paper"), target_guide=_halves())


@pytest.fixture
def workdir(materials, tmp_path, monkeypatch):
    exemplar, guide, _, _ = materials
    monkeypatch.chdir(tmp_path)
    write_image(tmp_path / "ex.png", exemplar, 8)
    write_image(tmp_path / "ex_guide.png", guide[..., None], 8)
    write_image(tmp_path / "target.png", _halves((48, 48))[..., None], 8)
    return tmp_path


def test_cli_guided_output_records_and_reproduces_itself(run_cli, workdir):
    result = run_cli("synth", "ex.png", "--guide", "ex_guide.png", "--target-guide",
                     "target.png", "-o", "out.png", "--size", "48", "--guide-weight", "2",
                     "--uv-out", "uv.exr", "--quiet")
    assert result.code == 0, result.err
    uv = read_image(workdir / "uv.exr").pixels  # u = exemplar column
    assert (uv[:, :20, 0] < 63.5).mean() > 0.9 and (uv[:, 28:, 0] >= 63.5).mean() > 0.9
    first = (workdir / "out.png").read_bytes()
    info = run_cli("info", "out.png", "--command")
    assert info.code == 0, info.err
    args = shlex.split(info.out.strip())
    assert args[args.index("--guide") + 1] == "ex_guide.png"
    assert args[args.index("--target-guide") + 1] == "target.png"
    assert args[args.index("--guide-weight") + 1] == "2"
    os.remove("out.png")
    assert run_cli(*args[1:]).code == 0
    assert (workdir / "out.png").read_bytes() == first
    shown = run_cli("info", "out.png")
    assert "target_guide" in shown.out and "guide_weight" in shown.out


def test_cli_without_guide_uses_the_exemplar_luminance(run_cli, workdir):
    result = run_cli("synth", "ex.png", "--target-guide", "target.png", "-o", "out.png",
                     "--size", "32", "--uv-out", "uv.exr", "--quiet")
    assert result.code == 0, result.err
    plain = run_cli("synth", "ex.png", "-o", "plain.png", "--size", "32", "--uv-out",
                    "plain_uv.exr", "--quiet")
    assert plain.code == 0
    assert "guide_weight" not in run_cli("info", "plain.png").out
    # the exemplar's blurred luminance at each output pixel's position follows the target (0 on
    # the left half, 1 on the right): guided 0.20 | 0.61, unguided 0.19 | 0.20
    luminance = auto_guide(read_image("ex.png").pixels)
    target = np.zeros((32, 32), np.float32)
    target[:, 16:] = 1.0

    def mismatch(uv_file):
        uv = np.rint(read_image(uv_file).pixels).astype(int)  # (u, v) = (column, row)
        return np.abs(luminance[uv[..., 1], uv[..., 0]] - target).mean()

    guided, unguided = mismatch("uv.exr"), mismatch("plain_uv.exr")
    assert guided < 0.75 * unguided, (guided, unguided)


@pytest.mark.parametrize("args, message", [
    (["--guide", "ex_guide.png"], "--guide needs --target-guide"),
    (["--target-guide", "target.png", "--method", "paper"], "--target-guide needs --method"),
    (["--target-guide", "target.png", "--also", "ex.png"], "does not combine with --also"),
])
def test_cli_refuses_flag_combinations(run_cli, workdir, args, message):
    result = run_cli("synth", "ex.png", "-o", "out.png", "--size", "32", *args)
    assert result.code == 2 and message in result.err, result.err
    assert not Path("out.png").exists()


def test_cli_refuses_guide_with_several_exemplars(run_cli, workdir):
    result = run_cli("synth", "ex.png", "ex_guide.png", "--out-dir", "o", "--guide",
                     "ex_guide.png", "--target-guide", "target.png")
    assert result.code == 2 and "--guide belongs to one exemplar" in result.err


def test_cli_bad_guide_files_are_one_line(run_cli, workdir):
    write_image(workdir / "five.exr", np.zeros((64, 128, 5), np.float32), 32)
    cases = [
        (["--target-guide", "missing.png"], "missing.png"),
        (["--guide", "target.png", "--target-guide", "target.png"], "target.png: 48x48"),
        (["--guide", "five.exr", "--target-guide", "target.png"], "five.exr: 5 channels"),
        (["--target-guide", "five.exr"], "five.exr: 5 channels"),
    ]
    for args, message in cases:
        result = run_cli("synth", "ex.png", "-o", "out.png", "--size", "32", *args)
        assert result.code == 1, (args, result.err)
        assert len(result.err_lines) == 1 and message in result.err, result.err
        assert "Traceback" not in result.err
    assert not Path("out.png").exists()


def test_help_shows_the_guide_flags(run_cli):
    text = " ".join(run_cli("synth", "--help").out.split())
    for flag in ("--guide GUIDE", "--target-guide GUIDE", "--guide-weight", "Guided synthesis"):
        assert flag in text
    assert "--target-guide photo.jpg" in text


def test_cli_batch_follows_one_target_guide(run_cli, workdir):
    result = run_cli("synth", "ex.png", "ex_guide.png", "--out-dir", "b", "--target-guide",
                     "target.png", "--size", "24", "--json")
    assert result.code == 0, result.err
    records = [json.loads(line) for line in result.out.splitlines() if line.strip()]
    assert len(records) == 2
    for record in records:
        assert record["target_guide"] == "target.png" and "guide" not in record
        assert record["options"]["guide_weight"] == 1.0
    assert Path("b/ex.png").exists() and Path("b/ex_guide.png").exists()


@pytest.mark.parametrize("command", ["inpaint", "tileable"])
def test_fills_take_no_guide_weight(run_cli, workdir, command):
    # a fill follows no target guide: the flag would do nothing, so the fills do not take it
    result = run_cli(command, "ex.png", "-o", "out.png", "--guide-weight", "2")
    assert result.code == 2 and "--guide-weight" in result.err, result.err
    assert not Path("out.png").exists()


def test_a_fill_from_a_preset_file_records_a_command_that_runs(run_cli, workdir):
    # a preset file's every key is written out as a flag, but for those the fills do not take
    Path("mine.toml").write_text("[synth]\nguide_weight = 3.0\nwindow_scale = 2.0\n")
    result = run_cli("tileable", "ex.png", "-o", "out.png", "--preset", "mine.toml",
                     "--seed", "3", "--quiet")
    assert result.code == 0, result.err
    first = Path("out.png").read_bytes()
    info = run_cli("info", "out.png", "--command")
    assert info.code == 0 and "--guide-weight" not in info.out, info.out
    assert "--window-scale" not in info.out and "--seam 1" in info.out, info.out
    os.remove("out.png")
    assert run_cli(*shlex.split(info.out.strip())[1:]).code == 0
    assert Path("out.png").read_bytes() == first

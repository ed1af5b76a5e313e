"""Regular textures keep their lattice: the analysis (osmap_cli.synth.lattice), the snapping
kernels (osmap_kernels.lattice), and synth / inpaint / tileable / --also on procedural bricks
whose lattice is known, scored with tests/texture_stats.regularity (its own autocorrelation,
no code shared with the pipeline)."""

from __future__ import annotations

import numpy as np
import pytest
import texture_stats as ts

from osmap_cli.errors import OsmapError
from osmap_cli.imageio import read_image, write_image
from osmap_cli.synth import SynthOptions, synthesize
from osmap_cli.synth.atlas import synthesize_several
from osmap_cli.synth.fill import border_bands, inpaint, make_tileable
from osmap_cli.synth.lattice import Lattice, find_lattice, parse_lattice
from osmap_cli.synth.regular import level_lattice
from osmap_kernels.lattice import lattice_offsets, lattice_snap


def bricks(size=96, course=12, length=28, seed=1):
    """Running-bond bricks: courses `course` px apart, bricks `length` px long, each course
    shifted by half a brick, 2 px of light mortar, every brick its own tone, a little noise.
    Its lattice: (course, +-length / 2)."""
    rng = np.random.default_rng(seed)
    image = np.full((size, size, 3), 0.8, np.float32)
    for row in range(0, size, course):
        shift = (row // course) % 2 * (length // 2)
        for x0 in range(-length, size, length):
            tone = rng.uniform(0.45, 0.75)
            left, right = max(x0 + shift, 0), max(x0 + shift + length - 2, 0)
            image[row:row + course - 2, left:right] = (tone, tone * rng.uniform(0.5, 0.7),
                                                       tone * 0.4)
    image += rng.normal(0, 0.03, image.shape).astype(np.float32)
    return np.clip(image, 0, 1)


def stripes(size=96, period=10.5, slope=0.02, chirp=0.0):
    """Dark lines across the rows, `period` px apart, tilted by `slope`; `chirp` widens the
    period from top to bottom (a lattice seen in perspective)."""
    rows, cols = np.indices((size, size), dtype=np.float64)
    local = period * (1 + chirp * (rows / size - 0.5))
    phase = (rows - slope * cols) / local
    gray = 0.8 - 0.5 * ((1 + np.cos(2 * np.pi * phase)) / 2) ** 8
    gray = gray + np.random.default_rng(0).normal(0, 0.05, gray.shape)
    return np.repeat(gray[..., None], 3, axis=2).astype(np.float32)


def test_the_analysis_reads_2d_lattices_and_stripes():
    lattice = find_lattice(bricks())
    assert lattice is not None and len(lattice.vectors) == 2
    vectors = sorted(tuple(np.round(np.abs(v), 0)) for v in lattice.vectors)
    assert vectors == [(12.0, 14.0), (12.0, 14.0)], lattice
    lines = find_lattice(stripes())
    assert lines is not None and len(lines.vectors) == 1
    (dy, dx), = lines.vectors
    assert abs(np.hypot(dy, dx) - 10.5) < 0.15 and abs(dx / dy + 0.02) < 0.01, lines


def test_no_lattice_in_noise_perspective_or_the_shipped_stochastic_samples(samples):
    rng = np.random.default_rng(0)
    assert find_lattice(rng.random((96, 96, 3)).astype(np.float32)) is None
    # a period that widens by a third across the image drifts by whole periods: refused
    assert find_lattice(stripes(chirp=0.35)) is None
    for name in ("cells.png", "grass.png", "gravel.png", "brick.png"):  # brick: perspective
        assert find_lattice(read_image(samples / name).pixels) is None, name
    assert len(find_lattice(read_image(samples / "weave.png").pixels).vectors) == 2


def test_lattice_values_parse_x_first_and_refuse_nonsense():
    assert parse_lattice("14,12").vectors == ((12.0, 14.0),)
    assert parse_lattice("28,0:14,12").vectors == ((0.0, 28.0), (12.0, 14.0))
    for bad, message in (("1,2", "at least 4"), ("12", "two numbers"), ("a,b", "two numbers"),
                         ("10,0:20,0", "parallel"), ("5,5:6,6:7,7", "at most two"),
                         ("inf,5", "finite")):
        with pytest.raises(ValueError, match=message):
            parse_lattice(bad)
    with pytest.raises(OsmapError, match="--lattice 12: not two numbers"):
        SynthOptions(lattice="12").validated()


@pytest.mark.parametrize("vectors", [((12.9, 0.2),), ((12.0, -14.0), (12.0, 14.0))])
def test_snapped_positions_are_consistent_integral_and_stay_put(vectors):
    lattice = Lattice(vectors)
    pos = np.zeros((8, 8, 2), np.float32)
    level = level_lattice(lattice, 1, np.eye(2), pos, (0, 0), (200, 200), pinned_phase=True)
    lp, maps = level.params, level.phase_map
    rng = np.random.default_rng(3)
    for _ in range(300):
        y, x = (int(v) for v in rng.integers(0, 64, 2))
        cy, cx = (float(v) for v in rng.integers(20, 180, 2))
        sy, sx = lattice_snap(cy, cx, y, x, lp, maps)
        assert sy == int(sy) and sx == int(sx)
        w0, w1 = lattice_offsets(sy, sx, y, x, lp, maps)
        # within half a pixel of the lattice (2D: on each axis; stripes: across them)
        residual = lattice.basis() @ np.array([w0, w1][:len(vectors)])
        assert np.abs(residual).max() <= 0.5 + 1e-9, residual
        assert lattice_snap(sy, sx, y, x, lp, maps) == (sy, sx)
        # a copy: the position one pixel on, for the pixel one pixel on, is as consistent
        assert lattice_snap(sy + 1, sx + 2, y + 1, x + 2, lp, maps) == (sy + 1, sx + 2)


def test_synth_keeps_the_lattice_that_copies_lose():
    exemplar = bricks()
    kept = synthesize(exemplar, SynthOptions(width=128, height=128, seed=1))
    lost = synthesize(exemplar, SynthOptions(width=128, height=128, seed=1, lattice="off"))
    assert kept.lattice is not None and lost.lattice is None
    short, long_ = ts.regularity(exemplar, kept.pixels)
    # measured: 0.98 / 0.99 (--lattice off: 0.10 / 0.22, courses stepping by half a brick)
    assert short > 0.85 and long_ > 0.85, (short, long_)
    assert ts.regularity(exemplar, lost.pixels)[1] < 0.6
    assert ts.coherence(exemplar, kept.pixels) <= ts.coherence(exemplar, lost.pixels)
    given = synthesize(exemplar, SynthOptions(width=128, height=128, seed=1,
                                              lattice="14,12:-14,12"))
    assert ts.regularity(exemplar, given.pixels)[1] > 0.85


def _phase_error(positions, lattice, exemplar_offset=(0.0, 0.0)):
    """Per pixel, how far (pixels, along each period) its exemplar position sits from the
    lattice phase that the pixel's own position in the image has."""
    rows, cols = np.indices(positions.shape[:2], dtype=np.float64)
    offset = positions - np.stack([rows, cols], -1) - np.asarray(exemplar_offset)
    cycles = offset @ lattice.dual().T
    return np.abs(cycles - np.rint(cycles)) * np.hypot(*lattice.basis())[None, None, :]


def test_inpaint_continues_the_lattice_of_the_kept_pixels():
    image = bricks(size=96)
    hole = np.zeros((96, 96), bool)
    hole[30:66, 30:66] = True
    filled = inpaint(image, hole, SynthOptions(seed=2))
    assert filled.lattice is not None
    error = _phase_error(filled.positions, filled.lattice)[hole]
    assert np.percentile(error, 95) <= 0.75, np.percentile(error, 95)
    assert np.array_equal(filled.pixels[~hole], image[~hole])


def test_tileable_photo_keeps_its_courses_across_the_wrap():
    photo = bricks(size=112)  # 112 = 4 bricks of 28, 9.3 courses of 12: the lattice wraps badly
    assert make_tileable(photo, border=16, options=SynthOptions(seed=1)).lattice is None
    photo = photo[:96]  # 8 courses: the courses and the bricks wrap in step
    tiled = make_tileable(photo, border=16, options=SynthOptions(seed=1))
    assert tiled.lattice is not None
    wrapped = np.tile(tiled.pixels, (2, 2, 1))
    assert ts.regularity(photo, wrapped)[1] > 0.92  # measured 0.99
    error = _phase_error(tiled.positions, tiled.lattice)[border_bands(photo.shape[:2], 16)]
    assert np.percentile(error, 95) <= 0.75, np.percentile(error, 95)


def test_several_exemplars_meet_in_step():
    wall = bricks(size=160)
    # two crops whose courses and bricks sit at different phases
    a, b = wall[:80, :80], wall[37:117, 51:131]
    result = synthesize_several([a, b], SynthOptions(width=128, height=128, seed=1))
    assert result.lattice is not None and 0.2 < (result.exemplar_index == 1).mean() < 0.8
    short, long_ = ts.regularity(a, result.pixels)
    assert short > 0.8 and long_ > 0.8, (short, long_)


def test_cli_reports_records_and_refuses(run_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_image("bricks.png", bricks(size=64), 8)
    result = run_cli("synth", "bricks.png", "-o", "out.png", "--size", "48", "--verbose")
    assert result.code == 0, result.err
    assert "lattice: 2D lattice (--lattice" in result.err + result.out
    assert "lattice" in run_cli("info", "out.png").out
    off = run_cli("synth", "bricks.png", "-o", "off.png", "--size", "48", "--lattice", "off",
                  "--verbose")
    assert off.code == 0 and "lattice: none" in off.err + off.out
    for args in (["--lattice", "2,2"], ["--lattice", "12,0", "--method", "paper"]):
        bad = run_cli("synth", "bricks.png", "-o", "bad.png", "--size", "48", *args)
        assert bad.code == 2 and len(bad.err_lines) == 1, bad.err
        assert "--lattice" in bad.err
    assert not (tmp_path / "bad.png").exists()

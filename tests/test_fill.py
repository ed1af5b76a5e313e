"""osmap inpaint and osmap tileable (osmap_cli.synth.fill): kept pixels bit for bit, a fill that
continues its surroundings without a rim, seamless tiling, and the command lines' contract."""

from __future__ import annotations

import os
import subprocess

import numpy as np
import pytest
from texture_stats import coherence, rim_z, steps


def _hole(shape, size, centre=None):
    free = np.zeros(shape, bool)
    cy, cx = centre or (shape[0] // 2, shape[1] // 2)
    free[cy - size // 2:cy + size // 2, cx - size // 2:cx + size // 2] = True
    return free


def _blob(shape):
    yy, xx = np.mgrid[:shape[0], :shape[1]]
    cy, cx = shape[0] // 2, shape[1] // 2
    angle, radius = np.arctan2(yy - cy, xx - cx), np.hypot(yy - cy, xx - cx)
    return radius < 22 + 7 * np.sin(3 * angle) + 4 * np.cos(5 * angle + 1)


def detail(image, where):
    """Mean step between horizontally and vertically adjacent pixels that are both in `where`."""
    values = [steps(image, axis)[where & np.roll(where, -1, axis)] for axis in (0, 1)]
    return np.concatenate(values).mean()


def seam_z(image):
    """texmetrics' wrap-around seam z-score, worst axis: the wrap step among the interior
    per-line mean steps."""
    worst = -np.inf
    for axis in (0, 1):
        per = steps(image, axis).mean(axis=1 - axis)
        inner = per[:-1]
        worst = max(worst, (per[-1] - inner.mean()) / inner.std())
    return worst


def _check_fill(image, result, free, rows_outside):
    """Kept pixels bit for bit, positions never inside the hole, coherence of a crop around the
    hole within 1.3x of the untouched crop, no rim."""
    assert np.array_equal(result.pixels[~free], image[~free])
    ys, xs = np.nonzero(free)
    used = np.rint(result.positions[free]).astype(int)
    assert not free[used[:, 0], used[:, 1]].any(), "the fill copied the hole's own content"
    y0, y1 = max(ys.min() - 12, 0), ys.max() + 13
    x0, x1 = max(xs.min() - 12, 0), xs.max() + 13
    reference = image[rows_outside]
    untouched = coherence(reference, image[y0:y1, x0:x1], stride=2)
    filled = coherence(reference, result.pixels[y0:y1, x0:x1], stride=2)
    assert filled < 1.3 * untouched, (filled, untouched)
    z = rim_z(image, result.pixels, free)
    assert z < 3.0, z
    # as much detail as the rest of the image (nearest-patch coherence alone lets blur pass)
    ratio = detail(result.pixels, free) / detail(image, ~free)
    assert 0.75 < ratio < 1.3, ratio


@pytest.fixture(scope="module")
def gravel(samples):
    from osmap_cli.imageio import read_image

    return read_image(samples / "gravel.png").pixels


def test_inpaint_square_hole_continues_its_surroundings(gravel):
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import fill

    free = _hole(gravel.shape[:2], 40)
    result = fill(gravel, free, SynthOptions(seed=1), source_free=False)
    rows = ~free.any(axis=1)
    _check_fill(gravel, result, free, rows)
    # the checks can fail: a smooth fill has no detail, a pasted patch leaves a rim
    from osmap_cli.synth.constraints import push_pull

    assert detail(push_pull(gravel, ~free), free) < 0.5 * detail(gravel, ~free)
    pasted = np.where(free[..., None], np.roll(gravel, (50, 50), (0, 1)), gravel)
    assert rim_z(gravel, pasted, free) > 3.0


def test_inpaint_irregular_mask_colour(samples):
    from osmap_cli.imageio import read_image
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import fill

    image = read_image(samples / "cells.png").pixels
    free = _blob(image.shape[:2])
    result = fill(image, free, SynthOptions(seed=2), source_free=False)
    _check_fill(image, result, free, ~free.any(axis=1))


def test_tileable_bands_wrap_without_seam(samples):
    from osmap_cli.imageio import read_image
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import border_bands, fill

    image = read_image(samples / "wood_side.png").pixels
    free = border_bands(image.shape[:2], 16)
    assert seam_z(image) > 3.0  # the photo as it is does not tile
    result = fill(image, free, SynthOptions(tileable=True), source_free=True)
    assert np.array_equal(result.pixels[~free], image[~free])
    assert seam_z(result.pixels) < 3.0
    band = coherence(image, np.roll(result.pixels, (16, 16), (0, 1))[:40], stride=2)
    whole = coherence(image, np.roll(image, (16, 16), (0, 1))[:40], stride=2)
    assert band < 1.3 * whole, (band, whole)


def test_tileable_occupancy_counts_the_bands_only(samples):
    from osmap_cli.imageio import read_image
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.constraints import LevelConstraint, identity_positions
    from osmap_cli.synth.fill import border_bands, make_tileable

    free = border_bands((32, 32), 4)
    pos = identity_positions((32, 32))
    none = np.zeros((32, 32), bool)
    used, samples_ = LevelConstraint(~free, pos, none, count_pinned=False).counted(pos, 1024)
    assert used.shape == (1, int(free.sum()), 2) and samples_ == 1024
    assert np.array_equal(used[0], pos[free])
    used, samples_ = LevelConstraint(~free, pos, none).counted(pos, 1024)
    assert used is pos and samples_ == 32 * 32
    # the option acts on tileable: without the penalty the bands repeat more of the centre
    image = read_image(samples / "wood_side.png").pixels
    a = make_tileable(image, 16, SynthOptions(seed=1))
    b = make_tileable(image, 16, SynthOptions(seed=1, occupancy=0.0))
    assert not np.array_equal(a.pixels, b.pixels)


def test_fill_refuses_empty_and_full_masks(gravel):
    from osmap_cli.errors import OsmapError
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import fill

    for mask in (np.zeros(gravel.shape[:2], bool), np.ones(gravel.shape[:2], bool)):
        with pytest.raises(OsmapError):
            fill(gravel, mask, SynthOptions(), source_free=False)


# --------------------------------------------------------------------------------------------
# the command lines


def _write(path, pixels, names=None):
    from osmap_cli.imageio import write_image

    write_image(path, np.asarray(pixels, np.float32), 8, names)
    return path


@pytest.fixture(scope="module")
def material(samples, tmp_path_factory):
    """A 64x64 image, an aligned map, a mask with a 20x20 hole and an RGBA copy whose hole is
    transparent."""
    from osmap_cli.imageio import read_image

    folder = tmp_path_factory.mktemp("fill")
    image = read_image(samples / "cells.png").pixels[:64, :64]
    rough = read_image(samples / "brick.png").pixels[:64, :64]
    free = _hole((64, 64), 20)
    rgba = np.concatenate([image, (~free)[..., None].astype(np.float32)], axis=2)
    return {"image": _write(folder / "img.png", image),
            "rough": _write(folder / "img_rough.png", rough),
            "mask": _write(folder / "img_mask.png", free[..., None]),
            "rgba": _write(folder / "img_rgba.png", rgba, ("R", "G", "B", "A")),
            "free": free, "folder": folder}


def test_inpaint_cli_keeps_maps_and_positions_aligned(material, run_cli, tmp_path):
    from osmap_cli.imageio import read_image, read_metadata

    out, uv = tmp_path / "out.png", tmp_path / "uv.exr"
    result = run_cli("inpaint", material["image"], "--mask", material["mask"], "-o", out,
                     "--with", f"rough={material['rough']}", "--uv-out", uv, "--seed", "3")
    assert result.code == 0, result.err
    free = material["free"]
    image = read_image(material["image"]).pixels
    written = read_image(out).pixels
    assert np.array_equal(written[~free], image[~free])
    positions = read_image(uv).pixels[..., ::-1]  # (u, v) -> (row, col)
    rows, cols = np.indices(free.shape)
    assert np.array_equal(positions[~free], np.stack([rows, cols], -1)[~free])
    rough = read_image(material["rough"]).pixels
    rough_out = read_image(tmp_path / "out_rough.png").pixels
    assert np.array_equal(rough_out[~free], rough[~free])
    # inside the hole (away from its border blending) the map follows the image's positions
    inner = _hole((64, 64), 12)
    ys, xs = np.nonzero(inner)
    idx = np.rint(positions[ys, xs]).astype(int)
    assert np.abs(rough_out[ys, xs] - rough[idx[:, 0], idx[:, 1]]).mean() < 0.05
    meta = read_metadata(out)
    assert meta["command"] == "inpaint" and meta["mask"] == "img_mask.png"
    info = run_cli("info", out, "--command")
    assert info.out.startswith("osmap inpaint img.png -o ") and "--mask img_mask.png" in info.out


def test_inpaint_alpha_mask(material, run_cli, tmp_path):
    from osmap_cli.imageio import read_image

    out = tmp_path / "out.png"
    result = run_cli("inpaint", material["rgba"], "--mask", "alpha", "-o", out)
    assert result.code == 0, result.err
    written = read_image(out).pixels
    free = material["free"]
    source = read_image(material["rgba"]).pixels
    assert np.array_equal(written[~free], source[~free])
    assert (written[free][:, 3] == 1.0).all()  # the fill is opaque, like what it copies


def test_fill_errors_are_one_line_and_write_nothing(material, run_cli, tmp_path):
    folder = material["folder"]
    small = _write(folder / "small_mask.png", np.ones((32, 64, 1)))
    empty = _write(folder / "empty_mask.png", np.zeros((64, 64, 1)))
    out = tmp_path / "out.png"
    cases = [
        (("inpaint", material["image"], "--mask", small), "32", "64x64"),
        (("inpaint", material["image"], "--mask", empty), "empty", "empty_mask.png"),
        (("inpaint", material["image"], "--mask", "alpha"), "no alpha", "img.png"),
        (("tileable", material["image"], "--border", "40"), "allowed 1 to 31", "img.png"),
    ]
    for args, phrase, name in cases:
        result = run_cli(*args, "-o", out)
        assert result.code == 1, result.err
        assert len(result.err_lines) == 1 and phrase in result.err and name in result.err, \
            result.err
        assert not out.exists()
    assert run_cli("tileable", material["image"], "--border", "-1", "-o", out).code == 2
    assert run_cli("inpaint", material["image"], "-o", out).code == 2  # --mask is required


def test_tileable_batch_same_bytes_any_threads(material, osmap_exe, tmp_path):
    """-j 2 --json in --out-dir, and separate runs with 1 or 2 Numba threads: same bytes."""
    import json

    from osmap_cli.imageio import read_image

    second = _write(material["folder"] / "img2.png",
                    np.roll(read_image(material["image"]).pixels, 20, 1))
    base = [osmap_exe, "tileable", "--border", "10", "--seed", "4"]
    done = subprocess.run([*base, str(material["image"]), str(second), "--out-dir",
                           str(tmp_path / "batch"), "-j", "2", "--json"],
                          capture_output=True, text=True, env=os.environ)
    assert done.returncode == 0, done.stderr
    records = [json.loads(line) for line in done.stdout.splitlines()]
    assert sorted(r["status"] for r in records) == ["ok", "ok"]
    assert all(r["options"]["border"] == 10 for r in records)
    outputs = []
    for threads in ("1", "2"):
        path = tmp_path / f"t{threads}.png"
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        run = subprocess.run([*base, str(material["image"]), "-o", str(path)],
                             capture_output=True, text=True, env=env)
        assert run.returncode == 0, run.stderr
        outputs.append(path.read_bytes())
    assert outputs[0] == outputs[1] == (tmp_path / "batch" / "img.png").read_bytes()


def test_fill_help_lists_the_flags_that_apply(run_cli, repo_root):
    from osmap_cli.options import flag, tunables
    from osmap_cli.synth.options import NOT_FILL_TUNABLES, SynthOptions

    usage = (repo_root / "docs" / "usage.md").read_text()
    for command, own in (("inpaint", "--mask"), ("tileable", "--border")):
        result = run_cli(command, "--help")
        assert result.code == 0
        text = " ".join(result.out.split())
        assert own in text and f"osmap {command} " in text and own in usage
        for name in tunables(SynthOptions):
            assert (flag(name) in text) == (name not in NOT_FILL_TUNABLES), (command, name)


# --------------------------------------------------------------------------------------------
# inpaint --exemplar: the hole filled from other images


def _tinted(pixels, tint):
    """pixels (any channels) as RGB, multiplied by tint: colours no other test image has."""
    rgb = np.repeat(pixels[..., :1], 3, 2) if pixels.shape[2] < 3 else pixels[..., :3]
    return (rgb * np.array(tint, np.float32)).astype(np.float32)


def test_inpaint_from_exemplars_draws_the_fill_from_them(samples):
    """The fill's positions lie in the exemplars, its colours are theirs (a red and a blue
    brick where the image is cells), the kept pixels are bit for bit."""
    from osmap_cli.imageio import read_image
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import inpaint

    image = read_image(samples / "cells.png").pixels[:80, :80]
    brick = read_image(samples / "brick.png").pixels
    red, blue = _tinted(brick[:64, :64], (1, 0.2, 0.1)), _tinted(brick[64:128, :72], (0.1, 0.2, 1))
    free = _hole((80, 80), 32)
    result = inpaint(image, free, SynthOptions(seed=1), exemplars=[red, blue])
    assert np.array_equal(result.pixels[~free], image[~free])
    index = result.exemplar_index
    assert (index[~free] == -1).all() and (index[free] >= 0).all()
    # local positions inside their exemplar, and the pixels rendered from them
    local = np.rint(result.local_positions[free]).astype(int)
    sizes = np.array([red.shape[:2], blue.shape[:2]])[index[free]]
    assert (local >= 0).all() and (local < sizes).all()
    inner = _hole((80, 80), 20)  # away from the border correction
    ys, xs = np.nonzero(inner)
    sources = [red, blue]
    drawn = np.array([sources[i][r, c] for i, (r, c) in
                      zip(index[ys, xs], np.rint(result.local_positions[ys, xs]).astype(int))])
    assert np.abs(result.pixels[ys, xs] - drawn).mean() < 0.05
    # the colours are the exemplars': red or blue dominates every inner pixel, which cells'
    # colours (any hue) would not give
    pix = result.pixels[inner]
    assert (np.abs(pix[:, 0] - pix[:, 2]) > 0.5 * pix[:, :3].max(1) - 1e-3).mean() > 0.9
    # without exemplars the same hole comes from the image itself
    own = inpaint(image, free, SynthOptions(seed=1))
    assert not np.array_equal(own.pixels[free], result.pixels[free])


def test_inpaint_from_exemplars_refuses_other_channels(gravel):
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.fill import inpaint

    with pytest.raises(ValueError, match="same channels"):
        inpaint(gravel, _hole(gravel.shape[:2], 20), SynthOptions(),
                exemplars=[np.zeros((32, 32, 2), np.float32)])


def test_inpaint_exemplar_cli(material, samples, run_cli, tmp_path):
    """--exemplar (repeatable, {stem} expanded) with a mask file and with --mask alpha: kept
    pixels bit for bit, the fill from the exemplar, provenance, the refusals."""
    from osmap_cli.imageio import read_image, read_metadata

    folder = material["folder"]
    brick = read_image(samples / "brick.png").pixels
    red = _write(folder / "img_red.png", _tinted(brick[:64, :64], (1, 0.2, 0.1)))
    gray = _write(folder / "gray.png", brick[:64, :64])
    free = material["free"]
    image = read_image(material["image"]).pixels
    out = tmp_path / "out.png"
    result = run_cli("inpaint", material["image"], "--mask", material["mask"], "-o", out,
                     "--exemplar", str(folder / "{stem}_red.png"), "--seed", "2")
    assert result.code == 0, result.err
    written = read_image(out).pixels
    assert np.array_equal(written[~free], image[~free])
    inner = _hole((64, 64), 12)
    assert (written[inner][:, 0] > 2 * written[inner][:, 2]).mean() > 0.9  # red, like EX
    meta = read_metadata(out)
    assert meta["exemplars"] == "img_red.png"
    info = run_cli("info", out, "--command")
    assert "--exemplar img_red.png" in info.out and "--mask img_mask.png" in info.out
    # --mask alpha: an RGBA image, an RGB exemplar (taken as opaque)
    out_a = tmp_path / "out_a.png"
    result = run_cli("inpaint", material["rgba"], "--mask", "alpha", "--exemplar", red,
                     "--exemplar", red, "-o", out_a)
    assert result.code == 0, result.err
    rgba = read_image(out_a).pixels
    source = read_image(material["rgba"]).pixels
    assert np.array_equal(rgba[~free], source[~free]) and (rgba[free][:, 3] == 1.0).all()
    assert (rgba[inner][:, 0] > 2 * rgba[inner][:, 2]).mean() > 0.9
    # refusals: one line, nothing written
    bad = tmp_path / "bad.png"
    for args, code, phrase in (
            (("--exemplar", gray), 1, "gray.png: 1 channels"),
            (("--exemplar", folder / "none.png"), 1, "none.png"),
            (("--exemplar", _write(folder / "tiny.png", np.full((5, 5, 3), 0.5))), 1,
             "tiny.png: the exemplars are too small"),
            (("--exemplar", red, "--with", f"r={material['rough']}"), 2, "--with"),
            (("--exemplar", red, "--uv-out", tmp_path / "uv.exr"), 2, "--uv-out")):
        result = run_cli("inpaint", material["image"], "--mask", material["mask"], "-o", bad,
                         *args)
        assert result.code == code and phrase in result.err, result.err
        assert len(result.err_lines) == 1 and not bad.exists()
        assert "Traceback" not in result.err
    text = " ".join(run_cli("inpaint", "--help").out.split())
    assert "--exemplar EX" in text and "osmap inpaint wall.png --mask hole.png --exemplar" in text


def test_inpaint_exemplar_same_bytes_any_threads(material, samples, osmap_exe, tmp_path):
    from osmap_cli.imageio import read_image

    red = _write(tmp_path / "red.png",
                 _tinted(read_image(samples / "brick.png").pixels[:48, :64], (1, 0.2, 0.1)))
    outputs = []
    for threads in ("1", "2"):
        path = tmp_path / f"t{threads}.png"
        run = subprocess.run([osmap_exe, "inpaint", str(material["image"]), "--mask",
                              str(material["mask"]), "--exemplar", str(red), "-o", str(path)],
                             capture_output=True, text=True,
                             env=dict(os.environ, NUMBA_NUM_THREADS=threads))
        assert run.returncode == 0, run.stderr
        outputs.append(path.read_bytes())
    assert outputs[0] == outputs[1]

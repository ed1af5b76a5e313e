"""Tests for osmap_cli.imageio: round trips, metadata, atomic writes and every error path."""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np
import OpenImageIO as oiio
import pytest

from osmap_cli import image_write
from osmap_cli.errors import OsmapError
from osmap_cli.imageio import output_format, read_image, read_metadata, write_image


def _random(shape, seed=0, scale=1.0):
    return (np.random.default_rng(seed).random(shape) * scale).astype(np.float32)


def _smooth(h=32, w=32, c=3):
    """A smooth gradient: survives JPEG compression with small error."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    chans = [(x / w), (y / h), ((x + y) / (w + h)), np.full((h, w), 0.75, np.float32)]
    return np.stack(chans[:c], axis=-1).astype(np.float32)


def _listing(directory):
    return sorted(os.listdir(directory))


# ---------------------------------------------------------------------------------------------
# round trips


@pytest.mark.parametrize(
    "ext, depth, tol",
    [
        ("png", 8, 0.5 / 255 + 1e-6),
        ("png", 16, 0.5 / 65535 + 1e-7),
        ("tif", 8, 0.5 / 255 + 1e-6),
        ("tiff", 16, 0.5 / 65535 + 1e-7),
        ("tif", 32, 0.0),
        ("exr", 16, 1e-3),
        ("exr", 32, 0.0),
    ],
)
def test_round_trip_formats_and_depths(tmp_path, ext, depth, tol):
    pixels = _random((12, 20, 4), seed=depth)
    path = tmp_path / f"img.{ext}"
    write_image(path, pixels, depth)
    image = read_image(path)
    assert image.pixels.dtype == np.float32
    assert image.pixels.shape == (12, 20, 4)
    assert image.bit_depth == (32 if ext == "exr" else depth)
    assert image.channel_names == ("R", "G", "B", "A")
    assert image.alpha_channel == 3
    assert image.path == str(path)
    err = np.abs(image.pixels - pixels).max()
    assert err <= tol
    # the data really was quantised where it should be (guards against a float fallback)
    if depth == 8:
        assert np.allclose(image.pixels * 255, np.round(image.pixels * 255), atol=1e-3)


@pytest.mark.parametrize("ext", ["png", "tif", "exr", "jpg"])
def test_default_bit_depths(tmp_path, ext):
    path = tmp_path / f"d.{ext}"
    write_image(path, _smooth(c=3))
    image = read_image(path)
    assert image.bit_depth == {"png": 8, "tif": 8, "exr": 32, "jpg": 8}[ext]
    if ext == "exr":  # default EXR is half: exact only to ~1e-3
        stored = str(_spec(path).format)
        assert stored == "half"


def _spec(path):
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None
    spec = inp.spec()
    inp.close()
    return spec


def test_jpeg_round_trip_smooth_image(tmp_path):
    pixels = _smooth(c=3)
    path = tmp_path / "smooth.JPG"  # extension is case-insensitive
    write_image(path, pixels)
    image = read_image(path)
    assert image.pixels.shape == (32, 32, 3)
    assert image.bit_depth == 8
    assert np.abs(image.pixels - pixels).mean() < 0.01
    assert np.abs(image.pixels - pixels).max() < 0.06


@pytest.mark.parametrize(
    "channels, names, alpha",
    [
        (1, ("Y",), None),
        (2, ("Y", "A"), 1),
        (3, ("R", "G", "B"), None),
        (4, ("R", "G", "B", "A"), 3),
    ],
)
def test_png_channel_counts(tmp_path, channels, names, alpha):
    pixels = _random((9, 7, channels), seed=channels)
    path = tmp_path / f"c{channels}.png"
    write_image(path, pixels)
    image = read_image(path)
    assert image.pixels.shape == (9, 7, channels)
    assert image.channel_names == names
    assert image.alpha_channel == alpha
    assert np.abs(image.pixels - pixels).max() <= 0.5 / 255 + 1e-6


def test_two_dimensional_array_is_one_channel(tmp_path):
    pixels = _random((6, 5))
    write_image(tmp_path / "g.png", pixels)
    image = read_image(tmp_path / "g.png")
    assert image.pixels.shape == (6, 5, 1)
    assert np.abs(image.pixels[..., 0] - pixels).max() <= 0.5 / 255 + 1e-6


def test_rgba_png_keeps_straight_alpha(tmp_path):
    # colour under alpha 0 must survive: no premultiplication on write or read
    pixels = np.zeros((4, 4, 4), np.float32)
    pixels[..., :3] = [0.8, 0.4, 0.2]
    pixels[:2, :, 3] = 0.0
    pixels[2:, :, 3] = 0.5
    for depth in (8, 16):
        write_image(tmp_path / "a.png", pixels, depth)
        got = read_image(tmp_path / "a.png").pixels
        assert np.abs(got - pixels).max() <= 0.5 / 255 + 1e-6
    write_image(tmp_path / "a.tif", pixels)
    got = read_image(tmp_path / "a.tif").pixels
    assert np.abs(got - pixels).max() <= 0.5 / 255 + 1e-6


def test_two_channel_float_exr_with_names(tmp_path):
    pos = _random((10, 11, 2), seed=5, scale=1000.0) - 300.0  # outside [0, 1]: stored as is
    path = tmp_path / "pos.exr"
    write_image(path, pos, 32, channel_names=("u", "v"))
    image = read_image(path)
    assert image.channel_names == ("u", "v")
    assert image.alpha_channel is None
    assert image.bit_depth == 32
    np.testing.assert_array_equal(image.pixels, pos)


def test_exr_many_channels(tmp_path):
    data = _random((5, 6, 7), seed=7)
    path = tmp_path / "many.exr"
    write_image(path, data, 32)
    image = read_image(path)
    assert image.pixels.shape == (5, 6, 7)
    assert len(image.channel_names) == 7
    assert len(set(image.channel_names)) == 7
    np.testing.assert_array_equal(image.pixels, data)


def test_half_exr_precision(tmp_path):
    data = _random((16, 16, 3), seed=3)
    write_image(tmp_path / "h.exr", data, 16)
    got = read_image(tmp_path / "h.exr").pixels
    err = np.abs(got - data).max()
    assert 0 < err <= 1e-3  # half, not float, was stored
    np.testing.assert_array_equal(got, data.astype(np.float16).astype(np.float32))


def test_16bit_png_keeps_16bit_precision(tmp_path):
    levels = np.arange(0, 65536, 257 // 2 + 1, dtype=np.float64)[: 16 * 16]
    levels = levels + (np.arange(levels.size) % 7)  # values that are not multiples of 257
    data = (levels / 65535.0).reshape(16, 16, 1).astype(np.float32)
    path = tmp_path / "deep.png"
    write_image(path, data, 16)
    image = read_image(path)
    assert image.bit_depth == 16
    assert str(_spec(path).format) == "uint16"
    np.testing.assert_array_equal(np.rint(image.pixels * 65535), levels.reshape(16, 16, 1))
    # an 8-bit file could not hold these values
    assert np.abs(image.pixels * 255 - np.rint(image.pixels * 255)).max() > 0.1


def test_integer_formats_round_and_clip(tmp_path):
    k = np.arange(0, 250, 10, dtype=np.float32)
    row = np.concatenate([(k + 0.4) / 255, (k + 0.6) / 255, [-0.5, 2.0, np.nan]])
    data = row.reshape(1, -1, 1).astype(np.float32)
    write_image(tmp_path / "r.png", data)
    got = np.rint(read_image(tmp_path / "r.png").pixels[0, :, 0] * 255)
    n = k.size
    np.testing.assert_array_equal(got[:n], k)  # x.4 rounds down
    np.testing.assert_array_equal(got[n : 2 * n], k + 1)  # x.6 rounds up (truncation would not)
    np.testing.assert_array_equal(got[2 * n :], [0, 255, 0])  # clipped; NaN written as 0


def test_jpeg_drops_alpha_named_a(tmp_path):
    rgba = _smooth(c=4)
    write_image(tmp_path / "x.jpg", rgba, channel_names=("R", "G", "B", "A"))
    image = read_image(tmp_path / "x.jpg")
    assert image.pixels.shape == (32, 32, 3)
    assert np.abs(image.pixels - rgba[..., :3]).mean() < 0.01
    write_image(tmp_path / "ya.jpg", _smooth(c=2), channel_names=("Y", "A"))
    assert read_image(tmp_path / "ya.jpg").pixels.shape == (32, 32, 1)


def test_jpeg_refuses_non_alpha_fourth_channel(tmp_path):
    with pytest.raises(OsmapError, match=r"x\.jpg: JPEG cannot store 4 channels"):
        write_image(tmp_path / "x.jpg", _smooth(c=4), channel_names=("R", "G", "B", "Z"))
    assert _listing(tmp_path) == []


def test_write_overwrites_and_leaves_no_temp(tmp_path):
    path = tmp_path / "o.png"
    write_image(path, np.zeros((4, 4, 3), np.float32))
    write_image(str(path), np.ones((4, 4, 3), np.float32))
    assert _listing(tmp_path) == ["o.png"]
    assert read_image(path).pixels.min() == 1.0


def test_first_subimage_of_multi_subimage_file(tmp_path):
    path = str(tmp_path / "multi.tif")
    first = np.full((4, 5, 3), 0.25, np.float32)
    second = np.full((6, 7, 3), 0.75, np.float32)
    out = oiio.ImageOutput.create(path)
    assert out.supports("multiimage")
    specs = (oiio.ImageSpec(5, 4, 3, "float"), oiio.ImageSpec(7, 6, 3, "float"))
    assert out.open(path, specs)
    assert out.write_image(first)
    assert out.open(path, specs[1], "AppendSubimage")
    assert out.write_image(second)
    out.close()
    image = read_image(path)
    np.testing.assert_array_equal(image.pixels, first)


# ---------------------------------------------------------------------------------------------
# metadata


META = {"command": "osmap synth bricks.png -o out.png --seed 3", "seed": "3", "note": "ä → ü"}


@pytest.mark.parametrize("ext", ["png", "exr", "tif", "jpg"])
def test_metadata_round_trip(tmp_path, ext):
    path = tmp_path / f"m.{ext}"
    write_image(path, _smooth(c=3), metadata=META)
    assert read_metadata(path) == META
    # reading pixels is unaffected
    assert read_image(path).pixels.shape == (32, 32, 3)


def test_metadata_stored_under_prefix(tmp_path):
    for ext in ("png", "exr"):
        path = tmp_path / f"p.{ext}"
        write_image(path, _smooth(c=3), metadata={"command": "x"})
        attrs = {p.name: p.value for p in _spec(path).extra_attribs}
        assert attrs.get("osmap:command") == "x"


def test_metadata_absent_and_foreign_attributes_ignored(tmp_path):
    path = str(tmp_path / "plain.png")
    write_image(path, _smooth(c=3))
    assert read_metadata(path) == {}
    # a file with other text chunks written by someone else
    spec = oiio.ImageSpec(4, 4, 3, "uint8")
    spec.attribute("Software", "other tool")
    spec.attribute("Comment", "hello")
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec)
    assert out.write_image(np.zeros((4, 4, 3), np.uint8))
    out.close()
    assert read_metadata(path) == {}


def test_read_metadata_errors(tmp_path):
    with pytest.raises(OsmapError, match="nothere.png"):
        read_metadata(tmp_path / "nothere.png")
    (tmp_path / "junk.png").write_bytes(b"not an image at all")
    with pytest.raises(OsmapError, match="junk.png"):
        read_metadata(tmp_path / "junk.png")


# ---------------------------------------------------------------------------------------------
# read errors


def _png_bytes(width, height, payload=None):
    def chunk(kind, data):
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    raw = payload if payload is not None else b"\x00" * (height * (width + 1))
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def test_handmade_png_helper_is_valid(tmp_path):
    (tmp_path / "ok.png").write_bytes(_png_bytes(3, 2))
    image = read_image(tmp_path / "ok.png")
    assert image.pixels.shape == (2, 3, 1)


def _big_file(tmp_path, ext, depth):
    path = tmp_path / f"big.{ext}"
    write_image(path, _random((128, 128, 3), seed=11), depth)
    return path.read_bytes()


def test_missing_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OsmapError, match=r"^missing\.png: no such file$"):
        read_image("missing.png")


def test_directory(tmp_path):
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(OsmapError, match=r"folder\.png: is a directory"):
        read_image(tmp_path / "folder.png")


def test_zero_byte_file(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(OsmapError, match=r"empty\.png: empty file"):
        read_image(tmp_path / "empty.png")


@pytest.mark.parametrize("name", ["notes.png", "notes.exr", "notes.txt"])
def test_not_an_image(tmp_path, name):
    (tmp_path / name).write_text("just some text, definitely not pixels\n" * 20)
    with pytest.raises(OsmapError) as info:
        read_image(tmp_path / name)
    assert str(info.value).startswith(f"{tmp_path / name}: not an image")


@pytest.mark.parametrize(
    "ext, depth", [("png", 8), ("png", 16), ("exr", 16), ("tif", 8), ("jpg", 8)]
)
def test_truncated_file(tmp_path, ext, depth):
    data = _big_file(tmp_path, ext, depth)
    path = tmp_path / f"cut.{ext}"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(OsmapError) as info:
        read_image(path)
    message = str(info.value)
    assert message.startswith(f"{path}: truncated or corrupt")
    assert "\n" not in message


def test_corrupt_png_data(tmp_path):
    data = bytearray(_big_file(tmp_path, "png", 8))
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(b ^ 0x5A for b in data[middle : middle + 64])
    path = tmp_path / "bricks.png"
    path.write_bytes(bytes(data))
    with pytest.raises(OsmapError, match=r"bricks\.png: truncated or corrupt PNG"):
        read_image(path)


def test_truncated_png_prints_nothing_on_stderr(tmp_path, capfd):
    data = _big_file(tmp_path, "png", 8)
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(OsmapError):
        read_image(tmp_path / "cut.png")
    captured = capfd.readouterr()
    assert "libpng" not in captured.err
    assert captured.err == ""


def test_zero_size_image(tmp_path):
    path = tmp_path / "zero.png"
    path.write_bytes(_png_bytes(0, 0, payload=b""))
    with pytest.raises(OsmapError, match=r"zero\.png: "):
        read_image(path)


def test_png_with_too_little_pixel_data(tmp_path):
    # valid chunk structure, but the IDAT stream holds only half the rows
    path = tmp_path / "short.png"
    path.write_bytes(_png_bytes(8, 8, payload=b"\x00" * (4 * 9)))
    with pytest.raises(OsmapError, match=r"short\.png: truncated or corrupt PNG"):
        read_image(path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can read any file")
def test_unreadable_file(tmp_path):
    path = tmp_path / "secret.png"
    write_image(path, _smooth())
    path.chmod(0)
    with pytest.raises(OsmapError, match=r"secret\.png: cannot open file"):
        read_image(path)


# ---------------------------------------------------------------------------------------------
# output_format


@pytest.mark.parametrize(
    "name, depth, expected",
    [
        ("a.png", None, ("png", 8)),
        ("a.PNG", 16, ("png", 16)),
        ("a.exr", None, ("openexr", 16)),
        ("a.exr", 32, ("openexr", 32)),
        ("a.tif", None, ("tiff", 8)),
        ("a.tiff", 32, ("tiff", 32)),
        ("a.jpg", None, ("jpeg", 8)),
        ("a.JPEG", 8, ("jpeg", 8)),
    ],
)
def test_output_format_valid(tmp_path, name, depth, expected):
    assert output_format(tmp_path / name, depth) == expected


@pytest.mark.parametrize("name", ["out.bmp", "out", "out.png.bak"])
def test_output_format_unknown_extension(tmp_path, name):
    with pytest.raises(OsmapError) as info:
        output_format(tmp_path / name)
    message = str(info.value)
    assert name in message
    for ext in (".png", ".exr", ".tif", ".jpg"):
        assert ext in message


@pytest.mark.parametrize(
    "name, depth, allowed",
    [
        ("o.jpg", 16, "8"),
        ("o.png", 32, "8, 16"),
        ("o.exr", 8, "16, 32"),
        ("o.tif", 12, "8, 16, 32"),
    ],
)
def test_output_format_bad_bit_depth(tmp_path, name, depth, allowed):
    with pytest.raises(OsmapError) as info:
        output_format(tmp_path / name, depth)
    message = str(info.value)
    assert name in message
    assert f"bit depth {depth}" in message
    assert f"allowed: {allowed}" in message


def test_output_format_channels(tmp_path):
    with pytest.raises(OsmapError, match=r"o\.png: PNG can store at most 4 channels"):
        output_format(tmp_path / "o.png", channels=5)
    assert output_format(tmp_path / "o.exr", channels=9) == ("openexr", 16)
    with pytest.raises(OsmapError, match=r"o\.exr"):
        output_format(tmp_path / "o.exr", channels=0)


def test_output_format_missing_directory(tmp_path):
    target = tmp_path / "nope" / "out.png"
    with pytest.raises(OsmapError, match=r"out\.png: output directory .*nope does not exist"):
        output_format(target)


def test_output_format_parent_is_a_file(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OsmapError, match=r"out\.png: output directory .* is not a directory"):
        output_format(tmp_path / "file" / "out.png")


def test_output_format_existing_directory(tmp_path):
    (tmp_path / "d.png").mkdir()
    with pytest.raises(OsmapError, match=r"d\.png: is an existing directory"):
        output_format(tmp_path / "d.png")


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_output_format_unwritable_directory(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        with pytest.raises(OsmapError, match="not writable"):
            output_format(locked / "o.png")
    finally:
        locked.chmod(0o755)


# ---------------------------------------------------------------------------------------------
# write errors and atomicity


def test_write_into_missing_directory(tmp_path):
    with pytest.raises(OsmapError, match=r"out\.png"):
        write_image(tmp_path / "missing" / "out.png", _smooth())
    assert _listing(tmp_path) == []


def test_write_bad_bit_depth_and_extension(tmp_path):
    with pytest.raises(OsmapError, match=r"o\.jpg: JPEG cannot store bit depth 16"):
        write_image(tmp_path / "o.jpg", _smooth(), 16)
    with pytest.raises(OsmapError, match=r"o\.gif"):
        write_image(tmp_path / "o.gif", _smooth())
    with pytest.raises(OsmapError, match=r"o\.png: 2 channel names given for 3 channels"):
        write_image(tmp_path / "o.png", _smooth(), channel_names=("R", "G"))
    assert _listing(tmp_path) == []


def _half_then(fail):
    """A _write_pixels replacement: really writes half the scanlines, then fails."""
    seen = {}

    def broken(out, data):
        h = data.shape[0] // 2
        assert out.write_scanlines(0, h, 0, data[:h])
        seen["files"] = _listing(seen["dir"])
        return fail()

    return broken, seen


@pytest.mark.parametrize("ext", ["png", "exr", "tif"])
@pytest.mark.parametrize("how", ["returns_false", "raises"])
def test_failed_write_leaves_nothing(tmp_path, monkeypatch, ext, how):
    def fail():
        if how == "raises":
            raise RuntimeError("disk on fire")
        return False

    broken, seen = _half_then(fail)
    seen["dir"] = tmp_path
    monkeypatch.setattr(image_write, "_write_pixels", broken)
    with pytest.raises(OsmapError) as info:
        write_image(tmp_path / f"out.{ext}", _random((64, 64, 3)))
    assert f"out.{ext}" in str(info.value)
    # mid-write there was a hidden temp file with the same extension, never the target
    assert len(seen["files"]) == 1
    temp = seen["files"][0]
    assert temp.startswith(".osmap-") and temp.endswith(f".{ext}")  # short: any target name fits
    assert _listing(tmp_path) == []


def test_failed_write_keeps_existing_target(tmp_path, monkeypatch):
    path = tmp_path / "keep.png"
    write_image(path, np.full((8, 8, 3), 0.5, np.float32))
    before = path.read_bytes()
    broken, seen = _half_then(lambda: False)
    seen["dir"] = tmp_path
    monkeypatch.setattr(image_write, "_write_pixels", broken)
    with pytest.raises(OsmapError, match=r"keep\.png: failed to write PNG"):
        write_image(path, np.zeros((8, 8, 3), np.float32))
    assert _listing(tmp_path) == ["keep.png"]
    assert path.read_bytes() == before


def test_failed_replace_removes_temp(tmp_path, monkeypatch):
    def no_replace(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(image_write.os, "replace", no_replace)
    with pytest.raises(OsmapError, match=r"r\.exr: cannot write file \(Permission denied\)"):
        write_image(tmp_path / "r.exr", _smooth())
    assert _listing(tmp_path) == []

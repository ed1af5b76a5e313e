"""Reading images: every channel of the first subimage as float32 (H, W, C), and the metadata
osmap stored in a file.

* 8- and 16-bit integer files are normalised to [0, 1]; float and half files (EXR, 32-bit TIFF)
  are read as stored.
* Alpha is never (un)premultiplied: PNG/TIFF alpha is read as the straight values in the file.

Every failure a user can cause (missing, unreadable, truncated or corrupt input) raises
OsmapError with a one-line message that starts with the path as the user gave it; what native
libraries print on stderr meanwhile is captured into that message (native_stderr_captured).
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import OpenImageIO as oiio

from osmap_cli.errors import OsmapError
from osmap_cli.image_formats import (
    DESCRIPTION_MARKER,
    FORMAT_LABELS,
    META_PREFIX,
    default_channel_names,
    display_path,
    format_from_signature,
)

__all__ = ["Image", "error_detail", "native_stderr_captured", "read_image", "read_metadata"]

_MAX_DETAIL = 300


@dataclass(frozen=True)
class Image:
    """A decoded image.

    ``pixels`` is float32 with shape (H, W, C), C >= 1 (1..4 for everything but EXR): 8/16-bit
    integer data normalised to [0, 1], float/half data as stored. ``bit_depth`` is the source's
    sample size: 8, 16, or 32 for a float or half source.
    """

    pixels: np.ndarray
    channel_names: tuple[str, ...]
    alpha_channel: int | None
    bit_depth: int
    path: str


def _one_line(text: str) -> str:
    """Collapse a (possibly multi-line) library message into one short line."""
    parts: list[str] = []
    for line in str(text).splitlines():
        line = " ".join(line.split())
        if line and line not in parts:
            parts.append(line)
    joined = "; ".join(parts)
    if len(joined) > _MAX_DETAIL:
        joined = joined[: _MAX_DETAIL - 3] + "..."
    return joined


def error_detail(*messages: str) -> str:
    """' (first non-empty message)' or ''."""
    for message in messages:
        message = _one_line(message or "")
        if message:
            return f" ({message})"
    return ""


@contextlib.contextmanager
def native_stderr_captured() -> Iterator[list[str]]:
    """Capture what native libraries print on file descriptor 2 while the block runs.

    libpng prints its own "libpng error: ..." line on stderr before OpenImageIO reports the error;
    that would break the CLI's one-line error output. The captured text is appended to the yielded
    list when the block ends, so it can be used as the message if OpenImageIO gives none.
    """
    captured: list[str] = []
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no usable fd 2: nothing to protect
        yield captured
        return
    try:
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 2)
            try:
                yield captured
            finally:
                os.dup2(saved, 2)
                tmp.seek(0)
                captured.append(tmp.read(4096).decode("utf-8", "replace"))
    finally:
        os.close(saved)


def _bit_depth_of(spec: oiio.ImageSpec) -> int:
    fmt = str(spec.format)
    if fmt in ("uint8", "int8"):
        return 8
    if fmt in ("uint16", "int16"):
        return 16
    return 32


@contextlib.contextmanager
def _openable(fspath) -> Iterator[str]:
    """A name OpenImageIO can open for FSPATH: itself, or, for a file name that is not valid
    UTF-8 (OpenImageIO takes only text), a link with a plain name in a temporary folder."""
    text = os.fsdecode(fspath)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        with tempfile.TemporaryDirectory(prefix="osmap-") as folder:
            link = os.path.join(folder, "input" + os.path.splitext(text)[1].encode(
                "utf-8", "replace").decode("utf-8"))
            os.symlink(os.path.abspath(fspath), link)
            yield link
        return
    yield text


def read_image(path: str | os.PathLike) -> Image:
    """Read the first subimage of an image file, all channels, as float32 (H, W, C).

    Raises OsmapError for a missing or unreadable path, a directory, an empty file, a file that is
    not an image, a truncated or corrupt image, an empty (zero-size) image, or a deep/volume image.
    """
    name = display_path(path)
    fspath = os.fspath(path)
    try:
        if not stat.S_ISREG(os.stat(fspath).st_mode) and not os.path.isdir(fspath):
            # a named pipe would block (and can be read only once), a device never ends
            raise OsmapError(f"{name}: not a regular file (a pipe or a device); save the "
                             "image to a file first")
        with open(fspath, "rb") as handle:
            head = handle.read(8)
            if not head:
                raise OsmapError(f"{name}: empty file (0 bytes), not an image")
    except IsADirectoryError:
        raise OsmapError(f"{name}: is a directory, not an image file") from None
    except FileNotFoundError:
        raise OsmapError(f"{name}: no such file") from None
    except OSError as exc:
        raise OsmapError(f"{name}: cannot open file ({exc.strerror or exc})") from None

    config = oiio.ImageSpec()
    # Keep straight (unassociated) alpha as stored; by default OpenImageIO premultiplies PNG/TIFF.
    config.attribute("oiio:UnassociatedAlpha", 1)
    oiio.geterror()  # clear any stale global error
    with native_stderr_captured() as native, _openable(fspath) as openable:
        inp = oiio.ImageInput.open(openable, config)
    if inp is None:
        detail = error_detail(oiio.geterror(), *native)
        signed = format_from_signature(head)
        if signed:  # the right magic number but unreadable header: damaged, not "not an image"
            raise OsmapError(f"{name}: truncated or corrupt {signed} file{detail}")
        raise OsmapError(f"{name}: not an image file OpenImageIO can read{detail}")
    label = FORMAT_LABELS.get(inp.format_name(), inp.format_name().upper() or "image")
    try:
        spec = inp.spec()
        if spec.deep:
            raise OsmapError(f"{name}: deep {label} images are not supported")
        if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
            raise OsmapError(
                f"{name}: empty image ({spec.width}x{spec.height}, {spec.nchannels} channels)"
            )
        if spec.depth > 1:
            raise OsmapError(f"{name}: volume images (depth {spec.depth}) are not supported")
        with native_stderr_captured() as native:
            pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        # JPEG returns (grey-filled) pixels for a truncated file and only flags the error, so
        # the error state is checked even when pixels came back.
        error = inp.geterror()
        if pixels is None or error:
            raise OsmapError(
                f"{name}: truncated or corrupt {label} file"
                + (error_detail(error, *native) or " (OpenImageIO could not decode the pixels)")
            )
    finally:
        inp.close()
        inp.geterror()

    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, np.newaxis]
    expected = (spec.height, spec.width, spec.nchannels)
    if pixels.shape != expected:
        raise OsmapError(
            f"{name}: OpenImageIO returned pixels of shape {pixels.shape}, expected {expected}"
        )
    names = tuple(str(n) for n in spec.channelnames)
    if len(names) != spec.nchannels:
        names = default_channel_names(spec.nchannels)
    alpha = spec.alpha_channel if 0 <= spec.alpha_channel < spec.nchannels else None
    return Image(
        pixels=np.ascontiguousarray(pixels),
        channel_names=names,
        alpha_channel=alpha,
        bit_depth=_bit_depth_of(spec),
        path=name,
    )


def read_metadata(path: str | os.PathLike) -> dict[str, str]:
    """Return the string metadata that :func:`write_image` stored in ``path`` (keys unprefixed).

    Only keys written by osmap (stored under the "osmap:" prefix, or in the osmap JSON block of a
    TIFF ImageDescription / JPEG comment) are returned; other attributes are ignored.
    """
    name = display_path(path)
    fspath = os.fspath(path)
    if not os.path.isfile(fspath):
        raise OsmapError(f"{name}: no such file")
    oiio.geterror()
    with native_stderr_captured() as native, _openable(fspath) as openable:
        inp = oiio.ImageInput.open(openable)
    if inp is None:
        raise OsmapError(f"{name}: not an image file OpenImageIO can read"
                         + error_detail(oiio.geterror(), *native))
    try:
        spec = inp.spec()
        attributes = [(str(p.name), p.value) for p in spec.extra_attribs]
    finally:
        inp.close()
        inp.geterror()

    result: dict[str, str] = {}
    for key, value in attributes:
        if key == "ImageDescription" and isinstance(value, str):
            if value.startswith(DESCRIPTION_MARKER):
                with contextlib.suppress(ValueError):
                    block = json.loads(value[len(DESCRIPTION_MARKER) :])
                    if isinstance(block, dict):
                        result.update({str(k): str(v) for k, v in block.items()})
    for key, value in attributes:
        if key.startswith(META_PREFIX) and isinstance(value, str):
            result[key[len(META_PREFIX) :]] = value
    return result

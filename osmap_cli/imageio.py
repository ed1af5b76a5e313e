"""Image reading and writing for osmap, all through OpenImageIO.

Pixels are handled as float32 arrays of shape (H, W, C):

* 8- and 16-bit integer files are normalised to [0, 1] on reading; on writing, values are clipped
  to [0, 1] and *rounded* (not truncated) to the integer range.
* Float and half files (EXR, 32-bit TIFF) are read and written as stored, with no clipping.
* Alpha is never (un)premultiplied: PNG/TIFF alpha is read and written as the straight values that
  are in the file, EXR channels exactly as stored.

Output formats, chosen by the extension (case-insensitive):

============  ==================  ========  ==================================
extension     bit depths          default   channels
============  ==================  ========  ==================================
.png          8, 16               8         1 (Y), 2 (Y,A), 3 (RGB), 4 (RGBA)
.exr          16 (half), 32       16        any count >= 1, any names
.tif / .tiff  8, 16, 32 (float)   8         1..4
.jpg / .jpeg  8                   8         1 or 3 (an alpha channel is dropped)
============  ==================  ========  ==================================

Every failure a user can cause (missing, unreadable, truncated or corrupt input; bad output path,
extension or bit depth; a failed write) raises :class:`~osmap_cli.errors.OsmapError` with a
one-line message that starts with the path as the user gave it.

Writing is atomic: :func:`write_image` stages the image in one output transaction
(:mod:`osmap_cli.output`): written to a hidden temporary file next to the target, synced, read back
and compared, and moved onto the target only once it is complete, so a failed write (a full disk
included) never leaves a partial output file or a stray temporary file. :func:`encode_image`
is the writer a transaction stages with.

Note on OpenImageIO's Python bindings: calling a method on an ``ImageOutput`` whose ``open()``
failed can crash the interpreter, and ``close()`` returns True even when the writer recorded an
error, so every call's result *and* the object's error state are checked here.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import sys
import tempfile
import threading
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import OpenImageIO as oiio

from osmap_cli.errors import OsmapError, UsageError

__all__ = [
    "Image",
    "SUPPORTED_EXTENSIONS",
    "encode_image",
    "output_depth",
    "output_format",
    "read_image",
    "read_metadata",
    "write_image",
]

# extension -> (OpenImageIO format name, allowed bit depths, default bit depth)
_FORMATS: dict[str, tuple[str, tuple[int, ...], int]] = {
    ".png": ("png", (8, 16), 8),
    ".exr": ("openexr", (16, 32), 16),
    ".tif": ("tiff", (8, 16, 32), 8),
    ".tiff": ("tiff", (8, 16, 32), 8),
    ".jpg": ("jpeg", (8,), 8),
    ".jpeg": ("jpeg", (8,), 8),
}
SUPPORTED_EXTENSIONS: tuple[str, ...] = tuple(_FORMATS)

_FORMAT_LABELS = {"png": "PNG", "openexr": "EXR", "tiff": "TIFF", "jpeg": "JPEG"}

# Metadata keys are stored under this prefix so that read_metadata() returns only what we wrote.
_META_PREFIX = "osmap:"
# TIFF and JPEG cannot store arbitrary named attributes: the metadata goes, as JSON, into the
# ImageDescription tag / JPEG comment behind this marker (no colon, because OpenImageIO parses a
# JPEG comment of the form "name: value" into an attribute called "name").
_DESCRIPTION_MARKER = "osmap-metadata "
_FORMATS_WITHOUT_ATTRIBUTES = ("tiff", "jpeg")

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


# --------------------------------------------------------------------------------------------
# helpers


def _display(path: str | os.PathLike) -> str:
    """The path as the user gave it, as a str, for messages."""
    return os.fsdecode(os.fspath(path))


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


def _detail(*messages: str) -> str:
    """' (first non-empty message)' or ''."""
    for message in messages:
        message = _one_line(message or "")
        if message:
            return f" ({message})"
    return ""


@contextlib.contextmanager
def _native_stderr_captured() -> Iterator[list[str]]:
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


_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "PNG"),
    (b"v/1\x01", "EXR"),
    (b"II*\x00", "TIFF"),
    (b"MM\x00*", "TIFF"),
    (b"II+\x00", "TIFF"),
    (b"MM\x00+", "TIFF"),
    (b"\xff\xd8\xff", "JPEG"),
)


def _format_from_signature(head: bytes) -> str | None:
    """The format label whose magic number ``head`` starts with, if it is one we write."""
    for magic, label in _SIGNATURES:
        if head.startswith(magic):
            return label
    return None


def _bit_depth_of(spec: oiio.ImageSpec) -> int:
    fmt = str(spec.format)
    if fmt in ("uint8", "int8"):
        return 8
    if fmt in ("uint16", "int16"):
        return 16
    return 32


# --------------------------------------------------------------------------------------------
# reading


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
    name = _display(path)
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
    with _native_stderr_captured() as native, _openable(fspath) as openable:
        inp = oiio.ImageInput.open(openable, config)
    if inp is None:
        detail = _detail(oiio.geterror(), *native)
        signed = _format_from_signature(head)
        if signed:  # the right magic number but unreadable header: damaged, not "not an image"
            raise OsmapError(f"{name}: truncated or corrupt {signed} file{detail}")
        raise OsmapError(f"{name}: not an image file OpenImageIO can read{detail}")
    label = _FORMAT_LABELS.get(inp.format_name(), inp.format_name().upper() or "image")
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
        with _native_stderr_captured() as native:
            pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        # JPEG returns (grey-filled) pixels for a truncated file and only flags the error, so
        # the error state is checked even when pixels came back.
        error = inp.geterror()
        if pixels is None or error:
            raise OsmapError(
                f"{name}: truncated or corrupt {label} file"
                + (_detail(error, *native) or " (OpenImageIO could not decode the pixels)")
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
        names = _default_channel_names(spec.nchannels)
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
    name = _display(path)
    fspath = os.fspath(path)
    if not os.path.isfile(fspath):
        raise OsmapError(f"{name}: no such file")
    oiio.geterror()
    with _native_stderr_captured() as native, _openable(fspath) as openable:
        inp = oiio.ImageInput.open(openable)
    if inp is None:
        raise OsmapError(
            f"{name}: not an image file OpenImageIO can read" + _detail(oiio.geterror(), *native)
        )
    try:
        spec = inp.spec()
        attributes = [(str(p.name), p.value) for p in spec.extra_attribs]
    finally:
        inp.close()
        inp.geterror()

    result: dict[str, str] = {}
    for key, value in attributes:
        if key == "ImageDescription" and isinstance(value, str):
            if value.startswith(_DESCRIPTION_MARKER):
                with contextlib.suppress(ValueError):
                    block = json.loads(value[len(_DESCRIPTION_MARKER) :])
                    if isinstance(block, dict):
                        result.update({str(k): str(v) for k, v in block.items()})
    for key, value in attributes:
        if key.startswith(_META_PREFIX) and isinstance(value, str):
            result[key[len(_META_PREFIX) :]] = value
    return result


# --------------------------------------------------------------------------------------------
# writing


def _default_channel_names(channels: int) -> tuple[str, ...]:
    if channels == 1:
        return ("Y",)
    if channels == 2:
        return ("Y", "A")
    base = ("R", "G", "B", "A")
    return base[:channels] + tuple(f"C{i}" for i in range(4, channels))


def output_format(
    path: str | os.PathLike, bit_depth: int | None = None, channels: int = 3
) -> tuple[str, int]:
    """Validate an output path before any work starts.

    Returns ``(format_name, effective_bit_depth)``, where ``format_name`` is OpenImageIO's name
    for the format ("png", "openexr", "tiff" or "jpeg") and ``bit_depth=None`` means the format's
    default (8 for PNG/TIFF/JPEG, 16 = half for EXR). Raises OsmapError for an unknown extension,
    a bit depth or channel count the format cannot store, a path that is an existing directory, or
    a missing or unwritable output directory.
    """
    name = _display(path)
    fspath = os.fsdecode(os.fspath(path))
    ext = os.path.splitext(fspath)[1].lower()
    if ext not in _FORMATS:
        shown = f'"{ext}"' if ext else "no extension"
        raise OsmapError(
            f"{name}: unsupported output format ({shown}); "
            f"use one of {', '.join(SUPPORTED_EXTENSIONS)}"
        )
    fmt, depths, default_depth = _FORMATS[ext]
    label = _FORMAT_LABELS[fmt]
    if bit_depth is None:
        depth = default_depth
    else:
        if isinstance(bit_depth, bool) or not isinstance(bit_depth, (int, np.integer)):
            raise OsmapError(f"{name}: bit depth must be an integer, got {bit_depth!r}")
        depth = int(bit_depth)
        if depth not in depths:
            allowed = ", ".join(str(d) for d in depths)
            raise OsmapError(f"{name}: {label} cannot store bit depth {depth} (allowed: {allowed})")
    if isinstance(channels, bool) or not isinstance(channels, (int, np.integer)) or channels < 1:
        raise OsmapError(f"{name}: cannot write an image with {channels!r} channels")
    if fmt != "openexr" and channels > 4:
        raise OsmapError(f"{name}: {label} can store at most 4 channels, got {channels} (use .exr)")
    if os.path.isdir(fspath):
        raise OsmapError(f"{name}: is an existing directory, cannot write an image there")
    from osmap_cli.output import check_parent

    check_parent(name)
    return fmt, depth


def output_depth(output: str, bit_depth: str | None, channels: int, input_depth: int):
    """(format, bit depth) for OUTPUT: --bit-depth, else the format's default raised to keep
    the exemplar's precision. A bad --bit-depth is a usage error."""
    fmt, default_depth = output_format(output, None, channels)
    if bit_depth is not None:
        try:
            return output_format(output, int(bit_depth), channels)
        except OsmapError as exc:
            raise UsageError(str(exc), option="--bit-depth") from None
    if fmt == "png" and input_depth >= 16:
        return fmt, 16
    if fmt == "tiff" and input_depth > default_depth:
        return fmt, input_depth
    return fmt, default_depth


def _write_pixels(out: oiio.ImageOutput, data: np.ndarray) -> bool:
    """Hand the whole pixel array to an opened ImageOutput (separate so tests can break it)."""
    return out.write_image(data)


def _prepare_pixels(name: str, pixels: np.ndarray, fmt: str, depth: int) -> np.ndarray:
    data = np.asarray(pixels)
    if data.dtype.kind not in "fiub":
        raise OsmapError(f"{name}: cannot write pixels of dtype {data.dtype}")
    data = data.astype(np.float32, copy=False)
    if data.ndim == 2:
        data = data[:, :, np.newaxis]
    if data.ndim != 3 or data.shape[0] == 0 or data.shape[1] == 0 or data.shape[2] == 0:
        raise OsmapError(f"{name}: cannot write pixels of shape {np.shape(pixels)}")
    if fmt == "openexr" or depth == 32:
        return np.ascontiguousarray(data)
    top = 255.0 if depth == 8 else 65535.0
    scaled = np.nan_to_num(data, nan=0.0, posinf=1.0, neginf=0.0)
    scaled = np.rint(np.clip(scaled, 0.0, 1.0) * top)
    return np.ascontiguousarray(scaled.astype(np.uint8 if depth == 8 else np.uint16))


def write_image(
    path: str | os.PathLike,
    pixels: np.ndarray,
    bit_depth: int | None = None,
    channel_names: Sequence[str] | None = None,
    metadata: Mapping[str, str] | None = None,
) -> None:
    """Write float pixels (H, W, C) or (H, W) atomically to ``path``; format from the extension.

    ``bit_depth=None`` is the format default (see :func:`output_format`). Integer formats clip to
    [0, 1] and round to the integer range; EXR and 32-bit TIFF store the floats unchanged.
    ``channel_names`` defaults to Y / Y,A / R,G,B / R,G,B,A; a channel named "A" is the alpha.
    ``metadata`` string pairs are stored in the file (PNG text chunks, EXR string attributes, a
    JSON block in the TIFF ImageDescription / JPEG comment) and read back by
    :func:`read_metadata`.

    JPEG cannot store alpha: for a 2- or 4-channel image whose last channel is named "A" (which
    is the case for the default names) that channel is silently dropped; any other 2- or
    4-channel image raises OsmapError.

    >>> write_image("out.png", np.zeros((8, 8, 3)), metadata={"note": "black"})
    """
    from osmap_cli.output import write_atomically

    name = _display(path)
    data = np.asarray(pixels)
    output_format(path, bit_depth, data.shape[2] if data.ndim == 3 else 1)
    write_atomically(name, lambda temp: encode_image(temp, pixels, bit_depth, channel_names,
                                                     metadata, name=name))


def encode_image(
    path: str | os.PathLike,
    pixels: np.ndarray,
    bit_depth: int | None = None,
    channel_names: Sequence[str] | None = None,
    metadata: Mapping[str, str] | None = None,
    name: str | None = None,
) -> None:
    """Write the image straight into ``path`` (not atomic: see :func:`write_image`), then read it
    back and check that it holds exactly these pixels (JPEG: that it decodes completely).
    ``name`` is the path shown in messages (the target of a staged write)."""


    name = name or _display(path)
    data = np.asarray(pixels)
    channels = data.shape[2] if data.ndim == 3 else 1
    fmt, depth = output_format(path, bit_depth, channels)
    label = _FORMAT_LABELS[fmt]

    if channel_names is None:
        names = list(_default_channel_names(channels))
    else:
        names = [str(n) for n in channel_names]
        if len(names) != channels:
            raise OsmapError(f"{name}: {len(names)} channel names given for {channels} channels")
    if fmt == "jpeg" and channels in (2, 4):
        if names[-1] != "A":
            raise OsmapError(
                f"{name}: JPEG cannot store {channels} channels ({', '.join(names)}); "
                "use .png, .tif or .exr"
            )
        data = data[..., : channels - 1] if data.ndim == 3 else data
        names = names[:-1]
        channels -= 1

    data = _prepare_pixels(name, data, fmt, depth)
    height, width, channels = data.shape
    type_name = {8: "uint8", 16: "uint16", 32: "float"}[depth]
    if fmt == "openexr":
        type_name = "half" if depth == 16 else "float"

    spec = oiio.ImageSpec(width, height, channels, type_name)
    spec.channelnames = tuple(names)
    spec.alpha_channel = names.index("A") if "A" in names else -1
    # The values are straight alpha: do not let the PNG/TIFF writer un-premultiply them.
    spec.attribute("oiio:UnassociatedAlpha", 1)
    # No time stamp (EXR capDate, TIFF DateTime): the same inputs must give the same bytes.
    spec.attribute("DateTime", "")
    if fmt == "tiff":
        # OpenImageIO 3.2 with libtiff 4.7 flags a spurious "failed TIFFWriteCustomDirectory() of
        # the Exif data" error on close() when there is no Exif data; we write none.
        spec.attribute("tiff:write_exif", 0)
    if metadata:
        clean: dict[str, str] = {}
        for key, value in metadata.items():
            key = str(key)
            if key.startswith(_META_PREFIX):
                key = key[len(_META_PREFIX) :]
            # a file name that is not UTF-8 cannot be stored as text: its odd bytes become U+FFFD
            clean[key] = str(value).encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        if fmt in _FORMATS_WITHOUT_ATTRIBUTES:
            spec.attribute("ImageDescription", _DESCRIPTION_MARKER + json.dumps(clean))
        else:
            for key, value in clean.items():
                spec.attribute(_META_PREFIX + key, value)

    fspath = os.fsdecode(os.fspath(path))
    if fmt == "jpeg" and _PIPE_PATHS:
        from osmap_cli.output import write_bytes

        encoded = _through_pipe(lambda target: _oiio_write(target, name, label, fmt, spec, data))
        write_bytes(fspath, encoded)
    else:
        _oiio_write(fspath, name, label, fmt, spec, data)
    _verify(fspath, name, label, fmt, depth, data)


def _oiio_write(fspath: str, name: str, label: str, fmt: str, spec, data: np.ndarray) -> None:
    """Hand the pixels to OpenImageIO's writer; every failure it reports raises OsmapError."""
    oiio.geterror()
    try:
        out = oiio.ImageOutput.create(fmt)
        if out is None:
            raise OsmapError(
                f"{name}: OpenImageIO has no {label} writer" + _detail(oiio.geterror())
            )
        with _native_stderr_captured() as native:
            opened = out.open(fspath, spec)
        if not opened:
            raise OsmapError(
                f"{name}: cannot create output file" + _detail(out.geterror(), *native)
            )
        with _native_stderr_captured() as native:
            try:
                written = _write_pixels(out, data)
            finally:
                # close() reports True even when the writer failed: check the error state too.
                closed = out.close()
        error = out.geterror()
        if not written or not closed or error:
            raise OsmapError(
                f"{name}: failed to write {label} file"
                + (_detail(error, *native) or " (OpenImageIO reported a write failure)")
            )
    except OsmapError:
        raise
    except OSError as exc:
        raise OsmapError(f"{name}: cannot write file ({exc.strerror or exc})") from exc
    except Exception as exc:
        raise OsmapError(f"{name}: failed to write {label} file ({exc!r})") from exc


# libjpeg ends the whole process (exit(1), no message) when a write fails, e.g. on a full disk.
# So JPEG is encoded into a pipe, which a thread drains while the encoder runs (OpenImageIO
# releases the GIL while it writes): a pipe is never full and has no size limit, so the encoder
# cannot fail there, and its bytes are then written with checked writes. (Encoding in a forked
# child instead hangs: libjpeg's exit() runs OpenImageIO's thread-pool destructor, which waits
# for pool threads that were not forked.) Without /dev/fd the encoder writes the file itself.
_PIPE_PATHS = os.path.isdir("/dev/fd")


def _through_pipe(write) -> bytes:
    """The bytes write(path) puts into the file at PATH, taken through a pipe instead."""
    read_end, write_end = os.pipe()
    chunks: list[bytes] = []

    def drain():
        while chunk := os.read(read_end, 1 << 16):
            chunks.append(chunk)

    thread = threading.Thread(target=drain, name="osmap-encode", daemon=True)
    thread.start()
    try:
        write(f"/dev/fd/{write_end}")
    finally:
        os.close(write_end)
        thread.join()
        os.close(read_end)
    return b"".join(chunks)


# The last bytes of a complete file: a writer that lost its tail to a full disk fails here.
_TRAILERS = {"png": b"IEND\xaeB`\x82", "jpeg": b"\xff\xd9"}


def _verify(fspath: str, name: str, label: str, fmt: str, depth: int, data: np.ndarray) -> None:
    """Read the written file back: it must decode completely and (except JPEG) give exactly
    the pixels that were written. OpenImageIO's writers do not all report a failed write (a
    full disk can leave a cut-off PNG behind a successful close()), so this is the check."""
    incomplete = OsmapError(f"{name}: failed to write {label} file (the file on disk is "
                            "incomplete: is the disk full?)")
    trailer = _TRAILERS.get(fmt)
    if trailer is not None:
        with open(fspath, "rb") as handle:
            handle.seek(0, os.SEEK_END)
            size = handle.tell()
            handle.seek(max(0, size - len(trailer)))
            if handle.read() != trailer:
                raise incomplete
    oiio.geterror()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # the straight values that were written
    with _native_stderr_captured():
        inp = oiio.ImageInput.open(fspath, config)
        if inp is None:
            oiio.geterror()
            raise incomplete
        try:
            stored = inp.read_image(0, 0, 0, data.shape[2], "float" if data.dtype.kind == "f"
                                    else data.dtype.name)
            failed = stored is None or bool(inp.geterror())
        finally:
            inp.close()
    if failed or stored.shape[:2] != data.shape[:2]:
        raise incomplete
    if fmt == "jpeg":
        return
    expected = data.astype(np.float16).astype(np.float32) if fmt == "openexr" and depth == 16 \
        else data
    if not np.array_equal(stored.reshape(data.shape), expected, equal_nan=True):
        raise incomplete


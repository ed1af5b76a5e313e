"""Writing images: float pixels to PNG, EXR, TIFF or JPEG (image_formats has the rules), each
file read back and checked.

* On writing to an integer format, values are clipped to [0, 1] and *rounded* (not truncated)
  to the integer range; EXR and 32-bit TIFF store the floats unchanged.
* Alpha is never premultiplied: PNG/TIFF alpha is written as the straight values given.

Writing is atomic: :func:`write_image` stages the image in one output transaction
(:mod:`osmap_cli.output`): written to a hidden temporary file next to the target, synced, read
back and compared, and moved onto the target only once it is complete, so a failed write (a
full disk included) never leaves a partial output file or a stray temporary file.
:func:`encode_image` is the writer a transaction stages with.

Note on OpenImageIO's Python bindings: calling a method on an ``ImageOutput`` whose ``open()``
failed can crash the interpreter, and ``close()`` returns True even when the writer recorded an
error, so every call's result *and* the object's error state are checked here.
"""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Mapping, Sequence

import numpy as np
import OpenImageIO as oiio

from osmap_cli.errors import OsmapError
from osmap_cli.image_formats import (
    DESCRIPTION_MARKER,
    FORMAT_LABELS,
    FORMATS_WITHOUT_ATTRIBUTES,
    META_PREFIX,
    check_jpeg_channels,
    default_channel_names,
    display_path,
    output_format,
)
from osmap_cli.image_read import error_detail, native_stderr_captured

__all__ = ["encode_image", "write_image"]


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

    name = display_path(path)
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

    name = name or display_path(path)
    data = np.asarray(pixels)
    channels = data.shape[2] if data.ndim == 3 else 1
    fmt, depth = output_format(path, bit_depth, channels)
    label = FORMAT_LABELS[fmt]

    if channel_names is None:
        names = list(default_channel_names(channels))
    else:
        names = [str(n) for n in channel_names]
        if len(names) != channels:
            raise OsmapError(f"{name}: {len(names)} channel names given for {channels} channels")
    check_jpeg_channels(name, fmt, names)
    if fmt == "jpeg" and channels in (2, 4):
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
            if key.startswith(META_PREFIX):
                key = key[len(META_PREFIX) :]
            # a file name that is not UTF-8 cannot be stored as text: its odd bytes become U+FFFD
            clean[key] = str(value).encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        if fmt in FORMATS_WITHOUT_ATTRIBUTES:
            spec.attribute("ImageDescription", DESCRIPTION_MARKER + json.dumps(clean))
        else:
            for key, value in clean.items():
                spec.attribute(META_PREFIX + key, value)

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
                f"{name}: OpenImageIO has no {label} writer" + error_detail(oiio.geterror())
            )
        with native_stderr_captured() as native:
            opened = out.open(fspath, spec)
        if not opened:
            raise OsmapError(
                f"{name}: cannot create output file" + error_detail(out.geterror(), *native)
            )
        with native_stderr_captured() as native:
            try:
                written = _write_pixels(out, data)
            finally:
                # close() reports True even when the writer failed: check the error state too.
                closed = out.close()
        error = out.geterror()
        if not written or not closed or error:
            raise OsmapError(
                f"{name}: failed to write {label} file"
                + (error_detail(error, *native) or " (OpenImageIO reported a write failure)")
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
    with native_stderr_captured():
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

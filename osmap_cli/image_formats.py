"""Image file formats: which extensions osmap writes, at which bit depths and channel counts,
and where its metadata goes in each. Output formats, chosen by the extension (case-insensitive):

============  ==================  ========  ==================================
extension     bit depths          default   channels
============  ==================  ========  ==================================
.png          8, 16               8         1 (Y), 2 (Y,A), 3 (RGB), 4 (RGBA)
.exr          16 (half), 32       16        any count >= 1, any names
.tif / .tiff  8, 16, 32 (float)   8         1..4
.jpg / .jpeg  8                   8         1 or 3 (an alpha channel is dropped)
============  ==================  ========  ==================================

This module holds the rules only (no pixels are read or written here): osmap_cli.imageio is
the public face of reading and writing.
"""

from __future__ import annotations

import os

import numpy as np

from osmap_cli.errors import OsmapError, UsageError

__all__ = ["FORMAT_LABELS", "FORMATS", "SUPPORTED_EXTENSIONS", "check_jpeg_channels",
           "default_channel_names", "display_path", "format_from_signature", "output_depth",
           "output_format"]

# extension -> (OpenImageIO format name, allowed bit depths, default bit depth)
FORMATS: dict[str, tuple[str, tuple[int, ...], int]] = {
    ".png": ("png", (8, 16), 8),
    ".exr": ("openexr", (16, 32), 16),
    ".tif": ("tiff", (8, 16, 32), 8),
    ".tiff": ("tiff", (8, 16, 32), 8),
    ".jpg": ("jpeg", (8,), 8),
    ".jpeg": ("jpeg", (8,), 8),
}
SUPPORTED_EXTENSIONS: tuple[str, ...] = tuple(FORMATS)

FORMAT_LABELS = {"png": "PNG", "openexr": "EXR", "tiff": "TIFF", "jpeg": "JPEG"}

# Metadata keys are stored under this prefix so that read_metadata() returns only what we wrote.
META_PREFIX = "osmap:"
# TIFF and JPEG cannot store arbitrary named attributes: the metadata goes, as JSON, into the
# ImageDescription tag / JPEG comment behind this marker (no colon, because OpenImageIO parses a
# JPEG comment of the form "name: value" into an attribute called "name").
DESCRIPTION_MARKER = "osmap-metadata "
FORMATS_WITHOUT_ATTRIBUTES = ("tiff", "jpeg")

# the magic numbers of the formats osmap writes
_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "PNG"),
    (b"v/1\x01", "EXR"),
    (b"II*\x00", "TIFF"),
    (b"MM\x00*", "TIFF"),
    (b"II+\x00", "TIFF"),
    (b"MM\x00+", "TIFF"),
    (b"\xff\xd8\xff", "JPEG"),
)


def format_from_signature(head: bytes) -> str | None:
    """The format label whose magic number ``head`` starts with, if it is one we write."""
    for magic, label in _SIGNATURES:
        if head.startswith(magic):
            return label
    return None


def display_path(path: str | os.PathLike) -> str:
    """The path as the user gave it, as a str, for messages."""
    return os.fsdecode(os.fspath(path))


def default_channel_names(channels: int) -> tuple[str, ...]:
    """Y, Y A, R G B, R G B A, then C4, C5, ... for more channels."""
    if channels == 1:
        return ("Y",)
    if channels == 2:
        return ("Y", "A")
    base = ("R", "G", "B", "A")
    return base[:channels] + tuple(f"C{i}" for i in range(4, channels))


def check_jpeg_channels(name: str, fmt: str, names) -> None:
    """Refuse 2 or 4 channels in a JPEG unless the last is the alpha ("A", then dropped): JPEG
    stores 1 or 3. NAME is the path shown in the message."""
    if fmt == "jpeg" and len(names) in (2, 4) and names[-1] != "A":
        raise OsmapError(f"{name}: JPEG cannot store {len(names)} channels "
                         f"({', '.join(names)}); use .png, .tif or .exr")


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
    name = display_path(path)
    fspath = os.fsdecode(os.fspath(path))
    ext = os.path.splitext(fspath)[1].lower()
    if ext not in FORMATS:
        shown = f'"{ext}"' if ext else "no extension"
        raise OsmapError(
            f"{name}: unsupported output format ({shown}); "
            f"use one of {', '.join(SUPPORTED_EXTENSIONS)}"
        )
    fmt, depths, default_depth = FORMATS[ext]
    label = FORMAT_LABELS[fmt]
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

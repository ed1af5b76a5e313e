"""Volume files: write and read a (Z, Y, X, C) float32 volume.

Formats (osmap_cli.solid.formats.FORMATS):
- ``npy``: the float32 array as is (NumPy cannot store metadata: no provenance);
- ``png`` / ``exr``: a folder of numbered slices ``slice_0000.png`` ... (one per z), PNG 8-bit
  (16-bit for a 16-bit or float exemplar), EXR 32-bit float; provenance in every slice;
- ``atlas``: one PNG with the z slices in a grid, row-major from the top left (the flipbook
  layout game engines use for volume textures); the grid is COLSxROWS from a file name ending
  in ``_COLSxROWS.png`` (e.g. ``marble_8x16.png``), else the smallest square-ish grid, and is
  recorded in the metadata (``atlas_grid``, ``atlas_slices``);
- ``nrrd``: a NRRD 0004 file (sizes C X Y Z, little-endian float, raw or gzip encoding) with the
  provenance as ``osmap:KEY:=VALUE`` key/value fields.

`volume_writer` gives what an output transaction (osmap_cli.output.Outputs) stages: every output
of a run is written next to its target and moved onto it only when all are complete.
"""

from __future__ import annotations

import gzip
import math
import os
import re

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.output import check_parent, synced_file, write_bytes
from osmap_cli.solid.formats import SLICE_FOLDERS, format_for

SLICE_PATTERN = re.compile(r"slice_(\d+)\.(png|exr)$")
ATLAS_GRID = re.compile(r"_(\d+)x(\d+)$")
META_PREFIX = "osmap:"


def check_target(path: str, fmt: str) -> None:
    """Refuse a path that cannot receive this format, before any work."""
    fspath = path.rstrip("/" + os.sep) or path
    check_parent(path)
    if fmt in SLICE_FOLDERS:
        if os.path.isfile(fspath):
            raise OsmapError(f"{path}: is a file; slices need a folder")
        if os.path.isdir(fspath):
            foreign = [n for n in os.listdir(fspath) if not SLICE_PATTERN.match(n)]
            if foreign:
                raise OsmapError(f"{path}: folder holds other files ({foreign[0]}); "
                                 "give a new or empty folder")
    elif os.path.isdir(fspath):
        raise OsmapError(f"{path}: is an existing directory, cannot write a {fmt} file there")
    if fmt == "atlas" and os.path.splitext(fspath)[1].lower() != ".png":
        raise OsmapError(f"{path}: an atlas is a .png file")


def atlas_grid(path: str, depth: int) -> tuple[int, int]:
    """(columns, rows) of the atlas: from a `_CxR` file-name suffix, else near-square."""
    stem = os.path.splitext(os.path.basename(path))[0]
    match = ATLAS_GRID.search(stem)
    if match:
        cols, rows = int(match.group(1)), int(match.group(2))
        if cols < 1 or rows < 1 or cols * rows < depth:
            raise OsmapError(f"{path}: atlas grid {cols}x{rows} in the file name has fewer than "
                             f"the {depth} slices")
        return cols, rows
    cols = math.ceil(math.sqrt(depth))
    return cols, math.ceil(depth / cols)


def to_atlas(volume: np.ndarray, grid) -> np.ndarray:
    """(rows * Y, cols * X, C) image: slice z at column z % cols, row z // cols."""
    Z, Y, X, C = volume.shape
    cols, rows = grid
    out = np.zeros((rows * Y, cols * X, C), np.float32)
    for z in range(Z):
        r, c = divmod(z, cols)
        out[r * Y:(r + 1) * Y, c * X:(c + 1) * X] = volume[z]
    return out


def from_atlas(image: np.ndarray, grid, depth: int) -> np.ndarray:
    """The inverse of to_atlas."""
    cols, rows = grid
    Y, X = image.shape[0] // rows, image.shape[1] // cols
    return np.stack([image[(z // cols) * Y:(z // cols + 1) * Y, (z % cols) * X:(z % cols + 1) * X]
                     for z in range(depth)])


# ---------------------------------------------------------------------------------------------
# NRRD


def nrrd_bytes(volume: np.ndarray, metadata: dict, encoding: str = "raw") -> bytes:
    """A complete NRRD 0004 file for a float32 (Z, Y, X, C) volume."""
    Z, Y, X, C = volume.shape
    lines = ["NRRD0004", "# written by osmap", "type: float"]
    if C == 1:
        lines += ["dimension: 3", f"sizes: {X} {Y} {Z}", "kinds: domain domain domain"]
    else:
        lines += ["dimension: 4", f"sizes: {C} {X} {Y} {Z}",
                  "kinds: vector domain domain domain"]
    lines += ["endian: little", f"encoding: {encoding}"]
    for key, value in metadata.items():
        text = str(value).replace("\n", " ")
        lines.append(f"{META_PREFIX}{key}:={text}")
    payload = np.ascontiguousarray(volume, "<f4").tobytes()
    if encoding == "gzip":
        payload = gzip.compress(payload, mtime=0)
    return ("\n".join(lines) + "\n\n").encode("utf-8") + payload


def read_nrrd_header(handle, path: str) -> tuple[dict, dict]:
    """(NRRD fields, osmap metadata) of an open NRRD file; leaves it at the payload."""
    if handle.readline().rstrip(b"\r\n")[:4] != b"NRRD":
        raise OsmapError(f"{path}: not a NRRD file")
    fields, meta = {}, {}
    for raw in handle:
        line = raw.rstrip(b"\r\n").decode("utf-8", "replace")
        if not line:
            return fields, meta  # the blank line ends the header
        if line.startswith("#"):
            continue
        if ":=" in line:
            key, value = line.split(":=", 1)
            if key.startswith(META_PREFIX):
                meta[key[len(META_PREFIX):]] = value
        elif ":" in line:
            key, value = line.split(":", 1)
            fields[key.strip()] = value.strip()
    raise OsmapError(f"{path}: not a NRRD file (the header does not end)")


def read_nrrd(path: str) -> tuple[np.ndarray, dict]:
    """(volume (Z, Y, X, C) float32, osmap metadata) from a NRRD file written by nrrd_bytes
    (also reads uint8/uint16/float NRRDs of the same layout)."""
    with open(path, "rb") as handle:
        fields, meta = read_nrrd_header(handle, path)
        payload = handle.read()
    sizes = [int(s) for s in fields["sizes"].split()]
    dtype = {"float": "<f4", "uint8": "u1", "uchar": "u1", "unsigned char": "u1",
             "uint16": "<u2", "ushort": "<u2"}[fields["type"]]
    if fields.get("encoding") in ("gzip", "gz"):
        payload = gzip.decompress(payload)
    array = np.frombuffer(payload, dtype).astype(np.float32)
    if len(sizes) == 3:
        sizes = [1] + sizes
    C, X, Y, Z = sizes
    return array.reshape(Z, Y, X, C), meta


# ---------------------------------------------------------------------------------------------
# staged writing


def write_npy(path: str, array: np.ndarray) -> None:
    """The float32 array as a .npy file (synced; the size checked)."""
    array = np.ascontiguousarray(array, np.float32)
    with synced_file(path) as handle:
        np.save(handle, array)
        size = handle.tell()
    if os.path.getsize(path) != size:
        raise OsmapError(f"{path}: incomplete write")


def volume_writer(path: str, volume: np.ndarray, fmt: str, *, depth: int, channel_names,
                  metadata: dict, encoding: str = "raw"):
    """(write(temp), is_folder): how to write the volume in `fmt`, for Outputs.stage(path, ...)."""
    from osmap_cli.imageio import encode_image

    if fmt == "npy":
        return (lambda temp: write_npy(temp, volume)), False
    if fmt == "nrrd":
        return (lambda temp: write_bytes(temp, nrrd_bytes(volume, metadata, encoding))), False
    if fmt == "atlas":
        Z, Y, X, _ = volume.shape
        grid = atlas_grid(path, Z)
        meta = dict(metadata, atlas_grid=f"{grid[0]}x{grid[1]}", atlas_slices=str(Z),
                    atlas_slice_size=f"{X}x{Y}")
        return (lambda temp: encode_image(temp, to_atlas(volume, grid), depth,
                                          channel_names=channel_names, metadata=meta,
                                          name=path)), False

    def write_slices(folder: str) -> None:
        digits = max(4, len(str(volume.shape[0] - 1)))
        for z in range(volume.shape[0]):
            name = f"slice_{z:0{digits}d}.{fmt}"
            encode_image(os.path.join(folder, name), volume[z], 32 if fmt == "exr" else depth,
                         channel_names=channel_names, metadata=dict(metadata, slice=str(z)),
                         name=os.path.join(path, name))

    return write_slices, True


# ---------------------------------------------------------------------------------------------
# reading


def read_volume(path: str, fmt: str | None = None) -> tuple[np.ndarray, dict]:
    """(float32 (Z, Y, X, C) volume, osmap metadata) from any format written here."""
    from osmap_cli.imageio import read_image, read_metadata

    fmt = format_for(path, fmt)
    if fmt == "npy":
        array = np.load(path)
        return (array[..., None] if array.ndim == 3 else array).astype(np.float32), {}
    if fmt == "nrrd":
        return read_nrrd(path)
    if fmt == "atlas":
        meta = read_metadata(path)
        image = read_image(path).pixels
        if "atlas_grid" in meta:
            cols, rows = (int(v) for v in meta["atlas_grid"].split("x"))
        else:
            match = ATLAS_GRID.search(os.path.splitext(os.path.basename(path))[0])
            if match is None:
                raise OsmapError(f"{path}: no atlas grid in the metadata or the file name")
            cols, rows = int(match.group(1)), int(match.group(2))
        depth = int(meta.get("atlas_slices", cols * rows))
        return from_atlas(image, (cols, rows), depth), meta
    names = sorted((int(m.group(1)), n) for n in os.listdir(path)
                   if (m := SLICE_PATTERN.match(n)))
    if not names:
        raise OsmapError(f"{path}: no slice_NNNN.png/.exr files")
    slices = [read_image(os.path.join(path, n)).pixels for _, n in names]
    return np.stack(slices), read_metadata(os.path.join(path, names[0][1]))

"""The volume formats of `osmap solid`, in one table (no NumPy: the command reads its --format
choices and default names from here without loading the writers, osmap_cli.solid.volumeio).

>>> list(FORMATS)
['npy', 'png', 'exr', 'atlas', 'nrrd']
>>> format_for("marble.nrrd", None), default_name("png")
('nrrd', ('{stem}', 'png'))
"""

from __future__ import annotations

import os

from osmap_cli.errors import OsmapError

# format -> the file extension of its output ({ext} in --name; png and exr: of each slice)
FORMATS = {"npy": "npy", "png": "png", "exr": "exr", "atlas": "png", "nrrd": "nrrd"}
# OUT's extension -> its format when --format is not given ("": a folder of PNG slices)
BY_EXTENSION = {".npy": "npy", ".nrrd": "nrrd", ".png": "atlas", "": "png"}
SLICE_FOLDERS = ("png", "exr")
NRRD_ENCODINGS = ("raw", "gzip")


def format_for(path: str, fmt: str | None) -> str:
    """The output format: --format if given, else by OUT's extension (no extension: PNG
    slices in a folder)."""
    if fmt is not None:
        if fmt not in FORMATS:
            raise OsmapError(f"--format: {fmt!r} is not one of {', '.join(FORMATS)}")
        return fmt
    ext = os.path.splitext(path.rstrip("/" + os.sep))[1].lower()
    if ext not in BY_EXTENSION:
        raise OsmapError(f"{path}: unsupported volume output ({ext}); use .npy, .nrrd, .png "
                         "(atlas), a folder without extension (PNG slices), or --format")
    return BY_EXTENSION[ext]


def default_name(kind: str) -> tuple[str, str]:
    """(default --name template, the {ext} field) for an output format."""
    return ("{stem}" if kind in SLICE_FOLDERS else "{stem}.{ext}"), FORMATS[kind]

"""The volume a carve samples: read from a file `osmap solid` wrote (or any float array), checked
for its kind, or synthesized on the fly through osmap_cli.solid's public face."""

from __future__ import annotations

import json
import os

import numpy as np

from osmap_cli.errors import OsmapError

__all__ = ["as_volume", "read_volume_file", "synthesized"]

MAX_CHANNELS = 4


def as_volume(array, name: str = "volume") -> np.ndarray:
    """float32 (Z, Y, X, C), C 1 to 4, finite; OsmapError naming NAME for anything else."""
    array = np.asarray(array)
    if array.dtype.kind not in "fiub":
        raise OsmapError(f"{name}: not a volume of numbers (dtype {array.dtype})")
    if array.ndim == 3:
        if array.shape[2] <= MAX_CHANNELS < min(array.shape[:2]):
            raise OsmapError(f"{name}: not a volume: an array of shape {array.shape} is an image "
                             "(rows, columns, channels); a volume is (Z, Y, X) or (Z, Y, X, C)")
        array = array[..., None]
    if array.ndim != 4:
        raise OsmapError(f"{name}: not a volume: expected (Z, Y, X) or (Z, Y, X, C) voxels, "
                         f"got an array of shape {array.shape}")
    if min(array.shape[:3]) < 2:
        raise OsmapError(f"{name}: not a volume: {array.shape[2]}x{array.shape[1]}x"
                         f"{array.shape[0]} voxels (every side needs at least 2)")
    if not 1 <= array.shape[3] <= MAX_CHANNELS:
        raise OsmapError(f"{name}: {array.shape[3]} channels; a carved colour map holds 1 to "
                         f"{MAX_CHANNELS}")
    volume = np.ascontiguousarray(array, np.float32)
    if not np.all(np.isfinite(volume)):
        raise OsmapError(f"{name}: the volume has NaN or infinite values")
    if _looks_like_positions(volume):
        raise OsmapError(f"{name}: this is a position volume (osmap solid --uv-out: exemplar "
                         "u, v and index per voxel), not colours; give the volume itself")
    return volume


def _looks_like_positions(volume: np.ndarray) -> bool:
    if volume.shape[3] != 3:
        return False
    index = volume[..., 2]
    uv = volume[..., :2]
    return bool(np.all(np.isin(index, (0.0, 1.0, 2.0))) and np.all(uv == np.rint(uv))
                and uv.max() > 2.0)


def read_volume_file(path: str) -> tuple[np.ndarray, bool]:
    """(volume, tileable): a .npy, .nrrd, PNG atlas or slice folder; tileable when its
    provenance says the volume wraps (a .npy has none)."""
    from osmap_cli.solid.volumeio import read_volume

    if not os.path.exists(path):
        raise OsmapError(f"{path}: no such file")
    try:
        if path.lower().endswith(".npy"):
            array, meta = np.load(path, allow_pickle=False), {}
        else:
            array, meta = read_volume(path)
    except OsmapError:
        raise
    except (OSError, ValueError, KeyError, EOFError) as exc:
        detail = " ".join(str(exc).split())[:200]
        raise OsmapError(f"{path}: not a volume osmap can read ({detail})") from None
    try:
        tileable = bool(json.loads(meta.get("options", "{}")).get("tileable", False))
    except (ValueError, AttributeError):
        tileable = False
    return as_volume(array, path), tileable


_LAST: dict = {}


def synthesized(files, images, options):
    """The SolidResult of osmap_cli.solid.synthesize_solid for these exemplars and options; the
    last one is kept, so a batch that carves many meshes from one material synthesizes it once
    per process (the same bytes either way)."""
    from osmap_cli.solid import synthesize_solid

    key = (tuple(files), options)
    if key not in _LAST:
        _LAST.clear()
        _LAST[key] = synthesize_solid([im.pixels for im in images], options)
    return _LAST[key]

"""One exemplar's layers seen at another angle: the exemplar sheared for the fill of a face.

Layers made from one exemplar are turned about their grain (layers.TILT), so one slice family
(the planks' ends) shows the bands inclined, where the exemplar shows them along its own stripe
direction. Filled from the exemplar as it is, that family's windows copy the exemplar's grain
across the inclined bands in short steps: a saw-tooth hatching that reads finer than the
material (texmetrics scale, granules' bright structures). That family reads instead the
exemplar sheared so that its stripes run along the face's bands: the columns (or rows) first
stretched along themselves so that the stripes keep their width across them (the one
resampling, alike in every column), then each moved a whole number of pixels, wrapping, so no
pixel is blurred across the columns and the wrap's seam runs along the stripes (it reads as one
more band boundary). The segmentation and the identity channels are sheared alike (nearest
pixel), and the fill's source positions are mapped back to the exemplar's own pixels.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

MIN_TURN = 10.0  # degrees: a face whose bands run within this of the exemplar's keeps it
MAX_SHEAR = 1.5  # pixels of shift per pixel: steeper shears would tear the stripes apart
ALONG = 1e-3  # a face whose trace of the layers is shorter than this runs along them


def face_trace(normal, family: int):
    """(dcol, drow) unit direction (rows down) of planar layers with unit `normal` (z, y, x)
    on the slices of `family` (0, 1, 2: normal to x, y, z; rows, cols as layers.stripe_direction),
    or None when the slices run along the layers."""
    axis = np.zeros(3)
    axis[2 - family] = 1.0
    t = np.cross(np.asarray(normal, np.float64), axis)
    rows_dim, cols_dim = ((0, 1), (0, 2), (1, 2))[family]
    d = np.array([t[cols_dim], t[rows_dim]])
    length = float(np.linalg.norm(d))
    return None if length < ALONG else d / length


def shear_between(source, target):
    """(vertical, m1, m2): the shear that turns stripes along `source` into stripes along
    `target` (both (dcol, drow)): vertical moves whole columns (m1, m2 the stripes' slopes in
    rows per column), else whole rows (the slopes in columns per row); the gentler of the two,
    None when the stripes would have to move more than MAX_SHEAR pixels per pixel."""
    options = []
    for vertical, (i, j) in ((True, (0, 1)), (False, (1, 0))):
        if abs(source[i]) > 0.3 and abs(target[i]) > 0.3:
            m1, m2 = source[j] / source[i], target[j] / target[i]
            options.append((vertical, float(m1), float(m2)))
    options = [o for o in options if abs(_stretch(o[1], o[2]) * o[1] - o[2]) <= MAX_SHEAR]
    return min(options, key=lambda o: abs(o[2] - o[1])) if options else None


def _stretch(m1: float, m2: float) -> float:
    """How much a vertical shear from slope m1 to m2 must first stretch the columns so that the
    stripes keep their width across them (the shear narrows them by sqrt(1 + m1^2) /
    sqrt(1 + m2^2))."""
    return float(np.sqrt((1 + m2 * m2) / (1 + m1 * m1)))


def stretch_rows(image: np.ndarray, g: float, nearest: bool) -> np.ndarray:
    """image (H, W[, C]) resampled to round(H * g) rows: OpenImageIO's Catmull-Rom resize
    along the columns (the rows' pixel centres mapped onto each other, the edge rows held), or
    the nearest row for labels."""
    import OpenImageIO as oiio

    h = image.shape[0]
    n = max(1, int(round(h * g)))
    if nearest:
        y = (np.arange(n) + 0.5) * h / n - 0.5
        return np.ascontiguousarray(image[np.clip(np.rint(y).astype(np.int64), 0, h - 1)])
    pixels = np.ascontiguousarray(image.reshape(h, image.shape[1], -1), np.float32)
    w, c = pixels.shape[1:]
    source = oiio.ImageBuf(oiio.ImageSpec(w, h, c, oiio.FLOAT))
    source.set_pixels(oiio.ROI(), pixels)
    out = oiio.ImageBufAlgo.resize(source, filtername="catmull-rom",
                                   roi=oiio.ROI(0, w, 0, n, 0, 1, 0, c))
    if out.has_error:
        raise RuntimeError(f"resize failed: {out.geterror()}")
    resized = np.asarray(out.get_pixels(oiio.FLOAT), np.float32)
    return resized.reshape((n,) + image.shape[1:]).astype(image.dtype)


def shear_image(image: np.ndarray, vertical: bool, s: float) -> np.ndarray:
    """image (H, W[, C]) with column c rolled round(s * c) rows down (vertical), or row r rolled
    round(s * r) columns right (c, r from the image's centre): whole pixels, wrapping."""
    if not vertical:
        return np.swapaxes(shear_image(np.swapaxes(image, 0, 1), True, s), 0, 1)
    h, w = image.shape[:2]
    rows = (np.arange(h)[:, None] - np.rint(s * (np.arange(w) - (w - 1) / 2)).astype(np.int64)
            [None, :]) % h
    return np.ascontiguousarray(image[rows, np.arange(w)[None, :]])


def turned_image(image: np.ndarray, shear, nearest: bool = False) -> np.ndarray:
    """image with its stripes turned by `shear` (shear_between's): the columns (or rows)
    stretched so that the stripes keep their width, then each moved whole pixels, wrapping."""
    vertical, m1, m2 = shear
    if not vertical:
        return np.swapaxes(turned_image(np.swapaxes(image, 0, 1), (True, m1, m2), nearest), 0, 1)
    g = _stretch(m1, m2)
    stretched = stretch_rows(image, g, nearest)
    return shear_image(stretched, True, m2 - g * m1)


def face_shears(found) -> dict:
    """{family: shear (shear_between's)} for every slice family whose bands run more than
    MIN_TURN degrees from the exemplar's stripes (one exemplar, planar layers only)."""
    model = found.model
    if found.kind != "layers" or len(found.images) != 1 or model.rings:
        return {}
    angle = np.radians(found.analyses[0].angle)
    stripe = np.array([np.cos(angle), -np.sin(angle)])
    out = {}
    for family in range(3):
        trace = face_trace(model.normal, family)
        if trace is None or abs(float(trace @ stripe)) > np.cos(np.radians(MIN_TURN)):
            continue
        shear = shear_between(stripe, trace)
        if shear is not None:
            out[family] = shear
    return out


def sheared_exemplars(task, found):
    """(task, found, back) where every slice family that shows the layers inclined against the
    exemplar's stripes reads the exemplar sheared along its bands (a new exemplar of the task
    and of the plan: images, pyramids, segmentation, identity); unchanged otherwise. back(source)
    turns the fill's source positions ((axis, row, col) per voxel) into the exemplar's own, so
    --uv-out and aligned maps (--with) look up the exemplar the user gave."""
    from osmap_cli.solid.core import SolidTask
    from osmap_cli.texture.pyramid import build_pyramid

    shears = face_shears(found)
    if not shears:
        return task, found, lambda source: source
    images, labels, identity = list(task.images), list(found.ex_labels), list(found.ex_identity)
    pyramids = list(task.pyramids)
    ex_of_axis = np.array(task.ex_of_axis, np.int64)
    made = {}
    for family, shear in sorted(shears.items()):
        key = tuple(round(v, 6) for v in shear)
        if key not in made:
            made[key] = len(images)
            images.append(turned_image(task.images[0], shear).astype(np.float32))
            labels.append(turned_image(found.ex_labels[0], shear, nearest=True))
            identity.append(turned_image(found.ex_identity[0], shear, nearest=True))
            pyramids.append(build_pyramid(images[-1], len(task.shapes)))
        ex_of_axis[family] = made[key]
    back = _source_map({family: (shear, images[made[tuple(round(v, 6) for v in shear)]].shape[:2])
                        for family, shear in shears.items()}, task.images[0].shape[:2])
    names = ", ".join("xyz"[f] for f in sorted(shears))
    task = SolidTask(images=images, ex_of_axis=ex_of_axis, pyramids=pyramids,
                     shapes=task.shapes, tileable=task.tileable, seed=task.seed)
    found = replace(found, images=images, ex_of_axis=ex_of_axis, ex_labels=labels,
                    ex_identity=identity,
                    notes=[*found.notes, f"slices normal to {names} filled from the exemplar "
                           "sheared along their bands"])
    return task, found, back


def _source_map(sheared: dict, shape):
    """back(source) for sheared_exemplars: {family: (shear, the sheared image's (rows, cols))}
    and the exemplar's (rows, cols); every sheared position goes to the exemplar pixel it was
    made from (the nearest, across the stretch)."""

    def back(source: np.ndarray) -> np.ndarray:
        out = np.array(source, copy=True)
        for family, ((vertical, m1, m2), size) in sheared.items():
            sel = out[..., 0] == family
            rows, cols = out[..., 1][sel].astype(np.int64), out[..., 2][sel].astype(np.int64)
            if not vertical:  # the image was sheared transposed
                rows, cols, size, orig = cols, rows, size[::-1], shape[::-1]
            else:
                orig = shape
            s = m2 - _stretch(m1, m2) * m1
            moved = np.rint(s * (cols - (size[1] - 1) / 2)).astype(np.int64)
            stretched = (rows - moved) % size[0]
            rows = np.clip(np.rint((stretched + 0.5) * orig[0] / size[0] - 0.5), 0,
                           orig[0] - 1).astype(out.dtype)
            cols = cols.astype(out.dtype)
            if not vertical:
                rows, cols = cols, rows
            out[..., 1][sel], out[..., 2][sel] = rows, cols
        return out

    return back

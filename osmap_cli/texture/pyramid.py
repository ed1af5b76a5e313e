"""Exemplar pyramids: each level half the size of the one below (OpenImageIO does the filtering),
and the resize behind them (also used to fit control fields to the output)."""

import numpy as np
import OpenImageIO as oiio


def _to_buf(image: np.ndarray) -> oiio.ImageBuf:
    h, w, c = image.shape
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, c, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), np.ascontiguousarray(image, np.float32))
    return buf


def resize(image: np.ndarray, height: int, width: int) -> np.ndarray:
    """image (h, w, C) float32 resized to (height, width) with OpenImageIO's default filter."""
    h, w, c = image.shape
    if (h, w) == (height, width):
        return image.copy()
    src = _to_buf(image)
    dst = oiio.ImageBufAlgo.resize(src, roi=oiio.ROI(0, width, 0, height, 0, 1, 0, c))
    out = dst.get_pixels(oiio.FLOAT)
    if out is None or dst.has_error:
        raise RuntimeError(f"resize failed: {dst.geterror()}")
    return np.asarray(out, np.float32).reshape(height, width, c)


def half_size(shape: tuple[int, int]) -> tuple[int, int]:
    """The size of the next coarser level."""
    return max(1, (shape[0] + 1) // 2), max(1, (shape[1] + 1) // 2)


def level_shapes(shape: tuple[int, int], levels: int) -> list[tuple[int, int]]:
    """[finest, ..., coarsest]: `shape` and the sizes of the `levels - 1` coarser levels."""
    shapes = [tuple(shape)]
    for _ in range(levels - 1):
        shapes.append(half_size(shapes[-1]))
    return shapes


def build_pyramid(image: np.ndarray, levels: int) -> list[np.ndarray]:
    """[finest, ..., coarsest]: `levels` images, each half the size of the previous one."""
    pyramid = [np.asarray(image, np.float32)]
    for _ in range(levels - 1):
        h, w = half_size(pyramid[-1].shape[:2])
        pyramid.append(resize(pyramid[-1], h, w))
    return pyramid

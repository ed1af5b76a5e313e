"""Make the scikit-image-derived sample exemplars (dev-only script).

NOT part of osmap and not needed to use it: this needs scikit-image, which is deliberately not a
project dependency. Run it from a separate virtualenv, from the repository root:

    python3 -m venv /tmp/samples-venv
    /tmp/samples-venv/bin/pip install scikit-image OpenImageIO numpy
    /tmp/samples-venv/bin/python samples/make_from_skimage.py

It reads the CC0 images bundled with scikit-image (``skimage.data.brick``, ``grass`` and
``gravel``: 512x512 grayscale uint8; no download) and writes, next to this script,

* ``NAME.png``     -- the whole image downscaled by 4 to 128x128,
* ``NAME_256.png`` -- the whole image downscaled by 2 to 256x256,

as 8-bit grayscale PNG, using OpenImageIO's ImageBufAlgo.resize with a Blackman-Harris filter
(a smooth, low-ringing filter that is widened automatically when downsampling, so no aliasing).
The output is deterministic.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import OpenImageIO as oiio
import skimage
import skimage.data

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCES = ("brick", "grass", "gravel")
SIZES = {"": 128, "_256": 256}
FILTER = "blackman-harris"


def downscale(gray: np.ndarray, size: int) -> np.ndarray:
    """Resize a (H, W) uint8 image to (size, size) float32 in [0, 1] with OpenImageIO."""
    height, width = gray.shape
    src = oiio.ImageBuf(oiio.ImageSpec(width, height, 1, "float"))
    if not src.set_pixels(oiio.ROI(), (gray.astype(np.float32) / 255.0)[:, :, np.newaxis]):
        raise RuntimeError(src.geterror())
    dst = oiio.ImageBuf(oiio.ImageSpec(size, size, 1, "float"))
    if not oiio.ImageBufAlgo.resize(dst, src, filtername=FILTER):
        raise RuntimeError(dst.geterror() or oiio.geterror())
    return np.asarray(dst.get_pixels("float")).reshape(size, size, 1)


def write_png(path: str, pixels: np.ndarray) -> None:
    quantised = np.rint(np.clip(pixels, 0.0, 1.0) * 255.0).astype(np.uint8)
    height, width, channels = quantised.shape
    spec = oiio.ImageSpec(width, height, channels, "uint8")
    out = oiio.ImageOutput.create(path)
    if out is None or not out.open(path, spec):
        raise RuntimeError(f"{path}: {oiio.geterror() or out.geterror()}")
    ok = out.write_image(quantised)
    out.close()
    error = out.geterror()
    if not ok or error:
        raise RuntimeError(f"{path}: {error}")


def main() -> int:
    print(f"scikit-image {skimage.__version__}, OpenImageIO {oiio.__version__}")
    for name in SOURCES:
        gray = getattr(skimage.data, name)()
        assert gray.shape == (512, 512) and gray.dtype == np.uint8, (name, gray.shape)
        for suffix, size in SIZES.items():
            path = os.path.join(HERE, f"{name}{suffix}.png")
            write_png(path, downscale(gray, size))
            print(f"wrote {os.path.relpath(path)} ({size}x{size}, 1 channel)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

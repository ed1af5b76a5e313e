"""Low-pass an exemplar and a volume alike, for coherence at matched sharpness.

    TEXMETRICS_PYTHON bench/lowpass.py EXEMPLAR VOLUME.npy SIGMA EX_OUT.png VOL_OUT.npy

Runs in the meters' virtualenv (scipy, OpenImageIO), not the project's. texmetrics.py's
coh_mean falls when a volume is blurred (a volume's slices carry 1-voxel disagreements between
the slice families that a blur removes, and soft patches sit near the exemplar's smooth areas),
so a sharper volume scores worse than a softer one of the same structure; with both sides
low-passed by the same Gaussian first, the comparison no longer rewards blur
(docs/solid.md, "Measured").
"""

import sys

import numpy as np
import OpenImageIO as oiio
from scipy.ndimage import gaussian_filter


def main(exemplar: str, volume: str, sigma: float, ex_out: str, vol_out: str) -> None:
    image = oiio.ImageInput.open(exemplar)
    pixels = image.read_image(format="float")
    image.close()
    pixels = gaussian_filter(pixels, (sigma, sigma, 0), mode="reflect")
    out = oiio.ImageOutput.create(ex_out)
    out.open(ex_out, oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "uint16"))
    out.write_image(pixels)
    out.close()
    voxels = np.load(volume).astype(np.float32)
    spread = (sigma,) * 3 + (0,) * (voxels.ndim - 3)
    np.save(vol_out, gaussian_filter(voxels, spread, mode="nearest").astype(np.float32))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4], sys.argv[5])

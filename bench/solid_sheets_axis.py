"""Why Gaussian detail noise cannot bring marble's axis-energy under its exemplar's: the share
of a slice's squared luminance gradient within 7.5 degrees of its axes (solidlook's axis share)
for 3D Gaussian noise of one radial band, isotropic, with its power moved onto the cube's
diagonals (every slice family then shows both diagonals), and stretched within planes normal to
marble's sheet normal (noise.oriented_field's grain). A Gaussian field's gradient at a point is
a Gaussian vector whose covariance is the slice's structure tensor, so its axis share depends on
that tensor alone: 1/6 when it is isotropic, whatever the spectrum's angular layout; only an
oriented grain lowers it.

    OSMAP_SHARED=/work/shared python bench/solid_sheets_axis.py [--side 64] [--exemplar PATH]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from osmap_cli.solid.structure.noise import oriented_field, spectral_field

SHARED = Path(os.environ.get("OSMAP_SHARED", Path(__file__).resolve().parents[2] / "shared"))
sys.path.insert(0, str(SHARED / "tools"))
from solidlook import axis_share, lum  # noqa: E402

NORMAL = np.array([0.632, -0.548, -0.548])  # marble_swirl_green's fitted sheet normal (64 px)


def band(k):
    return np.exp(-((k - 0.3) / 0.12) ** 2) * (k <= 0.5)


def diagonal_band(kz, ky, kx):
    k2 = kz ** 2 + ky ** 2 + kx ** 2
    weight = np.where(k2 > 0, 27 * (kz * ky * kx) ** 2 / np.maximum(k2, 1e-18) ** 3, 0.0)
    return np.sqrt(band(np.sqrt(k2)) * weight)


def shares(volume) -> list:
    n = volume.shape[0]
    return [float(np.mean([axis_share(np.take(volume, i, a)) for i in range(0, n, 8)]))
            for a in range(3)]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--side", type=int, default=64)
    ap.add_argument("--exemplar", type=Path,
                    default=SHARED / "exemplars" / "small" / "marble_swirl_green.png")
    a = ap.parse_args()
    shape = (a.side,) * 3
    freqs = np.linspace(0.0, 0.5, 64)
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(a.exemplar))
    ex = np.asarray(buf.get_pixels(oiio.FLOAT)).reshape(buf.spec().height, buf.spec().width, -1)
    if ex.shape[0] != a.side:
        from osmap_cli.texture.pyramid import resize
        ex = resize(ex, a.side, a.side)
    reference = axis_share(lum(ex))
    rows = [("isotropic", oriented_field(shape, freqs, band(freqs), 1)),
            ("power on the cube's diagonals", spectral_field(shape, diagonal_band, 1))]
    rows += [(f"grain {s} along the sheets", oriented_field(shape, freqs, band(freqs), 1,
                                                             NORMAL, s)) for s in (1.5, 2.0, 3.0)]
    print(f"exemplar axis share {reference:.3f}\n")
    print("| noise | axis share z / y / x | worst / exemplar's |\n|---|---|---|")
    for name, volume in rows:
        s = shares(volume)
        print(f"| {name} | {' / '.join(f'{v:.3f}' for v in s)} | {max(s) / reference:.2f} |")


if __name__ == "__main__":
    main()

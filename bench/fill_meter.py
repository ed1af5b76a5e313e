"""The texmetrics side of bench/fill_measure.py; runs in texmetrics' own venv.

    TEXMETRICS_PY bench/fill_meter.py JOBS.json   # prints one JSON object per job

Jobs (made by fill_measure.py): "inpaint" (original, output, mask .npy): whether the pixels
outside the mask are identical, coh_mean of the 96x96 crop around the hole over the same crop
of the original (both against the original without the hole's rows, stride 1), and the rim z
(mean Lab step across the mask border, as a z-score among the same contour moved to 200
random places of the original). "exemplar" (photo, original: its top part, output, mask):
the same for `inpaint --exemplar` (bench/fill_sheet.py's exemplar_split). "band" (exemplar,
output, mask .npy, tileable): the mean per-pixel coherence error over the mask's pixels
(stride 1), with texmetrics' seam_z when tileable.
"""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import numpy as np
from common import TEXMETRICS  # common imports no osmap: fine in this venv

sys.path.insert(0, str(TEXMETRICS.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import texmetrics as tm  # noqa: E402
from texture_stats import rim_z  # noqa: E402  (plain numpy: the tests' rim z, here in Lab)

CROP = 96


def _rgb(path: str) -> np.ndarray:
    return tm.read_image(path)[..., :3].astype(np.float64)


def inpaint(job: dict) -> dict:
    original, output, mask = _rgb(job["original"]), _rgb(job["output"]), np.load(job["mask"])
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    cy, cx = (ys.min() + ys.max() + 1) // 2, (xs.min() + xs.max() + 1) // 2
    y0 = min(max(cy - CROP // 2, 0), h - CROP)
    x0 = min(max(cx - CROP // 2, 0), w - CROP)
    reference = np.concatenate([original[:ys.min()], original[ys.max() + 1:]], 0)
    crops = [tm.evaluate(reference, im[y0:y0 + CROP, x0:x0 + CROP], stride=1)[0]["2d"]["coh_mean"]
             for im in (original, output)]
    rim = rim_z(tm.to_space(tm.clean(original), False), tm.to_space(tm.clean(output), False),
                mask)
    return {"outside_identical": bool(np.array_equal(original[~mask], output[~mask])),
            "crop_ratio": crops[1] / crops[0], "rim_z": float(rim)}


def from_exemplar(job: dict) -> dict:
    """`inpaint --exemplar`: the crop is the hole and 16 px around it, the reference the whole
    photo without the crop's rows (default stride); the rim z in RGB, as tests/test_fill.py."""
    photo, top = _rgb(job["photo"]), _rgb(job["original"])
    output, mask = _rgb(job["output"]), np.load(job["mask"])
    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - 16, 0), ys.max() + 17
    x0, x1 = max(xs.min() - 16, 0), xs.max() + 17
    reference = np.delete(photo, np.arange(y0, y1), axis=0)
    crops = [tm.evaluate(reference, im[y0:y1, x0:x1])[0]["2d"]["coh_mean"] for im in (top, output)]
    return {"outside_identical": bool(np.array_equal(top[~mask], output[~mask])),
            "crop_ratio": crops[1] / crops[0], "rim_z": float(rim_z(top, output, mask))}


@functools.lru_cache(maxsize=4)
def _evaluated(exemplar: str, output: str, tileable: bool):
    """texmetrics' (report, maps) at stride 1: several masks of one output share them."""
    return tm.evaluate(_rgb(exemplar), _rgb(output), tileable=tileable, stride=1)


def band(job: dict) -> dict:
    report, maps = _evaluated(job["exemplar"], job["output"], job["tileable"])
    out = {"error": float(maps["2d"][0][np.load(job["mask"])].mean())}
    if job["tileable"]:
        out["seam_z"] = float(report["seam_z"])
    return out


def main() -> None:
    for job in json.loads(Path(sys.argv[1]).read_text()):
        kinds = {"inpaint": inpaint, "exemplar": from_exemplar, "band": band}
        result = kinds[job["kind"]](job)
        print(json.dumps({"id": job["id"], **result}), flush=True)


if __name__ == "__main__":
    main()

"""Does coh_mean read what the eye reads on particle materials? For each exemplar: method
structure's volume (with --set changes), method osmap's, and method osmap's own 2D synthesis
(`osmap synth`, 128 px) of the same exemplar as a reference, each scored by texmetrics.py's
coh_mean (worst axis; raw and at matched sharpness, bench/lowpass.py), by the profile meter, and
by two coherences of the structure alone, on every slice's particle mask (read by the
exemplar's own segmentation, osmap_cli.solid.structure.analysis): as 9 x 9 binary patches, the
mean share of pixels that differ from the nearest exemplar mask patch; and as whole profiles,
each profile's mask centred on its centroid against the nearest exemplar profile's, turned or
mirrored (1 - intersection over union, weighted by the profile's area).

    python bench/solid_coherence_front.py [--names gravel_green_stones,terrazzo_granite]
        [--side 64] [--set KEY=VALUE]

Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import (
    REPO,
    TEXMETRICS_PY,
    matched_coherence,
    texmetrics,
    worst_axis,
    written_exemplars,
)

MASK_PATCH = 9  # pixels: about one stone of the development exemplars at 64 px
PROFILE_BOX = 31  # pixels: the box each profile's mask is centred in


def mask_patches(mask: np.ndarray) -> np.ndarray:
    view = np.lib.stride_tricks.sliding_window_view(mask.astype(np.float32),
                                                    (MASK_PATCH, MASK_PATCH))
    return view.reshape(-1, MASK_PATCH * MASK_PATCH)


def mask_coherence(exemplar: np.ndarray, images) -> float | None:
    """The mean share of differing pixels between each image's particle-mask patches and the
    nearest exemplar mask patch; None when the exemplar shows no particles."""
    from osmap_cli.solid.structure.analysis import analyse

    found = analyse(exemplar, False)
    if found.kind != "particles":
        return None
    ref = mask_patches(found.reader.particle_mask(exemplar))
    norms = (ref ** 2).sum(1)
    shares = []
    for image in images:
        own = mask_patches(found.reader.particle_mask(np.ascontiguousarray(image)))
        d = (own ** 2).sum(1)[:, None] - 2.0 * own @ ref.T + norms[None]
        shares.append(d.min(1) / MASK_PATCH ** 2)
    return float(np.concatenate(shares).mean())


def matched_picture(ex_path: Path, picture_path: Path, folder: Path, sigma: float = 1.0):
    """coh_mean of a 2D picture with it and the exemplar low-passed alike (bench/lowpass.py
    blurs its first argument as the exemplar; the volume it also wants is a dummy)."""
    dummy = folder / "dummy.npy"
    np.save(dummy, np.zeros((2, 2, 2, 3), np.float32))
    blurred = []
    for path in (ex_path, picture_path):
        out = folder / f"{path.stem}_lp.png"
        subprocess.run([str(TEXMETRICS_PY), str(REPO / "bench" / "lowpass.py"), str(path),
                        str(dummy), str(sigma), str(out), str(folder / "dummy_lp.npy")],
                       check=True)
        blurred.append(out)
    return worst_axis(texmetrics(*blurred))["coh_mean"]


def profile_masks(mask: np.ndarray):
    """(float32 (P, PROFILE_BOX ** 2) each profile of 4 pixels or more centred on its centroid,
    float64 (P,) their areas)."""
    from osmap_kernels.structure import label_components

    ids, count = label_components(np.where(mask, 1, -1).astype(np.int64), False, False)
    boxes, areas = [], []
    half = PROFILE_BOX // 2
    for k in range(count):
        ys, xs = np.nonzero(ids == k)
        if len(ys) < 4:
            continue
        yy = ys - int(round(ys.mean())) + half
        xx = xs - int(round(xs.mean())) + half
        inside = (yy >= 0) & (yy < PROFILE_BOX) & (xx >= 0) & (xx < PROFILE_BOX)
        box = np.zeros((PROFILE_BOX, PROFILE_BOX), np.float32)
        box[yy[inside], xx[inside]] = 1.0
        boxes.append(box.ravel())
        areas.append(float(len(ys)))
    return np.array(boxes, np.float32).reshape(-1, PROFILE_BOX ** 2), np.array(areas)


def profile_coherence(exemplar: np.ndarray, images) -> float | None:
    """The area-weighted mean of 1 - IoU between each image profile and the nearest exemplar
    profile in any of its eight turns and mirrors; None without particles."""
    from osmap_cli.solid.structure.analysis import analyse

    found = analyse(exemplar, False)
    if found.kind != "particles":
        return None
    ref, _ = profile_masks(found.reader.particle_mask(exemplar))
    square = ref.reshape(-1, PROFILE_BOX, PROFILE_BOX)
    turns = [np.rot90(square, k, (1, 2)) for k in range(4)]
    ref = np.concatenate([t for q in turns for t in (q, q[:, ::-1])]).reshape(len(ref) * 8, -1)
    ref_area = ref.sum(1)
    misses, weights = [], []
    for image in images:
        own, areas = profile_masks(found.reader.particle_mask(np.ascontiguousarray(image)))
        if len(own) == 0:
            continue
        inter = own @ ref.T
        union = own.sum(1)[:, None] + ref_area[None] - inter
        misses.append(1.0 - (inter / union).max(1))
        weights.append(areas)
    if not misses:
        return None
    return float(np.average(np.concatenate(misses), weights=np.concatenate(weights)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--names", default="gravel_green_stones,terrazzo_granite")
    ap.add_argument("--side", type=int, default=64)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a solid option changed for method structure")
    args = ap.parse_args(argv)
    from osmap_cli.imageio import read_image
    from osmap_cli.options import option_spec
    from osmap_cli.solid import SolidOptions, synthesize_solid
    from osmap_cli.solid.structure.meter import profile_meter
    from osmap_cli.solid.structure.slices import axis_slices

    changes = {}
    for item in args.set:
        key, value = item.split("=", 1)
        changes[key] = option_spec(SolidOptions, key).kind(value)
    side = args.side
    print("| exemplar | made by | coh_mean raw / matched | mask coherence | profile "
          "coherence | profile worst error |\n|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, exemplar, ex_path in written_exemplars(args.names.split(","), side, folder):
            for method in ("structure", "osmap", "synth"):
                if method == "synth":
                    out = folder / f"{name}_synth.png"
                    subprocess.run([str(REPO / ".venv" / "bin" / "osmap"), "synth", str(ex_path),
                                    "-o", str(out), "--size", str(2 * side), "--seed", "1"],
                                   check=True, capture_output=True)
                    picture = read_image(out).pixels[..., :3]
                    images, profile = [picture], None
                else:
                    options = SolidOptions(width=side, height=side, depth=side, seed=1,
                                           method=method)
                    if method == "structure":
                        options = options.replace(**changes)
                    voxels = synthesize_solid([exemplar], options).voxels
                    out = folder / f"{name}_{method}.npy"
                    np.save(out, voxels)
                    images = [s for _, _, s in axis_slices(voxels, 6)]
                    report = profile_meter(exemplar, voxels)
                    profile = report["worst"] if report else None
                raw = worst_axis(texmetrics(ex_path, out))["coh_mean"]
                matched = (matched_picture(ex_path, out, folder) if method == "synth"
                           else matched_coherence(ex_path, out))
                mask = mask_coherence(exemplar, images)
                whole = profile_coherence(exemplar, images)
                made = "method osmap's 2D synth" if method == "synth" else f"method {method}"
                print(f"| {name} | {made} | {raw:.2f} / {matched:.2f} | "
                      f"{'-' if mask is None else f'{mask:.3f}'} | "
                      f"{'-' if whole is None else f'{whole:.3f}'} | "
                      f"{'-' if profile is None else f'{profile:.2f}'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

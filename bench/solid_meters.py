"""The solid benches' shared pieces: where the development exemplars and the independent
meters are, and how a volume is read by texmetrics.py, solidlook.py and at matched sharpness
(bench/lowpass.py). The meters run in their own venv (TEXMETRICS_PYTHON)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
# ../shared beside the checkout (a worktree one level deeper finds it too)
SHARED = next((p / "shared" for p in REPO.parents if (p / "shared" / "exemplars").is_dir()),
              REPO.parent / "shared")
EXEMPLARS = SHARED / "exemplars" / "small"
TEXMETRICS = SHARED / "tools" / "texmetrics.py"
SOLIDLOOK = SHARED / "tools" / "solidlook.py"
GRANULES = SHARED / "tools" / "granules.py"
TEXMETRICS_PY = Path(os.environ.get("TEXMETRICS_PYTHON", "/tmp/texmetrics-venv/bin/python"))
NAMES = ("terrazzo_granite", "marble_swirl_green", "wood_planks_horizontal",
         "gravel_green_stones")


def load_exemplar(name: str, side: int) -> np.ndarray:
    """A development exemplar, or a shipped sample (`samples/gravel`), at `side` px."""
    from osmap_cli.imageio import read_image
    from osmap_cli.texture.pyramid import resize

    path = REPO / f"{name}.png" if name.startswith("samples/") else EXEMPLARS / f"{name}.png"
    image = read_image(path).pixels
    return image if image.shape[0] == side else resize(image, side, side)


def texmetrics(exemplar_path: Path, volume_path: Path) -> dict:
    out = subprocess.run([str(TEXMETRICS_PY), str(TEXMETRICS), str(exemplar_path),
                          str(volume_path), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def written_exemplars(names, side: int, folder: Path):
    """(name, exemplar pixels, the exemplar as an 8-bit PNG in FOLDER) for each name."""
    from osmap_cli.imageio import write_image

    for name in names:
        exemplar = load_exemplar(name, side)
        path = folder / f"{name.replace('/', '_')}.png"
        write_image(path, exemplar, 8)
        yield name, exemplar, path


def low_passed(exemplar_path: Path, volume_path: Path, sigma: float = 1.0) -> tuple[Path, Path]:
    """The exemplar and the volume blurred alike (bench/lowpass.py), written beside the volume."""
    ex_lp = volume_path.with_name(volume_path.stem + "_lp_ex.png")
    vol_lp = volume_path.with_name(volume_path.stem + "_lp.npy")
    subprocess.run([str(TEXMETRICS_PY), str(REPO / "bench" / "lowpass.py"), str(exemplar_path),
                    str(volume_path), str(sigma), str(ex_lp), str(vol_lp)], check=True)
    return ex_lp, vol_lp


def matched_coherence(exemplar_path: Path, volume_path: Path, sigma: float = 1.0) -> float:
    """Worst-axis coh_mean with exemplar and volume low-passed alike (bench/lowpass.py): blur
    no longer scores better, so sharp and soft methods compare on structure."""
    return worst_axis(texmetrics(*low_passed(exemplar_path, volume_path, sigma)))["coh_mean"]


def granules_report(exemplar_path: Path, volume_path: Path) -> dict:
    """granules.py's whole reading: per axis (x, y, z) and the worst."""
    out = subprocess.run([str(TEXMETRICS_PY), str(GRANULES), str(exemplar_path),
                          str(volume_path), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def granules(exemplar_path: Path, volume_path: Path) -> dict:
    """granules.py's worst-axis reading (bright_shift, dark_shift)."""
    return granules_report(exemplar_path, volume_path)["worst"]


def solidlook(exemplar_path: Path, volume_path: Path) -> dict:
    out = subprocess.run([str(TEXMETRICS_PY), str(SOLIDLOOK), str(exemplar_path),
                          str(volume_path), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def worst_axis(report: dict) -> dict:
    return report.get("worst") or report["2d"]

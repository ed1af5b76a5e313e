"""The README's pictures, one per command, made from the shipped samples with the `osmap`
command line of this checkout (so that anyone can make them again after a change):

    docs/readme_synth.jpg     osmap synth: exemplar (1:1) and a 256x256 output, three samples
    docs/readme_fill.jpg      osmap inpaint (image with a hole | filled) and osmap tileable
                              (the centre of the photo tiled 2x2 | the same of the result)
    docs/readme_solid.jpg     osmap solid --preview: a cube and three slices, two volumes
    docs/readme_surface.jpg   osmap surface --preview (one view): a torus, OS-Map | classic SOM

    .venv/bin/python bench/readme_pictures.py [--only synth,fill,solid,surface]

Seeds and sizes are fixed: the same code makes the same pictures. About two minutes on two free
cores (the two 96^3 volumes are most of it).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
DOCS = REPO / "docs"
OSMAP = Path(sys.executable).parent / "osmap"
GAP, BACKGROUND = 8, 0.13


def osmap(*args, cwd: Path) -> None:
    subprocess.run([str(OSMAP), *map(str, args)], cwd=cwd, check=True)


def rgb(path: Path) -> np.ndarray:
    from osmap_cli.imageio import read_image

    pixels = read_image(path).pixels[..., :3]
    return np.repeat(pixels, 3, axis=2) if pixels.shape[2] == 1 else pixels


def row(panels: list[np.ndarray]) -> np.ndarray:
    """Panels side by side, top-aligned, GAP apart, on the background."""
    height = max(p.shape[0] for p in panels)
    width = sum(p.shape[1] for p in panels) + GAP * (len(panels) - 1)
    out = np.full((height, width, 3), BACKGROUND, np.float32)
    x = 0
    for panel in panels:
        out[:panel.shape[0], x:x + panel.shape[1]] = panel
        x += panel.shape[1] + GAP
    return out


def column(rows: list[np.ndarray]) -> np.ndarray:
    return np.swapaxes(row([np.swapaxes(r, 0, 1) for r in rows]), 0, 1)


def save(path: Path, pixels: np.ndarray) -> None:
    from osmap_cli.imageio import write_image

    write_image(path, np.clip(pixels, 0, 1))
    print(f"wrote {path.relative_to(REPO)}", file=sys.stderr)


def synth_picture(work: Path) -> None:
    panels = []
    for name, extra in (("brick.png", ["--preset", "structured"]), ("weave.png", []),
                        ("gravel.png", [])):
        out = work / f"synth_{name}"
        osmap("synth", SAMPLES / name, "-o", out, "--size", "256", "--seed", "1", "-q", *extra,
              cwd=work)
        panels += [rgb(SAMPLES / name), rgb(out)]
    save(DOCS / "readme_synth.jpg", row(panels))


def fill_picture(work: Path) -> None:
    from osmap_cli.imageio import write_image

    image = rgb(SAMPLES / "brick_256.png")
    mask = np.zeros(image.shape[:2], np.float32)
    mask[96:160, 96:160] = 1.0
    write_image(work / "hole.png", mask[..., None])
    osmap("inpaint", SAMPLES / "brick_256.png", "--mask", "hole.png", "-o", "filled.png",
          "--seed", "1", "-q", cwd=work)
    holed = np.where(mask[..., None] > 0, 0.5, image)
    osmap("tileable", SAMPLES / "gravel_256.png", "-o", "tile.png", "--seed", "1", "-q",
          cwd=work)

    def crossing(pixels):  # the centre of the image tiled 2x2, 1:1: its edges meet in a cross
        h, w = pixels.shape[:2]
        return np.tile(pixels, (2, 2, 1))[h // 2:h // 2 + h, w // 2:w // 2 + w]

    panels = [holed, rgb(work / "filled.png"), crossing(rgb(SAMPLES / "gravel_256.png")),
              crossing(rgb(work / "tile.png"))]
    save(DOCS / "readme_fill.jpg", row(panels))


def solid_picture(work: Path) -> None:
    osmap("solid", SAMPLES / "cells.png", "-o", "cells.npy", "--size", "96", "--seed", "1",
          "--preview", "cells_preview.png", "-q", cwd=work)
    osmap("solid", "--x", SAMPLES / "wood_end.png", "--y", SAMPLES / "wood_side.png", "--z",
          SAMPLES / "wood_top.png", "-o", "wood.npy", "--size", "96", "--seed", "1",
          "--preview", "wood_preview.png", "-q", cwd=work)
    save(DOCS / "readme_solid.jpg", column([rgb(work / "cells_preview.png"),
                                            rgb(work / "wood_preview.png")]))


def surface_picture(work: Path) -> None:
    for method in ("osmap", "som"):
        osmap("surface", "--shape", "torus", "-o", f"{method}.obj", "--grid", "32x32",
              "--method", method, "--seed", "0", "--preview", f"{method}.png", cwd=work)
    views = [rgb(work / f"{method}.png") for method in ("osmap", "som")]
    save(DOCS / "readme_surface.jpg", row([v[:, :v.shape[1] // 2] for v in views]))


PICTURES = {"synth": synth_picture, "fill": fill_picture, "solid": solid_picture,
            "surface": surface_picture}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default=",".join(PICTURES),
                        help="comma-separated: " + ", ".join(PICTURES))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="osmap-readme-") as work:
        for name in args.only.split(","):
            PICTURES[name](Path(work))
    return 0


if __name__ == "__main__":
    sys.exit(main())

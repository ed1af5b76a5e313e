"""Contact sheets of `osmap inpaint` and `osmap tileable` on the development exemplars.

docs/fill_inpaint.jpg: per exemplar, the image with a 64x64 hole (grey), its fill, the image
with an irregular hole, its fill (seed 0, defaults). docs/fill_tileable.jpg: per exemplar, the
photo tiled 2x2 and the `osmap tileable` result tiled 2x2 (default border: an eighth of the
shorter side), each cell the 256x256 centre of the tiling, where the four copies meet (a cross
of seams for the photo). docs/fill_exemplar.jpg (`inpaint --exemplar`): per exemplar, its top
part (H/2 + 16 rows) with a 40x40 hole (grey), the hole filled from the bottom part alone,
and that bottom part (the exemplar EX). Images are shown 1:1 in 256x256 cells.

    python bench/fill_sheet.py [--exemplars DIR] [--names a,b] [--sheets inpaint,tileable,exemplar]
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions  # noqa: E402
from osmap_cli.synth.fill import inpaint, make_tileable  # noqa: E402

DOCS = os.path.join(os.path.dirname(__file__), "..", "docs")
NAMES = ("bricks_dark_red", "gravel_green_stones", "bark_vertical", "tomatoes",
         "text_newsprint", "water_caustics")
CELL, GAP = 256, 6


def square_hole(shape, size=64):
    free = np.zeros(shape, bool)
    cy, cx = shape[0] // 2, shape[1] // 2
    free[cy - size // 2:cy + size // 2, cx - size // 2:cx + size // 2] = True
    return free


def blob_hole(shape):
    yy, xx = np.mgrid[:shape[0], :shape[1]]
    cy, cx = shape[0] // 2, shape[1] // 2
    angle, radius = np.arctan2(yy - cy, xx - cx), np.hypot(yy - cy, xx - cx)
    return radius < 30 + 10 * np.sin(3 * angle) + 6 * np.cos(5 * angle + 1)


def exemplar_split(image):
    """(top part, bottom part, 40x40 hole at the top part's centre) of an image."""
    split = image.shape[0] // 2 + 16
    top, bottom = image[:split], image[split:]
    return top, bottom, square_hole(top.shape[:2], 40)


def crossing(image):
    """The centre CELL x CELL of the image tiled 2x2: where its four copies meet."""
    tiled = np.tile(image, (2, 2, 1))
    h, w = image.shape[:2]
    return tiled[max(h - CELL // 2, 0):h + CELL // 2, max(w - CELL // 2, 0):w + CELL // 2]


def cell(image):
    out = np.full((CELL, CELL, 3), 0.18, np.float32)
    h, w = min(image.shape[0], CELL), min(image.shape[1], CELL)
    y, x = (CELL - h) // 2, (CELL - w) // 2
    out[y:y + h, x:x + w] = image[:h, :w, :3]
    return out


def sheet(rows):
    width = len(rows[0]) * (CELL + GAP) + GAP
    out = np.full((len(rows) * (CELL + GAP) + GAP, width, 3), 0.13, np.float32)
    for r, row in enumerate(rows):
        for c, image in enumerate(row):
            y, x = GAP + r * (CELL + GAP), GAP + c * (CELL + GAP)
            out[y:y + CELL, x:x + CELL] = cell(image)
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--exemplars", default=os.path.join(os.path.dirname(__file__), "..",
                                                              "..", "shared", "exemplars"))
    parser.add_argument("--names", default=",".join(NAMES))
    parser.add_argument("--sheets", default="inpaint,tileable,exemplar")
    args = parser.parse_args()
    sheets = args.sheets.split(",")
    inpaint_rows, tile_rows, exemplar_rows = [], [], []
    for name in args.names.split(","):
        image = read_image(os.path.join(args.exemplars, name + ".png")).pixels[..., :3]
        if image.shape[2] == 1:
            image = np.repeat(image, 3, axis=2)
        if "inpaint" in sheets:
            row = []
            for hole in (square_hole(image.shape[:2]), blob_hole(image.shape[:2])):
                shown = np.where(hole[..., None], 0.5, image)
                row += [shown, inpaint(image, hole, SynthOptions(seed=0)).pixels]
            inpaint_rows.append(row)
        if "tileable" in sheets:
            tiled = make_tileable(image).pixels
            tile_rows.append([crossing(image), crossing(tiled)])
        if "exemplar" in sheets:
            top, bottom, hole = exemplar_split(image)
            filled = inpaint(top, hole, SynthOptions(seed=0), exemplars=[bottom]).pixels
            exemplar_rows.append([np.where(hole[..., None], 0.5, top), filled, bottom])
        print(name, flush=True)
    for rows, file in ((inpaint_rows, "fill_inpaint.jpg"), (tile_rows, "fill_tileable.jpg"),
                       (exemplar_rows, "fill_exemplar.jpg")):
        if rows:
            write_image(os.path.join(DOCS, file), sheet(rows), 8)


if __name__ == "__main__":
    main()

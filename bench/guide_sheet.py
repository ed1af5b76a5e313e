"""Contact sheet of guided synthesis on shipped samples: docs/guide.png.

Row 1, a guide that separates two materials: the exemplar (left half gravel, right half brick,
the top-left 64x64 of each sample), its guide (0 | 1), a target guide (a disc of 1 in 0), the
guided output (192x192) and the unguided one. Row 2, transfer onto shapes without --guide (the
exemplar's blurred luminance is its guide): samples/cells.png, its automatic guide, a target
of diagonal bands, the guided output, the unguided one. Seed 1, defaults; cells 192 px, 6 px
gaps, outputs shown 1:1.

    python bench/guide_sheet.py
"""

from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions, synthesize  # noqa: E402
from osmap_cli.synth.guide import auto_guide  # noqa: E402
from osmap_cli.texture.pyramid import resize  # noqa: E402

ROOT = os.path.join(os.path.dirname(__file__), "..")
SIDE, GAP = 192, 6


def _grey(values: np.ndarray) -> np.ndarray:
    return np.repeat(values[..., None], 3, axis=2).astype(np.float32)


def _cell(image: np.ndarray) -> np.ndarray:
    image = image[..., :3] if image.shape[2] >= 3 else np.repeat(image, 3, axis=2)
    if image.shape[0] != SIDE or image.shape[1] != SIDE:
        scale = SIDE / max(image.shape[:2])
        image = resize(image, max(1, round(image.shape[0] * scale)),
                       max(1, round(image.shape[1] * scale)))
    out = np.full((SIDE, SIDE, 3), 0.15, np.float32)
    out[:image.shape[0], :image.shape[1]] = image
    return out


def _row(exemplar, guide, target, options):
    guided = synthesize(exemplar, options, guide=guide, target_guide=target).pixels
    plain = synthesize(exemplar, options).pixels
    shown_guide = guide if guide is not None else auto_guide(exemplar)
    return [_cell(exemplar), _cell(_grey(shown_guide)), _cell(_grey(target)), _cell(guided),
            _cell(plain)]


def main() -> None:
    options = SynthOptions(width=SIDE, height=SIDE, seed=1)
    yy, xx = np.mgrid[:SIDE, :SIDE]
    gravel = read_image(os.path.join(ROOT, "samples", "gravel.png")).pixels[:64, :64]
    brick = read_image(os.path.join(ROOT, "samples", "brick.png")).pixels[:64, :64]
    pair = np.concatenate([gravel, brick], axis=1)
    pair_guide = np.zeros((64, 128), np.float32)
    pair_guide[:, 64:] = 1.0
    disc = ((yy - SIDE / 2) ** 2 + (xx - SIDE / 2) ** 2 < (SIDE / 3) ** 2).astype(np.float32)
    cells = read_image(os.path.join(ROOT, "samples", "cells.png")).pixels
    bands = (((yy + xx) // 48) % 2).astype(np.float32)
    rows = [_row(pair, pair_guide, disc, options), _row(cells, None, bands, options)]
    gap_v = np.full((SIDE, GAP, 3), 0.15, np.float32)
    lines = []
    for row in rows:
        parts = []
        for cell in row:
            parts += [cell, gap_v]
        lines += [np.concatenate(parts[:-1], axis=1),
                  np.full((GAP, len(row) * (SIDE + GAP) - GAP, 3), 0.15, np.float32)]
    write_image(os.path.join(ROOT, "docs", "guide.png"), np.concatenate(lines[:-1], axis=0), 8)


if __name__ == "__main__":
    main()

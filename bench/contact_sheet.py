"""Contact sheets comparing osmap with the peers on the development exemplars.

docs/contact_sheet.jpg: one row per exemplar of ../shared/exemplars/small/; columns: the
exemplar (1:1, centred in its cell), osmap default, osmap paper, then the peers resynth, embark,
quilting and opara_patch (../shared/design/peers/<peer>/<name>.png). Every cell is 256x256.

docs/contact_sheet_tileable.jpg: the exemplar, the tileable output, the output tiled 2x2 at
half scale, and the centre 256x256 of the 2x2 tiling at 1:1 (where the four wrap seams cross).

The osmap outputs are read from the quality scratch folder (OUTDIR/<variant>/<name>.png, see
bench/quality.py); missing ones are synthesized first (seed 1), unless --no-synth.

    python bench/contact_sheet.py [--outdir DIR] [--no-synth]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import common
import numpy as np
import OpenImageIO as oiio
import quality
from common import DOCS_DIR, PEERS_DIR, SMALL_EXEMPLARS

CELL = 256
GAP = 6
MARGIN = 10
HEADER = 34
LABEL_W = 150
BG = (0.13, 0.13, 0.13)
EMPTY = (0.22, 0.22, 0.22)
MAT = (0.18, 0.18, 0.18)  # the cell behind an image smaller than the cell
TEXT = (0.95, 0.95, 0.95)
DIM = (0.65, 0.65, 0.65)
MAX_BYTES = 1_500_000
PEERS = ("resynth", "embark", "quilting", "opara_patch")


def load_rgb(path: Path) -> np.ndarray | None:
    """float32 (h, w, 3) in [0, 1]: gray replicated, alpha dropped; None if unreadable."""
    if not path.exists():
        return None
    buf = oiio.ImageBuf(str(path))
    pixels = buf.get_pixels(oiio.FLOAT)
    if buf.has_error or pixels is None:
        return None
    pixels = np.asarray(pixels, np.float32).reshape(buf.spec().height, buf.spec().width, -1)
    c = pixels.shape[2]
    if c in (1, 2):
        pixels = np.repeat(pixels[..., :1], 3, axis=2)
    return np.ascontiguousarray(pixels[..., :3])


def fit_cell(img: np.ndarray) -> np.ndarray:
    """Crop to at most CELL x CELL (images are never scaled here)."""
    return img[:CELL, :CELL]


def half(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
    img = img[:h, :w]
    return 0.25 * (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2])


class Sheet:
    """A grid of 256x256 cells with a header row of column labels and a column of row labels."""

    def __init__(self, columns: list[str], rows: list[str], title: str = ""):
        self.columns, self.rows, self.title = columns, rows, title
        self.width = MARGIN * 2 + LABEL_W + len(columns) * (CELL + GAP) - GAP
        self.height = MARGIN * 2 + HEADER + len(rows) * (CELL + GAP) - GAP
        self.canvas = np.empty((self.height, self.width, 3), np.float32)
        self.canvas[:] = BG
        self.texts: list[tuple] = []  # (x, y, text, size, colour, alignx, aligny)

    def cell_origin(self, row: int, col: int) -> tuple[int, int]:
        return (MARGIN + HEADER + row * (CELL + GAP), MARGIN + LABEL_W + col * (CELL + GAP))

    def put(self, row: int, col: int, img: np.ndarray | None, centre: bool = False,
            caption: str = ""):
        y0, x0 = self.cell_origin(row, col)
        if img is None:
            self.canvas[y0:y0 + CELL, x0:x0 + CELL] = EMPTY
            self.texts.append((x0 + CELL // 2, y0 + CELL // 2, "missing", 18, DIM,
                               "center", "center"))
            return
        img = fit_cell(img)
        h, w = img.shape[:2]
        oy, ox = ((CELL - h) // 2, (CELL - w) // 2) if centre else (0, 0)
        if (h, w) != (CELL, CELL):
            self.canvas[y0:y0 + CELL, x0:x0 + CELL] = MAT
        self.canvas[y0 + oy:y0 + oy + h, x0 + ox:x0 + ox + w] = np.clip(img, 0, 1)
        if caption:
            self.texts.append((x0 + CELL // 2, y0 + CELL - 12, caption, 14, DIM,
                               "center", "baseline"))

    def labels(self):
        for c, label in enumerate(self.columns):
            _, x0 = self.cell_origin(0, c)
            self.texts.append((x0 + CELL // 2, MARGIN + HEADER // 2, label, 20, TEXT,
                               "center", "center"))
        if self.title:
            self.texts.append((MARGIN + 4, MARGIN + HEADER // 2, self.title, 14, DIM,
                               "left", "center"))
        for r, name in enumerate(self.rows):
            y0, _ = self.cell_origin(r, 0)
            lines = wrap_name(name)
            step = 22
            top = y0 + CELL // 2 - (len(lines) - 1) * step // 2
            for k, line in enumerate(lines):
                self.texts.append((MARGIN + 4, top + k * step, line, 18, TEXT, "left", "center"))

    def write(self, path: Path, log=print) -> Path:
        self.labels()
        buf = oiio.ImageBuf(oiio.ImageSpec(self.width, self.height, 3, oiio.FLOAT))
        buf.set_pixels(oiio.ROI(0, self.width, 0, self.height, 0, 1, 0, 3), self.canvas)
        text_ok = True
        for x, y, text, size, colour, ax, ay in self.texts:
            if not oiio.ImageBufAlgo.render_text(buf, x, y, text, size, "", colour, ax, ay):
                text_ok = False
        if not text_ok:
            log(f"warning: OpenImageIO could not render text ({oiio.geterror()}); "
                f"{path.name} has no labels")
        return write_jpeg(buf, path, log=log)


def wrap_name(name: str, width: int = 13) -> list[str]:
    """Split an exemplar name at underscores into lines of at most ~width characters."""
    lines, current = [], ""
    for part in name.split("_"):
        candidate = f"{current}_{part}" if current else part
        if current and len(candidate) > width:
            lines.append(current + "_")
            current = part
        else:
            current = candidate
    lines.append(current)
    return lines


def write_jpeg(buf: oiio.ImageBuf, path: Path, log=print) -> Path:
    """Write as JPEG, lowering the quality until the file is under MAX_BYTES."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.jpg")
    out = oiio.ImageBuf(buf.spec())
    oiio.ImageBufAlgo.copy(out, buf, oiio.UINT8)
    for jpeg_quality in (92, 90, 88, 86, 84, 82, 80, 78, 76, 74, 72, 70, 65, 60):
        out.specmod().attribute("Compression", f"jpeg:{jpeg_quality}")
        if not out.write(str(tmp), oiio.UINT8):
            raise RuntimeError(f"could not write {path}: {out.geterror()}")
        size = tmp.stat().st_size
        if size <= MAX_BYTES:
            break
    os.replace(tmp, path)
    log(f"wrote {common.rel(path)}: {out.spec().width}x{out.spec().height}, JPEG quality "
        f"{jpeg_quality}, {size / 1e6:.2f} MB")
    return path


# ----------------------------------------------------------------------------- the sheets

def ensure_outputs(outdir: Path, variants: list[str], names: list[str], log=print):
    """Synthesize the osmap outputs the sheets need that are not in OUTDIR yet."""
    for v in variants:
        variant = quality.VARIANTS[v]
        missing = [n for n in names if not (outdir / v / f"{n}.png").exists()]
        if missing:
            quality.warm_up(variant, missing[0], {})
        for n in missing:
            log(f"[sheet] synthesizing {v}/{n}")
            quality.synth_one(variant, n, outdir / v / f"{n}.png", quality.SEED, {})


def comparison_sheet(outdir: Path, names: list[str], path: Path, log=print) -> Path:
    columns = ["exemplar (1:1)", "osmap default", "osmap paper", *PEERS]
    sheet = Sheet(columns, names, title="osmap: seed 1")
    for r, name in enumerate(names):
        ex = load_rgb(SMALL_EXEMPLARS / f"{name}.png")
        caption = f"{ex.shape[1]}x{ex.shape[0]}" if ex is not None else ""
        sheet.put(r, 0, ex, centre=True, caption=caption)
        sheet.put(r, 1, load_rgb(outdir / "default" / f"{name}.png"))
        sheet.put(r, 2, load_rgb(outdir / "paper" / f"{name}.png"))
        for c, peer in enumerate(PEERS, start=3):
            sheet.put(r, c, load_rgb(PEERS_DIR / peer / f"{name}.png"))
    return sheet.write(path, log=log)


def tileable_sheet(outdir: Path, names: list[str], path: Path, log=print) -> Path:
    columns = ["exemplar (1:1)", "osmap tileable", "2x2 tiled, half scale", "2x2 centre, 1:1"]
    sheet = Sheet(columns, names, title="osmap: seed 1")
    for r, name in enumerate(names):
        ex = load_rgb(SMALL_EXEMPLARS / f"{name}.png")
        caption = f"{ex.shape[1]}x{ex.shape[0]}" if ex is not None else ""
        sheet.put(r, 0, ex, centre=True, caption=caption)
        out = load_rgb(outdir / "tileable" / f"{name}.png")
        sheet.put(r, 1, out)
        if out is None:
            sheet.put(r, 2, None)
            sheet.put(r, 3, None)
            continue
        tiled = np.tile(out, (2, 2, 1))
        sheet.put(r, 2, half(tiled), centre=True)
        h, w = out.shape[:2]
        cy, cx = h - CELL // 2, w - CELL // 2
        sheet.put(r, 3, tiled[max(cy, 0):max(cy, 0) + CELL, max(cx, 0):max(cx, 0) + CELL])
    return sheet.write(path, log=log)


def make_all(outdir: Path, synth_missing: bool = True, log=print) -> list[tuple[Path, str]]:
    """Both sheets; returns [(path, description)]."""
    names = quality.exemplar_names()
    if synth_missing:
        ensure_outputs(outdir, ["default", "paper", "tileable"], names, log=log)
    made = [
        (comparison_sheet(outdir, names, DOCS_DIR / "contact_sheet.jpg", log=log),
         "rows: the 11 dev exemplars; columns: exemplar at 1:1, osmap default, osmap paper, "
         "resynth, embark, quilting, opara_patch (all 256x256, seed 1 for osmap)"),
        (tileable_sheet(outdir, names, DOCS_DIR / "contact_sheet_tileable.jpg", log=log),
         "exemplar, `tileable=True` output, the output tiled 2x2 at half scale, and the "
         "centre of the 2x2 tiling at 1:1 (the wrap seams cross in the middle)"),
    ]
    return made


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--outdir", type=Path, default=None,
                    help="quality scratch folder holding <variant>/<name>.png "
                         "(default ${TMPDIR:-/tmp}/osmap-quality)")
    ap.add_argument("--no-synth", action="store_true",
                    help="do not synthesize missing outputs (their cells say 'missing')")
    args = ap.parse_args(argv)
    if not SMALL_EXEMPLARS.is_dir() or not PEERS_DIR.is_dir():
        print(common.shared_note("the contact sheets"), file=sys.stderr)
        return 2
    outdir = args.outdir or quality.default_outdir()
    for path, _ in make_all(outdir, synth_missing=not args.no_synth):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

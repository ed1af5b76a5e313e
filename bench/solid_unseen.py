"""Method structure on materials it was not tuned on: for every other exemplar in
../shared/exemplars/small (bark, a basket weave, bricks, a knit, printed text, tomatoes, water
caustics), what the analysis reads (the structure kind, its phases, particle sizes, layer
spacing, orientation) and methods structure and osmap side by side on every meter of
bench/solid_structure.py, with its contact sheet (preview cube, middle slices, an oblique cut).

    python bench/solid_unseen.py [--sides 64] [--names bark_vertical,...]
        [--methods structure,osmap] [--sheet out.jpg] [--markdown out.md] [--analyse-only]

Prints the readings (one row per exemplar and size), then bench/solid_structure.py's tables.
Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from solid_meters import load_exemplar
from solid_structure import BARS, HEADER, run, tables

UNSEEN = ("bark_vertical", "basket_weave_diagonal", "bricks_dark_red", "knit_rope_mesh",
          "text_newsprint", "tomatoes", "water_caustics")

READING_HEADER = ("| exemplar | px | read as | phases | particles (count, fraction, diameter "
                  "median / 90 %) | orientation, coherence | spacing |\n"
                  "|---|---|---|---|---|---|---|")


def reading(name: str, side: int) -> dict:
    """What method structure's analysis reads from the exemplar at `side` px."""
    from osmap_cli.solid.structure.analysis import PERIODIC
    from osmap_cli.solid.structure.method import plan

    found = plan([load_exemplar(name, side)], np.zeros(3, np.int64), probe_cap=side)
    a = found.analyses[0]
    periodic = a.kind == "layers" or a.spacing_strength >= PERIODIC
    row = {"name": name, "side": side, "kind": found.kind, "notes": list(a.notes),
           "phases": [round(float(f), 2) for f in a.fractions], "angle": a.angle,
           "coherence": a.coherence, "spacing": a.spacing if periodic else 0.0,
           "report": found.report()}
    if a.profiles is not None:
        p = a.profiles.scaled(1.0 / a.reader.factor)
        q = p.quantiles()
        row["particles"] = (p.count, p.fraction, q[1], q[3])
    return row


def reading_row(r: dict) -> str:
    kind = r["kind"] + (f" ({'; '.join(r['notes'])})" if r["notes"] else "")
    phases = ", ".join(f"{100 * f:.0f} %" for f in r["phases"])
    particles = ("-" if "particles" not in r else
                 "{} profiles, {:.0%}, {:.1f} / {:.1f} px".format(*r["particles"]))
    spacing = f"{r['spacing']:.1f} px" if r["spacing"] else "-"
    return (f"| {r['name']} | {r['side']} | {kind} | {phases} | {particles} | "
            f"{r['angle']:.0f} deg, {r['coherence']:.2f} | {spacing} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sides", default="64")
    ap.add_argument("--names", default=",".join(UNSEEN))
    ap.add_argument("--methods", default="structure,osmap")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sheet", type=Path, default=None)
    ap.add_argument("--markdown", type=Path, default=None,
                    help="write the readings and both tables (Markdown) to this file")
    ap.add_argument("--analyse-only", action="store_true",
                    help="print the readings (and each one's full report) only")
    args = ap.parse_args(argv)
    names = args.names.split(",")
    sides = [int(s) for s in args.sides.split(",")]
    readings = [reading(n, s) for n in names for s in sides]
    lines = [READING_HEADER, *(reading_row(r) for r in readings)]
    print("\n".join(lines), flush=True)
    if args.analyse_only:
        for r in readings:
            print(f"\n{r['name']} at {r['side']} px:\n  " + "\n  ".join(r["report"]))
        return 0
    methods = args.methods.split(",")
    print("\n" + HEADER, flush=True)
    rows = run(names, sides, methods, args.sheet, seed=args.seed,
               log=lambda line: print(line, flush=True))
    text = tables(rows, methods)
    print(text[text.index(BARS) - 1:])
    if args.markdown is not None:
        args.markdown.write_text("\n".join(lines) + "\n\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The measured front of `osmap solid --method structure`: one point per variant of its settings
(and method osmap beside them), each summarised over the solid development exemplars against
the acceptance bars, with a contact sheet of the volumes. The variants show what each part of
the engine contributes and trades: the OS-Map layout (against the same method from a random
start), the guide channels' weight and reach, the final colour matching, the window side.

    python bench/solid_front.py [--side 64] [--only NAME,NAME] [--sheet FILE.jpg]

Prints a Markdown table. Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from solid_meters import NAMES
from solid_structure import SUMMARY_HEADER, run, summary

# (name, method, option changes, what it stands for)
VARIANTS = (
    ("structure", "structure", {}, "the default"),
    ("no-osmap", "structure", {"som_steps_per_node": 0.0},
     "the fill from the OS-Map's untrained (random) layout"),
    ("guide-0.5", "structure", {"guide_weight": 0.5}, "guide channels at half weight"),
    ("guide-2", "structure", {"guide_weight": 2.0}, "guide channels at twice the weight"),
    ("clip-2", "structure", {"guide_clip": 2.0}, "the distance guide saturates at 2 px"),
    ("clip-8", "structure", {"guide_clip": 8.0}, "the distance guide saturates at 8 px"),
    ("match-0", "structure", {"phase_match": 0.0}, "no colour matching per phase"),
    ("match-0.5", "structure", {"phase_match": 0.5}, "half the colour matching"),
    ("window-6", "structure", {"kopf_window": 6}, "6x6 slice windows"),
    ("osmap", "osmap", {}, "method osmap (the slice optimisation alone)"),
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=64, help="exemplar side and volume side")
    ap.add_argument("--only", default="", help="comma-separated variant names")
    ap.add_argument("--sheet", type=Path, default=None, help="write the contact sheet here")
    args = ap.parse_args(argv)
    chosen = [v for v in VARIANTS if not args.only or v[0] in args.only.split(",")]
    lines = [SUMMARY_HEADER.replace("| method |", "| variant |", 1)]
    sheets = []
    for name, method, changes, label in chosen:
        sheet = None
        if args.sheet is not None:
            sheet = args.sheet.with_name(f"{args.sheet.stem}_{name}{args.sheet.suffix}")
            sheets.append(sheet)
        rows = run(NAMES, (args.side,), (method,), sheet, changes=changes,
                   log=lambda line: print(line, file=sys.stderr, flush=True))
        for r in rows:
            r["method"] = name
        lines.append(summary(rows, name).replace(f"| {name} |", f"| {name}: {label} |", 1))
        print(lines[-1], file=sys.stderr, flush=True)
    print(f"{args.side} px -> {args.side}^3, seed 1, over {', '.join(NAMES)}\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())

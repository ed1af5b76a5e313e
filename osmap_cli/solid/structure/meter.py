"""The profile meter: the particle phases' 2D profile statistics (area fraction, size
distribution, shape) on a volume's slices and diagonal cuts, read with the exemplar's own
segmentation (its Reader), against the exemplar's.

>>> report = profile_meter(exemplar, volume)
>>> report["worst"]          # the largest relative error over the figures
"""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.structure.analysis import analyse
from osmap_cli.solid.structure.particles import pooled
from osmap_cli.solid.structure.profiles import relative_errors
from osmap_cli.solid.structure.slices import DIAGONALS, axis_slices, oblique_slice

SLICES = 6  # per family
OFFSETS = (-0.12, 0.0, 0.12)  # diagonal planes through the centre and shifted (x the side)


def profile_meter(exemplar: np.ndarray, volume: np.ndarray, wrap: bool = False) -> dict | None:
    """{"exemplar": figures, "axes": figures, "diagonal": figures, "errors": {...},
    "worst": float} or None when the exemplar shows no particles."""
    found = analyse(exemplar, wrap)
    if found.kind != "particles":
        return None
    reader = found.reader
    want = reader.profiles(exemplar, wrap)
    axes = pooled([reader.profiles(np.ascontiguousarray(s), False)
                   for _, _, s in axis_slices(volume, SLICES)])
    diagonal = pooled([reader.profiles(oblique_slice(volume, n, wrap=wrap, nearest=True,
                                                     offset=off), False)
                       for n in DIAGONALS for off in OFFSETS])
    errors = {"axes": relative_errors(axes, want), "diagonal": relative_errors(diagonal, want)}
    worst = max(v for e in errors.values() for v in e.values())
    return {"exemplar": want.figures(), "axes": axes.figures(), "diagonal": diagonal.figures(),
            "errors": errors, "worst": worst}

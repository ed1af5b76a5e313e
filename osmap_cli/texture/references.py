"""Similar positions: for every exemplar pixel, the k positions of a strided reference grid
whose appearance features are nearest (the k-coherence candidates of the search)."""

from __future__ import annotations

import math

import numpy as np

from osmap_kernels.coherence import KnnParams, knn_table

# positions within this many pixels of the pixel itself are not "similar positions"
EXCLUDE = 2

# The reference grid's size (`max_references`), one per use:
# - synth (osmap_cli.synth.refine): 2048 scores as 4096 on the development exemplars
#   (geometric-mean coh_mean 1.383 against 1.381) in 2/3 of the time;
# - solid (every method's level core, osmap_cli.solid.core): 4096, the grid the solid figures
#   (docs/solid.md, BENCHMARKS.md) are measured with; 2048 is not measured there.
SYNTH_REFERENCES = 2048
SOLID_REFERENCES = 4096


def similar_positions(feat: np.ndarray, lo, hi, k: int, max_references: int) -> np.ndarray:
    """int32 (h, w, max(k, 1), 2): for each pixel of feat (h, w, F), the k positions that look
    most alike among a grid of about `max_references` positions inside the valid box [lo, hi]
    (the grid's stride grows with the box's area)."""
    area = (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1)
    stride = max(1, math.ceil(math.sqrt(area / max_references)))
    return knn_table(feat, KnnParams((int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1])),
                                     max(k, 1), stride, EXCLUDE))

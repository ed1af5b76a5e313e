"""Render: output colours from the position field (bilinear; exact copies at integer positions)."""

import numpy as np

from osmap_kernels.coherence import sample_image


def render(exemplar: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """float32 (H, W, C): exemplar (h, w, C) sampled at every position of pos (H, W, 2)."""
    return sample_image(np.ascontiguousarray(exemplar, np.float32),
                        np.ascontiguousarray(pos, np.float32))

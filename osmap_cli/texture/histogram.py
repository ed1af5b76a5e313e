"""Histogram matching by quantiles: values moved towards a reference distribution, one channel at
a time, keeping their order."""

from __future__ import annotations

import numpy as np


def match_quantiles(values: np.ndarray, reference: np.ndarray, strength: float = 1.0):
    """values (..., C) float32 with each channel moved `strength` of the way to the value of the
    same rank in reference (M, C) (quantile mapping; ties ranked by position). strength 0:
    `values` itself."""
    if strength == 0.0:
        return values
    flat = values.reshape(-1, values.shape[-1])
    out = np.empty_like(flat)
    q = (np.arange(len(flat)) + 0.5) / len(flat)
    for d in range(flat.shape[1]):
        order = np.argsort(flat[:, d], kind="stable")
        target = np.quantile(reference[:, d], q).astype(np.float32)
        out[order, d] = flat[order, d] + strength * (target - flat[order, d])
    return np.ascontiguousarray(out.reshape(values.shape))

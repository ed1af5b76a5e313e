"""align_regions' screen (kernels/regions.py) only drops a shift that cannot win: its float32
terms stay within _SCREEN_SLACK of the exact float64 sums the choice is made on, for features
of any scale, also tiny differences beside large values."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels import regions


@pytest.mark.parametrize("offset, spread", [(0.0, 1.0), (40.0, 1e-3), (0.0, 1e-20), (3.0, 2.0)])
def test_screen_terms_are_within_the_slack_of_the_exact_sums(offset, spread):
    rng = np.random.default_rng(3)
    feat = (offset + spread * rng.standard_normal((9, 11, 16))).astype(np.float32)
    fixed = (offset + spread * rng.standard_normal((40, 16))).astype(np.float32)
    at = np.stack([rng.integers(0, 9, 8), rng.integers(0, 11, 8)], axis=1).astype(np.int64)
    screened = np.zeros((8, 2))
    exact = np.zeros(8)
    for n in range(len(fixed)):
        regions._screen_terms(fixed, n, feat, at, 8, screened)
        for k, (y, x) in enumerate(at):
            for f in range(16):  # as the kernel sums them: float64, term by term, in order
                diff = np.float64(fixed[n, f]) - np.float64(feat[y, x, f])
                exact[k] += diff * diff
    slack = regions._SCREEN_SLACK * exact + regions._UNDERFLOW
    assert np.all(np.abs(screened[:, 1] - exact) <= slack)

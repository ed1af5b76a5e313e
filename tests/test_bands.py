"""Row bands (osmap_kernels.bands): the same bytes for any thread count."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels import bands


def test_bands_cover_every_row_once():
    for rows in (1, 5, 64, 257):
        for threads in (1, 2, 3, 8):
            ranges = bands.band_ranges(rows, threads)
            covered = [y for a, b in ranges for y in range(a, b)]
            assert covered == list(range(rows))


@pytest.mark.parametrize("threads", [1, 3, 8])
def test_synthesis_is_identical_for_any_band_thread_count(monkeypatch, threads):
    from osmap_cli.synth import SynthOptions, synthesize

    exemplar = np.random.default_rng(3).random((40, 40, 3), dtype=np.float32)
    options = SynthOptions(width=48, height=40, seed=2, sweeps=2, coarse_sweeps=2)
    monkeypatch.setattr(bands, "thread_count", lambda: 1)
    reference = synthesize(exemplar, options)
    monkeypatch.setattr(bands, "thread_count", lambda: threads)
    result = synthesize(exemplar, options)
    assert np.array_equal(result.positions, reference.positions)
    assert result.pixels.tobytes() == reference.pixels.tobytes()

"""Texture quality of the default pipeline on shipped samples, measured against the exemplar.

Thresholds sit between what the pipeline achieves and what a broken pipeline gives: a random
position field (shuffled pixels), a verbatim tiling, or a zoomed copy all fail them.
"""

import numpy as np
import pytest
import texture_stats as ts

from osmap_cli.imageio import read_image
from osmap_cli.synth import SynthOptions, synthesize
from osmap_cli.synth.render import render
from osmap_kernels.regions import copy_region_areas

SIZE = 192


@pytest.fixture(scope="module")
def results(samples):
    out = {}
    for name in ("cells", "brick", "weave"):
        exemplar = read_image(samples / f"{name}.png").pixels
        result = synthesize(exemplar, SynthOptions(width=SIZE, height=SIZE, seed=1))
        out[name] = (exemplar, result)
    return out


def shuffled(output, seed=0):
    flat = output.reshape(-1, output.shape[2]).copy()
    np.random.default_rng(seed).shuffle(flat)
    return flat.reshape(output.shape)


@pytest.mark.parametrize("name", ["cells", "brick", "weave"])
def test_output_is_coherent_and_complete(results, name):
    exemplar, result = results[name]
    out = result.pixels
    assert out.shape == (SIZE, SIZE, exemplar.shape[2])
    coh = ts.coherence(exemplar, out)
    coh_random = ts.coherence(exemplar, shuffled(out))
    assert coh < 0.2 * coh_random, (coh, coh_random)  # OS-Map alone, no refinement: 0.25
    compl = ts.completeness(exemplar, out)
    compl_random = ts.completeness(exemplar, shuffled(out))
    assert compl < 0.5 * compl_random, (compl, compl_random)
    assert ts.histogram_distance(exemplar, out) < 0.04


# Measured with the defaults (seam 1, max_copy 56, align 4, blend 2, 6 sweeps): cells 0.0152 /
# 0.0311, weave 0.0068 / 0.0141 (coherence / completeness). Without the whole-copy shifts (align
# 0): cells 0.0206 / 0.0229, weave 0.0102 / 0.0092; before the seam penalty and blending cells
# 0.0299 / 0.0295, weave 0.0174 / 0.0110. The coherence guards sit between, so either regression
# fails them; the shifts trade some completeness on these small samples (not on the development
# exemplars: median compl 0.99 -> 1.18 against the best peer's 1.68), so that guard only catches
# a collapse to a few copies.
QUALITY_GUARD = {"cells": (0.018, 0.036), "weave": (0.0085, 0.017)}


@pytest.mark.parametrize("name", sorted(QUALITY_GUARD))
def test_quality_guard_on_shipped_samples(results, name):
    exemplar, result = results[name]
    coh_max, compl_max = QUALITY_GUARD[name]
    assert ts.coherence(exemplar, result.pixels) < coh_max
    assert ts.completeness(exemplar, result.pixels) < compl_max


@pytest.mark.parametrize("name", ["cells", "brick", "weave"])
def test_feature_scale_and_spectrum_match_the_exemplar(results, name):
    exemplar, result = results[name]
    assert abs(np.log2(ts.feature_scale(exemplar, result.pixels))) < 0.25
    # a blurred or noisy output scores 0.6 to 1.3 here; even a tiling of the exemplar ~0.24
    spec = ts.spectrum_distance(exemplar, result.pixels)
    assert spec < 0.4 and spec < 0.5 * ts.spectrum_distance(exemplar, shuffled(result.pixels))


@pytest.mark.parametrize("name", ["cells", "brick", "weave"])
def test_no_verbatim_tiling(results, name):
    """Copied regions (coherent runs of the position field) stay well below the exemplar."""
    exemplar, result = results[name]
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), (SIZE, SIZE, 2, 2)).copy()
    areas = copy_region_areas(result.positions, jac, False)
    weighted_side = float((np.sqrt(areas) * areas).sum() / areas.sum())
    assert weighted_side < 0.75 * min(exemplar.shape[:2]), weighted_side
    # ...and the output is not one region: many distinct copies
    assert areas.max() < 0.5 * SIZE * SIZE


def test_align_moves_copies_into_register(results, samples):
    """Whole-copy shifts (--align) make the borders between copies match: without them the
    weave's courses step at every border. (With its lattice kept, the copies are in register
    already: the shifts are measured here without it.)"""
    exemplar, kept = results["weave"]
    options = SynthOptions(width=SIZE, height=SIZE, seed=1, lattice="off")
    aligned = synthesize(exemplar, options)
    unaligned = synthesize(exemplar, options.replace(align=0))
    assert ts.coherence(exemplar, aligned.pixels) < 0.8 * ts.coherence(exemplar, unaligned.pixels)
    assert ts.coherence(exemplar, kept.pixels) < ts.coherence(exemplar, aligned.pixels)


def test_the_weave_keeps_its_lattice(results):
    """A regular sample keeps its lattice over the whole output (tests/texture_stats.regularity:
    the output's autocorrelation at the exemplar's period vectors and their multiples, over the
    exemplar's own peak). Measured at 192x192, seed 1: 0.97 / 0.97; with --lattice off (copies
    placed freely) 0.93 / 0.85: the weave drifts by a strand between copies."""
    exemplar, result = results["weave"]
    assert result.lattice is not None and len(result.lattice.vectors) == 2
    short, long_ = ts.regularity(exemplar, result.pixels)
    assert short > 0.95 and long_ > 0.95, (short, long_)


def _copy_side(positions):
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), (*positions.shape[:2], 2, 2)).copy()
    areas = copy_region_areas(positions, jac, False)
    return float((np.sqrt(areas) * areas).sum() / areas.sum())


def test_max_copy_bounds_the_copies(samples):
    exemplar = read_image(samples / "cells.png").pixels
    options = SynthOptions(width=128, height=128, seed=3)
    free = _copy_side(synthesize(exemplar, options.replace(max_copy=0.0)).positions)
    capped = _copy_side(synthesize(exemplar, options.replace(max_copy=20.0)).positions)
    assert capped < 0.8 * free and capped < 28, (capped, free)


def test_positions_render_the_output(results):
    exemplar, result = results["cells"]
    pos = result.positions
    assert np.array_equal(pos, np.rint(pos))  # identity Jacobian: integral positions
    rows, cols = pos[..., 0].astype(int), pos[..., 1].astype(int)
    copied = exemplar[rows, cols]
    # seam blending changes only pixels within `blend` of a seam; inside a copy they are exact
    r = SynthOptions().blend
    inside = np.ones(pos.shape[:2], bool)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            shifted = np.roll(pos, (-dy, -dx), axis=(0, 1)) - pos
            inside &= (shifted[..., 0] == dy) & (shifted[..., 1] == dx)
    inside[:r], inside[-r:], inside[:, :r], inside[:, -r:] = False, False, False, False
    assert inside.mean() > 0.3, inside.mean()
    assert np.array_equal(result.pixels[inside], copied[inside])
    assert not np.array_equal(result.pixels, copied)  # the seams are blended
    assert np.array_equal(render(exemplar, pos), copied)  # blend 0: hard copies


def test_seed_determines_the_output(samples):
    exemplar = read_image(samples / "cells.png").pixels
    runs = [synthesize(exemplar, SynthOptions(width=64, height=64, seed=s)).pixels
            for s in (5, 5, 6)]
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_tileable_output_has_no_wrap_seam(samples):
    exemplar = read_image(samples / "cells.png").pixels
    out = synthesize(exemplar, SynthOptions(width=128, height=128, seed=2, tileable=True)).pixels
    plain = synthesize(exemplar, SynthOptions(width=128, height=128, seed=2)).pixels

    def seam_ratio(img):
        interior = np.abs(np.diff(img, axis=1)).mean()
        wrap = np.abs(img[:, 0] - img[:, -1]).mean()
        return wrap / interior

    assert seam_ratio(out) < 1.3
    assert seam_ratio(plain) > seam_ratio(out)  # the plain output's edges do not match
    tiled = np.tile(out, (2, 2, 1))
    assert ts.coherence(exemplar, tiled) < 1.25 * ts.coherence(exemplar, out)


def test_scale_option_enlarges_features(samples):
    exemplar = read_image(samples / "cells.png").pixels
    out = synthesize(exemplar, SynthOptions(width=160, height=160, seed=1, scale=2.0)).pixels
    assert 1.5 < ts.feature_scale(exemplar, out) < 2.7


def test_orientation_option_rotates_the_structure(samples):
    exemplar = read_image(samples / "weave.png").pixels
    base = synthesize(exemplar, SynthOptions(width=128, height=128, seed=1)).pixels
    turned = synthesize(exemplar, SynthOptions(width=128, height=128, seed=1,
                                               orientation=90.0)).pixels
    delta = (ts.dominant_orientation(turned) - ts.dominant_orientation(base)) % 180.0
    assert abs(delta - 90.0) < 20.0, delta


def test_paper_method_is_the_plain_os_map(samples):
    """The published algorithm: one node per output pixel, a continuous position field."""
    exemplar = read_image(samples / "cells.png").pixels
    result = synthesize(exemplar, SynthOptions(width=48, height=48, seed=1, method="paper"))
    pos = result.positions
    assert pos.shape == (48, 48, 2)
    assert pos.min() >= 0 and pos[..., 0].max() <= exemplar.shape[0] - 1
    assert not np.array_equal(pos, np.rint(pos))  # SOM averaging: non-integral positions
    # the SOM keeps the field continuous: neighbouring positions stay close
    assert np.median(np.abs(np.diff(pos[..., 1], axis=1))) < 4.0

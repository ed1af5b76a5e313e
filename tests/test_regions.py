"""Copy regions: labelling and whole-region shifts (kernels/regions.py)."""

import numpy as np

from osmap_kernels.regions import (
    AlignParams,
    align_regions,
    copy_region_areas,
    copy_region_labels,
)

H = W = 32


def stripes(period=8, size=64):
    """Exemplar features: horizontal stripes (2 channels, a sine and a cosine of the row)."""
    rows = 2 * np.pi * np.arange(size) / period
    feat = np.stack([np.sin(rows), np.cos(rows)], axis=1)[:, None, :]
    return np.repeat(feat, size, axis=1).astype(np.float32)


def two_copies(step):
    """Left half copies the exemplar from (20, 20), the right half from (20 + step, 30)."""
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    pos = np.stack([ys + 20, xs + 20], axis=2)
    pos[:, W // 2:, 0] += step
    pos[:, W // 2:, 1] += 10
    return pos


def params(**overrides):
    base = dict(radius=2, wrap=False, lo=np.array([2.0, 2.0]), hi=np.array([61.0, 61.0]),
                seam=1.0, max_area=np.inf, reach=4)
    base.update(overrides)
    return AlignParams(**base)


def identity(shape=(H, W)):
    return np.broadcast_to(np.eye(2, dtype=np.float32), (*shape, 2, 2)).copy()


def stripe_step(pos):
    """Mismatch of the stripes' phase across the middle column (0: continuous)."""
    left, right = pos[:, W // 2 - 1, 0], pos[:, W // 2, 0]
    return np.abs(((right - left) + 4) % 8 - 4).max()


def test_labels_and_areas_of_two_copies():
    pos = two_copies(3)
    labels = copy_region_labels(pos, identity(), False)
    assert len(np.unique(labels)) == 2
    assert labels[0, 0] == 0 and labels[0, W - 1] == W // 2  # first pixel's scan index
    assert np.all(copy_region_areas(pos, identity(), False) == H * W // 2)


def test_shift_aligns_a_stepped_border():
    pos = two_copies(3)
    assert stripe_step(pos) == 3
    aligned = align_regions(pos, stripes(), identity(), params())
    assert stripe_step(aligned) == 0
    # a whole copy moved: each half is still one copy, and only rows moved
    assert len(np.unique(copy_region_labels(aligned, identity(), False))) <= 2
    assert np.array_equal(aligned[..., 1], pos[..., 1])
    assert np.array_equal(align_regions(pos, stripes(), identity(), params()), aligned)


def test_no_shift_without_gain_or_beyond_reach():
    aligned_already = two_copies(8)  # one stripe period: the border already matches
    out = align_regions(aligned_already, stripes(), identity(), params())
    assert np.array_equal(out, aligned_already)
    out = align_regions(two_copies(3), stripes(), identity(), params(reach=1))
    assert np.abs(out - two_copies(3)).max() == 1  # each copy moves one pixel at most
    assert stripe_step(out) == 1


def test_shift_never_leaves_the_valid_box():
    pos = two_copies(5)  # rows 20..51 and 25..56; aligning needs left -3 or right +3
    free = align_regions(pos, stripes(), identity(), params())
    assert stripe_step(free) == 0 and free[..., 0].min() < 20.0
    box = dict(lo=np.array([20.0, 2.0]), hi=np.array([56.0, 61.0]))
    out = align_regions(pos, stripes(), identity(), params(**box))
    assert out[..., 0].min() >= 20.0 and out[..., 0].max() <= 56.0
    assert stripe_step(out) < stripe_step(pos)


def test_merges_respect_max_area():
    # left half copies (20, 20), right half (21, 20): shifting one by a row merges them
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    pos = np.stack([ys + 20, xs + 20], axis=2)
    pos[:, W // 2:, 0] += 1
    merged = align_regions(pos, stripes(), identity(), params())
    assert len(np.unique(copy_region_labels(merged, identity(), False))) == 1
    kept = align_regions(pos, stripes(), identity(), params(max_area=H * W * 0.75))
    assert len(np.unique(copy_region_labels(kept, identity(), False))) == 2


def test_merges_in_one_pass_add_up():
    # three copies side by side, each one row further down the exemplar: every pair of
    # neighbours merges by a one-row shift, but all three together exceed max_area
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    pos = np.stack([ys + 20, xs + 20], axis=2)
    pos[:, 11:, 0] += 1
    pos[:, 22:, 0] += 1
    merged = align_regions(pos, stripes(), identity(), params())
    assert len(np.unique(copy_region_labels(merged, identity(), False))) == 1
    capped = align_regions(pos, stripes(), identity(), params(max_area=H * W * 0.7))
    areas = copy_region_areas(capped, identity(), False)
    assert areas.max() <= H * W * 0.7 and len(np.unique(copy_region_labels(
        capped, identity(), False))) == 2

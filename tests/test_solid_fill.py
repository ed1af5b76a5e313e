"""The structure fill's colour steps for particles: a particle's colour must not follow how
crowded its surroundings are more than the exemplar's does (decorrelate_particles)."""

import numpy as np

from osmap_cli.solid.structure.crowding import decorrelate_particles, plane_blur
from osmap_cli.solid.structure.fill import PLANE_AXES


def _exemplar(rng, side=64):
    """Grey stones (0.6 with noise independent of where they lie) on a dark matrix (0.2),
    evenly crowded: labels 1 for stone, 0 for matrix."""
    labels = np.ones((side, side), np.int64)
    labels[::14, :] = 0
    labels[:, ::14] = 0
    image = np.where(labels[..., None] == 1, 0.6 + 0.05 * rng.standard_normal((side, side, 1)),
                     0.2)
    return np.repeat(image, 3, 2).astype(np.float32), labels


def _volume(rng, side=32):
    """Stones crowded on one side (thin gaps), sparse on the other (wide matrix), their colour
    darker where the matrix pools, as the fill makes it."""
    z, y, x = np.mgrid[0:side, 0:side, 0:side]
    gap = np.where(x < side // 2, 1, 4)
    period = 6 + gap
    labels = (((z % period) >= gap) & ((y % period) >= gap)).astype(np.int64)
    share = plane_blur(labels.astype(np.float64), 5.0, (1, 2), False)
    grey = np.where(labels == 1, 0.3 + 0.4 * share + 0.05 * rng.standard_normal(labels.shape),
                    0.2)
    return np.repeat(grey[..., None], 3, 3).astype(np.float32), labels


def _slope(voxels, labels, sigma=5.0):
    """The stones' local mean grey against their local share, over the three slice families."""
    inside = labels == 1
    out = []
    for axes in PLANE_AXES:
        share = plane_blur(inside.astype(np.float64), sigma, axes, False)[inside]
        local = (plane_blur(voxels[..., 0] * inside, sigma, axes, False)[inside]
                 / np.maximum(share, 1e-3))
        x = share - share.mean()
        out.append(float((x * (local - local.mean())).sum() / (x * x).sum()))
    return float(np.mean(out))


def test_stone_colour_stops_following_the_crowding():
    rng = np.random.default_rng(3)
    image, ex_labels = _exemplar(rng)
    voxels, labels = _volume(rng)
    before = _slope(voxels, labels)
    after_voxels = decorrelate_particles(voxels, labels, [image], np.zeros(3, np.int64),
                                         [ex_labels])
    after = _slope(after_voxels, labels)
    assert before > 0.2
    assert abs(after) < 0.25 * before
    stones = labels == 1
    # the stones' mean colour and the matrix stay where they were
    assert abs(float(after_voxels[stones].mean() - voxels[stones].mean())) < 0.01
    assert np.allclose(after_voxels[~stones], voxels[~stones], atol=1e-6)


def test_colours_independent_of_the_crowding_stay():
    rng = np.random.default_rng(4)
    image, ex_labels = _exemplar(rng)
    voxels, labels = _volume(rng)
    flat = np.where(labels[..., None] == 1, 0.6, voxels).astype(np.float32)
    out = decorrelate_particles(flat, labels, [image], np.zeros(3, np.int64), [ex_labels])
    assert np.abs(out - flat).max() < 0.02


def test_sparse_particles_keep_their_colours():
    rng = np.random.default_rng(5)
    image, ex_labels = _exemplar(rng)
    sparse = np.zeros_like(ex_labels)
    sparse[2::8, 2::8] = 1  # chips apart in a continuous matrix
    sparse = sparse | np.roll(sparse, 1, 0) | np.roll(sparse, 1, 1)
    voxels, labels = _volume(rng)
    out = decorrelate_particles(voxels, labels, [image], np.zeros(3, np.int64), [sparse])
    assert np.array_equal(out, voxels)

"""Packed cells (osmap_cli.solid.structure.cells): samples/cells reads as cells, not as packed
stones; its volume is a tessellation whose walls have the exemplar's width (no pockets of wall
colour between the cells), whose cuts show the exemplar's profile sizes on axis slices and on
diagonal planes, and whose cells take each source profile's colour by its share of the
exemplar. Small volumes: a few seconds each."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_cli.imageio import read_image
from osmap_cli.solid.structure import cells as cl
from osmap_cli.solid.structure import particles as pt
from osmap_cli.solid.structure.analysis import analyse, reads_as_cells
from osmap_cli.solid.structure.measures import squared_distance
from osmap_cli.solid.structure.meter import diagonal_cuts
from osmap_cli.solid.structure.method import build_structure, plan
from osmap_cli.solid.structure.profiles import relative_errors
from osmap_cli.solid.structure.slices import axis_slices


@pytest.fixture(scope="module")
def cells64(samples):
    """samples/cells.png at 64 px: Voronoi cells with thin dark walls."""
    return read_image(samples / "cells.png").pixels[::2, ::2].copy()


@pytest.fixture(scope="module")
def cells_plan(cells64):
    return plan([cells64], np.zeros(3, np.int64), seed=1, probe_cap=48)


@pytest.mark.parametrize("chunk", [cl.CHUNK, 31])  # 31: one block's distances at a time
def test_the_power_diagram_is_exact_and_wraps(chunk, monkeypatch):
    monkeypatch.setattr(cl, "CHUNK", chunk)
    rng = np.random.default_rng(0)
    shape = (20, 24, 28)
    for wrap in (True, False):
        centres = rng.random((30, 3)) * np.array(shape)
        weights = rng.random(30) * 6.0
        owner, wall = cl.laguerre(shape, centres, weights, wrap)
        pts = np.stack(np.meshgrid(*[np.arange(s) + 0.5 for s in shape], indexing="ij"),
                       -1).reshape(-1, 3)
        d = pts[:, None] - centres[None]
        if wrap:
            d -= np.array(shape) * np.round(d / np.array(shape))
        power = (d * d).sum(-1) - weights
        assert (power.argmin(1) == owner.ravel()).all()
        first, second = np.argsort(power, 1, kind="stable")[:, :2].T
        sep = centres[second] - centres[first]
        if wrap:
            sep -= np.array(shape) * np.round(sep / np.array(shape))
        rows = np.arange(len(pts))
        want = (power[rows, second] - power[rows, first]) / (2 * np.linalg.norm(sep, axis=1))
        assert np.allclose(wall.ravel(), want, atol=1e-4)


def test_cells_are_read_as_cells_and_other_particles_are_not(cells64):
    found = analyse(cells64)
    assert found.kind == "particles" and reads_as_cells(found)
    assert "packed cells" in found.report()[0] and found.summary()["particles"]["packed_cells"]
    # irregular packed stones: round blobs of three sizes on dark gaps (solidity, spread)
    rng = np.random.default_rng(1)
    image = np.full((128, 128, 3), 0.15, np.float32)
    yy, xx = np.mgrid[0:128, 0:128]
    for _ in range(70):
        y, x = rng.uniform(0, 128, 2)
        r = rng.choice([3.0, 6.0, 10.0])
        blob = (yy - y) ** 2 + ((xx - x) * rng.uniform(0.5, 1.0)) ** 2 < r * r
        image[blob] = rng.uniform(0.5, 0.9, 3)
    other = analyse(image)
    assert not reads_as_cells(other), (other.kind, other.profiles and other.profiles.figures())


def test_cells_fill_space_with_thin_walls_and_no_pockets(cells_plan):
    assert isinstance(cells_plan.model[1], cl.CellParams)
    built = build_structure(cells_plan, (40, 40, 40), seed=1, wrap=True)
    walls = built.regions < 0
    # every wall voxel lies beside a cell: packed ellipsoids left pockets of matrix 2-4
    # voxels across (the fill painted them with the walls' speckle)
    far = np.sqrt(squared_distance(~walls, True))[walls]
    assert far.max() <= 1.5, far.max()
    # the wall fraction is the exemplar's (measured 0.25 against 0.26)
    want = 1.0 - cells_plan.analyses[0].profiles.fraction
    assert abs(walls.mean() - want) < 0.05, walls.mean()


def test_cuts_show_the_exemplars_profile_sizes_on_slices_and_diagonals(cells_plan, cells64):
    # the built structure in flat colours (each cell its source's mean, the walls the
    # matrix's), read as the profile meter reads a volume
    built = build_structure(cells_plan, (64, 64, 64), seed=2, wrap=False)
    volume = built.identity
    reader = cells_plan.analyses[0].reader
    want = reader.profiles(cells64)
    slices = pt.pooled([reader.profiles(np.ascontiguousarray(s)) for _, _, s in
                        axis_slices(volume, 4)])
    diagonal = pt.pooled([reader.profiles(c) for c in diagonal_cuts(volume)[::3]])
    for got in (slices, diagonal):
        errors = relative_errors(got, want)
        # measured 0.01-0.07; packed ellipsoids' cuts read the median 0.83-0.92 of it
        assert max(errors[k] for k in ("fraction", "d50", "d90")) < 0.1, errors


def test_each_source_takes_its_share_of_the_cells():
    rng = np.random.default_rng(0)
    d = np.array([10.0, 10.0, 20.0, 5.0])
    sources = pt.ParticleSources(d, rng.random((4, 3)), None, 1.0)
    pick = cl.source_draw(sources, 100, np.random.default_rng(3))
    expected = d ** 2 / (d ** 2).sum() * 100
    assert len(pick) == 100
    assert (np.abs(np.bincount(pick, minlength=4) - expected) < 1).all()
    again = cl.source_draw(sources, 100, np.random.default_rng(3))
    assert (pick == again).all()


def test_tileable_cells_wrap(cells_plan):
    built = build_structure(cells_plan, (32, 32, 32), seed=3, wrap=True)
    r = built.regions
    # a cell that touches one face continues on the opposite face
    across = (r[0] >= 0) & (r[-1] >= 0)
    assert (r[0][across] == r[-1][across]).mean() > 0.8


def _axis_share(image: np.ndarray) -> float:
    """The share of an image's squared gradient (central differences) within 7.5 degrees of
    the axes (solidlook's axis-energy before its division by the exemplar's)."""
    gy = (image[2:, 1:-1] - image[:-2, 1:-1]) / 2
    gx = (image[1:-1, 2:] - image[1:-1, :-2]) / 2
    angle = np.degrees(np.arctan2(np.abs(gy), np.abs(gx)))
    near = (angle < 7.5) | (angle > 82.5)
    energy = gy * gy + gx * gx
    return float(energy[near].sum() / energy.sum())


@pytest.mark.parametrize("gap", [1.0, 1.5])
def test_a_wall_at_an_angle_is_antialiased_without_steps(gap):
    # two cells whose wall's normal lies 30 degrees off the y axis, painted as the fill paints
    # them: wall voxels dark, cell voxels light
    turn = np.radians(30.0)
    normal = np.array([0.0, np.cos(turn), np.sin(turn)])
    middle = np.array([2.0, 24.0, 24.3])
    cell, wall = cl.laguerre((4, 48, 48), np.stack([middle - 8 * normal, middle + 8 * normal]),
                             np.zeros(2), False)
    sdf = (wall - 0.5 * gap).astype(np.float32)
    painted = np.repeat(np.where(sdf > 0, 0.8, 0.2).astype(np.float32)[..., None], 3, 3)
    soft = cl.antialiased(painted, cell, sdf, gap, False)
    before, after = painted[2, ..., 0], soft[2, ..., 0]
    # the voxel steps put the edges' gradients on the axes (measured 0.37 and 0.20); the
    # antialiased wall's gradients lie across it (0.03, 0.02)
    assert _axis_share(before) > 0.15
    assert _axis_share(after) < 0.05, _axis_share(after)
    # every column crosses about the wall's width over the cosine of the angle (measured
    # within 0.11-0.13 of it; painted, one or two whole voxels: 0.73-0.85 off)
    for image, most in ((before, 0.3), (after, 0.15)):
        ink = (0.8 - image)[8:40, 8:40].sum(0) / 0.6
        assert (np.abs(ink - gap / np.cos(turn)).max() < most) == (image is after), ink
    # the cells' colours are untouched away from the wall
    assert np.allclose(after[sdf[2] > 1.0], 0.8)

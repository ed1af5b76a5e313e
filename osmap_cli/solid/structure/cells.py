"""Packed cells in 3D (cell mosaics, cracked mud, foam, packed polygonal stones): a Laguerre
(power) tessellation that fills space, with walls of the exemplar's width between the cells.

Where packed particles (particles.py) stop short of their cells' walls and leave pockets of
matrix wider than the walls, a tessellation's cells meet along planes: every voxel belongs to
the cell of least power distance |x - c_i|^2 - w_i, and lies in the wall when its distance to
the plane it shares with the runner-up cell is under half the wall width. The seeds are as
regular as the exemplar's cells: a hard-core process (random sequential addition of equal
spheres) relaxed by Lloyd steps (each seed moved to its cell's centroid), which narrows the
cells' sizes. A few rounds of build, cut and measure (as particles.fit) fit the number of cells
to the exemplar's profile sizes and the wall width to its area fraction.

The result is a particles.Particles record (owner, signed distance to the wall, source profile
per cell, and the tessellation's Walls), so the fill and the colour matching treat cells as they
treat particles. The fill paints every voxel wall or cell; soften_walls then gives each voxel
the wall's exact share of it (the walls are planes), so walls at an angle to the axes do not
step along them.

>>> params, _ = fit(sources, seed=1, factor=2)
>>> built = build((64, 64, 64), params, sources, seed=1, wrap=False, factor=2)
>>> voxels = soften_walls(filled_voxels, built.walls, wrap=False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from osmap_cli.solid.structure import particles as pt
from osmap_cli.solid.structure.analysis import PACKED_CELLS
from osmap_cli.solid.structure.segment import smooth_volume
from osmap_kernels.cells import power_cells
from osmap_kernels.structure import place_spheres

BLOCK = 8  # voxels: the labelling works block by block, on each block's nearest seeds
CANDIDATES = 24  # seeds examined per block (the bound is checked; all are taken if needed)
CHUNK = 1 << 20  # block-seed distances computed at once (24 MiB of offsets)
HARD_CORE = 0.30  # packing fraction of the seeds' exclusion spheres (random addition jams
#                   near 0.38; the attempts below reach about this)
PLACE_ATTEMPTS = 64
FIT_ROUNDS = 6
MIN_CELL = 27.0  # voxels per cell at the least (a 3-voxel cube)
# fitted: the fraction and the median and 90th-percentile diameters; not the area-weighted
# mean, which the few profiles a 1-voxel wall fails to part on a diagonal cut of the probe
# inflate (the fit then made the cells 0.85-0.9 of the exemplar's size)
FITTED = ("fraction", "d50", "d90")
FOOTPRINT = 0.75  # voxels: the width across a wall that a voxel's colour averages (coverage;
#                  a full voxel, 1.0, softens the walls beyond the exemplar's: samples/cells'
#                  hist 0.92 against 0.75 at 64^3 on seed 2)
WALL_SIGMA = 1.0  # voxels: the walls' local colour is their voxels' Gaussian mean this wide


@dataclass(frozen=True)
class CellParams:
    """density: cells per voxel of the analysis' pixels (as ParticleParams.density); gap:
    wall width (px of the analysis); lloyd: relaxation steps of the seeds; spread: the
    power weights' spread (0: a Voronoi tessellation)."""

    density: float
    gap: float = 1.5
    lloyd: int = 2
    spread: float = 0.0


def laguerre(shape, centres, weights, wrap: bool, step: float = 1.0):
    """(owner int32 (Z, Y, X): each voxel's cell, wall float32: the voxel centre's distance to
    the nearest wall) of the power diagram of `centres` (N, 3) (z, y, x) with `weights` (N,),
    periodic with wrap; `step`: voxel size (the grid spans shape / step voxels a side).
    Worked block by block, each block on the seeds nearest its centre: CANDIDATES of them,
    or all when one left out could be nearer to a voxel of the block than the second."""
    grid = tuple(int(round(s / step)) for s in shape)
    size = np.asarray(shape, np.float64)
    nb = [-(-g // BLOCK) for g in grid]
    corners = np.stack(np.meshgrid(*[np.arange(b) * BLOCK for b in nb], indexing="ij"),
                       -1).reshape(-1, 3)
    mids = (corners + 0.5 * BLOCK) * step
    candidates, counts = _candidates(mids, centres, weights, size, wrap,
                                     0.5 * BLOCK * step * math.sqrt(3.0))
    owner = np.empty(grid, np.int32)
    wall = np.empty(grid, np.float32)
    power_cells(corners.astype(np.int64), BLOCK, float(step), np.array(grid, np.int64),
                np.ascontiguousarray(centres, np.float64),
                np.ascontiguousarray(weights, np.float64), candidates, counts, size, wrap,
                owner, wall)
    return owner, wall


def _candidates(mids, centres, weights, size, wrap: bool, half: float):
    """(candidates int64 (B, K), counts (B,)): for every block centre `mids` (B, 3) of half
    diagonal `half`, its nearest seeds in order of distance: CANDIDATES of them, and every seed
    that could be nearer to a voxel of the block than the second nearest seed is to any of
    them (power weights widen the bound). Worked in chunks of blocks, so that the block-by-seed
    distances stay small whatever the volume's size."""
    n = len(centres)
    wmax = float(weights.max() - weights.min())
    chunk = max(1, CHUNK // max(n, 1))
    counts = np.empty(len(mids), np.int64)
    orders = []
    for start in range(0, len(mids), chunk):
        d = centres[None, :, :] - mids[start:start + chunk, None, :]
        if wrap:
            d -= size * np.round(d / size)
        dist = np.sqrt((d * d).sum(-1))
        second = np.partition(dist, min(1, n - 1), axis=1)[:, min(1, n - 1)]
        reach = np.sqrt(second ** 2 + wmax) + 2.0 * half
        part = np.maximum((dist < reach[:, None]).sum(1), min(n, CANDIDATES))
        counts[start:start + chunk] = part
        take = int(part.max())
        nearest = (np.argpartition(dist, take - 1, axis=1)[:, :take] if take < n else
                   np.broadcast_to(np.arange(n), dist.shape))
        order = np.argsort(np.take_along_axis(dist, nearest, 1), axis=1, kind="stable")
        orders.append(np.take_along_axis(nearest, order, 1))
    candidates = np.zeros((len(mids), counts.max()), np.int64)
    for start, order in zip(range(0, len(mids), chunk), orders):
        candidates[start:start + len(order), :order.shape[1]] = order
    return candidates, counts


def relax(shape, centres, weights, wrap: bool, steps: int, step: float = 2.0):
    """The seeds moved `steps` times to their cells' centroids (Lloyd), measured on a grid of
    `step` voxels."""
    size = np.asarray(shape, np.float64)
    for _ in range(steps):
        owner, _ = laguerre(shape, centres, weights, wrap, step)
        grid = owner.shape
        pts = np.stack(np.meshgrid(*[(np.arange(g) + 0.5) * step for g in grid],
                                   indexing="ij"), -1).reshape(-1, 3)
        lab = owner.ravel()
        d = pts - centres[lab]
        if wrap:
            d -= size * np.round(d / size)
        count = np.bincount(lab, minlength=len(centres)).astype(np.float64)
        shift = np.stack([np.bincount(lab, d[:, c], len(centres)) for c in range(3)], 1)
        centres = centres + shift / np.maximum(count, 1.0)[:, None]
        centres = np.mod(centres, size) if wrap else np.clip(centres, 0.0, size - 1e-6)
    return centres


def seeds(shape, count: int, params: CellParams, seed: int, wrap: bool):
    """(centres (N, 3), power weights (N,)): a hard-core set of `count` seeds relaxed by
    params.lloyd Lloyd steps."""
    volume = float(np.prod(shape))
    radius = (HARD_CORE * volume / count / (4.0 / 3.0 * math.pi)) ** (1.0 / 3.0)
    radii = np.full(count, radius)
    centres = place_spheres(np.array(shape, np.float64), radii, 1.0, PLACE_ATTEMPTS,
                            np.uint64(seed), wrap)
    rng = np.random.default_rng(seed)
    spacing = (volume / count) ** (1.0 / 3.0)
    weights = (params.spread * spacing) ** 2 * rng.random(count)
    return relax(shape, centres, weights, wrap, params.lloyd), weights


def source_draw(sources: pt.ParticleSources, count: int, rng) -> np.ndarray:
    """Each cell's source profile. The cells being of like volumes, a source's share of the
    cells is its share of the exemplar's particle area: every source appears its expected
    number of times (rounded down; the rest drawn by the remainders), in random order."""
    area = sources.diameters ** 2
    expected = area / area.sum() * count
    whole = np.floor(expected).astype(np.int64)
    rest = count - int(whole.sum())
    extra = rng.choice(len(area), rest, replace=False,
                       p=(expected - whole) / (expected - whole).sum()) if rest > 0 else []
    draws = np.concatenate([np.repeat(np.arange(len(area)), whole),
                            np.asarray(extra, np.int64)])
    return rng.permutation(draws)


@dataclass(frozen=True)
class Walls:
    """A tessellation's walls: cell int32 (Z, Y, X), every voxel's cell, walls included; sdf
    float32, the distance to the nearest wall less half its width (positive inside a cell);
    gap, the wall width in voxels."""

    cell: np.ndarray
    sdf: np.ndarray
    gap: float


def tessellation(shape, params: CellParams, seed: int, wrap: bool,
                 factor: float = 1.0) -> tuple[Walls, int]:
    """(the walls, the number of cells) of a (Z, Y, X) volume's tessellation (periodic with
    wrap)."""
    shape = tuple(int(s) for s in shape)
    volume = float(np.prod(shape))
    count = max(2, min(int(round(params.density * factor ** 3 * volume)),
                       int(volume // MIN_CELL)))
    # the seeds of a periodic set, also for a volume that does not wrap: relaxed within the
    # volume's faces, the cells along them grow (their seeds move inwards)
    centres, weights = seeds(shape, count, params, seed, True)
    cell, wall = laguerre(shape, centres, weights, wrap)
    gap = max(params.gap / factor, pt.FINAL_GAP)
    return Walls(cell, (wall - 0.5 * gap).astype(np.float32), gap), count


def build(shape, params: CellParams, sources: pt.ParticleSources, seed: int, wrap: bool,
          factor: float = 1.0) -> pt.Particles:
    """The cells of a (Z, Y, X) volume (periodic with wrap), as particles: owner (-1 in the
    walls), sdf (distance to the wall less half its width, positive inside a cell), each
    cell's source profile and the walls (for soften_walls); `factor` as for particles.build."""
    walls, count = tessellation(shape, params, seed, wrap, factor)
    owner = np.where(walls.sdf > 0, walls.cell, -1).astype(np.int32)
    pick = source_draw(sources, count, np.random.default_rng(seed + 1))
    return pt.Particles(owner, walls.sdf, pick, walls)


def wall_coverage(sdf: np.ndarray, gap: float) -> np.ndarray:
    """float32: the wall's share of every voxel, from its centre's distance to the wall's
    middle plane (sdf + gap / 2): the overlap of the wall (`gap` wide) with a window FOOTPRINT
    wide across it. At least one half exactly in the wall's voxels (sdf <= 0)."""
    d = sdf.astype(np.float64) + 0.5 * gap
    half = 0.5 * FOOTPRINT
    over = np.minimum(d + half, 0.5 * gap) - np.maximum(d - half, -0.5 * gap)
    return np.clip(over / FOOTPRINT, 0.0, 1.0).astype(np.float32)


def soften_walls(voxels: np.ndarray, walls: Walls | None, wrap: bool) -> np.ndarray:
    """voxels (a filled volume of the structure whose `walls` these are) with antialiased walls
    (antialiased); unchanged when the structure has none (it is not packed cells)."""
    if walls is None:
        return voxels
    return antialiased(voxels, walls.cell, walls.sdf, walls.gap, wrap)


def antialiased(voxels: np.ndarray, cell: np.ndarray, sdf: np.ndarray, gap: float,
                wrap: bool) -> np.ndarray:
    """voxels (Z, Y, X, C) of a tessellation (its Walls' cell, sdf and gap) whose every
    voxel the fill painted wall (sdf <= 0) or cell, with antialiased walls: painted so, a wall
    at an angle to the axes steps along them. Each voxel takes the wall's share of it
    (wall_coverage, from the power diagram's planes: exact, no staircase) of the wall colour
    and the rest of its cell's: a wall voxel moves towards its own cell's mean colour (the
    cell on its side of the wall), a cell voxel towards the walls' local colour (the Gaussian
    mean of the wall voxels near it, WALL_SIGMA). The walls' share of the volume is kept: what
    a wall voxel gives up, its neighbours across the wall take."""
    count = int(cell.max()) + 1
    cover = wall_coverage(sdf, gap)
    inwall = sdf <= 0
    lab = cell[~inwall]
    area = np.bincount(lab, minlength=count)
    has_cell = area[cell] > 0  # a cell left without a voxel of its own keeps its walls' colour
    weight = smooth_volume(inwall.astype(np.float32), WALL_SIGMA, wrap)
    near = weight > 1e-3
    out = np.empty(voxels.shape, np.float32)
    for c in range(voxels.shape[3]):  # a channel at a time: a 256^3 volume's copies stay small
        v = voxels[..., c]
        mean = (np.bincount(lab, v[~inwall], count) / np.maximum(area, 1)).astype(np.float32)
        own = np.where(has_cell, mean[cell], v)
        local = smooth_volume(np.where(inwall, v, 0.0), WALL_SIGMA, wrap)
        wall = np.where(near, local / np.maximum(weight, 1e-3), v)
        out[..., c] = np.where(inwall, cover * v + (1.0 - cover) * own,
                               (1.0 - cover) * v + cover * wall)
    return out


def initial_params(sources: pt.ParticleSources) -> CellParams:
    """Cells whose mean cut matches the profiles: a cell of volume V cut at random shows about
    0.69 V^(2/3) of area on average (Voronoi cells of regular seeds)."""
    t = sources.target
    area = float(np.mean(math.pi / 4.0 * t.diameters ** 2)) / max(t.fraction, 1e-6)
    volume = (area / 0.69) ** 1.5
    return CellParams(density=1.0 / volume,
                      gap=float(np.clip(sources.gap, pt.MIN_GAP, pt.MAX_GAP)))


def fit(sources: pt.ParticleSources, seed: int, probe: int | None = None, log=None,
        factor: float = 1.0, cap: int | None = None, growth: float = 1.0):
    """(CellParams, the best probe's cut statistics): rounds of build, cut, measure and correct
    on a periodic probe volume (as particles.fit): the number of cells sets their size, the wall
    width the area fraction; the round with the least error wins."""
    tf = sources.target.scaled(1.0 / (factor * growth)).figures()
    if probe is None:
        probe = int(np.clip(4 * max(tf["d90"], 8.0), *pt.PROBE_SIDE))
        if cap is not None:
            probe = min(probe, max(2 * int(cap), pt.MIN_PROBE))
    shape = (probe, probe, probe)
    params = initial_params(sources)
    rounds = []
    for round_ in range(FIT_ROUNDS):
        stats = pt.cut_stats(build(shape, params, sources, seed + 7919 * round_, True,
                                   factor).owner >= 0, True)
        got = stats.figures()
        if log is not None:
            log(round_, params, got)
        rounds.append((max(abs(got[k] / tf[k] - 1.0) for k in FITTED if tf[k] > 0), round_,
                       params, stats))
        params = _corrected(params, got, tf)
    _, _, params, stats = min(rounds, key=lambda r: r[:2])
    return params, stats


def _step(ratio: float, power: float) -> float:
    """A damped multiplicative correction (as the particles' fit takes)."""
    return float(np.clip(ratio ** power, 1 / pt.MAX_STEP, pt.MAX_STEP))


def _corrected(params: CellParams, got: dict, want: dict) -> CellParams:
    """The next round's parameters: more cells where the cuts read large, thinner walls where
    they read too much wall."""
    size = math.sqrt(want["d50"] * want["d90"] / max(got["d50"] * got["d90"], 1e-6))
    fraction = want["fraction"] / max(got["fraction"], 1e-6)
    return replace(params, density=params.density * _step(size, -2.4),
                   gap=float(np.clip(params.gap * _step(fraction, -1.2), pt.MIN_GAP,
                                     pt.MAX_GAP)))


def fit_packing(analyses, sources: pt.ParticleSources, seed: int, factor: float = 1.0,
                cap: int | None = None):
    """The model of a particle exemplar: cells (CellParams) when the analysis read every
    exemplar as packed cells (analysis.reads_as_cells), else particles (particles.fit);
    (params, cut statistics)."""
    if all(PACKED_CELLS in found.notes for found in analyses):
        return fit(sources, seed, factor=factor, cap=cap)
    return pt.fit(sources, seed, factor=factor, cap=cap)


def build_packing(shape, params, sources: pt.ParticleSources, seed: int, wrap: bool,
                  factor: float = 1.0) -> pt.Particles:
    """The volume's cells or particles, as `params` (fit_packing's) say."""
    maker = build if isinstance(params, CellParams) else pt.build
    return maker(shape, params, sources, seed, wrap, factor)

"""Particles in 3D: stones, chips, grains and cells as separate bodies whose cuts show the
exemplar's profiles.

Stereology by simulation (the spirit of Jagnow, Dorsey and Rushmeier 2004, without the analytic
unfolding): each 3D particle takes one exemplar profile as its source (its colour and its
relative size), the 3D number distribution weighting each profile by 1 / diameter (a plane hits
a particle with probability proportional to its size); a few rounds of build, cut (axis slices
and diagonal planes), measure with the exemplar's own profile statistics and correct (number,
size, spread of sizes, elongation, roughness) land the cuts' area fraction, size distribution
and shape on the exemplar's.

A sparse volume is then corrected on its own cuts (build): the fit's probe is a smaller draw of
the same model, and its figures vary by seed more than the profile bar allows; the source
profiles are drawn systematically (every range of sizes its expected number within one).

Shapes: an ellipsoid of random orientation cut by a few random planes (angular chips) with a
smooth bump on its radius (irregular outlines). Placement: random sequential addition of their
bounding spheres, then every voxel belongs to the particle of least power distance (a Laguerre
cell, so neighbours never merge) if inside its shape and more than half a gap from the cell's
wall: sparse particles keep their shapes, dense ones pack as cells with gaps between them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from osmap_cli.solid.structure.particle_colour import ColourSpreads, colour_spreads
from osmap_cli.solid.structure.profiles import ProfileStats, profile_stats
from osmap_cli.solid.structure.slices import DIAGONALS, axis_slices, oblique_slice
from osmap_kernels.structure import place_spheres, render_particles

PLANES = 6  # random cutting planes per particle
MIN_VOXELS = 64  # voxels per particle at the least (a 4-voxel cube)
BUMPS = 6  # random cosine bumps on the radius
PLACE_ATTEMPTS = 24
FIT_ROUNDS = 6
PROBE_SLICES = 6  # per family, plus the diagonal planes
DENSE = 0.5  # area fraction above which particles pack as cells
MIN_GAP, MAX_GAP = 1.5, 6.0  # px of the analysis: thinner walls do not separate cells on a cut
MAX_STEP = 1.3
FINAL_GAP = 1.0  # voxels: the least gap between touching particles in a volume (the fill keeps
#                  1-voxel gaps: osmap_cli.solid.structure.fill, label_constraint)
PROBE_SIDE = (32, 64)  # voxels: the fit's probe volume, four 90th-percentile diameters a side
MIN_PROBE = 32  # voxels: the least probe side when a small volume caps it
VOLUME_ROUNDS = 3  # builds of a volume corrected on its own cuts (build)
# builds of one whose exemplar is read enlarged, each a new draw and placement (build)
REDRAWN_ROUNDS = 4
VOLUME_SLICES = 16  # per axis, plus the diagonal planes: the volume's own cuts
VOLUME_TOLERANCE = 0.05  # a build whose cuts read within this of the target is kept
# how much larger the fill and the colour matching read particles than built, by the factor the
# exemplar is read enlarged (analysis.Reader.factor): 64 px exemplars (read 2x) grow 1.1
# (granules.py and texmetrics' scale on gravel and terrazzo at 64^3); 128 px ones (read 1x)
# do not (gravel at 128^3 fitted 1.1 smaller read 0.90 of the exemplar's diameters finished)
FILL_GROWTH = {1: 1.0, 2: 1.1}
# sparse particles built to the fitted sizes on the volume itself (build) are not read larger
# filled: terrazzo at 64^3 fitted 1.1 small read its finished cuts' area-weighted diameter
# 0.86-0.91 of the exemplar's over three seeds, fitted at its size 0.91-0.96
SPARSE_GROWTH = 1.0
# how much larger the fill reads sparse particles' median cut than built (it loses small chips),
# by the factor the exemplar is read enlarged: terrazzo at 128^3, the axis slices' median
# diameter 1.04-1.06 times the built structure's over three seeds; a volume corrected on its own
# cuts aims its median that much small (build)
MEDIAN_LOSS = {1: 1.06, 2: 1.0}
SOURCE_MIN_AREA = 1  # px: specks too are particles (the fill alone does not make them)
# the sizes fitted are the area-weighted mean and the 90th percentile: what the eye reads as the
# stones' size (the many small cuts of a particle's caps, which a 2D exemplar need not show,
# weigh little in both)
FITTED = ("fraction", "diameter", "d90", "elongation", "solidity")
# a volume's own cuts are many: there the median too is read reliably (the spread of sizes),
# when the exemplar is read at its own size (build)
VOLUME_FITTED = FITTED + ("d50",)
DRAW_STEP = 7919  # seed step between a volume's builds (each a new draw and placement)


@dataclass(frozen=True)
class ParticleSources:
    """The exemplar's profiles: diameter (px), mean colour and phase of each; the statistics
    the 3D particles' cuts must reproduce; the typical gap between touching profiles (px)."""

    diameters: np.ndarray
    colours: np.ndarray
    target: ProfileStats
    gap: float
    spreads: ColourSpreads | None = None  # each profile's colour distribution


@dataclass(frozen=True)
class ParticleParams:
    """density: particles per voxel; size: 3D radius over the source profile's radius;
    spread: exponent on the relative source size (< 1 narrows the 3D size distribution);
    aspect: longest over shortest ellipsoid axis; bumps: radius modulation amplitude;
    cut: depth of the cutting planes (relative radius, 1 = no cut); exclusion: how far
    apart placement keeps the bounding spheres (x the sum of radii); gap: voxels between
    touching particles."""

    density: float
    size: float = 4.0 / math.pi
    spread: float = 0.8
    aspect: float = 1.4
    bumps: float = 0.08
    cut: float = 0.5
    exclusion: float = 0.9
    gap: float = 1.5


@dataclass(frozen=True)
class Particles:
    """A built structure: owner int32 (Z, Y, X) particle index (-1: matrix); sdf float32:
    signed distance-like value, positive inside particles (voxels); source int64 (N,): the
    exemplar profile of every particle; walls: packed cells' cells.Walls (None otherwise)."""

    owner: np.ndarray
    sdf: np.ndarray
    source: np.ndarray
    walls: object = None


def sources_from(image: np.ndarray, mask: np.ndarray, stats: ProfileStats,
                 wrap: bool = False) -> ParticleSources:
    """The profiles of a particle mask (bool (H, W)) with their colours."""
    from osmap_cli.solid.structure.measures import squared_distance
    from osmap_cli.solid.structure.profiles import profile_ids

    ids, count = profile_ids(mask.astype(np.int64), (1,), wrap)
    flat = ids.ravel()
    keep = flat >= 0
    area = np.bincount(flat[keep], minlength=count).astype(np.float64)
    big = area >= SOURCE_MIN_AREA
    colours = np.stack([np.bincount(flat[keep], image.reshape(-1, image.shape[2])[keep, c],
                                    count) / np.maximum(area, 1)
                        for c in range(image.shape[2])], 1)
    # the gap: twice the mean distance from matrix pixels between particles to the nearest one
    dist = np.sqrt(squared_distance(mask, wrap))
    between = (~mask) & (dist <= 4)
    gap = float(2 * dist[between].mean()) if between.any() else 1.5
    return ParticleSources(2 * np.sqrt(area[big] / np.pi), colours[big], stats, gap,
                           colour_spreads(image, ids, count).take(big))


def _draw(d: np.ndarray, n: int, rng) -> np.ndarray:
    """n source profiles of diameters d, each drawn with weight 1 / d (a plane cuts a particle
    with probability proportional to its size), systematically: the profiles in order of size,
    one draw at every unit step of their cumulative expected count from a random start, so
    every range of sizes gets its expected number within one. Drawn independently, a few large
    particles carry much of a sparse material's area (terrazzo's area-weighted diameter is above
    its 90th percentile) and a volume that drew fewer of them read its cuts' area-weighted
    diameter up to 20 % small. Sparse particles only: packed ones (gravel) are drawn
    independently."""
    order = np.argsort(-d, kind="stable")
    weights = 1.0 / d[order]
    cumulative = np.cumsum(weights) * (n / weights.sum())
    steps = rng.uniform(0.0, 1.0) + np.arange(n)
    return order[np.minimum(np.searchsorted(cumulative, steps, side="right"), len(d) - 1)]


def _rotations(rng, n):
    """n uniform random rotation matrices (from unit quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], 1)


def _unit(rng, shape):
    v = rng.normal(size=(*shape, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def build(shape, params: ParticleParams, sources: ParticleSources, seed: int,
          wrap: bool, factor: float = 1.0, growth: float | None = None) -> Particles:
    """The particles of a (Z, Y, X) volume (periodic with wrap), `params` as fitted, then
    corrected on the volume's own cuts. The fit's probe is another, smaller draw of the same
    model (terrazzo at 128^3: three probes of the fitted parameters read their cuts' fraction
    -16 % to +11 % and their area-weighted diameter -26 % to -10 % off the target), so a volume
    built from the round that read best there reads small or large by as much. Sparse
    particles in a volume at least as large as the probe: the volume is cut (VOLUME_SLICES per
    axis and the diagonal planes) and its number, size and spread of sizes corrected as in fit,
    up to VOLUME_ROUNDS builds (the median aimed MEDIAN_LOSS small); the build whose cuts read
    nearest the target wins. Read 2x enlarged (64 px exemplars), a volume holds few particles
    and its own cuts are not read like the exemplar: profiles of 1-3 voxels fall under
    MIN_PROFILE, which the exemplar's reading of 1-3 of its pixels keeps, so the median read
    17-26 % large on every build of terrazzo at 64^3, chose among them (seed 4 kept a fraction
    -20 %) and the spread chased it. There the median neither judges nor corrects, and each of
    up to REDRAWN_ROUNDS builds is a new draw and placement: where the few large particles fall
    moves the cuts' figures as much as the parameters do (seed 5: the diagonal planes read the
    area-weighted diameter 12-14 % small on builds of one draw whose axis slices read it within
    3 %). At 128^3 new draws did not help (terrazzo seed 1: the
    profile meter's worst error 0.12 against 0.05). Packed ones are built once. `factor`,
    `growth`: as for fit."""
    tf = sources.target.scaled(1.0 / (factor * _growth(sources, factor, growth))).figures()
    if tf["fraction"] > DENSE or min(shape) < _probe_side(tf):
        return _realise(shape, params, sources, seed, wrap, factor)
    tf = dict(tf, d50=tf["d50"] / MEDIAN_LOSS.get(int(round(factor)), MEDIAN_LOSS[2]))
    enlarged = int(round(factor)) > 1
    judged = FITTED if enlarged else VOLUME_FITTED
    rounds = REDRAWN_ROUNDS if enlarged else VOLUME_ROUNDS
    best = None
    for round_ in range(rounds):
        built = _realise(shape, params, sources, seed + DRAW_STEP * round_ * enlarged, wrap,
                         factor)
        got = cut_stats(built.owner >= 0, wrap, VOLUME_SLICES).figures()
        error = _error(got, tf, judged)
        if best is None or error < best[0]:
            best = (error, built)
        if error <= VOLUME_TOLERANCE or round_ == rounds - 1:
            break
        params = _number_and_size(params, got, tf, False, factor)
        if not enlarged:
            params = replace(params, spread=_spread(params, got, tf))
    return best[1]


def _realise(shape, params: ParticleParams, sources: ParticleSources, seed: int,
             wrap: bool, factor: float = 1.0) -> Particles:
    """The particles of a (Z, Y, X) volume drawn and placed with `params` (see build)."""
    rng = np.random.default_rng(seed)
    volume = float(np.prod(shape))
    # at most one particle per MIN_VOXELS voxels: a fit chasing a degenerate target (a few
    # large profiles among many specks) cannot ask for more particles than voxels
    n = max(1, min(int(round(params.density * factor ** 3 * volume)),
                   int(volume // MIN_VOXELS)))
    d = sources.diameters / factor
    if sources.target.fraction > DENSE:
        weights = 1.0 / d
        pick = rng.choice(len(d), n, p=weights / weights.sum())
    else:
        pick = _draw(d, n, rng)
    mean_d = float(np.exp(np.log(d).mean()))
    radii = 0.5 * params.size * mean_d * (d[pick] / mean_d) ** params.spread
    order = np.argsort(-radii, kind="stable")
    radii, pick = radii[order], pick[order]
    # oblate: two long axes, one short (chips and stones lie flat; their random cuts are as
    # elongated as the exemplar's profiles at a milder aspect than needles would need)
    a = params.aspect ** (1.0 / 3.0)
    axes = np.stack([np.full(n, a), np.full(n, a), np.full(n, a / params.aspect)], 1)
    rot = _rotations(rng, n)
    frames = (rot.transpose(0, 2, 1) / axes[:, :, None]).astype(np.float64)
    planes = np.concatenate([_unit(rng, (n, PLANES)),
                             rng.uniform(params.cut, 1.0, (n, PLANES, 1))], 2)
    bumps = np.concatenate([_unit(rng, (n, BUMPS)), rng.uniform(2.0, 5.0, (n, BUMPS, 1)),
                            rng.uniform(0, 2 * np.pi, (n, BUMPS, 1))], 2)
    gap = max(params.gap / factor, FINAL_GAP)
    centres = place_spheres(np.array(shape, np.float64), radii * a, params.exclusion,
                            PLACE_ATTEMPTS, np.uint64(seed), wrap)
    # size classes (halving radii), each searched within its own reach
    extents = radii * a * (1 + params.bumps * math.sqrt(BUMPS))
    level = np.floor(np.log2(radii.max() / radii)).astype(np.int64)
    classes = np.searchsorted(level, np.arange(level.max() + 2), side="left")
    reaches = np.array([extents[classes[k]] + gap + 1.0 for k in range(len(classes) - 1)])
    owner = np.empty(shape, np.int32)
    sdf = np.empty(shape, np.float32)
    render_particles(np.array(shape, np.int64), centres, radii, extents,
                     classes.astype(np.int64), reaches, frames, planes, bumps, params.bumps,
                     gap, wrap, owner, sdf)
    return Particles(owner, sdf, pick)


def cut_stats(inside: np.ndarray, wrap: bool, count: int = PROBE_SLICES) -> ProfileStats:
    """Profile statistics over axis slices and diagonal planes of a bool volume: diameters
    pooled, fraction and shapes averaged (weighted by the profiles of each cut)."""
    cuts = [s for _, _, s in axis_slices(inside, count)]
    cuts += [oblique_slice(inside, n, wrap=wrap, nearest=True) for n in DIAGONALS]
    return pooled([profile_stats(c.astype(np.int64), (1,), wrap and c.shape == inside.shape[1:])
                   for c in cuts])


def pooled(stats) -> ProfileStats:
    """One ProfileStats for several cuts."""
    counts = np.array([s.count for s in stats], np.float64)
    w = counts if counts.sum() > 0 else np.ones(len(stats))
    return ProfileStats(
        fraction=float(np.mean([s.fraction for s in stats])), count=int(counts.sum()),
        density=float(np.mean([s.density for s in stats])),
        diameters=np.sort(np.concatenate([s.diameters for s in stats])),
        solidity=float(np.average([s.solidity for s in stats], weights=w)),
        elongation=float(np.average([s.elongation for s in stats], weights=w)))


def initial_params(sources: ParticleSources) -> ParticleParams:
    """A first guess: spheres 4/pi the profiles' size (a sphere's mean cut is pi/4 of its
    diameter), as many as fill the exemplar's area fraction (Delesse: V_V = A_A); dense
    materials (cells) fill their Laguerre cells, uncut, and keep the exemplar's gap."""
    t = sources.target
    d = sources.diameters
    mean_d = float(np.exp(np.log(d).mean()))
    w = 1.0 / d
    dense = t.fraction > DENSE
    size = (4.0 / math.pi) * (1.6 if dense else 1.0)
    r3 = float(np.average((0.5 * 4.0 / math.pi * mean_d * (d / mean_d) ** 0.8) ** 3,
                          weights=w))
    density = t.fraction / (0.7 * 4.0 / 3.0 * math.pi * r3)
    gap = float(np.clip(sources.gap, MIN_GAP, MAX_GAP)) if dense else MIN_GAP
    # dense: no cutting planes (a cut particle leaves a pocket of matrix in its cell, wider than
    # the exemplar's gaps, which a cut through the volume shows as a stone-less blotch); one
    # exclusion for both: at 0.6 packed stones crowd and pool, coarse contrast the scale reads
    return ParticleParams(density=density, size=size, gap=gap, exclusion=0.7,
                          cut=1.0 if dense else 0.5)


def _step(ratio: float, power: float) -> float:
    """A damped multiplicative correction."""
    return float(np.clip(ratio ** power, 1 / MAX_STEP, MAX_STEP))


def _error(got: dict, want: dict, figures=FITTED) -> float:
    """The largest relative error over `figures`."""
    return max(abs(got[k] / want[k] - 1.0) for k in figures if want[k] > 0)


def _growth(sources: ParticleSources, factor: float, growth: float | None) -> float:
    """`growth`, else how much larger the fill reads these particles (FILL_GROWTH)."""
    if growth is not None:
        return growth
    if sources.target.fraction <= DENSE:
        return SPARSE_GROWTH
    return FILL_GROWTH.get(int(round(factor)), FILL_GROWTH[2])


def _probe_side(tf: dict, cap: int | None = None) -> int:
    """The fit's probe side for target figures `tf` (voxels; see fit)."""
    probe = int(np.clip(4 * max(tf["d90"], 8.0), *PROBE_SIDE))
    return probe if cap is None else min(probe, max(2 * int(cap), MIN_PROBE))


def _number_and_size(params: ParticleParams, got: dict, tf: dict, dense: bool,
                     factor: float) -> ParticleParams:
    """params with the number, size (and for dense packings the gap) corrected towards the
    target figures `tf` from the figures `got` their build's cuts read."""
    size_ratio = math.sqrt(tf["diameter"] * tf["d90"] / max(got["diameter"] * got["d90"], 1e-6))
    frac_ratio = tf["fraction"] / max(got["fraction"], 1e-6)
    if dense:
        density = params.density * _step(size_ratio, -1.8)
        size = params.size
        gap = float(np.clip(params.gap * _step(frac_ratio, -1.2), MIN_GAP, MAX_GAP))
        if gap / factor <= FINAL_GAP * 1.01 and frac_ratio > 1:
            size = params.size * _step(frac_ratio, 0.4)
        return replace(params, density=density, size=size, gap=gap)
    size = params.size * _step(size_ratio, 0.7)
    density = params.density * _step(frac_ratio * size_ratio ** -2.1, 1.0)
    return replace(params, density=density, size=size)


def _spread(params: ParticleParams, got: dict, tf: dict) -> float:
    """The spread of sizes corrected towards the target's 90th percentile over median."""
    ratio = (tf["d90"] / max(tf["d50"], 1e-6)) / max(got["d90"] / max(got["d50"], 1e-6), 1e-6)
    return float(np.clip(params.spread * _step(ratio, 0.8), 0.3, 1.3))


def fit(sources: ParticleSources, seed: int, probe: int | None = None, log=None,
        factor: float = 1.0, cap: int | None = None, growth: float | None = None):
    """(ParticleParams, the best probe's cut statistics in voxels): rounds of build, cut,
    measure, correct on a periodic probe volume built as the volumes will be (`factor`: the
    sources are in pixels `factor` times smaller than a voxel, as for build; the least gap
    included), so what is fitted is what is built; the round with the least error wins.
    The probe's side follows the particles' size (PROBE_SIDE), not the volume's, but is at
    most twice `cap` (at least MIN_PROBE): a tiny volume shows no more than itself, and a
    degenerate exemplar (a few large profiles among many specks) asks for many particles.
    Sparse particles: size sets the diameters, the number the area fraction; dense ones
    (cells): the number sets the diameters, the gap the fraction. The diameters are fitted
    `growth` times smaller than the exemplar's: the fill reads the particles that much larger
    (None: FILL_GROWTH of the factor; SPARSE_GROWTH for sparse particles)."""
    tf = sources.target.scaled(1.0 / (factor * _growth(sources, factor, growth))).figures()
    if probe is None:
        probe = _probe_side(tf, cap)
    shape = (probe, probe, probe)
    params = initial_params(sources)
    dense = tf["fraction"] > DENSE
    best = None
    for round_ in range(FIT_ROUNDS):
        built = _realise(shape, params, sources, seed + 7919 * round_, True, factor)
        stats = cut_stats(built.owner >= 0, True)
        got = stats.figures()
        error = _error(got, tf)
        if log is not None:
            log(round_, params, got)
        if best is None or error < best[0]:
            best = (error, params, stats)
        if round_ == FIT_ROUNDS - 1:
            break
        params = replace(
            _number_and_size(params, got, tf, dense, factor),
            spread=_spread(params, got, tf),
            aspect=float(np.clip(params.aspect * _step(tf["elongation"] / got["elongation"],
                                                       1.2), 1.0, 4.0)),
            bumps=float(np.clip(params.bumps + 0.4 * (got["solidity"] - tf["solidity"]),
                                0.0, 0.25)))
    return best[1], best[2]

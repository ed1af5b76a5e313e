"""Solid synthesis: exemplar pyramids -> OS-Map layout of the coarsest volume -> per level,
search + colour iterations -> upsample -> render. `synthesize_solid` is the library entry point
behind `osmap solid`.

Every voxel carries three exemplar positions, one per slice family (the model vector of the
OS-Map is in R^6: one (row, col) pair per axis, each pair's kernel broad inside its own slice
plane and zero across it), and a source: the (axis, row, col) its colour is copied from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from osmap_cli.engine import Orientation, OSMap, Schedule
from osmap_cli.solid.options import SolidOptions
from osmap_cli.solid.orient import is_turned, turn_volume
from osmap_cli.texture.features import appearance_features, feature_variance
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.occupancy import occupancy
from osmap_cli.texture.pyramid import build_pyramid, half_size
from osmap_cli.texture.references import similar_positions
from osmap_kernels.solid import (
    PLANE,
    ColourParams,
    SearchParams,
    blend_render,
    colour_pass,
    gather_sources,
    search_pass,
    usage_counts,
)

MIN_COARSE = 16  # the coarsest volume and exemplar level keep at least this many voxels a side
MAX_KNN_REFERENCES = 4096
ACROSS = 1.0e4  # OS-Map kernel weight across a component's slice plane: no update there
EXHAUSTIVE_ITERATIONS = 2  # coarsest level: exhaustive search first, then propagation
# ... unless voxels x exemplar pixels exceed this: a thin volume (8x8x1024) cannot be made
# coarser than its short side allows, and an exhaustive search over it took minutes
EXHAUSTIVE_BUDGET = 2**25
NORMAL_DIM = (2, 1, 0)  # volume dim (z, y, x order) normal to axis x, y, z


@dataclass(frozen=True)
class SolidResult:
    """voxels: float32 (Z, Y, X, C); source: int32 (Z, Y, X, 3) = (axis, row, col) of the
    exemplar pixel each voxel is copied from (axis 0, 1, 2 = the x, y, z exemplar); with
    `blend` > 0 the voxels on seams are blended, the others are their source pixel exactly."""

    voxels: np.ndarray
    source: np.ndarray

    def uv(self) -> np.ndarray:
        """float32 (Z, Y, X, 3): u = exemplar column, v = exemplar row, exemplar index."""
        s = self.source
        return np.stack([s[..., 2], s[..., 1], s[..., 0]], -1).astype(np.float32)


def _stack(arrays, shape_hw) -> np.ndarray:
    """Arrays (h_e, w_e, ...) padded (edge) to a common (H, W, ...) and stacked."""
    out = []
    for a in arrays:
        pad = [(0, shape_hw[0] - a.shape[0]), (0, shape_hw[1] - a.shape[1])]
        pad += [(0, 0)] * (a.ndim - 2)
        out.append(np.pad(a, pad, mode="edge"))
    return np.ascontiguousarray(np.stack(out))


def organise(shape, ex_shapes, ex_of_axis, lo, hi, opts: SolidOptions, seed: int) -> np.ndarray:
    """int32 (3, Z, Y, X, 2): the OS-Map's layout of three positions per voxel.

    Component (a, j) (axis a's exemplar row j=0 / column j=1) varies along volume dim
    PLANE[a, j], som_anisotropy times as steeply along the other in-plane dim, and not at all
    across the plane; its coherent target is x + (offset along PLANE[a, j]).
    """
    weights = np.zeros((6, 3))
    jac = np.zeros((6, 3))
    bounds = np.zeros((6, 2))
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            k = 2 * a + j
            weights[k, PLANE[a, j]] = 1.0
            weights[k, PLANE[a, 1 - j]] = opts.som_anisotropy
            weights[k, NORMAL_DIM[a]] = ACROSS
            jac[k, PLANE[a, j]] = 1.0
            bounds[k] = (lo[e, j], hi[e, j])
    extent = min(min(s) for s in ex_shapes)
    window = tuple(min(s, extent) for s in shape)
    som = OSMap(shape, 6, wrap=(opts.tileable,) * 3, window=window,
                orientation=Orientation.axis_aligned(weights), target_jacobian=jac,
                range_kernel=(2.0, 1.0), bounds=bounds)
    rng = np.random.default_rng(seed)
    count = max(4096, 4 * som.size)
    data = np.empty((count, 6))
    for k in range(6):
        data[:, k] = rng.integers(bounds[k, 0], bounds[k, 1] + 1, count)
    som.init_random(data, seed=seed)
    steps = int(opts.som_steps_per_node * som.size)
    if steps:
        schedule = Schedule(alpha_max=0.5, alpha_min=0.05, sigma_max=opts.som_sigma_max,
                            sigma_min=0.3)
        som.train(data, steps, schedule=schedule, seed=seed + 1)
    grid = np.rint(som.grid_weights()).reshape(*shape, 3, 2)
    pos = np.moveaxis(grid, 3, 0)
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            pos[a, ..., j] = np.clip(pos[a, ..., j], lo[e, j], hi[e, j])
    return np.ascontiguousarray(pos.astype(np.int32))


def upsample_positions(pos: np.ndarray, shape, lo, hi, ex_of_axis) -> np.ndarray:
    """Each axis' positions at the finer level: 2 S[v // 2] + in-plane offset (v mod 2)."""
    idx = [np.minimum(np.arange(n) // 2, pos.shape[1 + d] - 1) for d, n in enumerate(shape)]
    off = [np.arange(n) - 2 * i for n, i in zip(shape, idx)]
    coarse = pos[:, idx[0]][:, :, idx[1]][:, :, :, idx[2]].astype(np.int64)
    fine = 2 * coarse
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            d = PLANE[a, j]
            o = off[d].reshape([-1 if i == d else 1 for i in range(3)])
            fine[a, ..., j] = np.clip(fine[a, ..., j] + o, lo[e, j], hi[e, j])
    return np.ascontiguousarray(fine.astype(np.int32))


def upsample_source(source: np.ndarray, shape, ex_shapes, ex_of_axis) -> np.ndarray:
    """Sources at the finer level: the same axis, 2 (row, col) + in-plane offset."""
    idx = [np.minimum(np.arange(n) // 2, source.shape[d] - 1) for d, n in enumerate(shape)]
    off = [np.arange(n) - 2 * i for n, i in zip(shape, idx)]
    coarse = source[idx[0]][:, idx[1]][:, :, idx[2]].astype(np.int64)
    axis = coarse[..., 0]
    grids = np.meshgrid(*off, indexing="ij")
    fine = np.empty_like(coarse)
    fine[..., 0] = axis
    for j in range(2):
        dims = PLANE[axis, j]  # volume dim of this exemplar coordinate, per voxel
        o = np.choose(dims, grids)
        limit = np.array([ex_shapes[ex_of_axis[a]][j] - 1 for a in range(3)])[axis]
        fine[..., 1 + j] = np.clip(2 * coarse[..., 1 + j] + o, 0, limit)
    return np.ascontiguousarray(fine.astype(np.int32))


def upsample_linear(vol: np.ndarray, shape, wrap: bool) -> np.ndarray:
    """vol (z, y, x, C) resampled to shape (Z, Y, X) by separable linear interpolation, each fine
    voxel at its centre's position in the coarse grid."""
    out = vol.astype(np.float32)
    for d, n in enumerate(shape):
        m = out.shape[d]
        t = (np.arange(n) + 0.5) * (m / n) - 0.5
        i0 = np.floor(t).astype(np.int64)
        f = (t - i0).astype(np.float32)
        i1 = i0 + 1
        if wrap:
            i0, i1 = i0 % m, i1 % m
        else:
            i0, i1 = np.clip(i0, 0, m - 1), np.clip(i1, 0, m - 1)
        f = f.reshape([-1 if k == d else 1 for k in range(out.ndim)])
        out = np.take(out, i0, axis=d) * (1 - f) + np.take(out, i1, axis=d) * f
    return np.ascontiguousarray(out)


def colour_to_features(images, feats):
    """float64 (C + 1, F): the affine map from colour to appearance features, fitted by least
    squares on the exemplar pixels (exact for colour-only features)."""
    c = np.concatenate([im.reshape(-1, im.shape[2]) for im in images]).astype(np.float64)
    f = np.concatenate([ft.reshape(-1, ft.shape[2]) for ft in feats]).astype(np.float64)
    a = np.concatenate([c, np.ones((len(c), 1))], axis=1)
    return np.linalg.lstsq(a, f, rcond=None)[0]


def match_histogram(vol: np.ndarray, feats, strength: float) -> np.ndarray:
    """vol with each feature dimension moved `strength` of the way to the exemplars' distribution
    (quantile mapping), so the search sees minority colours at their exemplar frequency."""
    if strength == 0.0:
        return vol
    flat = vol.reshape(-1, vol.shape[-1])
    ref = np.concatenate([f.reshape(-1, f.shape[2]) for f in feats])
    out = np.empty_like(flat)
    q = (np.arange(len(flat)) + 0.5) / len(flat)
    for d in range(flat.shape[1]):
        order = np.argsort(flat[:, d], kind="stable")
        target = np.quantile(ref[:, d], q).astype(np.float32)
        out[order, d] = flat[order, d] + strength * (target - flat[order, d])
    return np.ascontiguousarray(out.reshape(vol.shape))


def synthesize_solid(exemplars, options: SolidOptions, progress=None) -> SolidResult:
    """A volume like the exemplars: one float32 (h, w, C) image for every axis, or a list of
    three (x, y, z) with equal channel counts. `progress(fraction)` is called as levels finish.
    """
    opts = options.validated().with_quality()  # validated: method is one of METHODS
    if is_turned(opts.angles):
        # the material axis-aligned in a box that holds the turned volume, then sampled turned
        z, y, x = opts.synthesis_shape()
        material = synthesize_solid(exemplars, options.replace(
            width=x, height=y, depth=z, rotate_x=0.0, rotate_y=0.0, rotate_z=0.0), progress)
        return SolidResult(*turn_volume(material.voxels, material.source, opts.shape,
                                        opts.angles))
    if len(exemplars) == 1:
        images, ex_of_axis = [exemplars[0]], np.zeros(3, np.int64)
    else:
        images, ex_of_axis = list(exemplars), np.arange(3, dtype=np.int64)
    images = [np.ascontiguousarray(im, np.float32) for im in images]
    n_ex = len(images)
    shape = opts.shape
    levels = level_count([im.shape[:2] for im in images], shape, opts.levels,
                         min_size=MIN_COARSE, round_up=False)
    pyramids = [build_pyramid(im, levels) for im in images]
    shapes = [shape]
    for _ in range(levels - 1):
        z, y, x = shapes[-1]
        shapes.append((half_size((z, y))[0], *half_size((y, x))))
    if opts.method != "legacy":
        return _synthesize_optimised(images, ex_of_axis, opts, pyramids, shapes, progress)
    r = opts.patch_radius
    work = [opts.coarse_iterations * 2] + [opts.iterations] * (levels - 1)
    total = float(sum(work))
    done = 0.0

    pos = source = colours = None
    for level in range(levels - 1, -1, -1):
        level_images = [p[level] for p in pyramids]
        ex_shapes = [im.shape[:2] for im in level_images]
        hw = (max(s[0] for s in ex_shapes), max(s[1] for s in ex_shapes))
        feats = appearance_features(level_images, opts.feature_dims, opts.feature_radius)
        variance = max(feature_variance(feats, np.float32), 1e-12)
        rr = min(r, (min(min(s) for s in ex_shapes) - 1) // 2)
        lo = np.array([[rr, rr]] * n_ex, np.int64)
        hi = np.array([[s[0] - 1 - rr, s[1] - 1 - rr] for s in ex_shapes], np.int64)
        feat_stack = _stack(feats, hw)
        knn = _stack([similar_positions(f, lo[e], hi[e], opts.knn, MAX_KNN_REFERENCES)
                      for e, f in enumerate(feats)], hw)
        if opts.knn == 0:
            knn = np.ascontiguousarray(knn[..., :0, :])
        vshape = shapes[level]
        coarsest = pos is None
        if coarsest:
            pos = organise(vshape, ex_shapes, ex_of_axis, lo, hi, opts, opts.seed)
            iterations = opts.coarse_iterations
            cost = np.ones((3, *vshape), np.float32)
            source = np.zeros((*vshape, 3), np.int32)
            vol = np.zeros((*vshape, feat_stack.shape[3]), np.float32)
            colour_pass(pos, cost, feat_stack, ex_of_axis,
                        np.ones((n_ex, *hw), np.float32),
                        ColourParams(opts.mode_radius, opts.tileable,
                                     opts.mode_bandwidth * variance,
                                     0.0, 1.0, 0.0, 0.0), vol.copy(), source, vol)
        else:
            pos = upsample_positions(pos, vshape, lo, hi, ex_of_axis)
            source = upsample_source(source, vshape, ex_shapes, ex_of_axis)
            vol = gather_sources(source, feat_stack, ex_of_axis)
            if opts.smooth_upsample:
                colours = upsample_linear(colours, vshape, opts.tileable)
                m = colour_to_features(level_images, feats)
                smooth = (colours @ m[:-1] + m[-1]).astype(np.float32)
                vol = np.ascontiguousarray(vol + opts.smooth_upsample * (smooth - vol))
            iterations = opts.iterations
        cparams = ColourParams(opts.mode_radius, opts.tileable, opts.mode_bandwidth * variance,
                               opts.mode_power, 1e-3 * variance * (2 * rr + 1) ** 2,
                               opts.occupancy, opts.across)
        # seam penalty unit: a whole window's feature variance, shared among the 8 neighbours.
        # The coarser levels' penalty sets the copy layout every finer level refines, the
        # finest level's how fragmented the rendered copies are (docs/solid.md, round 4)
        seam = opts.seam if level == 0 else opts.coarse_seam
        seam_unit = seam * variance * (2 * rr + 1) ** 2 / 8.0
        for it in range(iterations):
            sparams = SearchParams(rr, opts.tileable, opts.random_candidates,
                                   coarsest and it < EXHAUSTIVE_ITERATIONS
                                   and math.prod(vshape) * math.prod(hw) <= EXHAUSTIVE_BUDGET,
                                   lo, hi,
                                   opts.search_occupancy, np.uint64(opts.seed),
                                   np.uint64(level * 1000 + it), seam_unit)
            occ = occupancy(usage_counts(source, ex_of_axis, n_ex, *hw), source[..., 0].size)
            new_pos = np.empty_like(pos)
            cost = np.empty((3, *vshape), np.float32)
            vol = match_histogram(vol, feats, opts.histogram)
            search_pass(vol, pos, new_pos, cost, feat_stack, ex_of_axis, knn, occ, sparams)
            pos = new_pos
            new_source = np.empty_like(source)
            searched, vol = vol, np.empty_like(vol)
            colour_pass(pos, cost, feat_stack, ex_of_axis, occ, cparams, searched, new_source,
                        vol)
            source = new_source
            done += 2 if coarsest else 1
            if progress is not None:
                progress(done / total)
        colours = gather_sources(source, _stack(level_images, hw), ex_of_axis)
    full = _stack(images, (max(im.shape[0] for im in images), max(im.shape[1] for im in images)))
    if opts.blend == 0.0:
        return SolidResult(gather_sources(source, full, ex_of_axis), source)
    bparams = cparams._replace(bandwidth2=opts.blend * variance)
    return SolidResult(blend_render(pos, cost, feat_stack, full, ex_of_axis, source, bparams),
                       source)


def _synthesize_optimised(images, ex_of_axis, opts, pyramids, shapes, progress):
    """Methods osmap and kopf: texture optimisation (osmap_cli.solid.kopf); osmap starts from
    the OS-Map's layout of the coarsest volume, kopf from random positions."""
    from osmap_cli.solid import kopf

    def organise_fn(shape, ex_shapes, lo, hi):
        if opts.method != "osmap":
            return None
        return organise(shape, ex_shapes, ex_of_axis, lo, hi, opts, opts.seed)

    voxels, source = kopf.optimise(images, ex_of_axis, opts, shapes, pyramids, _stack,
                                   organise_fn, upsample_positions, upsample_linear, progress)
    return SolidResult(voxels, source)

"""Fill part of an image from the rest of it: inpainting a hole and re-synthesizing the border
bands of a photo so that it tiles. One engine for both (osmap_cli.synth.constraints):

    pyramid of the image (the hole pre-filled smoothly, for the features only)
    -> coarsest level: the kept pixels pinned to their own positions, the free ones at random
       allowed positions (measured: better than an OS-Map layout, which the kept pixels
       constrain anyway) -> coherence sweeps at every level, the free pixels' matching windows
       including the kept pixels around them, so the fill continues the surrounding structure
    -> render the free pixels (seam blending), keep every other pixel bit for bit.

    inpaint(image, hole, SynthOptions(seed=1))      # hole: bool (H, W), True = fill
    make_tileable(photo, border=16)                 # the bands along the edges, wrapping
"""

from __future__ import annotations

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.synth.atlas import SeveralResult
from osmap_cli.synth.constraints import (
    LevelConstraint,
    dilate,
    identity_positions,
    mask_pyramid,
    push_pull,
)
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.pipeline import (
    MIN_LEVEL_SIZE,
    LevelLoop,
    SynthResult,
    run_levels,
    uniform_jacobian,
    valid_box,
)
from osmap_cli.synth.regular import BAND_LEFTOVER, atlas_phase, leftover, resolve_lattice
from osmap_cli.synth.render import render
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.pyramid import build_pyramid

__all__ = ["border_bands", "fill", "inpaint", "make_tileable", "match_border", "render_fill"]

# the border correction of a hole fades out over this many pixels
BORDER_FADE = 6
# ... and is averaged along the border over this many pixels either side
BORDER_SPAN = 2


def border_bands(shape, border: int) -> np.ndarray:
    """bool (H, W): the pixels closer than `border` to an edge (what `tileable` re-synthesizes)."""
    free = np.zeros(shape, bool)
    free[:border] = free[-border:] = True
    free[:, :border] = free[:, -border:] = True
    return free


def inpaint(image: np.ndarray, mask: np.ndarray, options: SynthOptions | None = None,
            progress=None, exemplars=()) -> SynthResult:
    """image (H, W, C) with the pixels where mask (bool (H, W)) is True synthesized from the
    others, which are kept bit for bit (`osmap inpaint`).

    exemplars (float32 (h_i, w_i, C) each, optional): the hole is synthesized from them instead
    of from the rest of the image (`osmap inpaint --exemplar`); the kept pixels still take part
    in the matching windows, so the fill continues them. The result is then a
    :class:`osmap_cli.synth.atlas.SeveralResult`: positions in the atlas of [image, *exemplars],
    exemplar_index (-1: the image's own pixel, i: exemplars[i]) and local_positions."""
    return fill(image, mask, (options or SynthOptions()).replace(tileable=False),
                source_free=False, progress=progress, exemplars=exemplars)


def make_tileable(image: np.ndarray, border: int = 0, options: SynthOptions | None = None,
                  progress=None) -> SynthResult:
    """image (H, W, C) made to tile: the bands within `border` pixels of an edge (0: an eighth
    of the shorter side, at least 8) synthesized again, wrapping around; the centre kept bit
    for bit (`osmap tileable`)."""
    from osmap_cli.synth.options import FillOptions

    band = FillOptions(border=border).validated().band(np.shape(image)[:2])
    return fill(image, border_bands(np.shape(image)[:2], band),
                (options or SynthOptions()).replace(tileable=True), source_free=True,
                progress=progress)


def _check(image: np.ndarray, free: np.ndarray, opts: SynthOptions) -> None:
    if free.shape != image.shape[:2]:
        raise ValueError(f"mask {free.shape} and image {image.shape[:2]} differ in size")
    if opts.method != "osmap" or (opts.scale, opts.orientation, opts.anisotropy) != (1, 0, 1):
        raise ValueError("fill keeps the image's own scale: method osmap, scale 1, "
                         "orientation 0, anisotropy 1")
    if not free.any():
        raise OsmapError("the mask selects no pixel to fill")
    if free.all():
        raise OsmapError("the mask selects every pixel: nothing is left to fill from")


def _outer_half(band: np.ndarray) -> np.ndarray:
    """bool (H, W): the outer half (at least a pixel) of the border bands `band` (as
    border_bands makes them, here at one pyramid level)."""
    h, w = band.shape
    across = max(1, int(band[h // 2].sum()) // 4)  # left + right bands, halved
    down = max(1, int(band[:, w // 2].sum()) // 4)
    out = np.zeros_like(band)
    out[:down] = out[-down:] = True
    out[:, :across] = out[:, -across:] = True
    return out & band


def _random_allowed(rng, count: int, allowed: np.ndarray, lo, hi) -> np.ndarray:
    """count (row, col) positions drawn uniformly from the allowed pixels inside [lo, hi]."""
    box = np.zeros_like(allowed)
    box[int(np.ceil(lo[0])):int(hi[0]) + 1, int(np.ceil(lo[1])):int(hi[1]) + 1] = True
    choices = np.argwhere(allowed & box)
    if len(choices) == 0:
        choices = np.argwhere(box)
    return choices[rng.integers(0, len(choices), count)].astype(np.float32)


def fill(image: np.ndarray, free: np.ndarray, options: SynthOptions, *, source_free: bool,
         progress=None, exemplars=()) -> SynthResult:
    """image float32 (H, W, C) with the `free` pixels (bool (H, W)) synthesized from the others.

    source_free: may the free pixels' own content be copied (True for tileable bands, whose
    content is real; False for a hole, whose content is unknown). options.tileable makes the
    output wrap around. The size is the image's; the kept pixels come back bit for bit.
    exemplars (a hole only): the free pixels are synthesized from these images (same channels
    as image) instead of from the image's kept pixels (see inpaint).
    """
    opts = options.validated().with_quality()
    image = np.ascontiguousarray(image, np.float32)
    free = np.asarray(free, bool)
    _check(image, free, opts)
    exemplars = [np.ascontiguousarray(ex, np.float32) for ex in exemplars]
    if exemplars:
        _check_exemplars(image, exemplars, source_free)
    shape = image.shape[:2]
    wrap = opts.tileable
    source = image if source_free else push_pull(image, ~free)
    levels = level_count([shape, *(ex.shape[:2] for ex in exemplars)], shape, opts.levels,
                         min_size=MIN_LEVEL_SIZE)
    holes = mask_pyramid(free, levels)
    atlas = None
    if exemplars:
        # the image (its hole pre-filled) and the exemplars side by side: the kept pixels read
        # their own positions in it, the hole may take positions inside the exemplars only
        from osmap_cli.synth.atlas import pack

        atlas = pack([source, *exemplars], levels, max(opts.patch_radius, opts.blend) + 1)
        pyramid = build_pyramid(atlas.pixels, levels)
        off_limits = mask_pyramid(~atlas.inside(first=1), levels)
    else:
        pyramid = build_pyramid(source, levels)
        off_limits = holes
    rng = np.random.default_rng(opts.seed)

    def bounds(level, source_shape, jac_field):
        if source_free and level > 0:
            # the bands may continue the kept centre up to the image's edge (windows there read
            # edge-replicated pixels) at the coarse levels, where the bands are a pixel or two
            # wide: else they could only copy from elsewhere and cut a seam along the centre
            return np.zeros(2), np.array(holes[level].shape, np.float64) - 1
        return valid_box(source_shape, np.eye(2), opts.patch_radius)

    def constraint(level, lo, hi):
        """The kept pixels pinned to their own positions; for a hole, the positions whose
        window reaches it (or leaves the exemplars) forbidden."""
        forbidden = np.zeros(pyramid[level].shape[:2], bool)
        if not source_free:
            reach = opts.patch_radius + 1 if level else max(opts.patch_radius + 1, opts.blend)
            forbidden = dilate(off_limits[level], reach)
            if forbidden[int(lo[0]):int(hi[0]) + 1, int(lo[1]):int(hi[1]) + 1].all():
                # a mask this large (exemplars this small) at a coarse level: the hole (the
                # positions outside the exemplars) only
                forbidden = off_limits[level].copy()
        return LevelConstraint(~holes[level], identity_positions(holes[level].shape), forbidden,
                               count_pinned=not source_free)

    def start(level, lo, hi, constraint):
        hole = holes[level]
        pos = constraint.known.copy()
        if source_free:
            # the outer half of the bands starts from the photo rolled by half its size, whose
            # content runs on across the wrap line: the search then starts from two joins inside
            # the bands instead of the photo's own seam on the wrap line (measured: lower band
            # error on 4 seeds, see docs/fill.md)
            outer = _outer_half(hole)
            h, w = hole.shape
            pos[outer, 0] = (pos[outer, 0] + h // 2) % h
            pos[outer, 1] = (pos[outer, 1] + w // 2) % w
            pos[..., 0] = np.clip(pos[..., 0], lo[0], hi[0])
            pos[..., 1] = np.clip(pos[..., 1], lo[1], hi[1])
        else:
            pos[hole] = _random_allowed(rng, int(hole.sum()), ~constraint.forbidden, lo, hi)
        return pos

    def restyle(level, level_image, pos):
        # a hole's second round matches against the first round's fill instead of the smooth
        # pre-fill, which blurs the features of the kept pixels around the hole
        return _paste(level_image, holes[level], render(pyramid[level], pos))

    # the image's lattice (a hole: read from the kept pixels), kept by the fill
    lattice = resolve_lattice(opts.lattice, image, None if source_free else ~free)
    if lattice is not None and wrap and leftover(lattice, shape) > BAND_LEFTOVER:
        lattice = None  # its wrap lines would not meet in step: the bands find their own way

    def lattice_phase(level):
        return atlas_phase(lattice, [source, *exemplars], atlas.origins,
                           pyramid[level].shape[:2], level)

    loop = LevelLoop(pyramid, [h.shape for h in holes], uniform_jacobian(np.eye(2)), bounds,
                     start, constraint=constraint, rounds=1 if source_free else 2,
                     restyle=restyle, lattice=lattice,
                     lattice_phase=None if atlas is None else lattice_phase, pinned_phase=True)
    pos, jac_field, finest = run_levels(loop, opts, progress)
    forbidden = finest.forbidden
    if not source_free and forbidden[np.rint(pos[free]).astype(int)[:, 0],
                                      np.rint(pos[free]).astype(int)[:, 1]].any():
        raise OsmapError("the exemplars are too small to fill the mask from" if exemplars else
                         "the mask leaves too little of the image to fill it from")
    if atlas is None:
        pixels = render_fill(lambda px, blend: render(px, pos, jac_field, wrap, blend), image,
                             free, source_free, opts.blend)
        return SynthResult(pixels, pos, lattice=lattice)

    def draw(px, blend):
        # the image's pixels (as render_fill passes them) in the atlas, then rendered
        sheet = atlas.pixels.copy()
        sheet[:shape[0], :shape[1]] = px
        return render(sheet, pos, jac_field, wrap, blend)

    pixels = render_fill(draw, image, free, source_free, opts.blend)
    index, local = atlas.locate(pos)
    return SeveralResult(pixels, pos, None, lattice, index - 1, local)  # -1: the image itself


def _check_exemplars(image: np.ndarray, exemplars, source_free: bool) -> None:
    if source_free:
        raise ValueError("exemplars fill a hole only (not tileable bands)")
    for i, ex in enumerate(exemplars):
        if ex.ndim != 3 or ex.shape[2] != image.shape[2]:
            raise ValueError(f"exemplar {i} has shape {ex.shape}, the image {image.shape}: "
                             "they need the same channels")


def _paste(level_image: np.ndarray, hole: np.ndarray, drawn: np.ndarray) -> np.ndarray:
    """level_image (the image's level, or the atlas with the image at its top-left) with the
    hole's pixels replaced by `drawn` (the hole's shape)."""
    h, w = hole.shape
    if level_image.shape[:2] == (h, w):
        return np.where(hole[..., None], drawn, level_image)
    out = level_image.copy()
    out[:h, :w] = np.where(hole[..., None], drawn, level_image[:h, :w])
    return out


def render_fill(draw, pixels: np.ndarray, free: np.ndarray, source_free: bool,
                blend: int) -> np.ndarray:
    """The free pixels rendered by draw(pixels, blend) (osmap_cli.synth.render.render through
    the positions), every other pixel of `pixels` unchanged.

    Seam blending lets the kept pixels vote for their free neighbours with their own
    continuation. For a hole that continuation is the hole's unknown content, so the hole is
    first rendered without blending and the votes read that instead.
    """
    inside = free[..., None]
    source = pixels
    if not source_free and blend > 0:
        source = np.where(inside, draw(pixels, 0), pixels)
    out = np.where(inside, draw(source, blend), pixels).astype(np.float32)
    if not source_free:
        out = match_border(out, free)
    return out


def match_border(image: np.ndarray, free: np.ndarray, width: int = BORDER_FADE) -> np.ndarray:
    """image with the free pixels near the kept ones shifted toward them: the difference across
    the border (kept - free, smoothed along the border by push-pull) is added to the free
    pixels, fading to nothing `width` pixels in. Removes the colour step a fill would leave
    at its border; the kept pixels are untouched."""
    h, w = free.shape
    kept = ~free
    diff = np.zeros(image.shape, np.float64)
    count = np.zeros((h, w))
    for axis in (0, 1):
        for step in (1, -1):
            shifted_kept = np.roll(kept, step, axis)
            shifted = np.roll(image, step, axis)
            edge = free & shifted_kept
            if axis == 0:
                edge[0 if step == 1 else -1] = False
            else:
                edge[:, 0 if step == 1 else -1] = False
            diff[edge] += shifted[edge] - image[edge]
            count[edge] += 1
    diff[count > 0] /= count[count > 0][:, None]
    rim = count > 0
    if not rim.any():
        return image
    # the difference averaged along the border (a normalised box blur over the rim pixels):
    # the colour offset, not the pixel-to-pixel detail, which would copy the kept row inwards
    weight = rim.astype(np.float64)
    blur_diff, blur_weight = diff, weight
    for axis in (0, 1):
        blur_diff = sum(np.roll(blur_diff, d, axis) for d in range(-BORDER_SPAN, BORDER_SPAN + 1))
        blur_weight = sum(np.roll(blur_weight, d, axis)
                          for d in range(-BORDER_SPAN, BORDER_SPAN + 1))
    diff = np.where(rim[..., None], blur_diff / np.maximum(blur_weight, 1e-12)[..., None], 0.0)
    smooth = push_pull(diff.astype(np.float32), rim)
    depth = np.zeros((h, w))
    reached = rim.copy()
    for d in range(1, width):
        grown = dilate(reached, 1) & free
        depth[grown & ~reached] = d
        reached = grown
    fade = np.where(reached, np.clip(1.0 - depth / width, 0.0, 1.0), 0.0)
    fade = np.where(free, fade, 0.0)
    return (image + fade[..., None] * smooth).astype(np.float32)

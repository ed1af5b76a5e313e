"""Layers in 3D: wood grain, growth rings, sediment, veined sheets as the bands of a scalar
field u: planes perpendicular to a 3D normal (u = n . x) or cylinders around an axis (rings:
u = distance from the axis), both displaced by smooth noise (the exemplar's waviness). Along
u the bands follow each other as in the exemplar: the phases' run lengths across the stripes
and which phase follows which are read from the exemplar and sampled as a Markov chain.

The normal: every slice family whose exemplar shows stripes at an angle constrains the layers'
trace in that family's plane; the normal is the least-squares direction perpendicular to all
traces. With one exemplar the two side families (x and y, whose rows are z) are honoured
exactly; the third then shows the traces the geometry allows (docs/solid.md: a single planar
grain cannot run along the exemplar's diagonal in all three families; one shows the mirrored
diagonal, or the plane of the layers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.solid.structure import layer_scale as ls
from osmap_cli.solid.structure.layer_scale import COVERAGE, band_shares
from osmap_cli.solid.structure.noise import smooth_noise

RING_FIT = 0.25  # rings: the fitted centre's residual over the image size stays below this
RING_SIDES = 0.35  # ... and the other families' stripes are at least this coherent
MIN_RUN = 1.0
WOBBLE_LENGTH = 4.0  # the displacement's correlation length, in layer spacings
MAX_CHAIN = 1 << 20
FILL_WIDENING = 1.1  # the fill widens the bands of its guide by about this much
DRAWS = 16  # draws of the band sequence a volume chooses from (layer_bands)
DRAW_STEP = 7919  # ... their seeds apart
FACE_SCALE = 1.12  # ... the one kept: its farthest face reads nearest this times the exemplar's
#                    segmentation's scale (on the fill's guide, which reads coarser than the fill)
PARALLEL = 30.0  # degrees: one exemplar's layers this near a slice family's plane are tilted
TILT = 45.0  # ... this much about their grain, so that no family cuts along them (the
#               minimax of the families' band widths for turns about the grain: 1.41 : 1)


@dataclass(frozen=True)
class LayerModel:
    """normal (z, y, x) of planar layers, or axis (0, 1, 2 = x, y, z) and centre (the axis'
    two other volume coordinates, relative to the volume's centre) of rings; runs[k]: the
    exemplar's run lengths of phase k across the layers (px); transitions (K, K): which phase
    follows which; wobble: displacement amplitude (voxels); spacing: mean period (px)."""

    normal: np.ndarray | None
    axis: int
    centre: tuple
    runs: tuple
    transitions: np.ndarray
    wobble: float
    spacing: float
    extent: tuple = (0.0, 0.0)  # rings: the end exemplar's size (rows, cols), px
    tilt: float = 0.0  # one exemplar: degrees the layers were turned about their grain
    lightness: tuple = ()  # each phase's mean L*
    layouts: tuple = ()  # per family x, y, z: the segmentation (labels) of its exemplar

    @property
    def rings(self) -> bool:
        return self.normal is None


def stripe_direction(angle: float, family: int) -> np.ndarray:
    """The 3D direction (z, y, x) of a stripe at `angle` degrees (ccw from the image's x axis,
    rows down) in a slice of family 0, 1, 2 (normal to x: rows z, cols y; y: rows z, cols x;
    z: rows y, cols x)."""
    col, row = np.cos(np.radians(angle)), -np.sin(np.radians(angle))
    t = np.zeros(3)
    rows_dim, cols_dim = ((0, 1), (0, 2), (1, 2))[family]
    t[rows_dim], t[cols_dim] = row, col
    return t


def layer_normal(angles, weights) -> np.ndarray:
    """The unit normal (z, y, x) most nearly perpendicular to every family's stripe direction
    (angles[a] in degrees, None: no stripes in that family), weighted."""
    m = np.zeros((3, 3))
    for a, (angle, w) in enumerate(zip(angles, weights)):
        if angle is not None:
            t = stripe_direction(angle, a)
            m += w * np.outer(t, t)
    vals, vecs = np.linalg.eigh(m)
    n = vecs[:, 0]
    return n * (1 if n[np.argmax(np.abs(n))] > 0 else -1)


def face_spacings(normal) -> np.ndarray:
    """(3,) how much wider than their spacing along the normal (z, y, x) planar layers show
    on the slices normal to z, y and x: a plane with unit normal e_i cuts them in bands
    1 / sqrt(1 - n_i^2) times their spacing (inf when the slices run along the layers)."""
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    return 1.0 / np.sqrt(np.maximum(1.0 - n * n, 0.0) + 1e-300)


RANDOM_CUT_LOG_WIDTH = 1.0 - np.log(2.0)  # mean log band width of uniformly random cuts


def stereological_scale(normal) -> float:
    """The spacing along the normal, in the exemplar's spacing, that shows the exemplar's
    spacing on the cuts a user sees: the exemplar is itself a cut, so the mean log width of
    the bands on the three slice families (those that run along the layers, one flat band,
    left out) and, weighted alike, on uniformly random cuts (whose cosine c with the normal is
    uniform: mean log width -E[log(1 - c^2)] / 2 = 1 - log 2 over the spacing) is the
    exemplar's. As the n_i^2 sum to 1, some family shows at least 1 / sqrt(2/3) = 1.22 times
    the spacing and only normals near a cube diagonal show every family the same width."""
    widths = face_spacings(normal)
    faces = float(np.mean(np.log(widths[widths < 1e6])))
    return float(np.exp(-(faces + RANDOM_CUT_LOG_WIDTH) / 2))


def turned_normal(normal, grain, degrees: float) -> np.ndarray:
    """The unit normal (z, y, x) of layers turned `degrees` about their grain (a direction
    within them; made perpendicular to the normal), sign as layer_normal's."""
    grain = grain - (grain @ normal) * normal
    grain = grain / max(np.linalg.norm(grain), 1e-9)
    side = np.cross(grain, normal)
    turned = np.cos(np.radians(degrees)) * normal + np.sin(np.radians(degrees)) * side
    return turned * (1 if turned[np.argmax(np.abs(turned))] > 0 else -1)


def ring_centre(lum: np.ndarray, sigma: float = 2.0):
    """((row, col) of the point the stripes curve around, residual over the image size): the
    least-squares intersection of the lines through every pixel along its gradient (weighted
    by the local coherence); residual inf when the stripes are straight (no intersection)."""
    from osmap_cli.solid.structure.segment import gaussian_blur

    gy, gx = np.gradient(lum)
    j = gaussian_blur(np.stack([gx * gx, gy * gy, gx * gy], -1), sigma)
    jxx, jyy, jxy = j[..., 0], j[..., 1], j[..., 2]
    theta = 0.5 * np.arctan2(2 * jxy, jxx - jyy)  # gradient direction (x right, y down)
    w = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2)
    ux, uy = np.cos(theta), np.sin(theta)
    rows, cols = np.mgrid[0:lum.shape[0], 0:lum.shape[1]].astype(np.float64)
    # perpendicular of each line: (I - u u^T); solve sum w P c = sum w P p
    pxx, pyy, pxy = 1 - ux * ux, 1 - uy * uy, -ux * uy
    a = np.array([[np.sum(w * pyy), np.sum(w * pxy)], [np.sum(w * pxy), np.sum(w * pxx)]])
    b = np.array([np.sum(w * (pyy * rows + pxy * cols)), np.sum(w * (pxy * rows + pxx * cols))])
    if np.linalg.cond(a) > 1e4:
        return None, np.inf
    c = np.linalg.solve(a, b)
    dr, dc = rows - c[0], cols - c[1]
    off = dr * pyy * dr + 2 * dr * pxy * dc + dc * pxx * dc  # squared distance to each line
    residual = np.sqrt(np.sum(w * off) / np.sum(w)) / max(lum.shape)
    return (float(c[0]), float(c[1])), float(residual)


def runs_along(labels: np.ndarray, starts, step) -> list:
    """[(phase, length)] runs of labels along the lines from `starts` (rows, cols float arrays)
    in direction `step` (drow, dcol), nearest-pixel sampling; the first and last run of every
    line (cut by the image border) left out."""
    h, w = labels.shape
    out = []
    for r0, c0 in zip(*starts):
        t = np.arange(0, 2 * max(h, w))
        r = np.rint(r0 + t * step[0]).astype(int)
        c = np.rint(c0 + t * step[1]).astype(int)
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        if inside.sum() < 4:
            continue
        vals = labels[r[inside], c[inside]]
        change = np.flatnonzero(np.diff(vals)) + 1
        bounds = np.concatenate([[0], change, [len(vals)]])
        for i in range(1, len(bounds) - 2):
            out.append((int(vals[bounds[i]]), float(bounds[i + 1] - bounds[i])))
    return out


def run_statistics(runs, phases: int):
    """(run lengths per phase, transition matrix between consecutive phases)."""
    lengths = [np.array([n for k, n in runs if k == p] or [MIN_RUN]) for p in range(phases)]
    trans = np.ones((phases, phases)) * 1e-3
    np.fill_diagonal(trans, 0.0)
    for (k0, _), (k1, _) in zip(runs[:-1], runs[1:]):
        if k0 != k1:
            trans[k0, k1] += 1
    trans /= trans.sum(1, keepdims=True)
    return tuple(lengths), trans


def band_sequence(model: LayerModel, extent: float, seed: int):
    """(starts, phases): band boundaries along u covering [-extent, extent], sampled from the
    run lengths with the transition matrix (a Markov chain of phases)."""
    rng = np.random.default_rng(seed)
    k = len(model.runs)
    phase = int(rng.integers(k))
    u = -extent - float(rng.uniform(0, model.spacing))
    starts, phases = [], []
    while u < extent and len(starts) < MAX_CHAIN:
        starts.append(u)
        phases.append(phase)
        u += max(MIN_RUN, float(rng.choice(model.runs[phase])))
        phase = int(rng.choice(k, p=model.transitions[phase]))
    starts.append(u)
    return np.array(starts), np.array(phases, np.int64)


def periodic_normal(shape, normal, spacing: float):
    """(normal', period): the direction nearest `normal` (z, y, x) along which planar bands
    repeat across the faces of a volume of `shape`: u = normal' . x with normal'_d = k_d
    period / shape_d for whole numbers k_d, |normal'| = 1, so u grows by whole periods across
    each face. Of the wave numbers up to 4 per axis, the nearest direction whose period holds at
    least two spacings (else the longest period)."""
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    size = np.asarray(shape, np.float64)
    best, longest = None, None
    for k in np.ndindex(9, 9, 9):
        k = np.asarray(k, np.float64) - 4
        if not k.any():
            continue
        g = k / size
        period = 1.0 / np.linalg.norm(g)
        cos = float(g @ n) * period
        if cos <= 0:
            continue
        if period >= 2 * spacing and (best is None or cos > best[0] + 1e-12):
            best = (cos, g * period, period)
        if longest is None or period > longest[2] + 1e-9 or (
                abs(period - longest[2]) <= 1e-9 and cos > longest[0]):
            longest = (cos, g * period, period)
    _, direction, period = best if best is not None else longest
    return direction, float(period)


def periodic_bands(model, period: float, seed: int):
    """(starts, phases) of a band sequence (band_sequence) stretched to fill [0, period)
    exactly, to be read at u modulo the period."""
    starts, phases = band_sequence(model, period / 2, seed)
    starts = (starts - starts[0]) * period / max(starts[-1] - starts[0], 1e-9)
    return starts, phases


def band_index(starts, phases, u, period: float | None = None) -> np.ndarray:
    """The phase of the band every value of u falls in (u modulo `period` when given)."""
    if period is not None:
        u = np.mod(u, period)
    return phases[np.clip(np.searchsorted(starts, u, side="right") - 1, 0, len(phases) - 1)]


def layer_coordinate(shape, model: LayerModel, seed: int, wrap: bool):
    """(u float32 (Z, Y, X) at every voxel centre, displaced by the wobble; the period of the
    bands along u when they wrap (--tileable planar layers), else None)."""
    grids = np.meshgrid(*(np.arange(n, dtype=np.float32) + 0.5 - n / 2 for n in shape),
                        indexing="ij")
    period = None
    if model.rings:
        # the axis as far from the end face's centre as in the end exemplar, in proportion to
        # the face's size when it is smaller (a smaller face shows the exemplar's framing)
        dims = [d for d in range(3) if d != 2 - model.axis]
        k = [min(1.0, shape[d] / e) if e else 1.0 for d, e in zip(dims, model.extent)]
        u = np.hypot(grids[dims[0]] - k[0] * model.centre[0],
                     grids[dims[1]] - k[1] * model.centre[1])
    else:
        normal = model.normal
        if wrap:
            normal, period = periodic_normal(shape, normal, model.spacing)
        u = sum(float(normal[d]) * grids[d] for d in range(3))
    if model.wobble > 0:
        length = WOBBLE_LENGTH * model.spacing
        u = u + model.wobble * smooth_noise(shape, length, seed + 11, wrap)
    return u.astype(np.float32), period


def fitted_runs(model: LayerModel) -> np.ndarray:
    """(K,) each phase's mean band width along u that a volume holds: the chain's (runs of at
    least MIN_RUN) over FILL_WIDENING."""
    return np.array([float(np.mean(np.maximum(r, MIN_RUN))) for r in model.runs]) \
        / FILL_WIDENING


def layer_bands(shape, model: LayerModel, seed: int, wrap: bool) -> Bands:
    """The layers of a volume of `shape`: u at every voxel and the bands along it. A volume
    holds few bands, and how the few wide and narrow ones of a draw fall moves the scale each
    face shows by up to a sixth between seeds: of DRAWS draws of the chain, each with its
    widths within the volume fitted (layer_scale.fitted_sequence), the one whose faces read
    nearest FACE_SCALE times the exemplar's scale (the farthest face the nearest) is kept.
    Rings keep one draw as drawn; --tileable layers one draw stretched to their period."""
    u, period = layer_coordinate(shape, model, seed, wrap)
    if period is not None:
        return Bands(u, *periodic_bands(model, period, seed), period)
    if model.rings:
        return Bands(u, *band_sequence(model, float(np.abs(u).max()) + 2 * model.spacing, seed),
                     None)
    held = np.sort(u, axis=None).astype(np.float64)
    # drawn over more than the volume spans, so that bands narrowed about its centre still
    # cover it
    extent = ls.MAX_FIT * (float(np.abs(u).max()) + 2 * model.spacing)
    read = ls.face_reader(u, model.lightness, model.layouts) if model.layouts else None
    best = None
    for d in range(DRAWS if read else 1):
        starts, phases = band_sequence(model, extent, seed + DRAW_STEP * d)
        starts = ls.fitted_sequence(starts, phases, held, fitted_runs(model))
        miss = ls.worst_miss(read(starts, phases), FACE_SCALE) if read else 0.0
        if best is None or miss < best[0]:
            best = (miss, starts, phases)
    return Bands(u, best[1], best[2], None)


@dataclass(frozen=True)
class Bands:
    """Bands of a scalar field: u float32 (Z, Y, X); starts (B + 1,) the band boundaries along
    u and phases (B,) each band's phase; period: u is read modulo it (or None)."""

    u: np.ndarray
    starts: np.ndarray
    phases: np.ndarray
    period: float | None

    def labels(self) -> np.ndarray:
        """int64 (Z, Y, X): the phase of the band every voxel's centre falls in."""
        return band_index(self.starts, self.phases, self.u, self.period)

    def coverage(self, phases: int, sigma: float = COVERAGE) -> np.ndarray:
        """float32 (Z, Y, X, K): every phase's share of each voxel, from the signed distance of
        its centre to the nearest band boundaries measured along the field's gradient, through
        a smooth step as wide as a Gaussian of `sigma` voxels: the smooth boundaries blurred,
        where blurring the voxels' labels keeps their staircases along the grid."""
        grad = [np.gradient(self.u, axis=a) for a in range(3)]
        width = np.maximum(np.sqrt(sum(g * g for g in grad)), 1e-6) * sigma
        return band_shares(self.starts, self.phases, self.period, self.u, width, phases)


def wobble_amplitude(lum: np.ndarray, angle: float, spacing: float) -> float:
    """Voxels of displacement that give the exemplar's waviness: the local stripe angle's
    spread (radians, coherence-weighted) times the displacement's correlation length."""
    from osmap_cli.solid.structure.segment import gaussian_blur

    gy, gx = np.gradient(gaussian_blur(lum[..., None], max(1.0, spacing / 4))[..., 0])
    j = gaussian_blur(np.stack([gx * gx, gy * gy, gx * gy], -1), max(2.0, spacing / 2))
    jxx, jyy, jxy = j[..., 0], j[..., 1], j[..., 2]
    w = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2)
    local = 0.5 * np.arctan2(2 * jxy, jxx - jyy)
    mean = 0.5 * np.arctan2(np.sum(w * np.sin(2 * local)), np.sum(w * np.cos(2 * local)))
    dev = np.angle(np.exp(2j * (local - mean))) / 2
    spread = float(np.sqrt(np.sum(w * dev ** 2) / max(np.sum(w), 1e-12)))
    return float(np.tan(min(spread, 0.6)) * WOBBLE_LENGTH * spacing / np.sqrt(2))


def fit_layers(images, labels, analyses, ex_of_axis) -> LayerModel:
    """The layer model of the exemplars (images / labels / analyses: one per distinct
    exemplar; ex_of_axis: the exemplar of each slice family)."""
    from osmap_cli.solid.structure.segment import gaussian_blur, lab

    lums = [gaussian_blur(lab(im), 0.8)[..., 0] for im in images]
    layered = [an.kind == "layers" for an in analyses]
    if not any(layered):  # layers asked for (--structure layers): every exemplar's stripe angle
        layered = [True] * len(analyses)
    single = len(images) == 1
    phases = int(max(lb.max() for lb in labels)) + 1
    # rings: one family's exemplar curves around a centre, the others show straight stripes
    ring = None
    if not single:
        for a in range(3):
            e = int(ex_of_axis[a])
            centre, residual = ring_centre(lums[e])
            if centre is None or residual >= RING_FIT or analyses[e].coherence >= 0.85:
                continue
            # the other families show stripes along the axis (their straight cuts of the rings)
            axis_dir = np.zeros(3)
            axis_dir[2 - a] = 1.0
            if all(analyses[int(ex_of_axis[b])].coherence >= RING_SIDES
                   and abs(stripe_direction(analyses[int(ex_of_axis[b])].angle, b) @ axis_dir)
                   >= np.cos(np.radians(20)) for b in range(3) if b != a):
                ring = (a, centre)
                break
    runs = []
    if ring is not None:
        a, centre = ring
        e = int(ex_of_axis[a])
        lb = labels[e]
        h, w = lb.shape
        angles = np.linspace(0, 2 * np.pi, 90, endpoint=False)
        for t in angles:
            runs += runs_along(lb, (np.array([centre[0]]), np.array([centre[1]])),
                               (np.sin(t), np.cos(t)))
        normal, axis = None, a
        rel = (centre[0] - h / 2 + 0.5, centre[1] - w / 2 + 0.5)
    else:
        weights = [1.0, 1.0, 1e-3] if single else [1.0, 1.0, 1.0]
        angles = [analyses[int(ex_of_axis[a])].angle if layered[int(ex_of_axis[a])] else None
                  for a in range(3)]
        normal, axis, rel = layer_normal(angles, weights), -1, (0.0, 0.0)
        e = next(int(ex_of_axis[a]) for a in range(3) if angles[a] is not None)
        lb = labels[e]
        h, w = lb.shape
        ang = np.radians(analyses[e].angle)
        step = (np.cos(ang), np.sin(ang))  # across the stripes (rows down)
        along = np.linspace(-max(h, w), max(h, w), 4 * max(h, w))
        r0 = h / 2 - along * np.sin(ang) - step[0] * max(h, w)
        c0 = w / 2 + along * np.cos(ang) - step[1] * max(h, w)
        runs = runs_along(lb, (r0, c0), step)
        angle_ref, lum_ref = analyses[e].angle, lums[e]
    lengths, trans = run_statistics(runs, phases)
    spacing = float(sum(np.mean(x) for x in lengths))
    if ring is not None:
        # the waviness along the axis shows on the other families' straight stripes
        e = int(ex_of_axis[(ring[0] + 1) % 3])
        angle_ref, lum_ref = analyses[e].angle, lums[e]
    wobble = wobble_amplitude(lum_ref, angle_ref, spacing)
    tilt = 0.0
    if single and np.abs(normal).max() > np.cos(np.radians(PARALLEL)):
        # one exemplar shows the layers on every face, but layers along an axis would lie
        # parallel to one slice family (one flat band there): turned TILT degrees about their
        # grain (the side faces' stripe direction), two families show the exemplar's stripes
        # along its direction and the third (the end grain) straight stripes across it
        normal = turned_normal(normal, stripe_direction(analyses[0].angle, 1), TILT)
        tilt = TILT
    if single:
        # the exemplar is itself a cut: the bands (and their displacement) are made as thick
        # as gives the slice families the exemplar's spacing (`spacing` stays the spacing
        # the faces are fitted to show)
        thin = stereological_scale(normal)
        lengths = tuple(x * thin for x in lengths)
        wobble *= thin
    extent = labels[int(ex_of_axis[ring[0]])].shape if ring is not None else (0.0, 0.0)
    light = [np.concatenate([lab(im)[..., 0][lb == p] for im, lb in zip(images, labels)])
             for p in range(phases)]
    lightness = tuple(float(v.mean()) if len(v) else 0.0 for v in light)
    layouts = tuple(labels[int(ex_of_axis[a])] for a in range(3))
    return LayerModel(normal, axis, rel, lengths, trans, wobble, spacing,
                      tuple(float(v) for v in extent), tilt, lightness, layouts)

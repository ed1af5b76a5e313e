"""What structure an exemplar has, read from the image alone: particles (stones, chips, cells in
a matrix or separated by dark gaps), layers (wood grain, sediment: stripes along one direction),
veins (marble's swirled bands and veins: phases laid out in sheets that change little along
their course), a phase field (mottled regions of a few colours) or none of these (the slice
optimisation then synthesizes it).

>>> found = analyse(image)
>>> found.kind, found.report()
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from osmap_cli.solid.structure import measures
from osmap_cli.solid.structure.profiles import ProfileStats, profile_stats
from osmap_cli.solid.structure.segment import MAX_SAMPLES, Segmenter, gaussian_blur, kmeans, lab
from osmap_kernels.structure import label_components, split_touching

KINDS = ("particles", "layers", "veins", "field", "none")

NETWORK_RADIUS = 3  # disc of the black top-hat that finds dark gaps up to about 6 px wide
PERCOLATING = 0.7  # a matrix: its largest component holds at least this share of it
SPLIT_DYNAMIC = 1.5  # px: touching stones split where the neck is this much thinner
LAYER_COHERENCE = 0.45  # structure tensor, global: stripes run one way
LAYER_LOCAL = 0.85  # ... and locally
LATTICE = 0.35  # second autocorrelation peak (another direction): a lattice, not a material
# ... or of the dark network alone (black top-hat): mortar courses and a weave's gaps repeat
# even where the bricks' or strands' own colours vary too much for the image's peaks
# (bricks_dark_red 0.20-0.35, basket_weave_diagonal 0.19-0.22 at 64-128 px; stones, cells,
# veins, bark, tomatoes, caustics 0.11 or less at 32-128 px)
NETWORK_LATTICE = 0.16
MIN_PARTICLES = 8
MIN_SOLIDITY = 0.75
MIN_DIAMETER = 4.0  # px: finer structure is texture, left to the fill
MIN_EDGE = 1.4  # profile outlines lie on edges: their mean gradient over the image's
MAX_SPLIT = 0.12  # split lines may complete a gap network, not make most of it
PERIODIC = 0.2  # autocorrelation at the first peak across the stripes: a spacing worth naming
FIELD_SEPARATION = 1.3  # between-phase over within-phase colour spread for a phase field
# ... and this many times the spread of one Gaussian cloud of the exemplar's colours (their
# mean and covariance) cut into as many phases: a continuum of colours (shading, light on
# water) cut in two scores 1.2-1.3 by itself (water_caustics 1.01-1.08 times it at 64-128 px;
# tomatoes 1.29, bark 1.14-1.32, marble 1.34-1.38, mottled patches 4.0-4.2). Veins are also
# read from their layout (SHEETS); a phase field has only this to tell it from a cut continuum.
FIELD_OVER_CONTINUUM = 1.15
# a phase field is one Gaussian field cut at thresholds: only phases next to each other in its
# order meet (its cuts: none out of order). At most this share of the exemplar's phase
# boundary may join phases that are not (tomatoes at 128 px 0.15: stems on the fruit, out of
# the order gaps, fruit, highlights; marble, terrazzo, cells, mottled patches 0.006 or less)
OUT_OF_ORDER = 0.05
SHEETS = 0.55  # ... whose layout varies this much less along its local stripes than across
SHEET_LAG = 10.0  # px of the working resolution: the lag of that comparison
SHEET_SIGMA = 2.0  # px: the structure tensor's scale giving each pixel's local direction
# packed cells (a cell mosaic, cracked mud, foam: structure.cells) rather than packed stones:
# read through thin dark walls alone, covering most of the image, convex and of like sizes
# (samples/cells: fraction 0.74-0.79, solidity 0.90-0.92, 90th over 50th percentile diameter
# 1.11-1.17; gravel_green_stones: 0.72-0.73, 0.78-0.80, 1.35)
CELL_FRACTION = 0.6
CELL_SOLIDITY = 0.86
CELL_SPREAD = 1.25
PACKED_CELLS = "packed cells"  # the note that says so
WORKING_SIDE = 128  # smaller images are analysed enlarged to about this (the thresholds above
MAX_FACTOR = 4  # are in pixels of this resolution)


def working_factor(shape) -> int:
    """How many times a small image is enlarged before it is read."""
    return int(np.clip(np.ceil(WORKING_SIDE / max(min(shape[:2]), 1) - 0.25), 1, MAX_FACTOR))


def enlarge(image: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return image
    from osmap_cli.texture.pyramid import resize

    return resize(np.ascontiguousarray(image, np.float32), image.shape[0] * factor,
                  image.shape[1] * factor)


def reduce(labels: np.ndarray, factor: int) -> np.ndarray:
    """Labels of an enlarged image back at the original size (each pixel's centre sample)."""
    if factor == 1:
        return labels
    off = factor // 2
    return np.ascontiguousarray(labels[off::factor, off::factor])


@dataclass(frozen=True)
class Reader:
    """How phases and particle profiles are read from an image: the exemplar and, later, the
    slices of a volume are read alike (the profile meter)."""

    segmenter: Segmenter
    matrix: tuple = ()  # phases that form the matrix (particles: the other phases)
    network: float | None = None  # black top-hat threshold: darker gaps are matrix too
    split: bool = False  # touching profiles are separated (watershed of the distance map)
    factor: int = 1  # images are read enlarged this many times

    def phases(self, image: np.ndarray, wrap: bool = False) -> np.ndarray:
        """int64 (H, W): the phase of every pixel."""
        return reduce(self.segmenter.labels(enlarge(image, self.factor), wrap), self.factor)

    def particle_mask(self, image: np.ndarray, wrap: bool = False) -> np.ndarray:
        """bool (H, W): particle pixels (profiles' split lines excluded)."""
        return reduce(self._mask(enlarge(image, self.factor), wrap), self.factor)

    def profiles(self, image: np.ndarray, wrap: bool = False) -> ProfileStats:
        """The particle profiles' statistics, in pixels of `image`."""
        mask = self.working_mask(enlarge(image, self.factor), wrap)
        return profile_stats(mask.astype(np.int64), (1,), wrap).scaled(1.0 / self.factor)

    def working_mask(self, image: np.ndarray, wrap: bool = False) -> np.ndarray:
        """particle_mask of an image already enlarged `factor` times, at that size."""
        return self._mask(image, wrap)

    def _mask(self, image: np.ndarray, wrap: bool) -> np.ndarray:
        labels = self.segmenter.labels(image, wrap)
        mask = ~np.isin(labels, np.asarray(self.matrix, np.int64))
        if self.network is not None:
            lum = gaussian_blur(lab(image), self.segmenter.sigma, wrap)[..., 0]
            mask &= measures.black_tophat(lum, NETWORK_RADIUS, wrap) <= self.network
        if self.split:
            mask &= ~split_lines(mask, wrap)
        return mask


def reads_as_cells(found: Analysis) -> bool:
    """Whether particles found are packed cells: profiles outlined by the dark wall network
    alone (no colour phase as matrix), covering most of the image, convex, of like sizes."""
    p = found.profiles
    if found.kind != "particles" or p is None or found.reader.network is None \
            or found.reader.matrix or not len(p.diameters):
        return False
    q = p.quantiles()
    return (p.fraction >= CELL_FRACTION and p.solidity >= CELL_SOLIDITY
            and q[3] <= CELL_SPREAD * q[1])


def split_lines(mask: np.ndarray, wrap: bool = False) -> np.ndarray:
    """bool (H, W): watershed lines between touching profiles of `mask`."""
    dist = np.sqrt(measures.squared_distance(~mask, wrap))
    return split_touching(dist, mask, SPLIT_DYNAMIC, wrap)


@dataclass(frozen=True)
class Analysis:
    """What `analyse` found. labels: the phase of every exemplar pixel (particles: 0 matrix,
    1 particle); colours: mean exemplar colour per phase."""

    kind: str
    reader: Reader
    labels: np.ndarray
    colours: np.ndarray
    fractions: np.ndarray
    angle: float  # dominant stripe direction, degrees ccw from the image's x axis
    coherence: float
    local_coherence: float
    spacing: float  # layers: period along the normal (px); 0 when not periodic
    spacing_strength: float
    lattice: tuple
    profiles: ProfileStats | None = None  # in pixels of the enlarged image (reader.factor)
    notes: tuple = field(default=())
    sheetness: float | None = None  # phase layouts: variation along over across (veins: low)

    def report(self) -> list[str]:
        """Lines for --analyse and --verbose."""
        lines = [f"structure: {self.kind}" + (f" ({'; '.join(self.notes)})" if self.notes else "")]
        phases = ", ".join(f"{i}: {100 * f:.0f} % {_hex(c)}"
                           for i, (f, c) in enumerate(zip(self.fractions, self.colours)))
        lines.append(f"phases: {phases}")
        if self.profiles is not None:
            p = self.profiles.scaled(1.0 / self.reader.factor)
            q = p.quantiles()
            lines.append(f"particles: {p.count} profiles, area fraction {100 * p.fraction:.0f} %, "
                         f"diameter median {q[1]:.1f} px (quartiles {q[0]:.1f}-{q[2]:.1f}, "
                         f"90 % {q[3]:.1f}), solidity {p.solidity:.2f}, "
                         f"elongation {p.elongation:.2f}")
        lines.append(f"orientation: {self.angle:.0f} deg, coherence {self.coherence:.2f} "
                     f"(local {self.local_coherence:.2f})")
        if self.sheetness is not None:
            lines.append(f"sheets: the phases vary {self.sheetness:.2f} times as much along "
                         f"their local direction as across it (veins at {SHEETS} or less)")
        if self.spacing > 0 and (self.kind == "layers" or self.spacing_strength >= PERIODIC):
            lines.append(f"layer spacing: {self.spacing:.1f} px "
                         f"(autocorrelation {self.spacing_strength:.2f})")
        return lines

    def summary(self) -> dict:
        """A JSON-able record (provenance)."""
        out = {"kind": self.kind, "phases": [round(float(f), 4) for f in self.fractions],
               "orientation_deg": round(self.angle, 2), "coherence": round(self.coherence, 3)}
        if self.spacing > 0 and (self.kind == "layers" or self.spacing_strength >= PERIODIC):
            out["layer_spacing_px"] = round(self.spacing, 2)
        if self.sheetness is not None:
            out["sheetness"] = round(self.sheetness, 3)
        if self.kind == "none" and self.notes:  # why method osmap makes it
            out["reason"] = "; ".join(self.notes)
        if self.profiles is not None:
            scaled = self.profiles.scaled(1.0 / self.reader.factor)
            out["particles"] = {k: round(float(v), 4) for k, v in scaled.figures().items()}
            if PACKED_CELLS in self.notes:
                out["particles"]["packed_cells"] = True
        return out


def _hex(colour) -> str:
    c = np.clip(np.asarray(colour, np.float64)[:3], 0, 1)
    if len(c) < 3:
        c = np.repeat(c[:1], 3)
    return "#" + "".join(f"{int(round(v * 255)):02x}" for v in c)


def _particle_candidates(image, seg, labels, lum, tophat, wrap, factor):
    """(score, Reader, stats) for every way of reading the image as particles in a matrix: each
    colour phase as the matrix, with and without the dark gap network, and the network alone.
    A reading counts when the matrix (with the split lines) percolates, the profiles are many,
    compact and outlined by edges; the score prefers readings that explain more of the image
    with compact, well-outlined profiles."""
    gy, gx = np.gradient(lum)
    gradient = np.hypot(gy, gx)
    threshold = measures.otsu(tophat)
    gaps = tophat > threshold
    out = []
    options = [((m,), None) for m in range(len(seg.centres))]
    options += [((m,), threshold) for m in range(len(seg.centres))]
    options.append(((), threshold))
    for matrix, network in options:
        is_matrix = np.isin(labels, np.asarray(matrix, np.int64))
        if network is not None:
            is_matrix |= gaps
        if not is_matrix.any() or is_matrix.all():
            continue
        lines = split_lines(~is_matrix, wrap)
        full = is_matrix | lines
        ids, _ = label_components(np.where(full, 1, -1).astype(np.int64), True, wrap)
        share = np.bincount(ids[ids >= 0]).max() / full.sum()
        if share < PERCOLATING or lines.sum() > MAX_SPLIT * full.sum():
            continue
        mask = ~full
        stats = profile_stats(mask.astype(np.int64), (1,), wrap)
        edge = gradient[_outline(mask, wrap)].mean() / max(gradient.mean(), 1e-12)
        ok = (stats.count >= MIN_PARTICLES and stats.solidity >= MIN_SOLIDITY
              and stats.diameter_weighted >= MIN_DIAMETER and 0.05 <= stats.fraction <= 0.92
              and edge >= MIN_EDGE)
        if ok:
            out.append((stats.fraction * stats.solidity * edge,
                        Reader(seg, matrix, network, True, factor), stats))
    return out


def _outline(mask: np.ndarray, wrap: bool) -> np.ndarray:
    """bool: mask pixels with a 4-neighbour outside the mask."""
    pad = np.pad(mask, 1, mode="wrap" if wrap else "edge")
    inner = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    return mask & ~inner


def analyse(image: np.ndarray, wrap: bool = False, phases: int | None = None) -> Analysis:
    """The structure of one exemplar (float32 (H, W, C) in [0, 1]); a small exemplar is read
    enlarged (working_factor) and the figures given in its own pixels."""
    factor = working_factor(image.shape)
    original = image
    image = enlarge(image, factor)
    seg = Segmenter.fit(image, phases, wrap)
    labels = seg.labels(image, wrap)
    lum = gaussian_blur(lab(image), seg.sigma, wrap)[..., 0]
    angle, coherence, local = measures.structure_tensor(lum, wrap)
    ac = measures.autocorrelation(lum)
    reach = min(lum.shape) // 2
    spacing, strength = measures.first_peak(measures.along(ac, angle + 90.0, reach))
    lattice = measures.lattice_strength(ac)
    tophat = measures.black_tophat(lum, NETWORK_RADIUS, wrap)
    network = measures.lattice_strength(measures.autocorrelation(tophat))
    k = len(seg.centres)
    fractions = np.bincount(labels.ravel(), minlength=k) / labels.size
    colours = np.array([image[labels == i].mean(0) if (labels == i).any()
                        else np.zeros(image.shape[2]) for i in range(k)])
    common = dict(colours=colours, fractions=fractions, angle=angle, coherence=coherence,
                  local_coherence=local, spacing=spacing / factor, spacing_strength=strength,
                  lattice=lattice)
    plain = Reader(seg, factor=factor)
    small = reduce(labels, factor)
    if coherence >= LAYER_COHERENCE and local >= LAYER_LOCAL:
        return Analysis("layers", plain, small, **common)
    if lattice[1] >= LATTICE:
        return Analysis("none", plain, small, notes=("a regular lattice",), **common)
    if network[1] >= NETWORK_LATTICE:
        return Analysis("none", plain, small, notes=("a regular lattice of dark gaps",),
                        **common)
    candidates = _particle_candidates(image, seg, labels, lum, tophat, wrap, factor)
    if candidates:
        _, reader, stats = max(candidates, key=lambda c: c[0])
        mask = reader.particle_mask(original, wrap)
        found = Analysis("particles", reader, mask.astype(np.int64),
                         **{**common, "colours": _mask_colours(original, mask),
                            "fractions": np.array([1 - mask.mean(), mask.mean()])},
                         profiles=stats)
        return replace(found, notes=(PACKED_CELLS,)) if reads_as_cells(found) else found
    feats = lab(image)
    separation = _separation(feats, labels)
    if separation >= FIELD_SEPARATION:
        sheetness = sheet_ratio(image, labels)
        if sheetness <= SHEETS:
            return Analysis("veins", plain, small, sheetness=sheetness, **common)
        if separation < FIELD_OVER_CONTINUUM * continuum_separation(feats, k):
            why = "phases no more distinct than a continuum of colours"
        elif out_of_order(labels, k) > OUT_OF_ORDER:
            why = "phases that meet out of any one order: no phase field"
        else:
            return Analysis("field", plain, small, sheetness=sheetness, **common)
        return Analysis("none", plain, small, sheetness=sheetness, notes=(why,), **common)
    return Analysis("none", plain, small, notes=("no separable phases",), **common)


def _mask_colours(image, mask):
    return np.array([image[~mask].mean(0) if (~mask).any() else np.zeros(image.shape[2]),
                     image[mask].mean(0) if mask.any() else np.zeros(image.shape[2])])


def _separation(feats: np.ndarray, labels: np.ndarray) -> float:
    """Spread of the phase centres over the mean spread within the phases (CIELAB)."""
    flat = feats.reshape(-1, feats.shape[2])
    lab_ = labels.ravel()
    centres = np.array([flat[lab_ == i].mean(0) for i in range(lab_.max() + 1)])
    within = np.sqrt(np.mean([((flat[lab_ == i] - centres[i]) ** 2).sum(1).mean()
                              for i in range(len(centres))]))
    between = np.sqrt(((centres - flat.mean(0)) ** 2).sum(1).mean())
    return float(between / max(within, 1e-9))


def continuum_separation(feats: np.ndarray, k: int, seed: int = 0) -> float:
    """_separation of k phases clustered (as Segmenter.fit does) in one Gaussian cloud with
    the mean and covariance of `feats` (H, W, F): what cutting a continuum of colours scores."""
    flat = feats.reshape(-1, feats.shape[2])
    cov = np.atleast_2d(np.cov(flat.T))
    cov = cov + np.eye(len(cov)) * 1e-9 * max(float(np.trace(cov)), 1e-12)
    # a Cholesky factor is unique (an SVD's signs are not): the same cloud on every machine
    normal = np.random.default_rng(seed).standard_normal((MAX_SAMPLES, len(cov)))
    cloud = flat.mean(0) + normal @ np.linalg.cholesky(cov).T
    centres, _ = kmeans(cloud, k, seed)
    labels = ((cloud[:, None, :] - centres[None]) ** 2).sum(2).argmin(1)
    if len(np.unique(labels)) < k:
        return float("inf")
    return _separation(cloud[:, None, :], labels[:, None])


def out_of_order(labels: np.ndarray, k: int) -> float:
    """The share of the phase boundary (4-neighbour pairs) between phases that are not next
    to each other in the phase field's order (field.phase_order)."""
    from osmap_cli.solid.structure.field import phase_order

    adj = np.zeros((k, k))
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1], labels[1:])):
        diff = a != b
        np.add.at(adj, (a[diff], b[diff]), 1)
    adj = adj + adj.T
    order = phase_order(labels, k)
    inside = sum(adj[order[i], order[i + 1]] for i in range(k - 1))
    return float(1.0 - inside / max(adj.sum() / 2, 1.0))


def sheet_ratio(image: np.ndarray, labels: np.ndarray, wrap: bool = False) -> float:
    """How much the phases' layout (field.latent) changes SHEET_LAG px along each pixel's local
    stripe direction over how much it changes as far across it (mean squares): veins and
    swirled bands, sheets in 3D, change little along their course; blobs and patches change
    alike both ways."""
    from osmap_cli.solid.structure.field import latent, phase_order

    z = latent(image, labels, phase_order(labels, int(labels.max()) + 1), wrap)
    feats = gaussian_blur(lab(image), 1.0, wrap)
    jxx = jyy = jxy = 0.0
    for c in range(feats.shape[2]):
        gy, gx = np.gradient(feats[..., c])
        jxx, jyy, jxy = jxx + gx * gx, jyy + gy * gy, jxy + gx * gy
    j = gaussian_blur(np.stack([jxx, jyy, jxy], -1), SHEET_SIGMA, wrap)
    theta = 0.5 * np.arctan2(2 * j[..., 2], j[..., 0] - j[..., 1])  # across (x right, y down)
    nx, ny = np.cos(theta), np.sin(theta)
    rows, cols = np.mgrid[0:z.shape[0], 0:z.shape[1]].astype(np.float64)
    m = int(np.ceil(SHEET_LAG)) + 1
    inner = (slice(m, -m), slice(m, -m)) if min(z.shape) > 4 * m else (slice(None),) * 2
    lag = SHEET_LAG
    across = (_bilinear(z, rows + lag * ny, cols + lag * nx, wrap) - z)[inner]
    along = (_bilinear(z, rows + lag * nx, cols - lag * ny, wrap) - z)[inner]
    return float(np.mean(along ** 2) / max(np.mean(across ** 2), 1e-12))


def _bilinear(img: np.ndarray, r: np.ndarray, c: np.ndarray, wrap: bool) -> np.ndarray:
    h, w = img.shape
    if wrap:
        r, c = r % h, c % w
    else:
        r, c = np.clip(r, 0, h - 1.001), np.clip(c, 0, w - 1.001)
    r0, c0 = np.floor(r).astype(int), np.floor(c).astype(int)
    fr, fc = r - r0, c - c0
    r1, c1 = (r0 + 1) % h, (c0 + 1) % w
    return ((1 - fr) * (1 - fc) * img[r0, c0] + (1 - fr) * fc * img[r0, c1]
            + fr * (1 - fc) * img[r1, c0] + fr * fc * img[r1, c1])

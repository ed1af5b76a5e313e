"""Phase fields in 3D (marble, mottled and veined stone): a truncated Gaussian field. A smooth
3D Gaussian field is cut at thresholds into the exemplar's phases, in the order in which the
phases neighbour each other in the exemplar (a phase met between two others becomes the sheet
between them: a vein), at the exemplar's area fractions.

The field's covariance is the exemplar's: its colours are mapped to one latent value (the
position along the ordered phase colours), Gaussianised, and the autocorrelation of that image
is the covariance of every planar cut of an isotropic 3D field with the same covariance
function. Stripes give the field an anisotropy: correlation lengthened within sheets whose
normal follows the stripes as in osmap_cli.solid.structure.layers. One round of build, cut and
measure corrects the scale on the phase-boundary density of the cuts.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from statistics import NormalDist

import numpy as np

from osmap_cli.solid.structure.layers import layer_normal
from osmap_cli.solid.structure.noise import spectral_field
from osmap_cli.solid.structure.segment import gaussian_blur, lab
from osmap_cli.solid.structure.slices import axis_slices

MAX_ANISOTROPY = 4.0
FIT_ROUNDS = 3
LATENT_SIGMA = 2.0  # px: the phases' layout, not the texture inside them, sets the covariance
PROBE = 64


@dataclass(frozen=True)
class FieldModel:
    """order: the phases along the latent value; cuts: the thresholds (Gaussian quantiles);
    profile: the latent autocorrelation against the lag s (px, across the stripes), s = 0, 1,
    ...; normal (z, y, x) and anisotropy (correlation length within the sheets over across);
    scale: lag multiplier (fitted)."""

    order: tuple
    cuts: np.ndarray
    profile: np.ndarray
    normal: np.ndarray
    anisotropy: float
    scale: float = 1.0
    boundary: float = 0.0  # the exemplar's phase-boundary density (cut pairs per pixel pair)


def phase_order(labels: np.ndarray, phases: int) -> tuple:
    """The order of the phases that puts the most boundary between neighbours in the order."""
    adj = np.zeros((phases, phases))
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1], labels[1:])):
        diff = a != b
        np.add.at(adj, (a[diff], b[diff]), 1)
    adj = adj + adj.T
    best = max(itertools.permutations(range(phases)),
               key=lambda p: (sum(adj[p[i], p[i + 1]] for i in range(phases - 1)), -p[0]))
    return tuple(int(v) for v in best)


def latent(image: np.ndarray, labels: np.ndarray, order, wrap: bool = False) -> np.ndarray:
    """float64 (H, W): the phases' rank in `order` at every pixel, smoothed (the layout of the
    phases, not the texture inside them), ties broken by the colour's position along the
    ordered phase colours; Gaussianised by rank."""
    rank = np.empty(int(labels.max()) + 1)
    rank[list(order)] = np.arange(len(order))
    smooth = gaussian_blur(rank[labels][..., None], LATENT_SIGMA, wrap)[..., 0]
    feats = gaussian_blur(lab(image), 0.8, wrap)
    flat = feats.reshape(-1, feats.shape[2])
    centres = np.array([flat[labels.ravel() == k].mean(0) for k in order])
    axis = centres[-1] - centres[0]
    tie = flat @ axis / max(float(axis @ axis), 1e-9)
    pos = smooth.ravel() + 1e-3 * (tie - tie.min()) / max(np.ptp(tie), 1e-9)
    ranks = np.argsort(np.argsort(pos, kind="stable"), kind="stable")
    nd = NormalDist()
    z = np.array([nd.inv_cdf((r + 0.5) / len(ranks)) for r in range(len(ranks))])[ranks]
    return z.reshape(labels.shape)


def boundary_density(labels: np.ndarray) -> float:
    """The share of 4-neighbour pixel pairs that cross a phase boundary."""
    a = (labels[:, :-1] != labels[:, 1:]).mean()
    b = (labels[:-1] != labels[1:]).mean()
    return float((a + b) / 2)


def _lengths(ac: np.ndarray, angle: float) -> tuple[float, float]:
    """Lags (px) where the autocorrelation first falls to 1/2 along the stripes and across."""
    from osmap_cli.solid.structure.measures import along

    reach = min(ac.shape) // 2
    out = []
    for a in (angle, angle + 90.0):
        prof = along(ac, a, reach)
        below = np.flatnonzero(prof < 0.5)
        out.append(float(below[0]) if len(below) else float(reach))
    return out[0], out[1]


def fit_field(images, labels, analyses, ex_of_axis, seed: int) -> FieldModel:
    """The field model of the exemplars (one entry per distinct exemplar)."""
    from osmap_cli.solid.structure.measures import autocorrelation

    phases = int(max(lb.max() for lb in labels)) + 1
    joint = np.concatenate([lb.ravel() for lb in labels])
    order = phase_order(labels[0], phases) if len(labels) == 1 else phase_order(
        np.concatenate(labels, 1), phases)
    fractions = np.array([np.mean(joint == k) for k in order])
    nd = NormalDist()
    cuts = np.array([nd.inv_cdf(float(c)) for c in np.clip(np.cumsum(fractions)[:-1],
                                                            1e-4, 1 - 1e-4)])
    # covariance profile across the stripes of the first exemplar (the others alike)
    image, lb, an = images[0], labels[0], analyses[0]
    z = latent(image, lb, order)
    ac = autocorrelation(z)
    along_len, across_len = _lengths(ac, an.angle)
    ratio = float(np.clip(along_len / max(across_len, 1e-6), 1.0, MAX_ANISOTROPY))
    if an.coherence < 0.1:
        ratio = 1.0
    h, w = ac.shape
    yy, xx = np.mgrid[0:h, 0:w]
    dy, dx = -(yy - h // 2), xx - w // 2  # up, right
    ang = np.radians(an.angle)
    t = dx * np.cos(ang) + dy * np.sin(ang)
    nrm = -dx * np.sin(ang) + dy * np.cos(ang)
    s = np.sqrt(nrm ** 2 + (t / ratio) ** 2)
    reach = min(h, w) // 2
    bins = np.rint(s).astype(int)
    keep = bins < reach
    sums = np.bincount(bins[keep], ac[keep], reach)
    counts = np.maximum(np.bincount(bins[keep], None, reach), 1)
    profile = sums / counts
    if len(images) == 1:
        angles, weights = [an.angle] * 3, [1.0, 1.0, 1e-3]
    else:
        angles = [analyses[int(ex_of_axis[a])].angle for a in range(3)]
        weights = [max(analyses[int(ex_of_axis[a])].coherence, 1e-3) for a in range(3)]
    model = FieldModel(tuple(order), cuts, profile, layer_normal(angles, weights), ratio,
                       boundary=float(np.mean([boundary_density(x) for x in labels])))
    for _ in range(FIT_ROUNDS):
        probe = build_field((PROBE,) * 3, model, seed, True)
        got = np.mean([boundary_density(c) for _, _, c in axis_slices(probe, 4)])
        model = replace(model, scale=model.scale * float(np.clip(got / model.boundary,
                                                                 0.5, 2.0)))
    return model


def nnls(a: np.ndarray, b: np.ndarray, iterations: int = 3000) -> np.ndarray:
    """Non-negative least squares min |a x - b|, x >= 0 (projected gradient; small systems)."""
    step = 1.0 / max(np.linalg.norm(a, 2) ** 2, 1e-12)
    x = np.zeros(a.shape[1])
    for _ in range(iterations):
        x = np.maximum(x - step * (a.T @ (a @ x - b)), 0.0)
    return x


def gaussian_mixture(profile: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(weights, lengths): non-negative Gaussian covariances sum w exp(-s^2 / 2 l^2) fitted to
    the profile; positive definite in 3D as in 2D (a measured 2D profile need not be)."""
    s = np.arange(len(profile), dtype=np.float64)
    lengths = 0.5 * 1.4 ** np.arange(int(np.log(max(len(profile), 2) / 0.5) / np.log(1.4)) + 1)
    basis = np.exp(-s[:, None] ** 2 / (2 * lengths[None] ** 2))
    return nnls(basis, profile), lengths


def build_field(shape, model: FieldModel, seed: int, wrap: bool) -> np.ndarray:
    """int64 (Z, Y, X): the phase of every voxel (periodic; without wrap the field is made
    on a box a correlation length larger and cropped)."""
    weights, lengths = gaussian_mixture(model.profile)
    lengths = lengths * model.scale
    pad = 0 if wrap else int(min(2 * float(np.average(lengths, weights=weights + 1e-12)), 48))
    big = tuple(n + 2 * pad for n in shape)
    n = model.normal
    a = model.anisotropy

    def amplitude(kz, ky, kx):
        across = n[0] * kz + n[1] * ky + n[2] * kx
        within2 = np.maximum(kz * kz + ky * ky + kx * kx - across ** 2, 0.0)
        # the covariance stretched a times within the sheets: its spectrum a^2 narrower there
        k2 = across ** 2 + within2 * a * a
        power = sum(w * (a * a) * (2 * np.pi * ell * ell) ** 1.5
                    * np.exp(-2 * np.pi ** 2 * ell * ell * k2) for w, ell in zip(weights, lengths))
        return np.sqrt(power)

    field = spectral_field(big, amplitude, seed)
    if pad:
        field = field[pad:pad + shape[0], pad:pad + shape[1], pad:pad + shape[2]]
    idx = np.searchsorted(model.cuts, field)
    return np.asarray(model.order, np.int64)[idx]

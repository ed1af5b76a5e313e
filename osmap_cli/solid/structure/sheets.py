"""Veins in 3D (swirled marble, agate, onyx, furrowed bark): continuous sheets, the level sets of
one smooth scalar field, as Perlin's marble: u = n . x + A turbulence(x). Along u the phases
follow each other as bands, so every phase is a sheet, the set between two level values of one
continuous field: it thins and folds but does not break off (closed pockets form only around
the rare extremes of u), and every cut through the volume shows the bands as continuous curves.

Fitted to the exemplar:
- the order of the bands and each band's thickness: the phases' run lengths along lines across
  the exemplar (rows, columns, both diagonals) and which phase follows which, sampled as a Markov
  chain (osmap_cli.solid.structure.layers.band_sequence);
- the spacing: one scale on all band thicknesses, corrected by build, cut and measure until the
  cuts show the exemplar's density of phase boundaries (lines cross sheets obliquely, so runs
  are longer than the sheets are thick);
- the perturbation: fBm (three octaves) with a correlation length of WARP_LENGTH spacings, read
  at positions displaced by a vector fBm, with the least amplitude whose cuts' global
  orientation coherence is (within COHERENCE_TOLERANCE of) the best match to the exemplar's (a
  stronger perturbation swirls the sheets more);
- the dominant orientation: the sheets' mean normal, perpendicular to the exemplar's dominant
  stripe direction as layers' normals are (one family shows the mirrored diagonal:
  docs/solid.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from osmap_cli.solid.structure import layers as ly
from osmap_cli.solid.structure.field import boundary_density
from osmap_cli.solid.structure.noise import PeriodicNoise
from osmap_cli.solid.structure.slices import axis_slices

WARP_LENGTH = 2.5  # the perturbation's correlation length, in band spacings
OCTAVES = 3
SWIRL = 0.6  # the displacement of the positions the perturbation is read at, x warp length
GAIN = 0.5  # each octave half the length and half the amplitude of the one before
AMPLITUDES = (0.1, 0.2, 0.3, 0.45, 0.6)  # perturbation tried, x the warp length
COHERENCE_TOLERANCE = 0.05  # the least perturbation this near the best fit is kept
PROBE = 48  # the probe volume's side at most (else the exemplar's)
PROBE_BANDS = 4.0  # band spacings the probe holds (at the exemplar's run lengths)
SCALE_ROUNDS = 3
CHAINS = 12  # band sequences tried: the one whose volume fractions are the exemplar's
LINE_DIRECTIONS = (0.0, 45.0, 90.0, 135.0)  # degrees: lines whose runs give the bands
DIAGONAL = np.array([1.0, -1.0, -1.0]) / np.sqrt(3.0)  # normal when the exemplar has no
#                                                         dominant direction


@dataclass(frozen=True)
class SheetModel:
    """normal (z, y, x): the sheets' mean normal; runs[k]: phase k's run lengths across the
    exemplar (px); transitions (K, K): which phase follows which; spacing: mean period (px);
    scale: run-length multiplier (fitted); amplitude: the perturbation, in warp lengths
    (fitted); boundary, coherence, fractions: the exemplar's boundary density, orientation
    coherence and phase fractions (the fit's targets)."""

    normal: np.ndarray
    runs: tuple
    transitions: np.ndarray
    spacing: float
    scale: float = 1.0
    amplitude: float = 0.3
    boundary: float = 0.0
    coherence: float = 0.0
    fractions: np.ndarray | None = None  # the exemplar's phase fractions

    @property
    def warp_length(self) -> float:
        return WARP_LENGTH * self.spacing


def sheet_coordinate(shape, model: SheetModel, seed: int, wrap: bool):
    """(u float32 (Z, Y, X) at every voxel centre: voxels along the normal, plus fBm read at
    positions displaced by a vector fBm (a warped turbulence: the sheets fold and swirl where a
    plain perturbation would close into rings around its extremes); with wrap the period of the
    bands along u, else None: the normal is then the nearest along which they wrap)."""
    grids = np.stack(np.meshgrid(*(np.arange(n, dtype=np.float32) + 0.5 for n in shape),
                                 indexing="ij"), -1)
    centred = grids - np.asarray(shape, np.float32) / 2
    normal, period = model.normal, None
    if wrap:
        normal, period = ly.periodic_normal(shape, normal, model.spacing * model.scale)
    u = centred @ np.asarray(normal, np.float32)
    if model.amplitude <= 0:
        return u.astype(np.float32), period
    # periodic noise cannot be correlated over more than the box
    length = min(model.warp_length, min(shape) / 2) if wrap else model.warp_length
    box = shape if wrap else tuple(n + int(4 * length) for n in shape)
    warp = np.stack([_fbm(grids, box, length, seed + 31 + 7 * d, 2) for d in range(3)], -1)
    u = u + model.amplitude * length * _fbm(grids + SWIRL * length * warp, box, length,
                                            seed + 17, OCTAVES)
    return u.astype(np.float32), period


def sheet_normals(u: np.ndarray, period: float | None = None) -> np.ndarray:
    """float32 (Z, Y, X, 3): the unit normal (z, y, x) of the sheets through every voxel, the
    direction of u's gradient (central differences). With a period (tileable bands: u grows by
    whole periods across each face) the differences wrap, read modulo the period."""
    u = u.astype(np.float64)
    if period is None:
        grad = np.stack(np.gradient(u), -1)
    else:
        steps = [np.roll(u, -1, a) - np.roll(u, 1, a) for a in range(3)]
        grad = np.stack([(d - period * np.round(d / period)) / 2 for d in steps], -1)
    length = np.linalg.norm(grad, axis=-1, keepdims=True)
    return (grad / np.maximum(length, 1e-12)).astype(np.float32)


def _fbm(points, period, length: float, seed: int, octaves: int) -> np.ndarray:
    """Fractional Brownian motion (octaves of PeriodicNoise) read at points (..., 3)."""
    out = np.zeros(points.shape[:-1], np.float32)
    weight = 1.0
    for octave in range(octaves):
        out += weight * PeriodicNoise(period, length, seed + octave).at(points)
        length *= GAIN
        weight *= GAIN
    return out


def sheet_bands(shape, model: SheetModel, seed: int, wrap: bool) -> ly.Bands:
    """The sheets of a volume of `shape`: u at every voxel and the bands along it. A volume
    holds few bands, so of CHAINS band sequences the one whose phase fractions in this volume
    are nearest the exemplar's is kept. With wrap the bands repeat across the faces (a sequence
    stretched to the period along u, the normal the nearest that wraps: sheet_coordinate)."""
    u, period = sheet_coordinate(shape, model, seed, wrap)
    scaled = replace(model, runs=tuple(r * model.scale for r in model.runs),
                     spacing=model.spacing * model.scale)
    extent = float(np.abs(u).max()) + 2 * scaled.spacing
    sample = u.ravel()[::7]
    k = len(model.runs)
    best = None
    for chain in range(CHAINS if model.fractions is not None else 1):
        if period is None:
            bands = ly.band_sequence(scaled, extent, seed + 1000 * chain)
        else:
            bands = ly.periodic_bands(scaled, period, seed + 1000 * chain)
        if model.fractions is None:
            best = (0.0, bands)
            break
        got = np.bincount(ly.band_index(*bands, sample, period), minlength=k) / len(sample)
        err = float(np.abs(got - model.fractions).sum())
        if best is None or err < best[0]:
            best = (err, bands)
    return ly.Bands(u, *best[1], period)


def build_sheets(shape, model: SheetModel, seed: int, wrap: bool) -> np.ndarray:
    """int64 (Z, Y, X): the phase of every voxel (the band of u it falls in: sheet_bands)."""
    return sheet_bands(shape, model, seed, wrap).labels()


def label_coherence(labels: np.ndarray) -> float:
    """The global orientation coherence (structure tensor) of a label image's boundaries."""
    from osmap_cli.solid.structure.segment import gaussian_blur

    k = int(labels.max()) + 1
    onehot = (labels[..., None] == np.arange(k)).astype(np.float64)
    smooth = gaussian_blur(onehot, 1.0)
    gy, gx = np.gradient(smooth, axis=(0, 1))
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    return float(np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) / max(jxx + jyy, 1e-12))


def _cuts(volume: np.ndarray):
    return [c for _, _, c in axis_slices(volume, 3)]


def sheet_runs(labels: np.ndarray) -> list:
    """[(phase, length)] along lines at LINE_DIRECTIONS across the whole image."""
    h, w = labels.shape
    runs = []
    size = max(h, w)
    for deg in LINE_DIRECTIONS:
        ang = np.radians(deg)
        step = (-np.sin(ang), np.cos(ang))  # rows down
        across = np.linspace(-size, size, 2 * size)
        r0 = h / 2 + across * np.cos(ang) - step[0] * size
        c0 = w / 2 + across * np.sin(ang) - step[1] * size
        runs += ly.runs_along(labels, (r0, c0), step)
    return runs


def fit_sheets(labels, analyses, ex_of_axis, seed: int) -> SheetModel:
    """The sheet model of the exemplars (labels / analyses: one per distinct exemplar;
    ex_of_axis: the exemplar of each slice family)."""
    phases = int(max(lb.max() for lb in labels)) + 1
    runs = [r for lb in labels for r in sheet_runs(lb)]
    lengths, trans = ly.run_statistics(runs, phases)
    spacing = float(sum(np.mean(x) for x in lengths))
    if len(labels) == 1:
        angles, weights = [analyses[0].angle] * 3, [1.0, 1.0, 1e-3]
    else:
        angles = [analyses[int(ex_of_axis[a])].angle for a in range(3)]
        weights = [max(analyses[int(ex_of_axis[a])].coherence, 1e-3) for a in range(3)]
    if max(a.coherence for a in analyses) < 0.05:
        normal = DIAGONAL
    else:
        normal = ly.layer_normal(angles, weights)
    joint = np.concatenate([lb.ravel() for lb in labels])
    model = SheetModel(normal, lengths, trans, spacing,
                       boundary=float(np.mean([boundary_density(x) for x in labels])),
                       coherence=float(np.mean([label_coherence(x) for x in labels])),
                       fractions=np.bincount(joint, minlength=phases) / len(joint))
    side = min(PROBE, min(min(lb.shape) for lb in labels))
    # the probe holds PROBE_BANDS spacings: fitted on the model shrunk by `factor` (its
    # boundary density grows by it) and grown back; a probe narrower than the bands sees
    # one or two of them, and their boundary density says little
    factor = max(1.0, PROBE_BANDS * spacing / side)
    small = replace(model, runs=tuple(r / factor for r in lengths), spacing=spacing / factor,
                    boundary=model.boundary * factor)
    fitted = fit_perturbation(small, seed, side)
    return replace(fitted, runs=lengths, spacing=spacing, boundary=model.boundary)


def fit_perturbation(model: SheetModel, seed: int, side: int = PROBE) -> SheetModel:
    """The amplitude whose cuts have the exemplar's orientation coherence (the least of
    AMPLITUDES within COHERENCE_TOLERANCE of the best: swirl beyond what the exemplar shows is
    not added) and the scale whose cuts have its boundary density, on a probe volume."""
    shape = (side,) * 3
    model = _fit_scale(model, shape, seed)
    trials = []
    for a in AMPLITUDES:
        trial = _fit_scale(replace(model, amplitude=a), shape, seed)
        cuts = _cuts(build_sheets(shape, trial, seed, False))
        trials.append((abs(float(np.mean([label_coherence(c) for c in cuts]))
                           - model.coherence), trial))
    least = min(err for err, _ in trials)
    model = next(trial for err, trial in trials if err <= least + COHERENCE_TOLERANCE)
    for _ in range(SCALE_ROUNDS - 1):
        model = _fit_scale(model, shape, seed)
    return model


def _fit_scale(model: SheetModel, shape, seed: int) -> SheetModel:
    probe = build_sheets(shape, model, seed, False)
    got = float(np.mean([boundary_density(c) for c in _cuts(probe)]))
    if got <= 0 or model.boundary <= 0:
        return model
    return replace(model, scale=model.scale * float(np.clip(got / model.boundary, 0.5, 2.0)))

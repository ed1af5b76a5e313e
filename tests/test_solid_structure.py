"""`osmap solid --method structure` (the default): what the analysis reads from shipped samples,
the structure kernels, and guards on the structure of the volumes it makes: a particle exemplar
keeps its profile sizes and shapes, a layered one its spacing, the wood set's end face its
rings, with thresholds the slice optimisation alone (method osmap) fails. Small volumes, fast
quality: a few seconds each."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from osmap_cli.imageio import read_image, write_image
from osmap_cli.solid import SolidOptions, synthesize_solid
from osmap_cli.solid.structure import measures
from osmap_cli.solid.structure import particles as pt
from osmap_cli.solid.structure.analysis import Reader, analyse, split_lines
from osmap_cli.solid.structure.fill import match_phases, match_regions
from osmap_cli.solid.structure.layers import ring_centre
from osmap_cli.solid.structure.meter import diagonal_cuts, profile_meter
from osmap_cli.solid.structure.method import build_structure, plan
from osmap_cli.solid.structure.particle_colour import match_particles
from osmap_cli.solid.structure.profiles import ProfileStats
from osmap_cli.solid.structure.segment import Segmenter, lab
from osmap_cli.solid.volumeio import read_volume
from osmap_kernels.structure import label_components, place_spheres


@pytest.fixture(scope="module")
def cells64(samples):
    """samples/cells.png at 64 px: Voronoi cells with dark borders."""
    return read_image(samples / "cells.png").pixels[::2, ::2].copy()


@pytest.fixture(scope="module")
def wood(samples):
    """The end, side and top cuts of one log (samples/README.md)."""
    return [read_image(samples / f"wood_{n}.png").pixels for n in ("end", "side", "top")]


def _period_along_rows(image) -> tuple[float, float]:
    """(period in rows, autocorrelation there) of an image's lightness."""
    ac = measures.autocorrelation(lab(image)[..., 0])
    return measures.first_peak(measures.along(ac, 90.0, image.shape[0] // 2))


# --- kernels -----------------------------------------------------------------------------


def test_distance_transform_is_exact_and_wraps():
    rng = np.random.default_rng(0)
    feats = rng.random((9, 11, 7)) < 0.05
    got = measures.squared_distance(feats)
    pts = np.argwhere(feats)
    grid = np.stack(np.meshgrid(*(np.arange(n) for n in feats.shape), indexing="ij"), -1)
    brute = ((grid[..., None, :] - pts) ** 2).sum(-1).min(-1)
    assert np.array_equal(got, brute)
    line = np.zeros((1, 10), bool)
    line[0, 0] = True
    assert measures.squared_distance(line, wrap=True)[0, 9] == 1.0  # across the wrap
    assert measures.squared_distance(line)[0, 9] == 81.0
    # within the subspace of some axes only (a slice family's in-plane distance)
    assert measures.squared_distance(feats, axes=(1, 2))[0].max() >= got[0].max()


def test_components_and_the_split_of_touching_discs():
    yy, xx = np.mgrid[0:40, 0:60]
    two = (np.hypot(yy - 20, xx - 18) < 12) | (np.hypot(yy - 20, xx - 40) < 12)  # touching
    ids, count = label_components(np.where(two, 1, -1).astype(np.int64), False, False)
    assert count == 1
    lines = split_lines(two)
    ids, count = label_components(np.where(two & ~lines, 1, -1).astype(np.int64), False, False)
    assert count == 2 and lines.sum() < 25  # one short cut across the neck


def test_placement_keeps_spheres_apart_and_is_repeatable():
    radii = np.linspace(6.0, 2.0, 40)
    a = place_spheres(np.array([48.0, 48.0, 48.0]), radii, 1.0, 64, np.uint64(3), True)
    b = place_spheres(np.array([48.0, 48.0, 48.0]), radii, 1.0, 64, np.uint64(3), True)
    assert np.array_equal(a, b)
    d = np.abs(a[:, None] - a[None])
    d = np.minimum(d, 48.0 - d)
    dist = np.sqrt((d ** 2).sum(-1)) + np.eye(len(a)) * 1e9
    assert (dist >= radii[:, None] + radii[None] - 1e-9).all()


# --- analysis ----------------------------------------------------------------------------


def test_phase_matching_does_not_stretch_the_window_lattice_into_dots():
    # a wide, nearly uniform phase (a slow ramp along x) carrying the fill's faint 2-voxel
    # hatching along z, matched to an exemplar phase of a wider spread (and 2 % dark specks):
    # the mapping stretches the ramp, not the hatching (on a real volume, stretched hatching
    # turns into a grid of dark dots)
    z, _, x = np.mgrid[0:16, 0:16, 0:16]
    volume = (0.5 + 0.004 * (x - 7.5) + 0.01 * (z % 2 - 0.5))[..., None].astype(np.float32)
    rng = np.random.default_rng(1)
    exemplar = np.full((64, 64, 1), 0.5, np.float32) + rng.normal(0, 0.02, (64, 64, 1))
    exemplar[rng.random((64, 64)) < 0.02] = 0.1
    labels = np.zeros(volume.shape[:3], np.int64)
    coverage = np.ones((*volume.shape[:3], 1), np.float32)
    out = match_phases(volume, labels, coverage, [exemplar.astype(np.float32)],
                       np.zeros(3, np.int64), [np.zeros((64, 64), np.int64)])
    rows = np.abs(np.diff(out[..., 0], axis=0)).max()
    # measured 0.010 (the hatching passes as it came, 0.01); stretched with the ramp: 0.049
    assert rows < 0.02, rows
    lattice = match_phases(volume, labels, coverage, [exemplar.astype(np.float32)],
                           np.zeros(3, np.int64), [np.zeros((64, 64), np.int64)], nyquist=True)
    assert np.abs(np.diff(lattice[..., 0], axis=0)).max() > 0.04  # the test sees stretching


def test_analysis_reads_particles_layers_and_lattices(samples, cells64):
    found = analyse(cells64)
    assert found.kind == "particles"
    p = found.profiles.scaled(1.0 / found.reader.factor)
    assert 0.6 < p.fraction < 0.9 and 8 < p.quantiles()[1] < 13  # cells ~10 px at 64 px
    side = analyse(read_image(samples / "wood_side.png").pixels)
    assert side.kind == "layers" and abs(side.spacing - 7.0) < 0.5 and abs(side.angle) < 5
    assert analyse(read_image(samples / "weave.png").pixels).kind == "none"  # a lattice


# --- structure of the volumes --------------------------------------------------------------


def test_profile_meter_diagonal_cuts_sample_the_whole_volume():
    # each voxel carries the index of its 8^3 block: the diagonal planes must cross most blocks
    # (planes through the centre alone read the same few particles: 31 % of the blocks of a
    # 64^3 volume, and the same model of terrazzo read its diagonal diameter 0.74-1.02 of the
    # exemplar's over four seeds)
    z, y, x = np.indices((64, 64, 64)) // 8
    blocks = (z * 64 + y * 8 + x).astype(np.float32)[..., None]
    seen = np.unique(np.concatenate([c.ravel() for c in diagonal_cuts(blocks)]))
    assert len(seen) / 512 > 0.6, len(seen)  # measured 0.64


def test_particle_exemplar_keeps_its_profile_sizes_and_shapes(cells64):
    volume = synthesize_solid([cells64], SolidOptions(width=32, height=32, depth=32, seed=1,
                                                      quality="fast")).voxels
    report = profile_meter(cells64, volume)
    errors = report["errors"]["axes"]
    # measured 0.14 (d50), 0.07, 0.03; method osmap on the same volume: 0.33, 0.21, 0.20
    assert max(errors["d50"], errors["solidity"], errors["elongation"]) < 0.2, errors
    # the cells stay apart and of their size: area fraction and area-weighted diameter measured
    # 0.02 and 0.02 on the slices, fraction 0.02 on the diagonal cuts; when the fill let the
    # 1-voxel gaps between cells fade (the averaging unconstrained, gaps 1.5 voxels, the fit at
    # the analysis' scale): 0.08, 0.21 and 0.11
    assert max(errors["fraction"], errors["diameter"]) < 0.06, errors
    assert report["errors"]["diagonal"]["fraction"] < 0.06, report["errors"]["diagonal"]
    # every voxel a colour within the exemplar's range (the detail on a dark cell border went
    # below black, which an image file clips and the float volume kept)
    assert (volume >= cells64.min((0, 1))).all() and (volume <= cells64.max((0, 1))).all()


def test_the_fit_aims_sparse_particles_at_the_exemplars_sizes():
    # 80 profiles of 5-8 px at 30 %, as a 128 px exemplar shows them (read 1x) and as a 64 px
    # one read 2x shows them: sparse particles are fitted at the exemplar's sizes in both cases
    # (SPARSE_GROWTH; packed ones aim FILL_GROWTH small when read enlarged)
    rng = np.random.default_rng(0)
    for factor in (1.0, 2.0):
        d = rng.uniform(5, 8, 80) * factor
        target = ProfileStats(0.3, 80, 0.0, np.sort(d), 0.9, 1.3)
        sources = pt.ParticleSources(d, rng.uniform(0, 1, (80, 3)), target, 2.0 * factor)
        _, got = pt.fit(sources, 1, factor=factor, cap=16)
        g, w = got.figures(), target.scaled(1 / factor).figures()
        size = np.sqrt(g["diameter"] * g["d90"] / (w["diameter"] * w["d90"]))
        # measured 1.01 and 0.98; aimed 1.1 times small (FILL_GROWTH when read enlarged): 0.91
        assert abs(size - 1) < 0.05, (factor, size)


def _log_normal_sources(median, sigma, count, solidity, elongation) -> pt.ParticleSources:
    """`count` profiles of log-normal diameters (`median` voxels) at 40 %, as a 64 px exemplar
    read 2x shows them (pixels of the enlarged reading)."""
    rng = np.random.default_rng(0)
    d = np.exp(rng.normal(np.log(median), sigma, count)) * 2
    target = ProfileStats(0.4, len(d), 0.0, np.sort(d), solidity, elongation)
    return pt.ParticleSources(d, rng.uniform(0, 1, (len(d), 3)), target, 4.0)


def _size_errors(built, sources) -> dict:
    """The relative errors of a built volume's own cuts on the fraction and the sizes."""
    want = sources.target.scaled(0.5).figures()
    got = pt.cut_stats(built.owner >= 0, False, 16).figures()
    return {k: abs(got[k] / want[k] - 1) for k in ("fraction", "diameter", "d90")}


def test_a_sparse_volume_reads_its_target_whatever_the_seed():
    # 100 profiles of log-normal sizes at 40 % in a 64 px exemplar (read 2x): the volume's own
    # cuts read the target's area fraction, area-weighted and 90th-percentile diameters on
    # every seed. Measured within 0.07 on seeds 1-3; a volume built from the probe's best round
    # alone, aimed 1.1 times small, read 0.17 and 0.19 (90th percentile) off: the probe is
    # another, smaller draw of the same model
    sources = _log_normal_sources(5.0, 0.5, 100, 0.9, 1.3)
    for seed in (1, 2, 3):
        params, _ = pt.fit(sources, seed, factor=2.0, cap=48)
        errors = _size_errors(pt.build((48,) * 3, params, sources, seed, False, 2.0), sources)
        assert max(errors.values()) < 0.09, (seed, errors)


def test_a_sparse_volume_read_enlarged_is_not_judged_on_its_median():
    # 150 profiles of log-normal sizes (median 6.6 px, the 90th percentile 2.3 times it, as
    # terrazzo's) at 40 % in a 64 px exemplar read 2x, built from the first guess: the kept
    # build reads the fraction, the area-weighted and the 90th-percentile diameters within 0.08
    # on the volume's own cuts. Measured 0.03 and 0.05 on seeds 1 and 2 (at most 0.07 over
    # seeds 1-6); judged with the median, which its own cuts read large at 2x, and its spread
    # corrected on it, the builds overshot the fraction: 0.11 and 0.18 (0.10-0.18 over 1-6)
    sources = _log_normal_sources(3.3, 0.64, 150, 0.85, 1.5)
    for seed in (1, 2):
        built = pt.build((48,) * 3, pt.initial_params(sources), sources, seed, False, 2.0)
        errors = _size_errors(built, sources)
        assert max(errors.values()) < 0.08, (seed, errors)


def test_a_particle_filled_from_two_exemplar_cells_takes_one_cells_colours():
    # an exemplar of 16 flat cells of distinct colours, each with a light-to-dark shading
    # along x, on dark borders
    rng = np.random.default_rng(3)
    colours = rng.uniform(0.5, 0.95, (16, 3))
    image = np.full((64, 64, 3), 0.08, np.float32)
    shade = np.linspace(-0.08, 0.08, 14)[None, :, None]
    for k in range(16):
        y, x = 16 * (k // 4) + 1, 16 * (k % 4) + 1
        image[y:y + 14, x:x + 14] = colours[k] + shade
    centres = lab(np.array([[[0.08] * 3, colours.mean(0)]], np.float32))[0]
    reader = Reader(Segmenter(centres), matrix=(0,))
    spreads = pt.sources_from(image, reader.working_mask(image), None).spreads
    means, sizes = spreads.means, spreads.pixels
    assert len(means) == 16 and sizes.min() > 150  # the 14 x 14 cells, their rims read
    # two particles (z halves), each filled half from its own source, half from another cell
    regions = np.repeat(np.arange(2), 8)[:, None, None] * np.ones((16, 16, 16), np.int64)
    own = means[[0, 5]]
    other = means[[int(np.argmax(((means - m) ** 2).sum(1))) for m in own]]
    half = np.arange(16)[None, :, None, None] < 8
    voxels = np.where(half, own[regions], other[regions]).astype(np.float32)
    share = np.ones(regions.shape, np.float32)

    def split(v, hue=False):  # the largest difference between a particle's two halves' means
        top = np.broadcast_to(half[..., 0], regions.shape)
        out = 0.0
        for r in (0, 1):
            d = v[(regions == r) & top].mean(0) - v[(regions == r) & ~top].mean(0)
            out = max(out, np.abs(d - d.mean() if hue else d).max())  # hue: grey removed
        return out

    assert split(voxels) > 0.25 and split(voxels, hue=True) > 0.15
    # moving each particle's mean (match_regions) keeps the halves apart: measured 0.32, hue 0.31
    moved = match_regions(voxels, regions, own, share, 0.0, 1.0)
    assert split(moved) > 0.25 and split(moved, hue=True) > 0.15
    # the source's distribution along its colour axes: one hue, the halves apart only along
    # the source's shading (a grey ramp of 0.16): measured 0.13, hue 0.03
    matched = match_particles(voxels, regions, np.array([0, 5]), spreads, share,
                              image.min((0, 1)), image.max((0, 1)))
    assert split(matched) < 0.16 and split(matched, hue=True) < 0.06, (split(matched),
                                                                       split(matched, True))
    for r in (0, 1):
        assert np.abs(matched[regions == r].mean(0) - own[r]).max() < 0.02
    # within the exemplar's colours, which the rotated axes alone would leave
    assert (matched >= image.min((0, 1))).all() and (matched <= image.max((0, 1))).all()


def test_layered_exemplar_keeps_its_spacing(wood):
    side = wood[1]
    period, _ = _period_along_rows(side)  # 7.0 px, autocorrelation 0.92
    volume = synthesize_solid([side], SolidOptions(width=40, height=40, depth=40, seed=1,
                                                   quality="fast")).voxels
    found = [_period_along_rows(volume[:, y]) for y in (10, 20, 30)]  # y slices: rows z
    # measured 6.7-7.0 px at 0.58-0.75; method osmap: 6.9-7.5 px at 0.25-0.32 (the layers
    # break up into fragments)
    for got, strength in found:
        assert abs(got / period - 1) < 0.1 and strength > 0.45, found


def test_wood_end_face_shows_rings(wood):
    found = plan(wood, np.arange(3))
    assert found.kind == "layers" and found.model.rings and found.model.axis == 0
    built = build_structure(found, (48, 48, 48), 1, False)
    colours = found.colours[built.labels].astype(np.float32)
    for x in (12, 36):
        centre, residual = ring_centre(lab(colours[:, :, x])[..., 0])  # rows z, cols y
        # the rings curve around an axis above the face, as in wood_end.png (measured: about
        # 7 voxels above it, residual 0.16; method osmap's end faces: stepped lines whose
        # fitted "centre" lies inside the face, residual 0.25-0.31)
        assert residual < 0.22 and centre[0] < -2 and abs(centre[1] - 24) < 12, (centre,
                                                                                  residual)


# --- the command line ----------------------------------------------------------------------


def test_analyse_prints_and_writes_the_segmentation(run_cli, cells64, tmp_path):
    exemplar = tmp_path / "cells64.png"
    write_image(exemplar, cells64, 8)
    result = run_cli("solid", exemplar, "--analyse")
    assert result.code == 0, result.err
    assert "structure: particles" in result.out and "diameter median" in result.out
    picture = read_image(tmp_path / "cells64_segmentation.png").pixels
    assert picture.shape[1] > 2 * picture.shape[0]  # exemplar | segmentation
    again = run_cli("solid", exemplar, "--analyse")  # replaces its own picture
    assert again.code == 0, again.err
    bad = run_cli("solid", exemplar, "--analyse", "-o", tmp_path / "seg.npy")
    assert bad.code == 2 and "--analyse writes a .png" in bad.err


def test_verbose_and_provenance_say_what_was_built(run_cli, cells64, tmp_path):
    exemplar = tmp_path / "cells64.png"
    write_image(exemplar, cells64, 8)
    out = tmp_path / "v.nrrd"
    result = run_cli("solid", exemplar, "-o", out, "--size", 16, "--quality", "fast", "-v")
    assert result.code == 0, result.err
    assert "structure built: particles" in result.out and "structure step" in result.out
    record = json.loads(read_volume(str(out))[1]["structure"])
    assert record["structure"] == "particles"
    assert record["analysis"][0]["kind"] == "particles"


def test_forced_structure_that_is_not_there_is_one_clear_error(run_cli, samples, tmp_path):
    result = run_cli("solid", samples / "weave.png", "-o", tmp_path / "w.npy", "--size", 16,
                     "--structure", "particles")
    assert result.code == 1 and "shows no separable particles" in result.err
    assert not (tmp_path / "w.npy").exists()


def test_the_same_bytes_with_any_thread_count(osmap_exe, cells64, tmp_path):
    exemplar = tmp_path / "cells64.png"
    write_image(exemplar, cells64, 8)
    sums = []
    for threads in ("1", "2"):
        out = tmp_path / f"t{threads}.npy"
        env = {**os.environ, "NUMBA_NUM_THREADS": threads}
        subprocess.run([osmap_exe, "solid", str(exemplar), "-o", str(out), "--size", "16",
                        "--quality", "fast", "--tileable", "-q"], check=True, env=env)
        sums.append(np.load(out).tobytes())
    assert sums[0] == sums[1]


if __name__ == "__main__":
    sys.exit(pytest.main([__file__]))

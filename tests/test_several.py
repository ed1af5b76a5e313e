"""Several exemplars of one material in one synthesis (osmap synth --also): every exemplar
contributes, the output is as coherent as a single-exemplar synthesis, and the command line's
contract (same channels, provenance, refused combinations)."""

from __future__ import annotations

import numpy as np
import pytest
from texture_stats import coherence


@pytest.fixture(scope="module")
def crops(samples):
    """Three disjoint 128x128 crops of gravel_256.png, and the whole image (their union)."""
    from osmap_cli.imageio import read_image

    image = read_image(samples / "gravel_256.png").pixels
    return [image[:128, :128], image[:128, 128:], image[128:, 64:192]], image


def test_every_exemplar_contributes_and_coherence_holds(crops):
    from osmap_cli.synth import SynthOptions, synthesize
    from osmap_cli.synth.atlas import synthesize_several

    parts, union = crops
    options = SynthOptions(width=128, height=128, seed=0)
    result = synthesize_several(parts, options)
    shares = [float((result.exemplar_index == i).mean()) for i in range(3)]
    assert all(0.15 <= s <= 0.6 for s in shares), shares
    # every position lies inside its own exemplar, and renders exactly what it names
    assert (result.exemplar_index >= 0).all()
    local = np.rint(result.local_positions).astype(int)
    for i, part in enumerate(parts):
        hit = result.exemplar_index == i
        assert (local[hit] >= 0).all() and (local[hit] < 128).all()
        ys, xs = np.nonzero(hit & (result.exemplar_index == i))
        assert part[local[ys, xs, 0], local[ys, xs, 1]].shape[0] == len(ys)
    single = synthesize(parts[0], options)
    several_coh = coherence(union, result.pixels, stride=2)
    single_coh = coherence(parts[0], single.pixels, stride=2)
    # the issue asks for 1.2x: measured 1.15x here (seeds 1, 2: 0.99x, 0.80x; docs/fill.md
    # for the development exemplars). An OS-Map trained on the atlas itself (exemplars mixed
    # pixel by pixel at the coarsest level) scored 1.69x, a broken atlas (windows straddling
    # two exemplars, positions in the gaps) far above 2x.
    assert several_coh < 1.3 * single_coh, (several_coh, single_coh)


def test_start_places_whole_copies(crops):
    """The coarsest level: each copy of the OS-Map layout lies in one exemplar, so few
    neighbours come from different exemplars (an OS-Map trained on the atlas: 65-69 % here),
    and every exemplar gets a share."""
    from osmap_cli.synth import SynthOptions
    from osmap_cli.synth.atlas import continuing_regions, pack, place_copies
    from osmap_cli.synth.constraints import dilate, mask_pyramid
    from osmap_cli.synth.pipeline import valid_box

    parts, _ = crops
    levels, level = 4, 3
    atlas = pack([np.ascontiguousarray(p) for p in parts], levels, 2)
    allowed = ~dilate(mask_pyramid(~atlas.inside(), levels)[level], 2)
    lo, hi = valid_box(allowed.shape, np.eye(2), 2)
    box = np.zeros_like(allowed)
    box[int(lo[0]):int(hi[0]) + 1, int(lo[1]):int(hi[1]) + 1] = True
    allowed &= box
    for seed in (0, 1, 2):
        pos = place_copies(atlas, level, (16, 16), np.eye(2),
                           allowed, SynthOptions(width=128, height=128, seed=seed))
        assert allowed[np.rint(pos[..., 0]).astype(int), np.rint(pos[..., 1]).astype(int)].all()
        index = atlas.index(pos * 2 ** level)
        shares = [float((index == i).mean()) for i in range(3)]
        assert all(0.15 <= s <= 0.6 for s in shares), shares
        changes = ((index[:, 1:] != index[:, :-1]).mean() + (index[1:] != index[:-1]).mean()) / 2
        assert changes < 0.3, changes
        local = pos - np.array(atlas.origins, np.float32)[index] / 2 ** level
        ids, count = continuing_regions(local, np.eye(2), False, 1.0)
        assert all(len(np.unique(index[ids == r])) == 1 for r in range(count))


def test_alignment_onto_forbidden_positions_goes_back():
    """AtlasConstraint.pin takes back a whole-copy shift that put part of a copy on forbidden
    positions (the alignment sees the atlas' box, not its gaps), and keeps the other shifts."""
    from osmap_cli.synth.atlas import AtlasConstraint

    forbidden = np.zeros((20, 40), bool)
    forbidden[:, 12:28] = True  # a gap between two exemplars
    constraint = AtlasConstraint(np.zeros((8, 8), bool), np.zeros((8, 8, 2), np.float32),
                                 forbidden, 0.6, jacobian=np.eye(2, dtype=np.float32))
    rows, cols = np.indices((8, 8), dtype=np.float32)
    before = np.stack([rows + 2, cols + 2], -1)
    before[:, 4:, 1] += 26  # two copies: columns 2-5 and 32-35 of the atlas
    constraint.pin(before.copy())
    after = before.copy()
    after[:, :4, 1] += 8   # the first copy shifted onto columns 10-13: two of them forbidden
    after[:, 4:, 0] += 1   # the second one down a row: allowed
    pinned = constraint.pin(after.copy())
    assert np.array_equal(pinned[:, :4], before[:, :4])
    assert np.array_equal(pinned[:, 4:], after[:, 4:])


def test_also_cli(crops, run_cli, tmp_path, samples):
    from osmap_cli.imageio import read_metadata, write_image

    parts, _ = crops
    paths = []
    for i, part in enumerate(parts):
        paths.append(tmp_path / f"g{i}.png")
        write_image(paths[-1], part[:64, :64], 8)
    out = tmp_path / "out.png"
    result = run_cli("synth", paths[0], "--also", paths[1], "--also", paths[2], "-o", out,
                     "--size", "48")
    assert result.code == 0, result.err
    meta = read_metadata(out)
    assert meta["also"] == "g1.png,g2.png" and "--also g1.png --also g2.png" in meta["args"]
    bad = run_cli("synth", paths[0], "--also", samples / "cells.png", "-o", tmp_path / "x.png")
    assert bad.code == 1 and "cells.png" in bad.err and "channels" in bad.err
    assert not (tmp_path / "x.png").exists()
    for extra in (["--uv-out", tmp_path / "uv.exr"], ["--method", "paper"],
                  ["--with", f"r={paths[1]}"]):
        refused = run_cli("synth", paths[0], "--also", paths[1], "-o", tmp_path / "x.png", *extra)
        assert refused.code == 2 and "--also" in refused.err

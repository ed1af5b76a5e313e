"""osmap_cli.carving: the bake is exact (every covered texel is the volume at its 3D point), seams
agree, vertex colours are the volume at the vertices, placement and padding do what they say,
and reruns give the same arrays."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
from carve_support import (
    bilinear,
    seam_edges,
    small_knot,
    small_vase,
    smooth_volume,
    texel_points,
    trilinear,
)

from osmap_cli.carving import CarveOptions, carve
from osmap_cli.errors import OsmapError


def options(**more) -> CarveOptions:
    return CarveOptions(texture_width=96, texture_height=80, **more)


@pytest.mark.parametrize("module", ["osmap_cli.carving", "osmap_cli.carving.placement",
                                    "osmap_cli.carving.options"])
def test_docstring_examples(module):
    import importlib

    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0


def test_every_covered_texel_is_the_volume_at_its_point():
    vertices, faces, uv = small_vase()
    volume = smooth_volume()
    result = carve((vertices, faces, uv), volume, options())
    covered, points = texel_points(vertices, faces, uv, 96, 80)
    assert covered.mean() > 0.9
    assert np.array_equal(covered, result.covered)
    # placement, from its definition: the box centre to the volume centre, `fit` scale
    size = np.array(volume.shape[2::-1], float)
    centre = (vertices.min(0) + vertices.max(0)) / 2
    scale = np.min(size / np.ptp(vertices, axis=0))
    q = (points[covered] - centre) * scale + size / 2
    assert np.allclose(result.transform[:, :3], scale * np.eye(3))
    expected = trilinear(volume, q)
    assert np.abs(result.texture[covered] - expected).max() < 1e-5


def test_tricubic_interpolates_and_a_linear_volume_is_exact():
    # colour = a linear function of position: trilinear and tricubic (Catmull-Rom) both
    # reproduce it wherever the object stays inside the volume
    shape = (16, 16, 16)
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in shape), indexing="ij")
    volume = np.stack([x / 16, y / 16, 0.2 + 0.6 * z / 16], -1).astype(np.float32)
    vertices, faces, uv = small_vase()
    for method in ("trilinear", "tricubic"):
        result = carve((vertices, faces, uv), volume,
                       options(interpolation=method, scale_mode="voxels", scale=4.0))
        covered, points = texel_points(vertices, faces, uv, 96, 80)
        q = points[covered] @ result.transform[:, :3].T + result.transform[:, 3]
        assert q.min() > 2 and q.max() < 14  # inside: no clamping
        expected = np.stack([q[:, 0] / 16, q[:, 1] / 16, 0.2 + 0.6 * q[:, 2] / 16], 1)
        assert np.abs(result.texture[covered] - expected).max() < 1e-5, method


@pytest.mark.parametrize("mesh", ["vase", "knot"])
def test_both_sides_of_every_uv_seam_agree(mesh):
    # the vase has its own UVs (a seam where u wraps, pole fans); the knot gets an xatlas atlas
    vertices, faces, uv = small_vase() if mesh == "vase" else small_knot()
    volume = smooth_volume()
    result = carve((vertices, faces, uv), volume,
                   CarveOptions(texture_width=256, texture_height=256))
    m = result.mesh
    seams, positions = seam_edges(m.vertices, m.faces, m.uv)
    assert len(seams) >= 8
    index = {tuple(p): i for i, p in enumerate(positions)}
    worst = 0.0
    for f, g, a, b in seams:
        t = np.linspace(0.15, 0.85, 5)[:, None]
        p3 = (1 - t) * positions[a] + t * positions[b]
        truth = trilinear(volume, p3 @ result.transform[:, :3].T + result.transform[:, 3])
        sides = []
        for face in (f, g):
            corner = {index[tuple(m.vertices[v])]: m.uv[v] for v in m.faces[face]}
            uvs = (1 - t) * corner[a] + t * corner[b]
            sides.append(bilinear(result.texture, uvs[:, 0] * 256, (1 - uvs[:, 1]) * 256))
        worst = max(worst, np.abs(sides[0] - sides[1]).max(), np.abs(sides[0] - truth).max())
    assert worst < 3 / 255


def test_vertex_colours_are_the_volume_at_the_vertices():
    vertices, faces, _ = small_knot()
    volume = smooth_volume()
    result = carve((vertices, faces), volume, options(vertex_colors=True, rotate_y=30.0))
    assert result.texture is None
    q = result.mesh.vertices @ result.transform[:, :3].T + result.transform[:, 3]
    assert np.abs(result.vertex_colors - trilinear(volume, q)).max() < 1e-5


def test_placement_scale_offset_rotate_and_wrap():
    vertices, faces, uv = small_vase()
    volume = smooth_volume((16, 16, 16))
    size = np.array([16.0, 16, 16])
    extent = np.ptp(vertices, axis=0)
    centre = (vertices.min(0) + vertices.max(0)) / 2
    fit = carve((vertices, faces, uv), volume, options()).transform
    # fit: the object's tightest axis fills the volume, centred
    q = vertices @ fit[:, :3].T + fit[:, 3]
    assert np.isclose(np.max(np.ptp(q, axis=0) / size), 1.0)
    assert np.allclose((q.min(0) + q.max(0)) / 2, size / 2)
    voxels = carve((vertices, faces, uv), volume, options(scale_mode="voxels", scale=3.0,
                                                          offset_x=2.0)).transform
    assert np.allclose(voxels[:, :3], 3 * np.eye(3))
    assert np.allclose(voxels[:, :3] @ centre + voxels[:, 3], size / 2 + [2, 0, 0])
    repeats = carve((vertices, faces, uv), volume, options(scale_mode="repeats", scale=2.0,
                                                           wrap=True)).transform
    assert np.isclose(repeats[0, 0] * extent.max(), 2 * 16)
    turned = carve((vertices, faces, uv), volume, options(rotate_z=90.0)).transform
    # the material turned by +90 degrees about z: the object's +x meets the volume's -y
    step = turned[:, :3] @ [1.0, 0, 0]
    assert step[1] < 0 and abs(step[0]) < 1e-9
    # wrapping: a texel beyond the volume reads it modulo its size
    wrapped = carve((vertices, faces, uv), volume, options(scale_mode="repeats", scale=3.0,
                                                           wrap=True))
    covered, points = texel_points(vertices, faces, uv, 96, 80)
    qq = points[covered] @ wrapped.transform[:, :3].T + wrapped.transform[:, 3]
    assert qq.min() < 0 or qq.max() > 16
    assert np.abs(wrapped.texture[covered] - trilinear(volume, qq, wrap=True)).max() < 1e-5


def test_an_object_overrunning_a_clamped_volume_is_a_warning():
    vertices, faces, uv = small_vase()
    result = carve((vertices, faces, uv), smooth_volume(), options(scale_mode="repeats",
                                                                   scale=2.0))
    assert any("outside the volume" in w for w in result.warnings)
    assert not carve((vertices, faces, uv), smooth_volume(), options()).warnings


def test_padding_grows_islands_with_their_border_colours():
    vertices, faces, uv = small_knot(uv=True)
    uv = uv * [0.5, 0.8] + [0.2, 0.1]  # an island with empty texels around it
    volume = smooth_volume()
    base = carve((vertices, faces, uv), volume, options(padding=0))
    grown = carve((vertices, faces, uv), volume, options(padding=3))
    assert np.array_equal(base.covered, grown.covered)
    assert np.array_equal(base.texture[base.covered], grown.texture[grown.covered])
    assert (base.triangles >= 0).sum() == base.covered.sum()
    ring = (grown.triangles >= 0) & ~grown.covered
    assert ring.sum() > 0
    # every padding texel is within 3 texels (8-neighbourhood) of a covered one
    near = np.zeros_like(ring)
    h, w = ring.shape
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            shifted = np.zeros_like(ring)
            shifted[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = \
                grown.covered[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
            near |= shifted
    assert np.all(near[ring])
    assert not np.all(near)
    # a padding texel carries the colour at the nearest point of its island's border
    edge = grown.texture[ring]
    assert np.abs(edge - grown.texture[grown.covered].mean(0)).max() > 0.05
    empty = grown.triangles < 0
    assert np.allclose(grown.texture[empty], grown.texture[grown.covered].mean(0), atol=1e-6)


def test_overlapping_uv_islands_are_a_warning_and_atlas_removes_them():
    vertices, faces, uv = small_vase()
    folded = uv.copy()
    folded[:, 0] = np.where(folded[:, 0] > 0.5, 1.0 - folded[:, 0], folded[:, 0])  # mirrored
    result = carve((vertices, faces, folded), smooth_volume(), options())
    assert any("overlap" in w for w in result.warnings)
    fixed = carve((vertices, faces, folded), smooth_volume(), options(atlas=True))
    assert not any("overlap" in w for w in fixed.warnings)
    # shared edges alone are no overlap
    assert not carve((vertices, faces, uv), smooth_volume(), options()).warnings


@pytest.mark.parametrize("case, message", [
    ("empty", "no triangles"), ("nan", "NaN or infinite"), ("nonmanifold", "not manifold"),
    ("uv_outside", "outside [0, 1]"), ("point", "one point"),
])
def test_bad_meshes_are_one_line_errors(case, message):
    vertices, faces, uv = small_vase()
    if case == "empty":
        faces = faces[:0]
    elif case == "nan":
        vertices = vertices.copy()
        vertices[5, 1] = np.nan
    elif case == "nonmanifold":
        extra = len(vertices)
        vertices = np.concatenate([vertices, [[9.0, 9.0, 9.0]]])
        uv = np.concatenate([uv, [[0.5, 0.5]]])
        a, b = faces[100, 0], faces[100, 1]
        faces = np.concatenate([faces, [[a, b, extra]]])
    elif case == "uv_outside":
        uv = uv * 1.5
    elif case == "point":
        vertices = np.zeros_like(vertices)
    with pytest.raises(OsmapError, match=message.replace("[", r"\[").replace("]", r"\]")) as e:
        carve((vertices, faces, uv), smooth_volume(), options())
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("array, message", [
    (np.zeros((8, 8)), "not a volume"),
    (np.zeros((8, 8, 8, 5)), "channels"),
    (np.full((4, 4, 4, 3), np.nan), "NaN"),
    (np.zeros((1, 8, 8, 3)), "at least 2"),
])
def test_volumes_of_the_wrong_kind(array, message):
    with pytest.raises(OsmapError, match=message):
        carve(small_knot()[:2], array, options(vertex_colors=True))


def test_a_position_volume_is_refused():
    from osmap_cli.carving.volume import as_volume

    uv = np.zeros((8, 8, 8, 3), np.float32)
    uv[..., 0] = np.arange(8) * 3
    uv[..., 2] = 1
    with pytest.raises(OsmapError, match="uv-out"):
        as_volume(uv, "marble_uv.npy")


def test_reruns_are_identical_and_grey_volumes_work():
    vertices, faces, _ = small_knot()
    volume = smooth_volume()[..., :1]
    first = carve((vertices, faces), volume, options(interpolation="tricubic"))
    second = carve((vertices, faces), volume, options(interpolation="tricubic"))
    assert first.texture.shape[2] == 1
    assert np.array_equal(first.texture, second.texture)
    assert np.array_equal(first.mesh.uv, second.mesh.uv)


def test_preview_shows_the_object_in_three_views():
    from osmap_cli.carving import render_preview

    vertices, faces, uv = small_vase()
    result = carve((vertices, faces, uv), smooth_volume(), options())
    image = render_preview(result, 64)
    assert image.shape == (64, 3 * 64 + 16, 3)
    for k in range(3):
        panel = image[:, k * 72:k * 72 + 64]
        assert (np.abs(panel - 0.16).max(axis=2) > 0.02).mean() > 0.15
    assert np.array_equal(image, render_preview(result, 64))

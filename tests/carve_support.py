"""What the carve tests share: small meshes (from samples/make_meshes.py), procedural volumes, an
independent numpy trilinear sampler and UV rasteriser to check the kernels against, and the
Khronos glTF validator (npm gltf-validator, installed by .ci/run into .ci/node)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "samples"))

import make_meshes  # noqa: E402

VALIDATOR_PREFIX = REPO / ".ci" / "node"


def small_vase():
    """(vertices, faces, uv): 832 triangles, its own UVs with a seam and two pole fans."""
    return make_meshes.vase(segments=16, rings=8)


def small_knot(uv=False):
    """(vertices, faces, uv or None): 768 triangles, a closed tube."""
    return make_meshes.torus_knot(segments=48, sides=8, uv=uv)


def smooth_volume(shape=(20, 24, 28), seed=0) -> np.ndarray:
    """float32 (Z, Y, X, 3): a smooth colour field (a few low-frequency sines per channel)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in shape), indexing="ij")
    channels = []
    for _ in range(3):
        k = rng.uniform(0.1, 0.35, 3)
        phase = rng.uniform(0, 6.28, 3)
        channels.append(0.5 + 0.15 * (np.sin(k[0] * x + phase[0]) + np.sin(k[1] * y + phase[1])
                                      + np.sin(k[2] * z + phase[2])))
    return np.stack(channels, -1).astype(np.float32)


def trilinear(volume, q, wrap=False):
    """The volume at points q (N, 3) = (x, y, z) voxel units, voxel centres at +0.5."""
    size = np.array(volume.shape[2::-1])
    g = np.asarray(q, np.float64) - 0.5
    base = np.floor(g).astype(np.int64)
    frac = g - base
    out = np.zeros((len(g), volume.shape[3]))
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                d = np.array([dx, dy, dz])
                idx = base + d
                idx = idx % size if wrap else np.clip(idx, 0, size - 1)
                w = np.prod(np.where(d == 1, frac, 1.0 - frac), axis=1)
                out += w[:, None] * volume[idx[:, 2], idx[:, 1], idx[:, 0]]
    return out


def texel_points(vertices, faces, uv, width, height):
    """(covered bool (H, W), points float64 (H, W, 3)): texels whose centre lies in a triangle
    of the UV layout (on an edge counts), and the 3D point of the first such triangle."""
    covered = np.zeros((height, width), bool)
    points = np.zeros((height, width, 3))
    corner = np.stack([uv[:, 0] * width, (1 - uv[:, 1]) * height], 1)[faces]
    for t in range(len(faces)):
        (x0, y0), (x1, y1), (x2, y2) = corner[t]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        r0 = max(int(np.ceil(min(y0, y1, y2) - 0.5)), 0)
        r1 = min(int(np.floor(max(y0, y1, y2) - 0.5)), height - 1)
        c0 = max(int(np.ceil(min(x0, x1, x2) - 0.5)), 0)
        c1 = min(int(np.floor(max(x0, x1, x2) - 0.5)), width - 1)
        if r0 > r1 or c0 > c1:
            continue
        py, px = np.mgrid[r0:r1 + 1, c0:c1 + 1] + 0.5
        b1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / area
        b2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / area
        b0 = 1 - b1 - b2
        inside = (b0 >= -1e-9) & (b1 >= -1e-9) & (b2 >= -1e-9)
        free = inside & ~covered[r0:r1 + 1, c0:c1 + 1]
        p = (b0[..., None] * vertices[faces[t, 0]] + b1[..., None] * vertices[faces[t, 1]]
             + b2[..., None] * vertices[faces[t, 2]])
        points[r0:r1 + 1, c0:c1 + 1][free] = p[free]
        covered[r0:r1 + 1, c0:c1 + 1] |= inside
    return covered, points


def bilinear(image, x, y):
    """image (H, W, C) at texel coordinates (x, y) (texel centres at +0.5), clamped."""
    h, w = image.shape[:2]
    gx, gy = np.asarray(x) - 0.5, np.asarray(y) - 0.5
    x0, y0 = np.floor(gx).astype(int), np.floor(gy).astype(int)
    fx, fy = (gx - x0)[:, None], (gy - y0)[:, None]

    def at(yy, xx):
        return image[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]

    return ((1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1))
            + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1)))


def seam_edges(vertices, faces, uv):
    """[(face a, face b, position p, position q)]: the edges where two triangles meet in 3D but
    their UVs differ (a UV seam), with the edge's two end positions."""
    key = {tuple(v): i for i, v in enumerate(np.unique(vertices, axis=0))}
    merged = np.array([key[tuple(v)] for v in vertices])
    owners = {}
    for f, tri in enumerate(faces):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            owners.setdefault(tuple(sorted((merged[a], merged[b]))), []).append((f, a, b))
    seams = []
    for (ma, mb), sides in owners.items():
        if len(sides) != 2:
            continue
        (f, a, b), (g, c, d) = sides
        ends = {merged[a]: a, merged[b]: b}
        other = {merged[c]: c, merged[d]: d}
        if not (np.allclose(uv[ends[ma]], uv[other[ma]]) and
                np.allclose(uv[ends[mb]], uv[other[mb]])):
            seams.append((f, g, ma, mb))
    return seams, np.unique(vertices, axis=0)


def validate_gltf(*paths) -> None:
    """Every file passes the Khronos glTF validator with no errors (and no warnings)."""
    module = VALIDATOR_PREFIX / "node_modules" / "gltf-validator"
    node = shutil.which("node")
    if node is None or not module.is_dir():
        message = ("the glTF validator is not installed: npm install --prefix .ci/node "
                   "gltf-validator (.ci/run does)")
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    script = Path(__file__).resolve().parent / "gltf_validate.mjs"
    done = subprocess.run([node, str(script), str(VALIDATOR_PREFIX), *map(str, paths)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    reports = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(reports) == len(paths)
    for report in reports:
        assert report["errors"] == 0 and report["warnings"] == 0, report

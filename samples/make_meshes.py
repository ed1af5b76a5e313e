"""Sample meshes for `osmap carve`, made from formulas (no downloaded assets), y up as in glTF:

- vase.obj: a thick-walled vase of revolution (outer wall, rim, inner wall, both bottoms closed at
  the axis), with its own UVs: u around the axis (a seam where u wraps), v along the profile by
  arc length (the bottom poles are fans, one UV per triangle there). A closed manifold.
- torus_knot.ply: a (2, 3) torus knot tube without UVs (carve makes an atlas with xatlas).

`vase()` and `torus_knot()` are imported by tests and benchmarks for meshes of other sizes;
`torus_knot(..., uv=True)` adds the tube's own UVs (u along the knot, v around the tube).

    python samples/make_meshes.py          # writes samples/vase.obj and samples/torus_knot.ply

Deterministic: the same files byte for byte on every run (trimesh's writers, fixed digits).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def vase_profile(rings: int = 36) -> np.ndarray:
    """(k, 2) (radius, height): from the outer bottom centre out, up the outside, over the rim,
    down the inside, in to the inner bottom centre."""
    height, wall, floor = 2.2, 0.06, 0.1

    def radius(t):
        return (0.34 + 0.46 * np.exp(-((t - 0.36) / 0.26) ** 2)
                + 0.1 * np.exp(-((t - 1.0) / 0.09) ** 2))

    t = np.linspace(0.0, 1.0, rings)
    outer = np.stack([radius(t), t * height], 1)
    inner_t = np.linspace(1.0, floor / height, rings)
    inner = np.stack([radius(inner_t) - wall, inner_t * height], 1)
    base = np.stack([np.linspace(0.0, outer[0, 0], 6)[:-1], np.zeros(5)], 1)
    floor_in = np.stack([np.linspace(inner[-1, 0], 0.0, 6)[1:], np.full(5, floor)], 1)
    return np.concatenate([base, outer, inner, floor_in])


def revolve(profile: np.ndarray, segments: int):
    """(vertices, faces, uv) of PROFILE turned about y; profile points at radius 0 are poles
    (triangle fans with one vertex per triangle, so each has its own u)."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(profile, axis=0), axis=1))])
    v_of = 1.0 - arc / arc[-1]
    angles = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    vertices, uvs, rows = [], [], []
    for (r, y), v in zip(profile, v_of):
        if r == 0.0:  # a pole: one vertex per segment, at the segment's middle u
            us = (np.arange(segments) + 0.5) / segments
            ring = np.zeros((segments, 3))
            ring[:, 1] = y
        else:
            us = angles / (2.0 * math.pi)
            ring = np.stack([r * np.cos(angles), np.full_like(angles, y),
                             -r * np.sin(angles)], 1)
            ring[-1] = ring[0]  # the seam: the same position twice, with u 0 and 1
        rows.append(np.arange(len(ring)) + sum(len(x) for x in vertices))
        vertices.append(ring)
        uvs.append(np.stack([us, np.full(len(us), v)], 1))
    faces = []
    for a, b in zip(rows, rows[1:]):
        for j in range(segments):
            if len(a) == segments:  # from a pole
                faces.append((a[j], b[j], b[j + 1]))
            elif len(b) == segments:  # to a pole
                faces.append((a[j], b[j], a[j + 1]))
            else:
                faces += [(a[j], b[j], b[j + 1]), (a[j], b[j + 1], a[j + 1])]
    return np.concatenate(vertices), np.array(faces, np.int64), np.concatenate(uvs)


def vase(segments: int = 48, rings: int = 36):
    """(vertices, faces, uv) of the vase."""
    return revolve(vase_profile(rings), segments)


def torus_knot(segments: int = 240, sides: int = 16, p: int = 2, q: int = 3,
               tube: float = 0.32, uv: bool = False):
    """(vertices, faces, uv or None) of a (p, q) torus knot tube, about 2 x 2 x 0.7 units, in the
    x-y plane. Frames are parallel-transported along the curve, the closing twist spread evenly."""
    t = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)

    def curve(t):
        r = 1.0 + 0.42 * np.cos(q * t)
        return np.stack([r * np.cos(p * t), r * np.sin(p * t), 0.42 * np.sin(q * t)], -1)

    centre = curve(t)
    tangent = curve(t + 1e-4) - curve(t - 1e-4)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.empty_like(centre)
    first = np.cross(tangent[0], [0.0, 0.0, 1.0])
    normal[0] = first / np.linalg.norm(first)
    for k in range(1, segments + 1):
        n = normal[k - 1] - np.dot(normal[k - 1], tangent[k % segments]) * tangent[k % segments]
        n /= np.linalg.norm(n)
        if k == segments:
            closing = n
        else:
            normal[k] = n
    binormal = np.cross(tangent, normal)
    # the transported frame comes back turned by `twist`; undo it a little at every step
    twist = math.atan2(np.dot(np.cross(closing, normal[0]), tangent[0]), np.dot(closing,
                                                                               normal[0]))
    phase = twist * np.arange(segments) / segments
    around = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    angle = phase[:, None] + around[None, :]
    ring = (np.cos(angle)[..., None] * normal[:, None]
            + np.sin(angle)[..., None] * binormal[:, None])
    vertices = (centre[:, None] + tube * ring).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    if not uv:
        a = i * sides + j
        b = ((i + 1) % segments) * sides + j
        c = ((i + 1) % segments) * sides + (j + 1) % sides
        d = i * sides + (j + 1) % sides
        faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                                np.stack([a, c, d], -1).reshape(-1, 3)])
        return vertices, faces, None
    # with UVs: one more column and row of vertices where u and v wrap (the same positions)
    grid = vertices.reshape(segments, sides, 3)
    grid = np.concatenate([grid, grid[:1]], 0)
    grid = np.concatenate([grid, grid[:, :1]], 1)
    n_i, n_j = segments + 1, sides + 1
    a = i * n_j + j
    b = (i + 1) * n_j + j
    c = (i + 1) * n_j + j + 1
    d = i * n_j + j + 1
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    uu, vv = np.meshgrid(np.arange(n_i) / segments, np.arange(n_j) / sides, indexing="ij")
    return grid.reshape(-1, 3), faces, np.stack([uu, vv], -1).reshape(-1, 2)


def write(path: Path, vertices, faces, uv) -> None:
    import trimesh
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import SimpleMaterial

    visual = TextureVisuals(uv=uv, material=SimpleMaterial()) if uv is not None else None
    mesh = trimesh.Trimesh(vertices, faces, visual=visual, process=False)
    if path.suffix == ".obj":
        text = trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_color=False,
                                               include_texture=True, digits=6,
                                               header="made by samples/make_meshes.py")
        # no material file: the UVs are what the sample is for
        lines = [ln for ln in text.splitlines() if not ln.startswith(("mtllib", "usemtl"))]
        path.write_text("\n".join(lines) + "\n")
    else:
        path.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary"))


def main() -> None:
    write(HERE / "vase.obj", *vase())
    write(HERE / "torus_knot.ply", *torus_knot())
    print("wrote samples/vase.obj and samples/torus_knot.ply")


if __name__ == "__main__":
    main()

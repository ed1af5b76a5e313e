"""The warm-up plan: which small command runs compile every kernel a default run uses, and
their inputs (osmap_cli.kernelwarm runs it: at build time for the portable cache, or for this
CPU without one).

    PLAN["synth"]       # the arguments of one entry, "{ex}"-style fields filled by write_inputs
"""

from __future__ import annotations

import os

__all__ = ["PLAN", "plan_digest", "plan_exemplar", "write_inputs"]

# The plan: small runs of the commands, each in its own process, that between them call
# every kernel with the argument types of a real run (sizes do not change them: a 64x64 synth
# compiles what 256x256 to 4096x4096 ones use, as do RGBA, gray, 16-bit, --tileable, --uv-out,
# guides, inpaint, tileable and apply). "{ex}": a 48x48 RGB exemplar, "{regular}": a 48x48
# exemplar with a 2D lattice (its run calls the lattice kernels), "{mesh}": a tetrahedron with
# UVs (OBJ), "{out}": a scratch folder.
# `osmap solid` at 32^3: the plan's exemplar reads as particles, so the default method builds
# that structure and fills it over two levels (16^3 is a single level: the fill's upsampling
# and labelled sharpening would compile on a user's first run); "{cells}", a mosaic of
# polygons with thin dark walls, reads as packed cells, whose tessellation has a kernel of its
# own (one batch, one process: the solid kernels compile once); every other structure kind,
# and --tileable, calls the same kernels with the same types.
# Each command runs with its defaults, so a new default method is covered as it lands; other
# methods (`osmap solid --method legacy`: 70 CPU s of parallel kernels) compile on first use.
# A new command with kernels of its own needs one line here.
PLAN = {
    "synth": ["synth", "{ex}", "{regular}", "--out-dir", "{out}", "--size", "64", "--quiet"],
    "surface": ["surface", "--shape", "torus", "-o", "{out}/grid.obj", "--grid", "6x6",
                "--points", "400", "--steps", "600", "--quiet"],
    "solid": ["solid", "{ex}", "{cells}", "--out-dir", "{out}", "--size", "32", "--quiet"],
    "carve": ["carve", "{mesh}", "--exemplar", "{ex}", "--size", "16", "-o", "{out}/carved.glb",
              "--texture-size", "64", "--quiet"],
}


def plan_exemplar(kind: str = "blocks"):
    """float32 (48, 48, 3): one of the plan's exemplars. "blocks": blocks of noise; "regular": a
    16x16 tile repeated three times each way, that --lattice auto reads as a 2D lattice;
    "cells": 25 polygons of random colours with walls about 1 px wide (a periodic Voronoi
    mosaic of a jittered grid), that method structure reads as packed cells."""
    import numpy as np

    rng = np.random.default_rng(0)
    if kind == "regular":
        pixels = np.tile(rng.random((16, 16, 3)), (3, 3, 1)) * 0.9 + 0.1 * rng.random((48, 48, 3))
    elif kind == "cells":
        side, count = 48, 5
        grid = (np.arange(count) + 0.5) * side / count
        seeds = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2)
        seeds += rng.uniform(-4.0, 4.0, seeds.shape)  # less and it reads as a lattice of gaps
        offsets = (np.stack(np.mgrid[0:side, 0:side], -1) + 0.5)[:, :, None, :] - seeds
        offsets -= side * np.round(offsets / side)
        dist = np.sqrt((offsets ** 2).sum(-1))
        nearest = np.sort(dist, -1)
        pixels = (0.35 + 0.6 * rng.random((count * count, 3)))[np.argmin(dist, -1)]
        pixels[nearest[..., 1] - nearest[..., 0] < 1.0] = 0.08
        pixels += 0.03 * rng.random((side, side, 3))
    else:
        base = rng.random((12, 12, 3)).astype(np.float32)
        pixels = np.kron(base, np.ones((4, 4, 1), np.float32)) * 0.8 + 0.2 * rng.random((48, 48, 3))
    return pixels.astype(np.float32)


EXEMPLARS = {"ex": "blocks", "regular": "regular", "cells": "cells"}  # the plan's field: kind


def plan_digest() -> str:
    """sha256 of the plan and its exemplars: a portable cache built by another plan (one that
    ran fewer kernels) is rebuilt by `portable --if-stale`."""
    import hashlib
    import json

    digest = hashlib.sha256(json.dumps(PLAN, sort_keys=True).encode())
    for kind in EXEMPLARS.values():
        digest.update(plan_exemplar(kind).tobytes())
    return digest.hexdigest()


# four triangles, each with its own UV triangle: a closed mesh whose UV islands do not overlap
TETRAHEDRON_OBJ = """v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1
vt 0.05 0.05\nvt 0.45 0.05\nvt 0.05 0.45\nvt 0.55 0.05\nvt 0.95 0.05\nvt 0.55 0.45
vt 0.05 0.55\nvt 0.45 0.55\nvt 0.05 0.95\nvt 0.55 0.55\nvt 0.95 0.55\nvt 0.55 0.95
f 1/1 3/2 2/3\nf 1/4 2/5 4/6\nf 1/7 4/8 3/9\nf 2/10 3/11 4/12
"""


def write_inputs(folder: str) -> dict[str, str]:
    """Write the plan's inputs into FOLDER; the plan's fields (but "out") as paths."""
    from osmap_cli.imageio import write_image

    fields = {"mesh": os.path.join(folder, "mesh.obj")}
    for field, kind in EXEMPLARS.items():
        fields[field] = os.path.join(folder, f"{field}.png")
        write_image(fields[field], plan_exemplar(kind), 8)
    with open(fields["mesh"], "w") as handle:
        handle.write(TETRAHEDRON_OBJ)
    return fields

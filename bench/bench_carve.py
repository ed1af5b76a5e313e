"""Benchmark of `osmap carve`: a 50,000-triangle mesh baked to 2048x2048 from an existing volume.

`run()` returns the Markdown section ("## Carve"); `python bench/bench_carve.py [--quick]`
prints it. The inputs are made here: a (2, 3) torus knot tube of 50,016 triangles with its own
UVs (samples/make_meshes.py's torus_knot(1563, 16, uv=True)) written as GLB, and a smooth
128^3 RGB volume as .npy. Measured:

- end to end, `osmap carve knot.glb --volume vol.npy -o knot_out.glb --texture-size 2048`: wall
  and CPU seconds of the process (interpreter start, reading, baking, the PNG map written and
  read back, the GLB), median of RUNS after one warm-up run (which loads the Numba cache);
- the same with `--preview`, and the same mesh without UVs (`--atlas`: xatlas makes the
  layout), one run each;
- the stages in one process (osmap_cli.carving): reading the mesh, carve() (rasterising,
  padding, sampling), encoding the map;
- peak resident memory (one process per row) against the mesh's triangles and the map's
  texels: the map sets it, the mesh hardly.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "samples"))

import common  # noqa: E402

RUNS = 5
QUICK_RUNS = 2
SEGMENTS = 1563  # x 16 sides x 2 = 50,016 triangles
COMMAND = "osmap carve knot.glb --volume vol.npy -o knot_out.glb --texture-size 2048"


def make_inputs(folder: Path, segments: int = SEGMENTS, volume: bool = True) -> Path:
    """knot_<triangles>.glb (own UVs) and vol.npy in FOLDER; returns the mesh path."""
    import make_meshes

    from osmap_cli.carving import meshio
    from osmap_cli.carving.mesh import Mesh, smooth_normals

    vertices, faces, uv = make_meshes.torus_knot(segments=segments, sides=16, uv=True)
    path = folder / f"knot_{len(faces)}.glb"
    normals = smooth_normals(Mesh(vertices, faces, uv))
    path.write_bytes(meshio.gltf_bytes(True, vertices, faces, normals, uv, None, None, {}))
    if volume and not (folder / "vol.npy").exists():
        z, y, x = np.meshgrid(*(np.arange(128) + 0.5,) * 3, indexing="ij")
        vol = np.stack([0.5 + 0.25 * (np.sin(x / 5) + np.sin(y / 7 + z / 9)),
                        0.5 + 0.25 * (np.sin(y / 4) + np.sin(z / 6 + 1)),
                        0.5 + 0.25 * (np.sin(z / 3) + np.sin(x / 8 + 2))], -1)
        np.save(folder / "vol.npy", vol.astype(np.float32))
    return path


def _carve_cmd(mesh: Path, folder: Path, *more) -> list[str]:
    exe = common.venv_bin() / "osmap"
    return [str(exe), "carve", str(mesh), "--volume", str(folder / "vol.npy"), "-o",
            str(folder / "knot_out.glb"), "--texture-size", "2048", "-q", *map(str, more)]


def _peak_rss_mib(cmd: list[str]) -> float:
    """Peak resident memory of CMD (run alone in a child of a fresh interpreter), MiB."""
    code = ("import resource, subprocess, sys\n"
            "done = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
            "assert done.returncode == 0\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", code, *cmd], capture_output=True, text=True,
                         check=True)
    return int(out.stdout.split()[-1]) / 1024.0


def _stages(mesh_path: Path, folder: Path) -> list[tuple[str, float]]:
    from osmap_cli.carving import CarveOptions, carve, meshio
    from osmap_cli.imageio import encode_image

    volume = np.load(folder / "vol.npy")
    options = CarveOptions(texture_width=2048, texture_height=2048)
    carve(meshio.read_mesh(str(mesh_path)), volume, options)  # warm: kernels loaded
    t0 = time.perf_counter()
    mesh = meshio.read_mesh(str(mesh_path))
    t1 = time.perf_counter()
    result = carve(mesh, volume, options)
    t2 = time.perf_counter()
    encode_image(str(folder / "stage.png"), result.texture, 8)
    t3 = time.perf_counter()
    return [("read the mesh (trimesh)", t1 - t0), ("carve(): rasterise, pad, sample", t2 - t1),
            ("the 2048x2048 PNG written and read back", t3 - t2)]


def _load() -> str:
    return f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "unknown"


def run(quick: bool = False, log=None) -> str:
    log = log or (lambda message: print(message, file=sys.stderr, flush=True))
    runs = QUICK_RUNS if quick else RUNS
    with tempfile.TemporaryDirectory(prefix="osmap-bench-carve-", dir=common.tmp_root()) as tmp:
        folder = Path(tmp)
        mesh = make_inputs(folder)
        threads = os.cpu_count() or 1
        log(f"[carve] {mesh.name}, {runs} runs")
        cmd = _carve_cmd(mesh, folder)
        common.timed_run(cmd)  # warm-up
        timings = [common.timed_run(cmd) for _ in range(runs)]
        walls = common.Stats([w for w, _ in timings])
        cpus = common.Stats([c for _, c in timings])
        preview = common.timed_run(_carve_cmd(mesh, folder, "--preview", folder / "p.png"))
        log("[carve] atlas")
        atlas = common.timed_run(_carve_cmd(mesh, folder, "--atlas"))
        stages = _stages(mesh, folder)
        log("[carve] memory")
        memory = []
        big = make_inputs(folder, segments=SEGMENTS * 4, volume=False)
        for label, path, size in (("50,016", mesh, 1024), ("50,016", mesh, 2048),
                                  ("200,064", big, 2048), ("50,016", mesh, 4096)):
            cmd = _carve_cmd(path, folder)
            cmd[cmd.index("--texture-size") + 1] = str(size)
            memory.append((label, f"{size}x{size}", f"{_peak_rss_mib(cmd):.0f}"))
    rows = [
        ("end to end, `" + COMMAND + "`", walls.text(2), cpus.text(2)),
        ("the same with `--preview knot.png` (three 384 px views)", f"{preview[0]:.2f}",
         f"{preview[1]:.2f}"),
        ("the same with `--atlas` (xatlas makes the layout)", f"{atlas[0]:.2f}",
         f"{atlas[1]:.2f}"),
    ]
    lines = [
        "## Carve",
        "",
        f"_{common.stamp()}; reproduce with `.venv/bin/python bench/run.py --only carve"
        f"{' --quick' if quick else ''}` (bench/bench_carve.py)._",
        "",
        f"A (2, 3) torus knot tube of 50,016 triangles with its own UVs (GLB) baked from a "
        f"128^3 RGB volume (.npy) to a 2048x2048 map, {threads} cores. End to end: the whole "
        f"`osmap` process, median (min–max) of {runs} runs after one warm-up; the other rows "
        "one run. Target: under 10 s. CPU s (user + system of the process, all threads) does "
        "not depend on what else the shared machine runs; wall s does: load average "
        f"{_load()} at the end of this run (2 cores).",
        "",
        common.md_table(("run", "wall s", "CPU s"), rows),
        "Stages in one process (after a warm-up call):",
        "",
        common.md_table(("stage", "s"), [(name, f"{t:.2f}") for name, t in stages]),
        "Peak resident memory of the whole process (MiB): the map sets it, not the mesh.",
        "",
        common.md_table(("triangles", "texture", "peak RSS MiB"), memory),
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(common.section_main(__doc__, run))

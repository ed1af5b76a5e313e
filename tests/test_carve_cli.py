"""`osmap carve` end to end: outputs that load back (trimesh) with the same geometry and UVs, pass
the Khronos glTF validator, carry provenance (`osmap info`), are the same bytes on every run and
thread count; bad inputs are one line, exit 1, nothing written."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from carve_support import small_knot, small_vase, smooth_volume, trilinear, validate_gltf

import osmap_cli as osmap
from osmap_cli.imageio import read_image, read_metadata


def _write_mesh(path, vertices, faces, uv=None):
    from osmap_cli.carving import meshio

    normals = np.zeros_like(vertices)
    normals[:, 2] = 1
    if path.suffix == ".obj":
        obj, _ = meshio.obj_bytes(vertices, faces, normals, uv, "m.mtl", "m.png", {})
        path.write_bytes(b"\n".join(ln for ln in obj.splitlines()
                                    if not ln.startswith((b"mtllib", b"usemtl"))) + b"\n")
    elif path.suffix == ".glb":
        path.write_bytes(meshio.gltf_bytes(True, vertices, faces, normals, uv, None, None, {}))
    else:
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        path.write_bytes(mesh.export(file_type=path.suffix[1:]))
    return path


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    folder = tmp_path_factory.mktemp("carve")
    np.save(folder / "vol.npy", smooth_volume())
    _write_mesh(folder / "vase.obj", *small_vase())
    _write_mesh(folder / "knot.stl", *small_knot()[:2])
    _write_mesh(folder / "knot.ply", *small_knot()[:2])
    return folder


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def test_glb_obj_gltf_and_ply_round_trip_and_validate(run_cli, work, tmp_path):
    vertices, faces, uv = small_vase()
    common = ["--volume", work / "vol.npy", "--texture-size", "64x48"]
    for name in ("vase.obj", "vase.gltf", "vase.glb"):
        result = run_cli("carve", work / "vase.obj", "-o", tmp_path / name, *common)
        assert result.code == 0, result.err
        assert result.err == ""
        loaded = trimesh.load(tmp_path / name, force="mesh", process=False)
        assert loaded.vertices.shape == vertices.shape and np.array_equal(loaded.faces, faces)
        assert np.abs(loaded.vertices - vertices).max() < 1e-5
        assert np.abs(loaded.visual.uv - uv).max() < 1e-6
    texture = read_image(tmp_path / "vase_color.png")
    assert texture.pixels.shape == (48, 64, 3) and texture.bit_depth == 8
    mtl = (tmp_path / "vase.mtl").read_text()
    assert "map_Kd vase_color.png" in mtl
    validate_gltf(tmp_path / "vase.glb", tmp_path / "vase.gltf")
    # the GLB embeds the texture map's own bytes (the last run wrote both)
    assert (tmp_path / "vase_color.png").read_bytes() in (tmp_path / "vase.glb").read_bytes()

    result = run_cli("carve", work / "knot.stl", "-o", tmp_path / "knot.ply", "--vertex-colors",
                     "--volume", work / "vol.npy", "--preview", tmp_path / "knot.png")
    assert result.code == 0, result.err
    loaded = trimesh.load(tmp_path / "knot.ply", process=False)
    kv, kf, _ = small_knot()
    assert len(loaded.faces) == len(kf)
    # the STL's unshared corners come back as they were read; colours are the volume there
    colours = loaded.visual.vertex_colors[:, :3] / 255.0
    q = _fit_q(loaded.vertices, loaded.vertices)
    assert np.abs(colours - trilinear(smooth_volume(), q)).max() <= 0.5 / 255 + 1e-6
    result = run_cli("carve", work / "knot.ply", "-o", tmp_path / "knot_vc.glb",
                     "--vertex-colors", "--volume", work / "vol.npy")
    assert result.code == 0, result.err
    validate_gltf(tmp_path / "knot_vc.glb")


def _fit_q(points, vertices):
    """Voxel coordinates of POINTS with --scale fit on the mesh VERTICES (smooth_volume())."""
    size = np.array([28.0, 24, 20])
    centre = (vertices.min(0) + vertices.max(0)) / 2
    return (points - centre) * np.min(size / np.ptp(vertices, axis=0)) + size / 2


def test_the_baked_png_is_within_1_255_of_the_volume(run_cli, work, tmp_path):
    from carve_support import texel_points

    vertices, faces, uv = small_vase()
    result = run_cli("carve", work / "vase.obj", "-o", tmp_path / "v.glb", "--volume",
                     work / "vol.npy", "--texture-size", "80", "--bit-depth", "16")
    assert result.code == 0, result.err
    covered, points = texel_points(vertices, faces, uv, 80, 80)
    pixels = read_image(tmp_path / "v_color.png").pixels
    expected = trilinear(smooth_volume(), _fit_q(points[covered], vertices))
    assert np.abs(pixels[covered] - expected).max() < 1 / 255


def test_an_atlas_for_a_mesh_without_uvs_with_preview_and_info(run_cli, work, tmp_path,
                                                               monkeypatch):
    out = tmp_path / "knot.glb"
    result = run_cli("carve", work / "knot.stl", "-o", out, "--volume", work / "vol.npy",
                     "--texture-size", "96", "--preview", tmp_path / "p.png", "--rotate",
                     "0,90,0", "--interpolation", "tricubic")
    assert result.code == 0, result.err
    loaded = trimesh.load(out, force="mesh", process=False)
    assert loaded.visual.uv.min() >= 0 and loaded.visual.uv.max() <= 1
    assert len(loaded.faces) == len(small_knot()[1])
    validate_gltf(out)
    preview = read_image(tmp_path / "p.png")
    assert preview.pixels.shape[2] == 3 and read_metadata(tmp_path / "p.png")["role"] == \
        "preview"
    info = run_cli("info", out, "--json")
    meta = json.loads(info.out)
    assert meta["command"] == "carve" and meta["volume"] == "vol.npy"
    assert "--rotate 0,90,0" in meta["args"] and "--interpolation tricubic" in meta["args"]
    # the command osmap info prints writes the same bytes again
    command = run_cli("info", tmp_path / "knot_color.png", "--command").out.split()
    assert command[:3] == ["osmap", "carve", "knot.stl"]
    again = tmp_path / "again"
    again.mkdir()
    monkeypatch.chdir(work)
    args = [a.replace(str(tmp_path), str(again)) for a in command[1:]]
    assert run_cli(*args).code == 0
    for name in ("knot.glb", "knot_color.png"):
        assert (again / name).read_bytes() == (tmp_path / name).read_bytes(), name


def test_reruns_and_thread_counts_give_the_same_bytes(run_cli, work, tmp_path, osmap_exe):
    outputs = []
    for threads in ("1", None):  # a new process on one thread, then this one on all cores
        folder = tmp_path / (threads or "all")
        folder.mkdir()
        args = ["carve", work / "knot.stl", work / "vase.obj", "--out-dir", folder, "--volume",
                work / "vol.npy", "--texture-size", "64", "--preview", "{stem}_preview.png",
                "--json"]
        if threads:
            env = dict(os.environ, NUMBA_NUM_THREADS=threads)
            done = subprocess.run([osmap_exe, *map(str, args)], capture_output=True, text=True,
                                  env=env, timeout=300)
            assert done.returncode == 0, done.stderr
            out = done.stdout
        else:
            result = run_cli(*args)
            assert result.code == 0, result.err
            out = result.out
        assert [json.loads(line)["status"] for line in out.splitlines()] == ["ok", "ok"]
        outputs.append({p.name: p.read_bytes() for p in folder.iterdir()})
    assert sorted(outputs[0]) == ["knot.glb", "knot_color.png", "knot_preview.png", "vase.glb",
                                  "vase_color.png", "vase_preview.png"]
    assert outputs[0] == outputs[1]


def _bad_inputs(folder):
    (folder / "empty.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (folder / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    (folder / "fin.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                    "f 1 2 3\nf 2 1 4\nf 1 2 5\n")
    (folder / "uv.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1.5 0\nvt 0 1\n"
                                   "f 1/1 2/2 3/3\n")
    (folder / "junk.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x"
                                     "\nend_header\n1\n")
    np.save(folder / "flat.npy", np.zeros((16, 16, 3), np.float32))
    np.save(folder / "many.npy", np.zeros((8, 8, 8, 6), np.float32))
    uv = np.zeros((8, 8, 8, 3), np.float32)
    uv[..., 0] = np.arange(8) * 5
    np.save(folder / "vol_uv.npy", uv)


@pytest.mark.parametrize("mesh, volume, extra, message", [
    ("empty.obj", "vol.npy", (), "empty.obj: the mesh has no triangles"),
    ("nan.obj", "vol.npy", (), "nan.obj: 1 vertices have NaN"),
    ("fin.obj", "vol.npy", (), "fin.obj: the mesh is not manifold"),
    ("uv.obj", "vol.npy", (), "uv.obj: 1 UVs lie outside [0, 1]"),
    ("junk.ply", "vol.npy", (), "junk.ply: not a mesh trimesh can read"),
    ("missing.obj", "vol.npy", (), "missing.obj: no such file"),
    ("vase.obj", "flat.npy", (), "flat.npy: not a volume"),
    ("vase.obj", "many.npy", (), "many.npy: 6 channels"),
    ("vase.obj", "vol_uv.npy", (), "vol_uv.npy: this is a position volume"),
    ("vase.obj", "vol.npy", ("--texture-size", "16384"), "needs about"),
])
def test_bad_inputs_are_one_line_and_write_nothing(run_cli, work, tmp_path, monkeypatch, mesh,
                                                   volume, extra, message):
    _bad_inputs(work)
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "400M")
    out = tmp_path / "out"
    out.mkdir()
    (out / "m.glb").write_bytes(b"previous")
    result = run_cli("carve", work / mesh, "-o", out / "m.glb", "--volume", work / volume,
                     "--preview", out / "p.png", *extra)
    assert result.code == 1
    assert len(result.err_lines) == 1 and message in result.err_lines[0], result.err
    assert "Traceback" not in result.err
    assert _files(out) == ["m.glb"] and (out / "m.glb").read_bytes() == b"previous"


def test_overlapping_islands_warn_and_still_write(run_cli, work, tmp_path):
    vertices, faces, uv = small_vase()
    uv = uv.copy()
    uv[:, 0] = np.minimum(uv[:, 0], 1.0 - uv[:, 0]) * 2 * 0.999
    path = _write_mesh(tmp_path / "mirrored.obj", vertices, faces, uv)
    result = run_cli("carve", path, "-o", tmp_path / "m.glb", "--volume", work / "vol.npy",
                     "--texture-size", "64")
    assert result.code == 0
    assert any("overlap" in line and line.startswith("osmap: warning:")
               for line in result.err_lines)
    assert (tmp_path / "m.glb").exists()


@pytest.mark.parametrize("args, message", [
    (["--volume", "vol.npy", "--size", "32"], "--size sets up a synthesized volume"),
    (["--volume", "vol.npy", "--exemplar", "x.png"], "either --volume or --exemplar"),
    ([], "give the material"),
    (["--volume", "vol.npy", "--vertex-colors", "--texture", "t.png"], "--vertex-colors"),
    (["--volume", "vol.npy", "--scale", "-2"], "--scale"),
    (["--volume", "vol.npy", "--rotate", "1,2"], "--rotate"),
])
def test_usage_errors(run_cli, work, monkeypatch, args, message):
    monkeypatch.chdir(work)
    result = run_cli("carve", "vase.obj", "-o", "x.glb", *args)
    assert result.code == 2 and message in result.err, result.err


def test_output_formats_are_checked_before_work(run_cli, work, tmp_path):
    for out, extra, message in ((tmp_path / "x.stl", (), "unsupported output extension"),
                                (tmp_path / "x.obj", ("--vertex-colors",), "OBJ has no"),
                                (tmp_path / "x.ply", (), "PLY carries no texture"),
                                (tmp_path / "x.glb", ("--texture", tmp_path / "t.bmp"),
                                 "unsupported output format")):
        result = run_cli("carve", work / "vase.obj", "-o", out, "--volume", work / "vol.npy",
                         *extra)
        assert result.code in (1, 2) and message in result.err, result.err
    assert _files(tmp_path) == []


def test_on_the_fly_synthesis_with_a_material_map(run_cli, work, small_samples, tmp_path):
    from osmap_cli.imageio import write_image

    exemplar = small_samples / "cells.png"
    write_image(tmp_path / "cells_rough.png", read_image(exemplar).pixels[..., :1], 8)
    result = run_cli("carve", work / "vase.obj", "-o", tmp_path / "v.obj", "--exemplar",
                     exemplar, "--size", "16", "--levels", "1", "--coarse-iterations", "1",
                     "--kopf-iterations", "1", "--som-steps-per-node", "1",
                     "--texture-size", "48", "--with", f"rough={tmp_path / 'cells_rough.png'}",
                     "--tileable", "--scale", "2x")
    assert result.code == 0, result.err
    assert _files(tmp_path) == ["cells_rough.png", "v.mtl", "v.obj", "v_color.png",
                                "v_rough.png"]
    colour = read_image(tmp_path / "v_color.png").pixels
    rough = read_image(tmp_path / "v_rough.png").pixels
    assert rough.shape == (48, 48, 1) and colour.shape == (48, 48, 3)
    # the volume synthesized (osmap_cli.solid), the map rendered into it (render_volume) and
    # both carved through the API: the same texels
    from osmap_cli.carving import volume
    from osmap_cli.presets import read_preset

    solid = osmap.SolidOptions().replace(**read_preset("default", "solid").values).replace(
        width=16, height=16, depth=16, levels=1, coarse_iterations=1, kopf_iterations=1,
        som_steps_per_node=1.0, tileable=True)
    # the options resolved as osmap solid resolves them; the volume made once per process
    assert list(volume._LAST) == [((str(exemplar),), solid.validated())]
    made = volume._LAST[(str(exemplar),), solid.validated()]
    aligned = osmap.render_volume(made.uv(), read_image(tmp_path / "cells_rough.png").pixels)
    carved = osmap.carve(work / "vase.obj", made.voxels, osmap.CarveOptions(
        texture_width=48, texture_height=48, scale_mode="repeats", scale=2.0, wrap=True),
        aligned={"rough": aligned})
    assert np.abs(colour - carved.texture).max() <= 0.5 / 255 + 1e-6
    assert np.abs(rough - carved.maps["rough"]).max() <= 0.5 / 255 + 1e-6
    meta = read_metadata(tmp_path / "v_rough.png")
    assert meta["role"] == "with:rough" and meta["exemplar"] == "cells.png"
    assert "--with rough=cells_rough.png" in meta["args"] and "--tileable" in meta["args"]


def test_python_api_takes_a_path_and_a_volume_file(work):
    result = osmap.carve(str(work / "knot.ply"), str(work / "vol.npy"),
                         osmap.CarveOptions(texture_width=32, texture_height=32))
    assert result.texture.shape == (32, 32, 3) and isinstance(result, osmap.CarveResult)
    assert sys.modules.get("PIL") is None  # trimesh works without Pillow here


def test_aligned_volumes_and_mesh_provenance(run_cli, work, tmp_path):
    second = smooth_volume(seed=3)[..., :1]
    np.save(tmp_path / "height.npy", second)
    result = run_cli("carve", work / "knot.ply", "-o", tmp_path / "k.obj", "--volume",
                     work / "vol.npy", "--with", f"height={tmp_path / 'height.npy'}",
                     "--texture-size", "40", "--texture", tmp_path / "k.exr")
    assert result.code == 0, result.err
    height = read_image(tmp_path / "k_height.exr").pixels
    carved = osmap.carve(work / "knot.ply", second,
                         osmap.CarveOptions(texture_width=40, texture_height=40))
    assert np.abs(height - carved.texture).max() < 1e-3  # half floats
    assert "map_Kd k.exr" in (tmp_path / "k.mtl").read_text()
    for name in ("k.obj", "k.mtl"):
        meta = json.loads(run_cli("info", tmp_path / name, "--json").out)
        assert meta["command"] == "carve" and meta["role"] == "mesh"
        assert meta["reproduce"].startswith("osmap carve knot.ply -o ")
    np.save(tmp_path / "small.npy", second[:8])
    result = run_cli("carve", work / "knot.ply", "-o", tmp_path / "k2.glb", "--volume",
                     work / "vol.npy", "--with", f"h={tmp_path / 'small.npy'}")
    assert result.code == 1 and "aligned volumes have the same size" in result.err

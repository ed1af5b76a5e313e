"""`osmap surface`: fold-free quad grids on point-sampled surfaces.

Acceptance (fixed seeds 0, 1, 2) through the Python API, the same defaults as the CLI:
- torus R 2, r 0.7, 32x32 map wrapping both ways, cylindrical frame: windings correct, shortcut
  <= 0.005, flipped <= 0.005, angle <= 10 deg, fit <= 0.15; the classic SOM on the same harness
  fails (wrong winding and (shortcut >= 0.01 or angle >= 15));
- one-turn roll, flat 32x32 map: shortcut <= 0.005, flipped <= 0.01, angle <= 6, fit <= 0.2;
  the classic SOM fails (shortcut >= 0.008 or flipped >= 0.015).
Then the metrics on exact grids, the readers, and the CLI (outputs and every error case).
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np
import pytest
from click.testing import CliRunner

from osmap_cli.commands.surface import surface_command
from osmap_cli.surface.fit import build_map, fit_best, parse_grid, parse_vary, shape_config
from osmap_cli.surface.metrics import evaluate, grid_edges, grid_quads
from osmap_cli.surface.shapes import Roll, Torus

SEEDS = (0, 1, 2)
_CACHE: dict = {}


def _run(shape_name: str, method: str, seed: int) -> dict:
    key = (shape_name, method, seed)
    if key not in _CACHE:
        shape = (Torus(major_radius=2.0, minor_radius=0.7) if shape_name == "torus"
                 else Roll(turns=1.0, height=14.0))
        points = shape.sample(20000, np.random.default_rng(seed))
        result = fit_best(points, shape_config(shape, (32, 32), method, seed))
        _CACHE[key] = evaluate(result.grid_xyz, result.wrap, shape)
    return _CACHE[key]


# ------------------------------------------------------------------------------- acceptance
@pytest.mark.parametrize("seed", SEEDS)
def test_torus_osmap_is_clean(seed):
    m = _run("torus", "osmap", seed)
    assert m["windings_ok"], m["windings"]
    assert m["shortcut_edges"] <= 0.005
    assert m["flipped_quads"] <= 0.005
    assert m["angle_error_deg"] <= 10.0
    assert m["fit_error"] <= 0.15


@pytest.mark.parametrize("seed", SEEDS)
def test_torus_som_fails(seed):
    m = _run("torus", "som", seed)
    assert not m["windings_ok"], m["windings"]
    assert m["shortcut_edges"] >= 0.01 or m["angle_error_deg"] >= 15.0


@pytest.mark.parametrize("seed", SEEDS)
def test_roll_osmap_is_clean(seed):
    m = _run("roll", "osmap", seed)
    assert m["shortcut_edges"] <= 0.005
    assert m["flipped_quads"] <= 0.01
    assert m["angle_error_deg"] <= 6.0
    assert m["fit_error"] <= 0.2


@pytest.mark.parametrize("seed", SEEDS)
def test_roll_som_fails(seed):
    m = _run("roll", "som", seed)
    assert m["shortcut_edges"] >= 0.008 or m["flipped_quads"] >= 0.015


def test_som_comparison_shares_everything_but_orientation():
    shape = Torus()
    osm, som = shape_config(shape, method="osmap"), shape_config(shape, method="som")
    for field in ("grid", "wrap", "steps", "sigma", "alpha", "seed"):
        assert getattr(osm, field) == getattr(som, field)
    pts = shape.sample(3000, np.random.default_rng(0))
    starts = []
    for method in ("osmap", "som"):
        som, frame, data = build_map(shape_config(shape, (8, 8), method), pts)
        som.init_random(data, seed=0)
        starts.append(frame.from_frame(som.weights.astype(np.float64)))
    # the same initial node positions (the same data points drawn with the same seed)
    assert np.allclose(starts[0], starts[1], atol=1e-4)


# ---------------------------------------------------------------------------------- metrics
def _torus_grid(rows, cols, twist=0):
    t = Torus()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    phi = 2 * np.pi * (j + 0.5) / cols + twist * 2 * np.pi * i / rows
    theta = 2 * np.pi * (i + 0.5) / rows
    rho = t.major_radius + t.minor_radius * np.cos(theta)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), t.minor_radius * np.sin(theta)], -1)


def test_metrics_on_exact_torus_grid():
    m = evaluate(_torus_grid(32, 32), (True, True), Torus())
    assert m["shortcut_edges"] == 0 and m["flipped_quads"] == 0
    assert m["windings_ok"] and m["fit_error"] < 1e-9
    assert m["angle_error_deg"] < 4.0  # the exact (phi, theta) grid: trapezoids, 3.57 deg


def test_metrics_detect_wrong_winding_and_flips():
    m = evaluate(_torus_grid(32, 32, twist=1), (True, True), Torus())
    assert not m["windings_ok"]
    g = _torus_grid(16, 16)
    g[5:8, 5:8] = g[5:8, 7:4:-1]  # mirror a patch: its quads flip
    assert evaluate(g, (True, True), Torus())["flipped_quads"] > 0


def test_metrics_detect_roll_shortcut():
    r = Roll()
    from osmap_cli.surface.shapes import _spiral_arclength

    s0, s1 = _spiral_arclength(r.t0), _spiral_arclength(r.t1)
    t = r._t_of_s(np.linspace(s0 + 0.5, s1 - 0.5, 16))
    z = np.linspace(1, 13, 16)
    xy = np.stack([t * np.cos(t), t * np.sin(t)], 1)
    g = np.concatenate([np.broadcast_to(xy, (16, 16, 2)),
                        np.broadcast_to(z[:, None, None], (16, 16, 1))], -1).copy()
    clean = evaluate(g, (False, False), r)
    assert clean["shortcut_edges"] == 0 and clean["flipped_quads"] == 0
    g[:, 8:] = g[:, 15:7:-1]  # second half reversed: a jump between layers and a fold
    bad = evaluate(g, (False, False), r)
    assert bad["shortcut_edges"] > 0 and bad["flipped_quads"] > 0


def test_generic_metrics_agree_on_clean_torus():
    pts = Torus().sample(20000, np.random.default_rng(0))
    m = evaluate(_torus_grid(32, 32), (True, True), None, points=pts, area=Torus().area)
    assert m["shortcut_edges"] == 0 and m["fit_error"] < 0.05
    assert "flipped_quads" not in m


def test_grid_topology_counts():
    assert len(grid_edges(4, 5, (False, False))) == 4 * 4 + 3 * 5
    assert len(grid_edges(4, 5, (True, True))) == 2 * 20
    assert len(grid_quads(4, 5, (False, True))) == 3 * 5
    assert parse_grid("48x24") == (24, 48)
    assert [s.along for s in parse_vary("x=u,y=v:0.1,z=uv,r=30deg")] == ["u", "v", "uv", "angle"]


# ---------------------------------------------------------------------------------- helpers
def _invoke(args):
    runner = CliRunner()
    return runner.invoke(surface_command, [str(a) for a in args], catch_exceptions=False)


def _read_obj(path):
    v, vt, f = [], [], []
    for line in open(path):
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "v":
            v.append([float(x) for x in tok[1:]])
        elif tok[0] == "vt":
            vt.append([float(x) for x in tok[1:]])
        elif tok[0] == "f":
            f.append([tuple(int(i) for i in c.split("/")) for c in tok[1:]])
    return np.array(v), np.array(vt), f


def _write_xyz(path, pts):
    np.savetxt(path, pts, fmt="%.6f")
    return path


def _plane_points(n=400, seed=0):
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(0, 4, n), rng.uniform(0, 2, n), 0.05 * rng.standard_normal(n)]


# -------------------------------------------------------------------------------------- CLI
def test_cli_torus_obj_with_wrap_faces_report_and_outputs(tmp_path):
    out, ply, js, png = (tmp_path / n for n in ("t.obj", "t.ply", "t.json", "t.png"))
    res = _invoke(["--shape", "torus", "-o", out, "--grid", "12x8", "--steps", "4000",
                   "--points", "3000", "--ply-out", ply, "--report", "--report-json", js,
                   "--preview", png, "--quiet"])
    assert res.exit_code == 0, res.output
    v, vt, faces = _read_obj(out)
    assert v.shape == (96, 3) and len(faces) == 96  # wrap faces included both ways
    assert all(len(fc) == 4 for fc in faces)
    assert vt.shape == (13 * 9, 2) and vt.min() == 0 and vt.max() == 1
    idx = np.array([[c[0] for c in fc] for fc in faces])
    assert idx.min() == 1 and idx.max() == 96
    # every node is used by exactly four quads on a doubly wrapped map
    assert np.all(np.bincount(idx.ravel())[1:] == 4)
    for key in ("shortcut_edges", "flipped_quads", "angle_error_deg", "fit_error",
                "windings_ok"):
        assert key in res.output
    assert json.loads(js.read_text())["windings_ok"] in (True, False)
    header = ply.read_text().split("end_header")[0]
    assert "element vertex 96" in header and "element face 96" in header
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(png))
    assert inp is not None and inp.spec().width == 2 * inp.spec().height
    inp.close()
    assert sorted(os.listdir(tmp_path)) == ["t.json", "t.obj", "t.ply", "t.png"]


def test_cli_open_map_and_ply_output(tmp_path):
    out = tmp_path / "roll.ply"
    res = _invoke(["--shape", "roll", "-o", out, "--grid", "10x6", "--steps", "3000",
                   "--points", "2000", "--quiet"])
    assert res.exit_code == 0, res.output
    text = out.read_text()
    assert "element vertex 60" in text and f"element face {9 * 5}" in text


def test_cli_point_cloud_inputs(tmp_path):
    pts = _plane_points(300)
    xyz = _write_xyz(tmp_path / "p.xyz", pts)
    npy = tmp_path / "p.npy"
    np.save(npy, pts)
    ply_a, ply_b = tmp_path / "a.ply", tmp_path / "b.ply"
    head = ("ply\nformat {}\nelement vertex 300\nproperty float x\nproperty float y\n"
            "property float z\nproperty uchar red\nend_header\n")
    ply_a.write_text(head.format("ascii 1.0")
                     + "".join(f"{a} {b} {c} 7\n" for a, b, c in pts))
    ply_b.write_bytes(head.format("binary_little_endian 1.0").encode()
                      + b"".join(struct.pack("<fffB", *p, 7) for p in pts))
    for src in (xyz, npy, ply_a, ply_b):
        out = tmp_path / (src.stem + src.suffix[1:] + ".obj")
        res = _invoke([src, "-o", out, "--grid", "6x4", "--steps", "2000", "--vary",
                       "x=u,y=v", "--report"])
        assert res.exit_code == 0, (src, res.output)
        assert _read_obj(out)[0].shape == (24, 3)
        assert "flipped_quads: n/a" in res.output


def test_cli_mesh_input_is_sampled_by_area(tmp_path):
    obj = tmp_path / "quad.obj"
    obj.write_text("v 0 0 0\nv 3 0 0\nv 3 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\n")
    out = tmp_path / "g.obj"
    res = _invoke([obj, "-o", out, "--grid", "6x3", "--points", "2000", "--steps", "3000"])
    assert res.exit_code == 0, res.output
    v = _read_obj(out)[0]
    assert np.all(np.abs(v[:, 2]) < 1e-6) and v[:, 0].max() > 2.0
    ply = tmp_path / "tri.ply"
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                   "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                   "end_header\n0 0 0\n2 0 0\n0 2 1\n3 0 1 2\n")
    res = _invoke([ply, "-o", tmp_path / "h.obj", "--grid", "4x4", "--steps", "500"])
    assert res.exit_code == 0, res.output


def _bad_inputs(tmp_path):
    good = _plane_points(300)
    nan = good.copy()
    nan[5, 1] = np.nan
    inf = good.copy()
    inf[7, 2] = np.inf
    files = {
        "nan.xyz": lambda p: _write_xyz(p, nan),
        "inf.npy": lambda p: np.save(p, inf),
        "empty.xyz": lambda p: p.write_text(""),
        "comments.xyz": lambda p: p.write_text("# nothing here\n\n"),
        "few.xyz": lambda p: _write_xyz(p, good[:10]),
        "coincident.xyz": lambda p: _write_xyz(p, np.ones((300, 3))),
        "collinear.xyz": lambda p: _write_xyz(p, np.outer(np.linspace(0, 1, 300), [1, 2, 3])),
        "points.stl": lambda p: p.write_text("solid x\n"),
        "bad.xyz": lambda p: p.write_text("1 2 3\n4 five 6\n"),
        "bad.ply": lambda p: p.write_text("ply\nformat ascii 1.0\nelement vertex 2\n"
                                          "property float x\nend_header\n1\n2\n"),
        "trunc.ply": lambda p: p.write_bytes(
            b"ply\nformat binary_little_endian 1.0\nelement vertex 500\nproperty float x\n"
            b"property float y\nproperty float z\nend_header\n" + b"\0" * 100),
        "notply.ply": lambda p: p.write_text("hello\n"),
        "bad.npy": lambda p: np.save(p, np.zeros((10, 2))),
        "junk.npy": lambda p: p.write_bytes(b"not an npy file"),
        "badface.obj": lambda p: p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        "flat.obj": lambda p: p.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
        "badv.obj": lambda p: p.write_text("v 0 0\n"),
    }
    out = []
    for name, make in files.items():
        path = tmp_path / name
        make(path)
        out.append(path)
    out.append(tmp_path / "missing.xyz")
    return out


def test_cli_bad_inputs_give_one_line_errors_and_no_output(tmp_path):
    for src in _bad_inputs(tmp_path):
        outdir = tmp_path / ("out_" + src.name.replace(".", "_"))
        outdir.mkdir()
        res = _invoke([src, "-o", outdir / "g.obj", "--grid", "8x8", "--steps", "200",
                       "--preview", outdir / "p.png", "--ply-out", outdir / "g.ply"])
        assert res.exit_code == 1, (src.name, res.exit_code, res.output)
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1, (src.name, res.output)
        assert src.name in lines[0], (src.name, lines[0])
        assert os.listdir(outdir) == [], src.name


@pytest.mark.parametrize("args", [
    [],                                                   # neither INPUT nor --shape
    ["IN", "--shape", "torus"],                           # both
    ["--shape", "torus", "--grid", "32"],
    ["--shape", "torus", "--grid", "1x5"],
    ["--shape", "torus", "--vary", "x=w"],
    ["--shape", "torus", "--vary", "x=u"],                # x is not a cylindrical component
    ["--shape", "torus", "--vary", "rho=u,rho=v"],
    ["--shape", "roll", "--axis", "q"],
    ["--shape", "roll", "--axis", "0,0,0"],
    ["--shape", "roll", "--center", "1,2"],
    ["--shape", "roll", "--radius", "2"],                 # not a roll option
    ["--shape", "torus", "--minor-radius", "3"],
    ["--shape", "torus", "--major-radius", "-1"],
    ["--shape", "roll", "--anisotropy", "2"],
    ["--shape", "roll", "--sigma", "0.5,8"],
    ["--shape", "roll", "--alpha", "2,0.1"],
    ["--shape", "roll", "--steps", "0"],
    ["--shape", "roll", "--restarts", "0"],
    ["--shape", "roll", "--points", "100"],                # fewer points than nodes
    ["--shape", "roll", "--turns", "nan"],
    ["IN", "--turns", "2"],
    ["--shape", "roll", "OUTEXT"],
    ["--shape", "roll", "NODIR"],
    ["--shape", "roll", "--ply-out", "x.obj"],
    ["--shape", "roll", "--preview", "x.gif"],
    ["--shape", "roll", "--report-json", "x.txt"],
    ["--shape", "roll", "--ply-out", "SAME"],
])
def test_cli_bad_options_give_one_line_errors_and_no_output(tmp_path, args):
    src = tmp_path / "in.xyz"
    _write_xyz(src, _plane_points(300))
    outdir = tmp_path / "out"
    outdir.mkdir()
    out = outdir / "g.obj"
    sub = {"IN": src, "x.obj": outdir / "x.obj", "x.gif": outdir / "x.gif",
           "x.txt": outdir / "x.txt", "SAME": out}
    argv = [sub.get(a, a) for a in args if a not in ("OUTEXT", "NODIR")]
    if "OUTEXT" in args:
        out = outdir / "g.stl"
    if "NODIR" in args:
        out = tmp_path / "nowhere" / "g.obj"
    res = _invoke(argv + ["-o", out] + ([] if "--steps" in args else ["--steps", "200"]))
    assert res.exit_code != 0, args
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1, (args, res.output)
    assert os.listdir(outdir) == [], args


def test_usage_errors_exit_2_and_input_errors_exit_1_through_osmap_main(tmp_path, capsys):
    from osmap_cli.cli import main

    assert main(["surface", "--shape", "torus", "--grid", "32", "-o",
                 str(tmp_path / "a.obj")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("osmap: error: --grid")
    assert main(["surface", str(tmp_path / "none.xyz"), "-o", str(tmp_path / "a.obj")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none.xyz" in err[0]
    assert os.listdir(tmp_path) == []


def test_cli_help_documents_syntax_and_examples():
    res = _invoke(["--help"])
    assert res.exit_code == 0
    for word in ("--vary", "x=u,y=u,z=v", "--frame", "cylindrical", "--anisotropy", "--wrap",
                 "--method", "Examples", "--preview", "--report"):
        assert word in res.output


def test_command_module_imports_no_numba():
    import subprocess
    import sys

    code = ("import sys; import osmap_cli.commands.surface; "
            "print(any(m.split('.')[0] in ('numba', 'numpy') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"

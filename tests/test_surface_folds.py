"""`osmap surface` fits that never fold.

Point clouds come from tests/surface_samplers.py (independent of shapes.py), are written to .xyz
files and fitted through the CLI with the flags docs/surface.md gives for point files, as users
do; the grid is then scored against the analytic surface. Seeds 2, 18 and 22 of the one-turn
roll are the ones that folded before the fix (the issue's own seeds 0 and 9 are kept too), every
1.5-turn seed folded. The 50-seed sweeps are in bench/bench_surface.py (`--folds-only`).
Then the geodesic initialisation, the fold check and the refits on their own.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from surface_samplers import ROLL_FLAGS, VARIANTS, roll_points, sample_variant, torus_points

from osmap_cli.commands.surface import surface_command
from osmap_cli.surface.fit import FitConfig, fit_best, parse_vary
from osmap_cli.surface.folds import fold_check
from osmap_cli.surface.metrics import evaluate
from osmap_cli.surface.shapes import Roll, Torus, _spiral_arclength

N_POINTS = 60_000


def _cli(args):
    return CliRunner().invoke(surface_command, [str(a) for a in args],
                                              catch_exceptions=False)


def _fit_file(tmp_path, variant, seed, extra=(), n=N_POINTS):
    """(metrics against the analytic surface, the report JSON, the CLI result)."""
    shape_name, kwargs, flags = VARIANTS[variant]
    src, out, js = tmp_path / f"{variant}.xyz", tmp_path / f"{variant}.obj", tmp_path / "r.json"
    np.savetxt(src, sample_variant(variant, n, seed), fmt="%.6f")
    res = _cli([src, "-o", out, "--seed", seed, "--quiet", "--report-json", js, *flags, *extra])
    assert res.exit_code == 0, res.output
    verts = np.array([[float(v) for v in ln.split()[1:4]] for ln in open(out)
                      if ln.startswith("v ")])
    shape = Roll(turns=kwargs.get("turns", 1.0)) if shape_name == "roll" else Torus()
    wrap = (True, True) if shape_name == "torus" else (False, False)
    m = evaluate(verts.reshape(32, 32, 3), wrap, shape)
    return m, json.loads(js.read_text()), res


def _clean(m, angle):
    ok = (m["shortcut_edges"] <= 0.005 and m["flipped_quads"] <= 0.01
          and m["angle_error_deg"] <= angle and m["fit_error"] <= 0.2)
    return ok and m.get("windings_ok", True)


# ------------------------------------------------------------------- fold-free on user clouds
@pytest.mark.parametrize("seed", [0, 9, 2, 18, 22])
def test_one_turn_roll_formerly_folding_seeds_are_clean(tmp_path, seed):
    m, rep, _ = _fit_file(tmp_path, "roll", seed)
    assert _clean(m, 6.0), m
    assert rep["fold_check"] == "clean" and rep["init"] == "geodesic"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_and_a_half_turn_roll_is_learned(tmp_path, seed):
    m, rep, _ = _fit_file(tmp_path, "roll-1.5", seed)
    assert _clean(m, 6.0), m


@pytest.mark.parametrize("variant,seed", [("roll-noisy", 2), ("roll-nonuniform", 1),
                                          ("torus-noisy", 0), ("torus-nonuniform", 1),
                                          ("torus", 2)])
def test_noisy_and_nonuniform_clouds_are_clean(tmp_path, variant, seed):
    m, rep, _ = _fit_file(tmp_path, variant, seed)
    assert _clean(m, 6.0 if variant.startswith("roll") else 10.0), m
    assert rep["fold_check"] == "clean"


# ----------------------------------------------------------------- detection and refitting
def test_old_start_folds_and_the_check_reports_it(tmp_path):
    """Seed 2 with the pre-issue-17 start (random points, wide schedule) folds; the check sees
    it with no ground truth, and with --fold-retries 0 the user is warned and told why."""
    m, rep, res = _fit_file(tmp_path, "roll", 2, ["--init", "random", "--fold-retries", "0"])
    assert not _clean(m, 6.0)
    assert rep["fold_check"].startswith("folded") and rep["fits_run"] == 1
    assert rep["fold_gap_edges"] > 0 and rep["fold_off_surface_nodes"] > 0
    assert "warning: the grid is still folded" in res.stderr


def test_folded_fit_is_refitted_with_a_derived_seed(tmp_path):
    m, rep, res = _fit_file(tmp_path, "roll", 2, ["--init", "random", "--report"])
    assert _clean(m, 6.0), m
    assert rep["fits_run"] == 2 and rep["fold_check"].startswith("refitted")
    assert rep["seed_used"] != 2 and "fold_check: refitted" in res.stdout
    assert "warning" not in res.stderr


def _roll_grid(rows=16, cols=16, turns=1.0):
    r = Roll(turns=turns)
    s0, s1 = _spiral_arclength(r.t0), _spiral_arclength(r.t1)
    t = r._t_of_s(np.linspace(s0 + 0.5, s1 - 0.5, cols))
    z = np.linspace(0.5, 13.5, rows)
    xy = np.stack([t * np.cos(t), t * np.sin(t)], 1)
    return np.concatenate([np.broadcast_to(xy, (rows, cols, 2)),
                           np.broadcast_to(z[:, None, None], (rows, cols, 1))], -1).copy()


def test_fold_check_on_exact_and_broken_grids():
    pts = roll_points(20000, np.random.default_rng(5))
    g = _roll_grid()
    clean = fold_check(g, (False, False), pts)
    assert not clean["folded"] and clean["gap_edges"] == 0 and clean["reversed_quads"] == 0
    bridged = g.copy()
    bridged[:, 0, :2] = 0.5 * (g[:, 0, :2] + g[:, 15, :2])  # first column into the gap
    b = fold_check(bridged, (False, False), pts)
    assert b["folded"] and b["gap_edges"] > 0 and b["off_surface_nodes"] > 0
    folded = g.copy()
    folded[:, 9:] = g[:, 7:0:-1]  # the grid turns back over itself on the surface
    f = fold_check(folded, (False, False), pts)
    assert f["folded"] and f["reversed_quads"] > 0


def test_fold_check_clean_torus_and_twisted_som_torus():
    shape = Torus()
    pts = torus_points(20000, np.random.default_rng(3))
    i, j = np.meshgrid(np.arange(24), np.arange(24), indexing="ij")
    phi, theta = 2 * np.pi * (j + 0.5) / 24, 2 * np.pi * (i + 0.5) / 24
    rho = 2.0 + 0.7 * np.cos(theta)
    exact = np.stack([rho * np.cos(phi), rho * np.sin(phi), 0.7 * np.sin(theta)], -1)
    assert not fold_check(exact, (True, True), pts)["folded"]
    cfg = FitConfig(grid=(24, 24), wrap="uv", method="som", steps=60 * 576)
    som = fit_best(pts, cfg, fold_retries=0)
    assert not evaluate(som.grid_xyz, som.wrap, shape)["windings_ok"]
    assert som.folds["folded"]


# ------------------------------------------------------------------- geodesic initialisation
def test_geodesic_init_orders_columns_along_the_arc():
    from osmap_cli.surface.embed import geodesic_init
    from osmap_cli.surface.frames import Frame

    pts = roll_points(20000, np.random.default_rng(1), turns=1.5)
    init = geodesic_init(pts, (16, 24), Frame("cartesian").to_frame,
                         [(0, "u"), (1, "u"), (2, "v")], seed=0).reshape(16, 24, 3)
    s = Roll(turns=1.5).params(init.reshape(-1, 3))[:, 0].reshape(16, 24)
    col_s, row_z = np.median(s, axis=0), np.median(init[..., 2], axis=1)
    # monotonic along u (either way round) and z along v: the grid lies on the unrolled roll
    assert np.all(np.diff(col_s) > 0) or np.all(np.diff(col_s) < 0)
    assert np.all(np.diff(row_z) >= 0) or np.all(np.diff(row_z) <= 0)
    assert abs(row_z[-1] - row_z[0]) > 10


def test_auto_init_is_random_on_wrapped_maps_and_for_the_som():
    pts = torus_points(3000, np.random.default_rng(0))
    for cfg in (FitConfig(grid=(8, 8), wrap="uv", steps=500),
                FitConfig(grid=(8, 8), method="som", steps=500)):
        assert fit_best(pts, cfg).init == "random"
    roll = roll_points(3000, np.random.default_rng(0))
    cfg = FitConfig(grid=(8, 8), vary=parse_vary("x=u,y=u,z=v"), steps=500)
    assert fit_best(roll, cfg).init == "geodesic"


def test_output_is_identical_across_thread_counts(tmp_path):
    src = tmp_path / "roll.xyz"
    np.savetxt(src, roll_points(5000, np.random.default_rng(4), turns=1.5), fmt="%.6f")
    outs = []
    for threads in ("1", "2"):
        out = tmp_path / f"g{len(outs)}.obj"
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        subprocess.run([sys.executable, "-m", "osmap_cli.cli", "surface", str(src), "-o",
                        str(out), "--grid", "16x12", "--seed", "3", "--quiet", *ROLL_FLAGS],
                       check=True, env=env, capture_output=True)
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]


@pytest.mark.parametrize("args", [
    ["--shape", "torus", "--init", "geodesic"],   # a closed surface has no unrolling
    ["--shape", "roll", "--init", "spiral"],
    ["--shape", "roll", "--fold-retries", "-1"],
])
def test_new_options_reject_bad_values(tmp_path, args):
    res = _cli(args + ["-o", tmp_path / "g.obj", "--steps", "100"])
    assert res.exit_code == 2, res.output
    assert os.listdir(tmp_path) == []


def test_help_documents_new_options():
    res = _cli(["--help"])
    for word in ("--init", "geodesic", "--fold-retries", "fold"):
        assert word in res.stdout


def test_frame_centre_is_fitted_not_pulled_by_density():
    from osmap_cli.surface.frames import Frame

    pts = sample_variant("torus-nonuniform", 20000, 0)
    assert np.hypot(*pts.mean(0)[:2]) > 0.4  # the centroid is pulled toward the dense side
    fitted = Frame.fit("cylindrical", pts, np.array([0.0, 0.0, 1.0]))
    assert np.hypot(*fitted.center[:2]) < 0.05
    centroid = Frame.fit("cylindrical", pts, np.array([0.0, 0.0, 1.0]), "centroid")
    assert np.allclose(centroid.center, pts.mean(0))


def test_center_option_values(tmp_path):
    from osmap_cli.errors import OsmapError
    from osmap_cli.surface.frames import parse_center

    assert parse_center(None) is None and parse_center("fit") is None
    assert parse_center("centroid") == "centroid"
    assert np.allclose(parse_center("1,2,3"), [1, 2, 3])
    with pytest.raises(OsmapError):
        parse_center("middle")
    res = _cli(["--shape", "torus", "--center", "centroid", "--grid", "6x4", "--points", "500",
                "--steps", "300", "-o", tmp_path / "t.obj", "--quiet"])
    assert res.exit_code == 0, res.output

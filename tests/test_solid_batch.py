"""`osmap solid` batches: several exemplars to --out-dir / --name, a broken input among them,
--json, skip vs --overwrite, an output over an input, bytes equal to separate runs, -j."""

from __future__ import annotations

import io
import json
import os

import numpy as np
import pytest

from osmap_cli.imageio import read_image, write_image

FAST = ("--size", "16", "--preset", "fast", "--seed", "2")


@pytest.fixture(scope="module")
def three(samples, tmp_path_factory):
    """Three 24x24 crops of shipped samples."""
    folder = tmp_path_factory.mktemp("solid_three")
    paths = []
    for name in ("cells.png", "brick.png", "gravel.png"):
        path = folder / f"c_{name}"
        write_image(path, read_image(samples / name).pixels[:24, :24], 8)
        paths.append(path)
    return paths


def _json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines()]


def test_three_exemplars_to_out_dir_match_separate_runs(run_cli, three, tmp_path):
    out = tmp_path / "out"
    result = run_cli("solid", *three, "--out-dir", out, *FAST, "--json")
    assert result.code == 0, result.err
    records = _json_lines(result.out)  # nothing but JSON on stdout
    assert [r["status"] for r in records] == ["ok"] * 3
    assert [r["input"] for r in records] == [str(p) for p in three]
    assert all(r["size"] == [16, 16, 16] and r["seed"] == 2 for r in records)
    assert records[0]["options"]["preset"] == "fast"
    assert sorted(os.listdir(out)) == sorted(f"{p.stem}.npy" for p in three)
    for path in three:
        single = tmp_path / f"single_{path.stem}.npy"
        result = run_cli("solid", path, "-o", single, *FAST, "--quiet")
        assert result.code == 0, result.err
        assert (out / f"{path.stem}.npy").read_bytes() == single.read_bytes()


def test_a_broken_input_does_not_stop_the_others(run_cli, three, tmp_path, monkeypatch):
    bad = tmp_path / "broken.png"
    bad.write_text("not an image")
    monkeypatch.setattr("sys.stdin", io.StringIO(f"{three[0]}\n{bad}\n\n{three[1]}\n"))
    out = tmp_path / "out"
    result = run_cli("solid", "-", "--out-dir", out, *FAST, "--name", "{index}_{stem}.{ext}",
                     "--format", "nrrd")
    assert result.code == 1
    errors = [line for line in result.err_lines if line.startswith("osmap: error:")]
    assert len(errors) == 1 and "broken.png" in errors[0]
    assert result.err_lines[-1].startswith("osmap: 3 jobs: 2 written, 0 skipped, 1 failed")
    assert sorted(os.listdir(out)) == [f"1_{three[0].stem}.nrrd", f"3_{three[1].stem}.nrrd"]
    assert [line.split(":")[0] for line in result.out.splitlines()] == \
        [f"wrote {out / f'1_{three[0].stem}.nrrd'}", f"wrote {out / f'3_{three[1].stem}.nrrd'}"]


def test_fail_fast_stops_at_the_first_failure(run_cli, three, tmp_path):
    out = tmp_path / "out"
    result = run_cli("solid", tmp_path / "missing.png", *three[:2], "--out-dir", out, *FAST,
                     "--fail-fast")
    assert result.code == 1
    assert "missing.png" in result.err_lines[0]
    assert "1 failed, 2 not run (--fail-fast)" in result.err_lines[-1]
    assert os.listdir(out) == []


def test_existing_outputs_are_kept_unless_overwrite(run_cli, three, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    kept = out / f"{three[0].stem}.npy"
    kept.write_bytes(b"keep me")
    result = run_cli("solid", *three[:2], "--out-dir", out, *FAST, "--json")
    assert result.code == 0, result.err
    statuses = {r["input"]: r["status"] for r in _json_lines(result.out)}
    assert statuses == {str(three[0]): "skipped", str(three[1]): "ok"}
    assert kept.read_bytes() == b"keep me"
    assert any("skipped" in line and "--overwrite" in line for line in result.err_lines)
    result = run_cli("solid", *three[:2], "--out-dir", out, *FAST, "--overwrite", "--quiet")
    assert result.code == 0, result.err
    assert np.load(kept).shape == (16, 16, 16, 3)


def test_an_output_over_an_input_is_refused(run_cli, three, tmp_path):
    source = tmp_path / "a.png"
    source.write_bytes(three[0].read_bytes())
    before = source.read_bytes()
    for args in (["--out-dir", tmp_path, "--name", "{name}", "--overwrite"], ["-o", source]):
        result = run_cli("solid", source, *args, *FAST)
        assert result.code == 1
        assert "refusing to write over an input file" in result.err
        assert source.read_bytes() == before


def test_slice_folders_previews_and_j2(run_cli, three, tmp_path):
    out = tmp_path / "out"
    result = run_cli("solid", *three, "--out-dir", out, *FAST, "--format", "png", "-j", "2",
                     "--preview", "{stem}_preview.png", "--quiet")
    assert result.code == 0, result.err
    for path in three:
        assert len(os.listdir(out / path.stem)) == 16  # the default name has no extension
        assert read_image(out / f"{path.stem}_preview.png").pixels.ndim == 3
    single = tmp_path / "single"
    result = run_cli("solid", three[2], "-o", single, *FAST, "--quiet")
    assert result.code == 0, result.err
    for name in os.listdir(single):
        assert (out / three[2].stem / name).read_bytes() == (single / name).read_bytes()


@pytest.mark.parametrize("args, needle", [
    (["-o", "x.npy"], "--out-dir"),  # -o with several inputs
    ([], "--output"),
    (["--out-dir", "{tmp}", "--name", "same.npy"], "same output"),
    (["--out-dir", "{tmp}", "--name", "{nope}.npy"], "{depth}"),
    (["--out-dir", "{tmp}", "--x", "{ex}"], "--x/--y/--z"),
    (["-o", "{tmp}/v.npy", "--overwrite"], "--out-dir only"),  # (one exemplar)
])
def test_usage_errors(run_cli, three, tmp_path, args, needle):
    args = [str(a).replace("{tmp}", str(tmp_path)).replace("{ex}", str(three[0]))
            for a in args]
    count = 1 if "-o" in args and "--overwrite" in args else 2
    result = run_cli("solid", *three[:count], *args, *FAST)
    assert result.code == 2
    assert needle in result.err
    assert len(result.err_lines) == 1

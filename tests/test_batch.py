"""`osmap synth` batches: many inputs, --out-dir / --name, -j, stdin, failures, --json,
no clobbering."""

from __future__ import annotations

import io
import os

import pytest
from conftest import json_lines

from osmap_cli.commands.synth import NAME_FIELDS
from osmap_cli.imageio import read_image

FAST = ("--size", "32", "--preset", "fast", "--levels", "2")


def test_batch_j2_gives_the_bytes_of_separate_runs(run_cli, twenty, tmp_path):
    """Acceptance: a batch of 20 exemplars with -j 2 writes the same bytes as 20 runs."""
    batch = tmp_path / "batch"
    result = run_cli("synth", *twenty, "--out-dir", batch, "-j", "2", "--json", *FAST,
                     "--seed", "4")
    assert result.code == 0, result.err
    records = json_lines(result.out)  # stdout holds nothing but the JSON objects
    assert len(records) == 20 and {r["status"] for r in records} == {"ok"}
    assert sorted(r["input"] for r in records) == sorted(map(str, twenty))
    for record in records:
        assert set(record) >= {"input", "outputs", "size", "seed", "options", "seconds",
                               "status"}
        assert record["size"] == [32, 32] and record["seed"] == 4
        assert record["options"]["levels"] == 2 and record["options"]["preset"] == "fast"
    assert "20 jobs: 20 written, 0 skipped, 0 failed" in result.err
    separate = tmp_path / "separate"
    separate.mkdir()
    for path in twenty:
        one = run_cli("synth", path, "-o", separate / path.name, *FAST, "--seed", "4",
                      "--quiet")
        assert one.code == 0, one.err
        assert (batch / path.name).read_bytes() == (separate / path.name).read_bytes(), path


def test_stdin_inputs_a_failure_does_not_stop_the_others(run_cli, twenty, tmp_path,
                                                         monkeypatch):
    bad = tmp_path / "broken.png"
    bad.write_text("not an image")
    listing = f"{twenty[0]}\n\n{bad}\n{twenty[1]}\n"
    monkeypatch.setattr("sys.stdin", io.StringIO(listing))
    out = tmp_path / "out"
    result = run_cli("synth", "-", "--out-dir", out, *FAST, "--json")
    assert result.code == 1
    records = json_lines(result.out)
    assert [r["status"] for r in records] == ["ok", "failed", "ok"]
    assert records[1]["input"] == str(bad) and "broken.png" in records[1]["error"]
    errors = [line for line in result.err_lines if line.startswith("osmap: error:")]
    assert len(errors) == 1 and "broken.png" in errors[0]
    assert result.err_lines[-1].startswith("osmap: 3 jobs: 2 written, 0 skipped, 1 failed")
    assert sorted(os.listdir(out)) == sorted([twenty[0].name, twenty[1].name])


def test_text_mode_reports_each_job_and_a_summary(run_cli, twenty, tmp_path):
    result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path, *FAST,
                     "--name", "{index:02d}_{stem}_{width}x{height}_s{seed}.{ext}")
    assert result.code == 0, result.err
    names = [f"01_{twenty[0].stem}_32x32_s0.png", f"02_{twenty[1].stem}_32x32_s0.png"]
    assert [line.split(":")[0] for line in result.out.splitlines()] == \
        [f"wrote {tmp_path / n}" for n in names]
    assert result.err_lines == [result.err_lines[-1]]
    assert "2 jobs: 2 written" in result.err_lines[-1]


def test_fail_fast_stops_at_the_first_failure(run_cli, twenty, tmp_path):
    missing = tmp_path / "missing.png"
    out = tmp_path / "out"
    result = run_cli("synth", missing, *twenty[:2], "--out-dir", out, *FAST, "--fail-fast")
    assert result.code == 1
    assert "missing.png" in result.err_lines[0]
    assert "1 failed, 2 not run (--fail-fast)" in result.err_lines[-1]
    assert os.listdir(out) == []


def test_existing_outputs_are_kept_unless_overwrite(run_cli, twenty, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    kept = out / twenty[0].name
    kept.write_bytes(b"keep me")
    result = run_cli("synth", *twenty[:2], "--out-dir", out, *FAST, "--json")
    assert result.code == 0, result.err  # skipped is not a failure: re-runs resume a batch
    statuses = {r["input"]: r["status"] for r in json_lines(result.out)}
    assert statuses == {str(twenty[0]): "skipped", str(twenty[1]): "ok"}
    assert kept.read_bytes() == b"keep me"
    assert any("skipped" in line and "--overwrite" in line for line in result.err_lines)
    result = run_cli("synth", *twenty[:2], "--out-dir", out, *FAST, "--overwrite", "--quiet")
    assert result.code == 0, result.err
    assert read_image(kept).pixels.shape == (32, 32, 3)


def test_an_output_over_an_input_is_refused(run_cli, twenty, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    source = folder / "a.png"
    source.write_bytes(twenty[0].read_bytes())
    before = source.read_bytes()
    for args in (["--out-dir", folder, "--overwrite"], ["-o", source]):
        result = run_cli("synth", source, *args, *FAST)
        assert result.code == 1
        assert "refusing to write over an input file" in result.err
        assert source.read_bytes() == before


def test_uv_out_is_a_template_in_out_dir(run_cli, twenty, tmp_path):
    result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path, *FAST, "--quiet",
                     "--uv-out", "{stem}_uv.exr")
    assert result.code == 0, result.err
    for path in twenty[:2]:
        assert read_image(tmp_path / f"{path.stem}_uv.exr").channel_names == ("u", "v")


@pytest.mark.parametrize("args, needle", [
    (["-o", "x.png"], "--out-dir"),  # -o with several inputs
    ([], "--output"),
    (["--out-dir", "{tmp}", "--name", "same.png"], "same output"),
    (["--out-dir", "{tmp}", "--name", "{nope}.png"], "{stem}"),
    (["-o", "x.png", "--name", "{stem}.png"], "--name"),
    (["--out-dir", "{tmp}", "--uv-out", "{stem}.png"], "--uv-out"),
    (["--out-dir", "{tmp}", "--with", "a=b.png", "--with", "a=c.png"], "--with"),
])
def test_usage_errors_exit_2(run_cli, twenty, tmp_path, args, needle):
    args = [str(a).replace("{tmp}", str(tmp_path / "o")) for a in args]
    result = run_cli("synth", *twenty[:2], *args, *FAST)
    assert result.code == 2, result.err
    assert len(result.err_lines) == 1 and needle in result.err
    assert not (tmp_path / "o").exists() or os.listdir(tmp_path / "o") == []


def test_help_documents_batches_and_exit_codes(run_cli):
    text = run_cli("synth", "--help").out
    for field in NAME_FIELDS:
        assert "{" + field + "}" in text, field
    for phrase in ("--out-dir", "--name", "--jobs", "--fail-fast", "--json", "--overwrite",
                   "Exit codes: 0", "1 a job failed", "2 usage error", "skipped"):
        assert phrase in text, phrase

"""The `osmap` command line: help, synth outputs, determinism, and every error path.

Most runs go in-process through osmap_cli.cli.main (fast: Numba kernels are loaded once); a few
run the installed `osmap` script in a subprocess (start-up imports, thread counts, Ctrl-C).
Sizes are tiny (--size 48 --preset fast) to keep the whole file well under a minute.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio
import pytest

from osmap_cli import __version__, cli
from osmap_cli.errors import OsmapError
from osmap_cli.imageio import read_image, read_metadata, write_image
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.render import render

FAST = ("--size", "48", "--preset", "fast", "--quiet")


def _options(path) -> dict:
    return json.loads(read_metadata(path)["options"])


def _file_format(path) -> str:
    inp = oiio.ImageInput.open(str(path))
    try:
        return str(inp.spec().format)
    finally:
        inp.close()


def _listing(directory) -> list[str]:
    return sorted(os.listdir(directory))


def _assert_one_line_error(result, *needles):
    assert result.code != 0
    assert len(result.err_lines) == 1, result.err
    line = result.err_lines[0]
    assert line.startswith("osmap: "), line
    assert "Traceback" not in result.err
    for needle in needles:
        assert needle in line, (needle, line)


# ---------------------------------------------------------------------------------------------
# version, help, start-up


def test_version(run_cli):
    result = run_cli("--version")
    assert result.code == 0
    assert result.out.strip() == f"osmap {__version__}"


def _command_paths():
    """Every command and subcommand, as argument lists."""
    import click

    paths = [[]]
    ctx = click.Context(cli.cli)
    for name in cli.cli.list_commands(ctx):
        command = cli.cli.get_command(ctx, name)
        paths.append([name])
        if isinstance(command, click.Group):
            sub_ctx = click.Context(command)
            paths.extend([name, sub] for sub in command.list_commands(sub_ctx))
    return paths


def test_every_command_is_listed():
    names = [p[0] for p in _command_paths() if p]
    assert {"synth", "presets", "surface"} <= set(names)
    assert ["presets", "show"] in _command_paths()


@pytest.mark.parametrize("path", _command_paths(), ids=lambda p: " ".join(p) or "osmap")
def test_help_of_every_command_has_examples(run_cli, path):
    result = run_cli(*path, "--help")
    assert result.code == 0
    assert "Examples:" in result.out
    assert f"osmap {' '.join(path)}".strip() in result.out.split("Examples:")[1]
    assert result.err == ""


def test_no_arguments_prints_help(run_cli):
    result = run_cli()
    assert result.code == 0
    assert "Commands:" in result.out and "synth" in result.out


def test_synth_help_documents_every_flag(run_cli):
    import click

    result = run_cli("synth", "--help")
    command = cli.cli.get_command(click.Context(cli.cli), "synth")
    for param in command.params:
        if isinstance(param, click.Option):
            assert param.help, param.name
            assert param.opts[-1] in result.out, param.opts
    for phrase in ("u", "v", "exemplar column", "NUMBA_NUM_THREADS", "precedence"):
        assert phrase in result.out


def test_help_imports_no_heavy_modules_and_is_fast(osmap_exe):
    code = (
        "import sys; from osmap_cli.cli import main; code = main(['--help']); "
        "heavy = [m for m in ('numpy', 'numba', 'OpenImageIO', 'tqdm', 'osmap_cli.synth') "
        "if m in sys.modules]; print('HEAVY', heavy); sys.exit(code)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "HEAVY []" in done.stdout
    started = time.monotonic()
    done = subprocess.run([osmap_exe, "--help"], capture_output=True, text=True)
    elapsed = time.monotonic() - started
    assert done.returncode == 0 and "synth" in done.stdout
    assert elapsed < 3.0  # about 0.1 s; generous for loaded CI machines


def test_flags_and_usage_reference_come_from_the_declarations(run_cli, repo_root):
    """Each tunable is declared once (osmap_cli.options): its tuning flag on synth and solid,
    its help and range, and the rows of docs/usage.md are made from that declaration."""
    from osmap_cli.options import flag, tunables, usage_rows
    from osmap_cli.solid.options import SolidOptions

    usage = (repo_root / "docs" / "usage.md").read_text()
    for command, cls in (("synth", SynthOptions), ("solid", SolidOptions)):
        result = run_cli(command, "--help")
        text = " ".join(result.out.split())
        for name, spec in tunables(cls).items():
            assert flag(name) in text, (command, name)
            assert " ".join(spec.help.split()[:4]) in text, (command, name)
        for row in usage_rows(cls):
            assert row in usage, row
    defaults = SynthOptions()
    assert defaults.quality == "default" and defaults.method == "osmap"
    assert defaults.tileable is False



# ---------------------------------------------------------------------------------------------
# synth: formats, channels, bit depths


@pytest.mark.parametrize(
    "name, bit_depth, expected_depth, stored",
    [
        ("out.png", None, 8, "uint8"),
        ("out.png", "16", 16, "uint16"),
        ("out.exr", None, 32, "half"),
        ("out.exr", "32", 32, "float"),
        ("out.tif", None, 8, "uint8"),
        ("out.tiff", "16", 16, "uint16"),
        ("out.tif", "32", 32, "float"),
        ("out.jpg", None, 8, "uint8"),
        ("out.JPEG", "8", 8, "uint8"),
    ],
)
def test_synth_writes_every_format(run_cli, small_samples, tmp_path, name, bit_depth,
                                   expected_depth, stored):
    out = tmp_path / name
    args = ["synth", small_samples / "cells.png", "-o", out, "--size", "48x40", "--preset", "fast"]
    if bit_depth:
        args += ["--bit-depth", bit_depth]
    result = run_cli(*args)
    assert result.code == 0, result.err
    assert result.err == ""
    assert f"wrote {out}: 48x40" in result.out
    image = read_image(out)
    assert image.pixels.shape == (40, 48, 3)
    assert image.channel_names == ("R", "G", "B")
    assert image.bit_depth == expected_depth
    assert _file_format(out) == stored
    assert _listing(tmp_path) == [name]  # no temporary files left


def test_rgba_keeps_alpha(run_cli, small_samples, tmp_path):
    exemplar = read_image(small_samples / "cells_rgba.png")
    assert exemplar.pixels.shape[2] == 4
    for name in ("rgba.png", "rgba.exr", "rgba.tif"):
        result = run_cli("synth", small_samples / "cells_rgba.png", "-o", tmp_path / name, *FAST)
        assert result.code == 0, result.err
        image = read_image(tmp_path / name)
        assert image.pixels.shape == (48, 48, 4)
        assert image.channel_names == ("R", "G", "B", "A")
        assert image.alpha_channel == 3
        alpha = image.pixels[..., 3]
        assert alpha.min() < 0.1 and alpha.max() > 0.9  # transparent borders, opaque cells


def test_rgba_to_jpeg_drops_alpha_with_a_warning(run_cli, small_samples, tmp_path):
    out = tmp_path / "rgba.jpg"
    result = run_cli("synth", small_samples / "cells_rgba.png", "-o", out, "--size", "48",
                     "--preset", "fast")
    assert result.code == 0, result.err
    assert "alpha" in result.err and "warning" in result.err
    assert read_image(out).pixels.shape == (48, 48, 3)
    quiet = run_cli("synth", small_samples / "cells_rgba.png", "-o", out, *FAST)
    assert quiet.code == 0 and quiet.err == "" and quiet.out == ""


def test_gray_stays_one_channel(run_cli, small_samples, tmp_path):
    out = tmp_path / "gray.png"
    result = run_cli("synth", small_samples / "brick.png", "-o", out, *FAST)
    assert result.code == 0, result.err
    image = read_image(out)
    assert image.pixels.shape == (48, 48, 1)
    assert image.channel_names == ("Y",)


def test_16_bit_input_defaults_to_16_bit_output(run_cli, small_samples, tmp_path):
    source = tmp_path / "cells16.png"
    write_image(source, read_image(small_samples / "cells.png").pixels, 16)
    assert read_image(source).bit_depth == 16
    expected = {"a.png": 16, "b.tif": 16, "c.jpg": 8, "d.exr": 32}
    for name, depth in expected.items():
        result = run_cli("synth", source, "-o", tmp_path / name, *FAST)
        assert result.code == 0, result.err
        assert read_image(tmp_path / name).bit_depth == depth, name
    assert _file_format(tmp_path / "d.exr") == "half"
    result = run_cli("synth", source, "-o", tmp_path / "e.png", "--bit-depth", "8", *FAST)
    assert result.code == 0 and read_image(tmp_path / "e.png").bit_depth == 8


def test_metadata_records_provenance(run_cli, small_samples, tmp_path):
    out = tmp_path / "meta.png"
    result = run_cli("synth", small_samples / "cells.png", "-o", out, *FAST, "--seed", "5",
                     "--scale", "1.5")
    assert result.code == 0, result.err
    meta = read_metadata(out)
    assert meta["osmap_version"] == __version__
    assert meta["exemplar"] == "cells.png"
    assert meta["preset"] == "fast"
    assert meta["seed"] == "5"
    options = json.loads(meta["options"])
    # guide_weight is recorded by guided runs only (unguided outputs keep their bytes)
    assert set(options) == {f.name for f in dataclasses.fields(SynthOptions)} - {"guide_weight"}
    assert options["seed"] == 5 and options["scale"] == 1.5 and options["sweeps"] == 2
    assert SynthOptions(**options).validated()  # the record is a complete, valid option set


# ---------------------------------------------------------------------------------------------
# synth: --uv-out


def test_uv_out_reproduces_the_output(run_cli, small_samples, tmp_path):
    out, uv_path = tmp_path / "out.png", tmp_path / "uv.exr"
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--uv-out", uv_path,
                     "--size", "48x40", "--preset", "fast")
    assert result.code == 0, result.err
    assert str(uv_path) in result.out
    uv = read_image(uv_path)
    assert uv.channel_names == ("u", "v")
    assert uv.pixels.shape == (40, 48, 2)
    assert _file_format(uv_path) == "float"
    exemplar = read_image(small_samples / "cells.png").pixels
    h, w = exemplar.shape[:2]
    u, v = uv.pixels[..., 0], uv.pixels[..., 1]
    assert u.min() >= 0 and u.max() <= w - 1 and v.min() >= 0 and v.max() <= h - 1
    # default method, no scale/rotation: J = identity, every position is a whole pixel
    assert np.array_equal(u, np.rint(u)) and np.array_equal(v, np.rint(v))
    # the output is the exemplar rendered through the positions, seams blended as by default
    rendered = render(exemplar, np.stack([v, u], axis=-1), blend=SynthOptions().blend)
    assert np.abs(read_image(out).pixels - rendered).max() <= 0.5 / 255 + 1e-6
    assert "uv_channels" in read_metadata(uv_path)
    assert _listing(tmp_path) == ["out.png", "uv.exr"]


def test_uv_out_paper_method_stays_inside_the_exemplar(run_cli, samples, tmp_path):
    uv_path = tmp_path / "uv.exr"
    result = run_cli("synth", samples / "cells.png", "-o", tmp_path / "out.png", "--uv-out",
                     uv_path, "--method", "paper", "--size", "32", "--quiet")
    assert result.code == 0, result.err
    uv = read_image(uv_path).pixels
    assert uv.shape == (32, 32, 2)
    assert uv.min() >= 0 and uv[..., 0].max() <= 127 and uv[..., 1].max() <= 127


# ---------------------------------------------------------------------------------------------
# synth: options


@pytest.mark.parametrize("size, shape", [("40", (40, 40)), ("56x40", (40, 56)),
                                         ("40X56", (56, 40)), (" 48 x 32 ", (32, 48))])
def test_size_forms(run_cli, small_samples, tmp_path, size, shape):
    out = tmp_path / "out.png"
    result = run_cli("synth", small_samples / "brick.png", "-o", out, "--size", size,
                     "--preset", "fast", "--quiet")
    assert result.code == 0, result.err
    assert read_image(out).pixels.shape[:2] == shape


@pytest.mark.parametrize("size", ["0x5", "abc", "100000", "64x0", "-5", "64x", "4x4", "1e3",
                                  "99999999999x2"])
def test_bad_size_is_a_usage_error(run_cli, small_samples, tmp_path, size):
    result = run_cli("synth", small_samples / "brick.png", "-o", tmp_path / "out.png",
                     f"--size={size}")
    _assert_one_line_error(result, "--size")
    assert result.code == 2
    assert _listing(tmp_path) == []


@pytest.mark.parametrize(
    "extra",
    [
        ["--tileable"],
        ["--scale", "2", "--orientation", "30", "--anisotropy", "1.5"],
        ["--quality", "high"],
        ["--quality", "fast", "--preset", "structured"],
        ["--preset", "stochastic"],
        ["--preset", "directional", "--method", "paper"],
    ],
    ids=lambda extra: " ".join(extra),
)
def test_option_combinations_run(run_cli, small_samples, tmp_path, extra):
    out = tmp_path / "out.png"
    args = ["synth", small_samples / "weave.png", "-o", out, "--size", "40", "--quiet"]
    if "--preset" not in extra:
        args += ["--preset", "fast"]
    result = run_cli(*args, *extra)
    assert result.code == 0, result.err
    assert read_image(out).pixels.shape == (40, 40, 3)


def test_same_seed_same_bytes_different_seed_different(run_cli, small_samples, tmp_path):
    paths = {name: tmp_path / f"{name}.png" for name in ("a", "b", "c")}
    for name, seed in (("a", 3), ("b", 3), ("c", 4)):
        result = run_cli("synth", small_samples / "cells.png", "-o", paths[name], *FAST,
                         "--seed", seed)
        assert result.code == 0, result.err
    data = {name: path.read_bytes() for name, path in paths.items()}
    assert data["a"] == data["b"]
    assert data["a"] != data["c"]


def test_output_identical_for_any_thread_count(osmap_exe, small_samples, tmp_path):
    outputs = []
    for threads in ("1", "2"):
        out, uv = tmp_path / f"t{threads}.png", tmp_path / f"t{threads}.exr"
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        done = subprocess.run(
            [osmap_exe, "synth", str(small_samples / "cells.png"), "-o", str(out), *FAST,
             "--uv-out", str(uv)],
            env=env, capture_output=True, text=True,
        )
        assert done.returncode == 0, done.stderr
        assert done.stdout == "" and done.stderr == ""
        outputs.append((out.read_bytes(), read_image(uv).pixels))
    assert outputs[0][0] == outputs[1][0]
    assert np.array_equal(outputs[0][1], outputs[1][1])


def test_exr_and_tiff_outputs_are_byte_identical(run_cli, small_samples, tmp_path):
    first = []
    for run in ("a", "b"):
        if run == "b":
            time.sleep(1.1)  # the stamp has one-second resolution
        for ext in ("exr", "tif"):
            result = run_cli("synth", small_samples / "cells.png", "-o",
                             tmp_path / f"{run}.{ext}", *FAST)
            assert result.code == 0, result.err
    for ext in ("exr", "tif"):
        first.append((tmp_path / f"a.{ext}").read_bytes() == (tmp_path / f"b.{ext}").read_bytes())
    assert all(first)


def test_preset_precedence(run_cli, small_samples, tmp_path):
    preset = tmp_path / "mine.toml"
    preset.write_text('name = "mine"\n[synth]\nlevels = 2\nsweeps = 2\noccupancy = 1\n')
    out = tmp_path / "out.png"
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--size", "48", "--quiet",
                     "--preset", preset)
    assert result.code == 0, result.err
    options = _options(out)
    assert (options["levels"], options["sweeps"], options["occupancy"]) == (2, 2, 1.0)
    assert options["knn"] == SynthOptions().knn  # not in the file: the built-in default
    assert read_metadata(out)["preset"] == "mine.toml"
    # a flag on the command line beats the preset; the rest of the preset still applies
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--size", "48", "--quiet",
                     "--preset", preset, "--levels", "3", "--occupancy", "0.25")
    assert result.code == 0, result.err
    options = _options(out)
    assert (options["levels"], options["sweeps"], options["occupancy"]) == (3, 2, 0.25)
    # a built-in preset, overridden likewise
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--size", "48", "--quiet",
                     "--preset", "fast", "--sweeps", "3")
    assert result.code == 0, result.err
    options = _options(out)
    assert (options["knn"], options["sweeps"]) == (2, 3)


def test_existing_output_is_replaced(run_cli, small_samples, tmp_path):
    out = tmp_path / "out.png"
    out.write_bytes(b"old contents")
    result = run_cli("synth", small_samples / "cells.png", "-o", out, *FAST)
    assert result.code == 0, result.err
    assert read_image(out).pixels.shape == (48, 48, 3)
    assert _listing(tmp_path) == ["out.png"]


# ---------------------------------------------------------------------------------------------
# synth: errors (one line, right exit code, nothing written)


def _make_bad_inputs(directory, samples):
    directory.mkdir()
    (directory / "adir").mkdir()
    (directory / "empty.png").write_bytes(b"")
    (directory / "truncated.png").write_bytes((samples / "cells.png").read_bytes()[:100])
    (directory / "text.png").write_text("this is not an image\n")
    (directory / "malformed.toml").write_text('name = "x"\n[synth\nlevels = 3\n')
    (directory / "unknown_key.toml").write_text("[synth]\nlevelz = 3\n")
    (directory / "out_of_range.toml").write_text("[synth]\nlevels = 99\n")
    (directory / "wrong_type.toml").write_text('[synth]\nsweeps = "many"\n')


CELLS = "{samples}/cells.png"
BAD_CASES = [
    # (id, exemplar, output, extra args, exit code, text the one error line must contain)
    ("missing file", "{inputs}/missing.png", "out.png", [], 1, "missing.png"),
    ("directory", "{inputs}/adir", "out.png", [], 1, "adir"),
    ("zero-byte file", "{inputs}/empty.png", "out.png", [], 1, "empty.png"),
    ("truncated png", "{inputs}/truncated.png", "out.png", [], 1, "truncated.png"),
    ("text file", "{inputs}/text.png", "out.png", [], 1, "text.png"),
    ("unknown extension", CELLS, "out.bmp", [], 1, "out.bmp"),
    ("no extension", CELLS, "out", [], 1, "out"),
    ("missing output dir", CELLS, "nodir/out.png", [], 1, "nodir"),
    ("jpeg 16-bit", CELLS, "out.jpg", ["--bit-depth", "16"], 2, "--bit-depth"),
    ("png 32-bit", CELLS, "out.png", ["--bit-depth", "32"], 2, "--bit-depth"),
    ("bad bit depth", CELLS, "out.png", ["--bit-depth", "12"], 2, "--bit-depth"),
    ("uv-out not exr", CELLS, "out.png", ["--uv-out", "{out}/uv.png"], 2, "--uv-out"),
    ("uv-out same as output", CELLS, "out.exr", ["--uv-out", "{out}/out.exr"], 2, "--uv-out"),
    ("uv-out missing dir", CELLS, "out.png", ["--uv-out", "{out}/no/uv.exr"], 1, "uv.exr"),
    ("malformed preset", CELLS, "out.png", ["--preset", "{inputs}/malformed.toml"], 1,
     "malformed.toml"),
    ("unknown preset key", CELLS, "out.png", ["--preset", "{inputs}/unknown_key.toml"], 1,
     "levelz"),
    ("out-of-range preset", CELLS, "out.png", ["--preset", "{inputs}/out_of_range.toml"], 1,
     "out_of_range.toml"),
    ("wrong-type preset", CELLS, "out.png", ["--preset", "{inputs}/wrong_type.toml"], 1,
     "sweeps"),
    ("missing preset file", CELLS, "out.png", ["--preset", "{inputs}/nope.toml"], 1,
     "nope.toml"),
    ("unknown preset name", CELLS, "out.png", ["--preset", "nope"], 2, "--preset"),
    ("scale out of range", CELLS, "out.png", ["--scale", "100"], 2, "--scale"),
    ("orientation out of range", CELLS, "out.png", ["--orientation", "1000"], 2,
     "--orientation"),
    ("negative seed", CELLS, "out.png", ["--seed", "-1"], 2, "--seed"),
    ("tuning flag out of range", CELLS, "out.png", ["--levels", "9"], 2, "--levels"),
    ("not a number", CELLS, "out.png", ["--scale", "big"], 2, "--scale"),
    ("bad quality", CELLS, "out.png", ["--quality", "best"], 2, "--quality"),
    ("bad method", CELLS, "out.png", ["--method", "magic"], 2, "--method"),
    ("unknown option", CELLS, "out.png", ["--colour"], 2, "--colour"),
]


@pytest.mark.parametrize("case", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_input_gives_one_line_and_no_output(run_cli, samples, tmp_path, case):
    _, exemplar, output, extra, code, needle = case
    inputs, out_dir = tmp_path / "inputs", tmp_path / "out"
    _make_bad_inputs(inputs, samples)
    out_dir.mkdir()
    before_inputs = _listing(inputs)

    def fill(text):
        return text.format(samples=samples, inputs=inputs, out=out_dir)

    args = ["synth", fill(exemplar), "-o", out_dir / output, *map(fill, extra), "--size", "48"]
    result = run_cli(*args)
    _assert_one_line_error(result, needle)
    assert result.code == code
    assert result.out == ""
    assert _listing(out_dir) == []
    assert _listing(inputs) == before_inputs


def test_missing_output_option(run_cli, small_samples):
    result = run_cli("synth", small_samples / "cells.png")
    _assert_one_line_error(result, "--output")
    assert result.code == 2


def test_failed_second_write_leaves_nothing(run_cli, small_samples, tmp_path, monkeypatch):
    """If --uv-out cannot be written, the main output is not written (or replaced) either."""
    from osmap_cli import imageio

    real_write = imageio.encode_image

    def failing_write(path, *args, **kwargs):
        if str(path).endswith(".exr"):
            raise OsmapError(f"{path}: failed to write EXR file (disk full)")
        return real_write(path, *args, **kwargs)

    monkeypatch.setattr(imageio, "encode_image", failing_write)
    out = tmp_path / "out.png"
    out.write_bytes(b"previous output")
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--uv-out",
                     tmp_path / "uv.exr", *FAST)
    _assert_one_line_error(result, f"{tmp_path / 'uv.exr'}: failed to write EXR")
    assert result.code == 1
    assert ".osmap-" not in result.err  # the message names the user's path, not a temp file
    assert out.read_bytes() == b"previous output"
    assert _listing(tmp_path) == ["out.png"]


# ---------------------------------------------------------------------------------------------
# interrupts and internal errors


def test_ctrl_c_exits_130_without_output(run_cli, small_samples, tmp_path, monkeypatch):
    from osmap_cli import synth

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(synth, "synthesize", interrupted)
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "out.png", *FAST)
    assert result.code == 130
    assert result.err_lines == ["osmap: interrupted"]
    assert _listing(tmp_path) == []


def test_sigint_on_a_real_run(osmap_exe, samples, tmp_path, tmp_path_factory):
    # compile the kernels first (a fresh clone has no Numba cache): the interrupt is meant to
    # land in the run itself, not in a first-ever compilation
    warm = tmp_path_factory.mktemp("warm") / "warm.png"
    subprocess.run([osmap_exe, "synth", str(samples / "cells.png"), "-o", str(warm), "--size",
                    "16", "--method", "paper", "--quiet"], check=True, timeout=600)
    process = subprocess.Popen(
        [osmap_exe, "synth", str(samples / "cells.png"), "-o", str(tmp_path / "big.png"),
         "--size", "512", "--method", "paper"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    time.sleep(2.0)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert err.strip().splitlines() == ["osmap: interrupted"]
    assert _listing(tmp_path) == []


@pytest.mark.parametrize("debug", ["", "env", "flag"])
def test_internal_error_is_one_line_unless_debugging(run_cli, small_samples, tmp_path,
                                                     monkeypatch, debug):
    from osmap_cli import synth

    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(synth, "synthesize", broken)
    if debug == "env":
        monkeypatch.setenv("OSMAP_DEBUG", "1")
    else:
        monkeypatch.delenv("OSMAP_DEBUG", raising=False)
    prefix = ["--debug"] if debug == "flag" else []
    result = run_cli(*prefix, "synth", small_samples / "cells.png", "-o", tmp_path / "out.png",
                     *FAST)
    assert result.code == 1
    assert result.err_lines[-1].startswith("osmap: internal error: RuntimeError: boom")
    if debug:
        assert "Traceback" in result.err
    else:
        assert len(result.err_lines) == 1 and "Traceback" not in result.err
        assert "OSMAP_DEBUG" in result.err
    assert _listing(tmp_path) == []


# ---------------------------------------------------------------------------------------------
# osmap presets


def test_presets_list(run_cli):
    for args in (["presets"], ["presets", "list"]):
        result = run_cli(*args)
        assert result.code == 0, result.err
        lines = result.out.splitlines()
        names = [line.split()[0] for line in lines]
        assert names[0] == "default"
        assert {"default", "stochastic", "structured", "directional", "fast"} <= set(names)
        assert all(len(line.split(None, 1)) == 2 for line in lines)  # name  description


def test_presets_show(run_cli, repo_root, tmp_path):
    result = run_cli("presets", "show", "structured")
    assert result.code == 0
    assert result.out == (repo_root / "presets" / "structured.toml").read_text()
    own = tmp_path / "own.toml"
    own.write_text("[synth]\nlevels = 2\n")
    result = run_cli("presets", "show", own)
    assert result.code == 0 and result.out == "[synth]\nlevels = 2\n"
    result = run_cli("presets", "show", "nope")
    _assert_one_line_error(result, "nope")
    assert result.code == 2
    result = run_cli("presets", "show", tmp_path / "missing.toml")
    _assert_one_line_error(result, "missing.toml")
    assert result.code == 1


def test_shown_preset_round_trips_as_a_file(run_cli, small_samples, tmp_path):
    result = run_cli("presets", "show", "fast")
    own = tmp_path / "copy.toml"
    own.write_text(result.out)
    out = tmp_path / "out.png"
    result = run_cli("synth", small_samples / "cells.png", "-o", out, "--size", "48", "--quiet",
                     "--preset", own)
    assert result.code == 0, result.err
    assert (_options(out)["knn"], _options(out)["sweeps"]) == (2, 2)


# ---------------------------------------------------------------------------------------------
# progress bar


def test_progress_bar_adds_up_increments():
    import io

    from osmap_cli.progress import ProgressBar

    stream = io.StringIO()
    with ProgressBar(enabled=True, desc="osmap synth", file=stream) as bar:
        for _ in range(4):
            bar(0.25)
        bar(0.5)  # more than the whole: clamped
        bar(float("nan"))
        assert bar.done == 1.0
    assert "osmap synth:   0%" in stream.getvalue()  # later redraws are rate-limited
    silent = ProgressBar(enabled=False)
    silent(0.5)
    assert silent.done == 0.5
    silent.close()

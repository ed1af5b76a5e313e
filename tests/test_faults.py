"""Fault injection: a full disk at several offsets for every output kind, signals, hostile
names. Every case asserts the exit code, exactly one `osmap: ...` line on stderr, no traceback,
no temporary file left, and the previous output byte for byte as it was.

A full disk is simulated without root: the child process gets RLIMIT_FSIZE (with SIGXFSZ
ignored, so a write past the limit fails with EFBIG, as on a full disk).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

resource = pytest.importorskip("resource")

# small inputs: each case is one `osmap` process (about 2 s, mostly start-up)
SYNTH = ("--size", "24", "--preset", "fast", "--levels", "1", "-q")
SOLID = ("--size", "8", "--preset", "fast", "--levels", "1", "-q")
SURFACE = ("--shape", "torus", "--grid", "6x6", "--points", "400", "--steps", "600")


def _osmap(args, cwd, limit=None, env=None):
    def child():
        if limit is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    code = "import sys; from osmap_cli.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, preexec_fn=child,
                          env={**os.environ, **(env or {})})


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _assert_clean_failure(done, code, before, folder):
    lines = done.stderr.splitlines()
    assert done.returncode == code, done.stderr
    assert len(lines) == 1 and lines[0].startswith("osmap: "), done.stderr
    assert "Traceback" not in done.stderr
    assert not [p for p in folder.rglob(".osmap-*")], "temporary file left"
    assert _snapshot(folder) == before, "an output was changed"


@pytest.fixture(scope="module")
def exemplar(tmp_path_factory, samples):
    from osmap_cli.imageio import read_image, write_image

    folder = tmp_path_factory.mktemp("fault_inputs")
    write_image(folder / "ex.png", read_image(samples / "cells.png").pixels[:32, :32])
    write_image(folder / "ex_map.png", read_image(samples / "brick.png").pixels[:32, :32])
    return folder / "ex.png"


# (id, command, output arguments, the file whose size sets the limit)
CASES = [
    ("png", "synth", ("-o", "out.png"), "out.png"),
    ("exr", "synth", ("-o", "out.exr"), "out.exr"),
    ("tiff", "synth", ("-o", "out.tif"), "out.tif"),
    ("jpeg", "synth", ("-o", "out.jpg"), "out.jpg"),
    ("uv-out", "synth", ("-o", "out.png", "--uv-out", "uv.exr"), "uv.exr"),
    ("with", "synth", ("-o", "out.png", "--with", "m={dir}/ex_map.png"), "out_m.png"),
    ("npy", "solid", ("-o", "v.npy"), "v.npy"),
    ("nrrd", "solid", ("-o", "v.nrrd"), "v.nrrd"),
    ("atlas", "solid", ("-o", "v_2x4.png"), "v_2x4.png"),
    ("slices", "solid", ("-o", "slices"), "slices/slice_0007.png"),
    ("exr-slices", "solid", ("-o", "xs", "--format", "exr"), "xs/slice_0007.exr"),
    ("volume-uv", "solid", ("-o", "v.npy", "--uv-out", "vuv.npy"), "vuv.npy"),
    ("obj", "surface", ("-o", "g.obj"), "g.obj"),
    ("ply", "surface", ("-o", "g.obj", "--ply-out", "g.ply"), "g.ply"),
]


@pytest.fixture(scope="module")
def first_outputs(tmp_path_factory):
    """The outputs of each case's run without a limit, made once for both limits."""
    made = {}

    def outputs_of(case, args):
        if case not in made:
            folder = tmp_path_factory.mktemp("first")
            first = _osmap(args, folder)
            assert first.returncode == 0, first.stderr
            made[case] = _snapshot(folder)
        return made[case]

    return outputs_of


@pytest.mark.parametrize("where", ["middle", "last bytes"])
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_full_disk_leaves_the_previous_output(tmp_path, exemplar, first_outputs, case, where):
    _, command, outputs, limited = case
    outputs = [a.format(dir=exemplar.parent) for a in outputs]
    if command == "synth":
        args = ["synth", exemplar, *outputs, *SYNTH]
    elif command == "solid":
        args = ["solid", exemplar, *outputs, *SOLID]
    else:
        args = ["surface", *outputs, *SURFACE]
    for name, data in first_outputs(case[0], args).items():  # the previous outputs
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(data)
    before = _snapshot(tmp_path)
    size = (tmp_path / limited).stat().st_size
    limit = size // 2 if where == "middle" else size - 2
    done = _osmap(args, tmp_path, limit=limit)
    _assert_clean_failure(done, 1, before, tmp_path)
    assert "cannot write" in done.stderr or "failed to write" in done.stderr \
        or "incomplete" in done.stderr, done.stderr


def test_a_jpeg_on_a_full_disk_fails_once_threads_have_run(tmp_path, exemplar):
    """A pyramid (OpenImageIO's thread pool at work) before a JPEG that does not fit: one
    error line, not a hang. JPEG used to be encoded in a forked child, where libjpeg's exit()
    on the failed write waited forever for pool threads that had not been forked (and a killed
    run left the child running and its temporary file behind)."""
    args = ["synth", exemplar, "-o", "out.jpg", "--size", "24", "--preset", "fast", "-q"]
    first = _osmap(args, tmp_path)
    assert first.returncode == 0, first.stderr
    before = _snapshot(tmp_path)

    def child():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        limit = (tmp_path / "out.jpg").stat().st_size // 2
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    code = "import sys; from osmap_cli.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=tmp_path,
                               stderr=subprocess.PIPE, text=True, preexec_fn=child,
                               start_new_session=True)
    try:
        _, err = process.communicate(timeout=300)  # a few seconds unless it hangs
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)  # the run and any child it forked
        process.communicate()
        pytest.fail("writing a JPEG to a full disk hung")
    done = subprocess.CompletedProcess(process.args, process.returncode, "", err)
    _assert_clean_failure(done, 1, before, tmp_path)
    assert "out.jpg: cannot write file" in err, err


@pytest.mark.parametrize("signame,code", [("SIGTERM", 143), ("SIGHUP", 129), ("SIGINT", 130)])
def test_a_signal_mid_run_stops_cleanly(tmp_path, exemplar, signame, code):
    args = ["synth", exemplar, "-o", "out.png", "--size", "32", "-q"]
    assert _osmap(args, tmp_path).returncode == 0
    before = _snapshot(tmp_path)
    script = "import sys; from osmap_cli.cli import main; sys.exit(main(sys.argv[1:]))"
    # a large run, signalled once it has started working (its kernels are loaded by then)
    process = subprocess.Popen([sys.executable, "-c", script, "synth", str(exemplar), "-o",
                                "out.png", "--size", "1024", "-q"], cwd=tmp_path,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(4.0)
    process.send_signal(getattr(signal, signame))
    _, err = process.communicate(timeout=120)
    done = subprocess.CompletedProcess(process.args, process.returncode, "", err)
    _assert_clean_failure(done, code, before, tmp_path)


@pytest.mark.parametrize("signame,code,word", [("SIGINT", 130, "interrupted"),
                                               ("SIGTERM", 143, "terminated")])
def test_a_signal_during_shutdown_is_reported(tmp_path, exemplar, signame, code, word):
    """A stop signal that lands after the output is complete, while the `osmap` process shuts
    down: the output stays as written, and the exit says what happened (code and one line),
    as for a signal mid-run. A sitecustomize hook makes the shutdown last long enough to be
    hit on purpose."""
    script = Path(sys.executable).with_name("osmap")
    if not script.exists():
        pytest.skip("the osmap console script is not installed next to this interpreter")
    hook, flag = tmp_path / "hook", tmp_path / "shutting-down"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(
        "import atexit, time\n"
        "def slow_shutdown():\n"
        f"    open({str(flag)!r}, 'w').close()\n"
        "    time.sleep(3)\n"
        "atexit.register(slow_shutdown)\n")
    work = tmp_path / "work"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(hook)}
    process = subprocess.Popen([str(script), "synth", str(exemplar), "-o", "out.png", *SYNTH],
                               cwd=work, env=env, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not flag.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert flag.exists(), "the run ended before its shutdown began"
    process.send_signal(getattr(signal, signame))
    _, err = process.communicate(timeout=60)
    assert process.returncode == code, err
    assert err.splitlines() == [f"osmap: {word}"], err
    assert (work / "out.png").stat().st_size > 0
    assert not list(work.glob(".osmap-*")), "temporary file left"


@pytest.mark.parametrize("how", [("-j", "2"), ("--scheduler", "local:1")], ids=["j2", "dask"])
def test_the_fast_exit_leaves_no_process_and_no_temporary(tmp_path, exemplar, how):
    """The console script ends without the interpreter's teardown: worker processes (-j), a
    local Dask cluster, multiprocessing's resource tracker and temporary files are all gone or
    going by then, with nothing printed."""
    if how[0] == "--scheduler":
        pytest.importorskip("distributed")
    script = Path(sys.executable).with_name("osmap")
    if not script.exists():
        pytest.skip("the osmap console script is not installed next to this interpreter")
    second = tmp_path / "ex2.png"
    second.write_bytes(exemplar.read_bytes())
    process = subprocess.Popen([str(script), "synth", str(exemplar), str(second), "--out-dir",
                                "out", *SYNTH, *how], cwd=tmp_path, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)
    _, err = process.communicate(timeout=300)  # also waits for every child holding stderr
    assert process.returncode == 0 and err == "", err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["ex.png", "ex2.png"]
    assert not list(tmp_path.rglob(".osmap-*"))
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        table = subprocess.run(["ps", "-eo", "sid=,stat=,args="], capture_output=True,
                               text=True).stdout.splitlines()
        alive = [row for row in table if row.split()[0] == str(process.pid)
                 and not row.split()[1].startswith("Z")]
        if not alive:
            break
        time.sleep(0.2)
    assert not alive, alive


def test_long_output_names_work(tmp_path, exemplar):
    name = "n" * 240 + ".png"  # the temporary file's name must not grow from it
    done = _osmap(["synth", exemplar, "-o", name, *SYNTH], tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / name).exists()
    done = _osmap(["synth", exemplar, "-o", "m" * 256 + ".png", *SYNTH], tmp_path)
    assert done.returncode == 1 and len(done.stderr.splitlines()) == 1, done.stderr
    assert ".osmap-" not in done.stderr  # messages name the user's path, not the temporary


def test_closed_stdout_is_quiet(tmp_path):
    """`osmap presets | head -0`: the reader went away; Unix tools stop quietly (SIGPIPE)."""
    script = "import sys; from osmap_cli.cli import main; sys.exit(main(sys.argv[1:]))"
    for args in (["presets"], ["presets", "show", "default"]):
        with subprocess.Popen([sys.executable, "-c", script, *args], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, cwd=tmp_path) as process:
            process.stdout.close()
            err = process.stderr.read()
            process.wait(timeout=60)
        assert err == ""
        assert process.returncode == 141


def test_file_names_that_are_not_utf8(tmp_path, exemplar):
    source = os.fsencode(tmp_path) + b"/ex\xff.png"
    target = os.fsencode(tmp_path) + b"/out\xfe.png"
    with open(exemplar, "rb") as handle, open(source, "wb") as copy:
        copy.write(handle.read())
    done = subprocess.run([sys.executable, "-c", "import sys; from osmap_cli.cli import main; "
                           "sys.exit(main(sys.argv[1:]))", b"synth", source, b"-o", target,
                           *(a.encode() for a in SYNTH)], capture_output=True)
    assert done.returncode == 0, done.stderr
    assert os.path.getsize(target) > 0


def test_a_named_pipe_is_refused_not_read(tmp_path, run_cli):
    pipe = tmp_path / "pipe.png"
    os.mkfifo(pipe)
    result = run_cli("synth", pipe, "-o", tmp_path / "out.png")
    assert result.code == 1 and "not a regular file" in result.err
    assert len(result.err_lines) == 1


@pytest.mark.parametrize("value", ["0", "lots", "-2"])
def test_bad_thread_counts_are_usage_errors(run_cli, monkeypatch, tmp_path, exemplar, value):
    monkeypatch.setenv("NUMBA_NUM_THREADS", value)
    result = run_cli("synth", exemplar, "-o", tmp_path / "out.png")
    assert result.code == 2 and "NUMBA_NUM_THREADS" in result.err
    assert len(result.err_lines) == 1 and "Traceback" not in result.err


def test_seeds_are_whole_numbers_to_two_to_the_63(run_cli, tmp_path, exemplar):
    big = 2**53 + 1  # not a float: compared exactly
    result = run_cli("synth", exemplar, "-o", tmp_path / "a.png", "--seed", big, *SYNTH)
    assert result.code == 0, result.err
    for command, out in (("synth", "b.png"), ("solid", "b.npy")):
        result = run_cli(command, exemplar, "-o", tmp_path / out, "--seed", 2**63)
        assert result.code == 2 and "--seed" in result.err, result.err
    result = run_cli("surface", "--shape", "torus", "-o", tmp_path / "t.obj", "--seed", -1)
    assert result.code == 2 and "--seed" in result.err, result.err


def test_the_memory_guard_refuses_before_any_work(run_cli, monkeypatch, tmp_path, exemplar):
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "300M")
    result = run_cli("synth", exemplar, "-o", tmp_path / "big.png", "--size", 4096)
    assert result.code == 1 and "4096x4096 texture needs about" in result.err, result.err
    assert "OSMAP_MEMORY_LIMIT" in result.err and list(tmp_path.iterdir()) == []
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "8G")  # a 24 GiB machine's share, whatever runs
    result = run_cli("synth", exemplar, "-o", tmp_path / "huge.png", "--size", 16384)
    assert result.code == 1 and "needs about" in result.err, result.err


def test_the_memory_guard_counts_the_atlas_of_also(run_cli, monkeypatch, tmp_path, exemplar):
    # a 1024x1024 synthesis is estimated at 324 MiB, with --also at 476 MiB (measured: 271 and
    # 414 MiB): a limit between the two lets one through and refuses the other before any work
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "400M")
    result = run_cli("synth", exemplar, "--also", exemplar, "-o", tmp_path / "a.png",
                     "--size", 1024)
    assert result.code == 1 and "1024x1024 texture needs about" in result.err, result.err
    assert list(tmp_path.iterdir()) == []
    from osmap_cli.memory import check_memory, texture_bytes

    check_memory(texture_bytes(1024, 1024, 3), "a 1024x1024 texture")  # no --also: fits


def test_solid_refuses_nan_pixels(run_cli, tmp_path):
    import numpy as np

    from osmap_cli.imageio import write_image

    pixels = np.random.default_rng(0).random((16, 16, 3)).astype(np.float32)
    pixels[3, 4, 1] = np.nan
    pixels[5, 6, 0] = np.inf
    write_image(tmp_path / "nan.exr", pixels, 32)
    result = run_cli("solid", tmp_path / "nan.exr", "-o", tmp_path / "v.npy", *SOLID)
    assert result.code == 1 and "NaN or infinite" in result.err, result.err
    assert len(result.err_lines) == 1


def test_thin_volume_gets_a_coarse_level_small_enough_to_search():
    """`osmap solid EX --size 8x8x1024` planned a single level (no side of 8 voxels can be
    halved), whose exhaustive search compared every voxel with every exemplar pixel: over a
    minute. The plan halves the sides that can be halved, so the coarsest level is as small as a
    cube's; a cube's plan is unchanged."""
    from osmap_cli.solid.pipeline import plan_levels

    exemplar = [(128, 128)]
    shapes = plan_levels(exemplar, (1024, 8, 8), 4)
    assert shapes == [(1024, 8, 8), (512, 8, 8), (256, 8, 8), (128, 8, 8)]
    coarsest_exemplar = 16 * 16  # 128 px halved three times
    assert math.prod(shapes[-1]) * coarsest_exemplar <= 2**21  # was 8 * 8 * 1024 * 128 * 128
    assert plan_levels(exemplar, (128, 128, 128), 4) == [(128,) * 3, (64,) * 3, (32,) * 3,
                                                        (16,) * 3]
    assert plan_levels(exemplar, (16, 64, 40), 4) == [(16, 64, 40), (16, 32, 20), (16, 16, 20)]
    assert plan_levels(exemplar, (16, 16, 16), 4) == [(16, 16, 16)]

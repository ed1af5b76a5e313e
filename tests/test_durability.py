"""Durability of the output transaction under injected faults: os.fsync (of a file, of a
directory) and os.replace raising ENOSPC or EIO, at each step of writing a run's several files
and a slice folder. Every case asserts exit code 1, one `osmap: ...` line naming the output, the
previous outputs byte for byte, and no temporary left (osmap_cli.output's contract)."""

from __future__ import annotations

import errno
import os
import shutil
import stat
from pathlib import Path

import pytest

SYNTH = ("--size", "24", "--preset", "fast", "--levels", "1", "-q")
SOLID = ("--size", "8", "--preset", "fast", "--levels", "1", "-q")
# (id, arguments after the exemplar, the outputs)
RUNS = {
    "files": ("synth", ("-o", "out.png", "--uv-out", "uv.exr", *SYNTH), ("out.png", "uv.exr")),
    "folder": ("solid", ("-o", "slices", "--uv-out", "uv.npy", *SOLID), ("slices", "uv.npy")),
}


@pytest.fixture(scope="module")
def previous(tmp_path_factory, small_samples):
    """For each run: a folder with the exemplar and the run's outputs as a first run wrote
    them, and a snapshot of every file in it."""
    from osmap_cli.cli import main

    made = {}
    for name, (command, args, _) in RUNS.items():
        folder = tmp_path_factory.mktemp(f"durable_{name}")
        shutil.copy(small_samples / "cells.png", folder / "ex.png")
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            assert main([command, "ex.png", *args]) == 0
        finally:
            os.chdir(cwd)
        made[name] = folder
    return made


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _fail_fsync(monkeypatch, code, directories):
    real = os.fsync

    def fsync(fd):
        if stat.S_ISDIR(os.fstat(fd).st_mode) == directories:
            raise OSError(code, os.strerror(code))
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def _fail_replace(monkeypatch, code, call):
    real, calls = os.replace, []

    def replace(src, dst, **kwargs):
        calls.append(dst)
        if len(calls) == call:
            raise OSError(code, os.strerror(code))
        return real(src, dst, **kwargs)

    monkeypatch.setattr(os, "replace", replace)


FAULTS = {
    "fsync of a file": lambda mp, code: _fail_fsync(mp, code, directories=False),
    "fsync of a directory": lambda mp, code: _fail_fsync(mp, code, directories=True),
    "first rename": lambda mp, code: _fail_replace(mp, code, 1),
    "second rename": lambda mp, code: _fail_replace(mp, code, 2),
}


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO], ids=["ENOSPC", "EIO"])
@pytest.mark.parametrize("fault", list(FAULTS))
@pytest.mark.parametrize("run", list(RUNS))
def test_a_failing_sync_or_rename_leaves_the_previous_outputs(run_cli, previous, tmp_path,
                                                              monkeypatch, run, fault, code):
    command, args, outputs = RUNS[run]
    shutil.copytree(previous[run], tmp_path, dirs_exist_ok=True)
    before = _snapshot(tmp_path)
    monkeypatch.chdir(tmp_path)
    with monkeypatch.context() as patch:
        FAULTS[fault](patch, code)
        # another seed: outputs that differ from the previous ones in every byte count
        result = run_cli(command, "ex.png", *args, "--seed", "9")
    assert result.code == 1, result.err
    assert len(result.err_lines) == 1 and result.err.startswith("osmap: "), result.err
    assert os.strerror(code) in result.err and any(o in result.err for o in outputs), result.err
    assert ".osmap-" not in result.err
    assert not list(tmp_path.rglob(".osmap-*")), "temporary left"
    assert _snapshot(tmp_path) == before, "a previous output was changed"


@pytest.mark.parametrize("run", list(RUNS))
def test_a_failed_first_run_leaves_nothing(run_cli, small_samples, tmp_path, monkeypatch, run):
    """No previous outputs: the directory sync after the renames fails, the new outputs are
    taken away again."""
    command, args, _ = RUNS[run]
    shutil.copy(small_samples / "cells.png", tmp_path / "ex.png")
    monkeypatch.chdir(tmp_path)
    real = os.fsync

    def fsync(fd):
        if os.path.samestat(os.fstat(fd), os.stat(tmp_path)):
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        return real(fd)

    with monkeypatch.context() as patch:
        patch.setattr(os, "fsync", fsync)
        result = run_cli(command, "ex.png", *args)
    assert result.code == 1 and len(result.err_lines) == 1, result.err
    assert sorted(os.listdir(tmp_path)) == ["ex.png"]


def test_without_hard_links_the_previous_file_is_moved_and_restored(run_cli, previous, tmp_path,
                                                                    monkeypatch):
    """A file system without hard links: the previous file is moved aside for the commit and
    moved back when a later step fails."""
    command, args, _ = RUNS["files"]
    shutil.copytree(previous["files"], tmp_path, dirs_exist_ok=True)
    before = _snapshot(tmp_path)
    monkeypatch.chdir(tmp_path)

    def no_link(*args, **kwargs):
        raise OSError(errno.EPERM, os.strerror(errno.EPERM))

    with monkeypatch.context() as patch:
        patch.setattr(os, "link", no_link)
        _fail_fsync(patch, errno.EIO, directories=True)
        result = run_cli(command, "ex.png", *args, "--seed", "9")
    assert result.code == 1 and len(result.err_lines) == 1, result.err
    assert not list(tmp_path.rglob(".osmap-*"))
    assert _snapshot(tmp_path) == before
    # and a run that succeeds replaces the outputs and keeps no backup
    with monkeypatch.context() as patch:
        patch.setattr(os, "link", no_link)
        result = run_cli(command, "ex.png", *args, "--seed", "5")
    assert result.code == 0, result.err
    assert not list(tmp_path.rglob(".osmap-*"))
    after = _snapshot(tmp_path)
    assert after.keys() == before.keys()
    assert all(after[p] != before[p] for p in after if p.name != "ex.png")


def test_a_file_system_that_cannot_sync_directories_is_not_an_error(run_cli, previous, tmp_path,
                                                                    monkeypatch):
    command, args, _ = RUNS["folder"]
    shutil.copytree(previous["folder"], tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    before = _snapshot(tmp_path)
    with monkeypatch.context() as patch:
        _fail_fsync(patch, errno.EINVAL, directories=True)
        result = run_cli(command, "ex.png", *args, "--seed", "4")
    assert result.code == 0, result.err
    assert not list(tmp_path.rglob(".osmap-*"))
    assert _snapshot(tmp_path)[Path("uv.npy")] != before[Path("uv.npy")]


# ---------------------------------------------------------------------------------------------
# the transaction itself (osmap_cli.output), without a command around it


def _write_text(text):
    def write(temp):
        with open(temp, "w") as handle:
            handle.write(text)
    return write


def _write_folder(names):
    def write(temp):
        for name in names:
            Path(temp, name).write_text(name)
    return write


def test_a_folder_output_replaces_the_previous_folder(tmp_path):
    from osmap_cli.output import write_atomically

    write_atomically(str(tmp_path / "vol"), _write_folder(["a", "b"]), folder=True)
    write_atomically(str(tmp_path / "vol"), _write_folder(["c"]), folder=True)
    assert sorted(os.listdir(tmp_path)) == ["vol"]
    assert sorted(os.listdir(tmp_path / "vol")) == ["c"]


def test_a_link_as_target_is_replaced_and_put_back_on_failure(tmp_path, monkeypatch):
    """A symbolic link (to a folder) where a file goes: the link itself is replaced; when the
    commit fails the link is back, still a link."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out.txt").symlink_to(tmp_path / "elsewhere")
    with monkeypatch.context() as patch:
        _fail_fsync(patch, errno.EIO, directories=True)
        with pytest.raises(OsmapError, match=r"out\.txt: cannot write file \(Input/output"):
            write_atomically(str(tmp_path / "out.txt"), _write_text("new"))
    assert (tmp_path / "out.txt").is_symlink() and (tmp_path / "elsewhere").is_dir()
    assert sorted(os.listdir(tmp_path)) == ["elsewhere", "out.txt"]
    write_atomically(str(tmp_path / "out.txt"), _write_text("new"))
    assert not (tmp_path / "out.txt").is_symlink() and (tmp_path / "out.txt").read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["elsewhere", "out.txt"]


@pytest.mark.parametrize("raised, message", [
    (OSError("disk gone"), "o.txt: cannot write file (disk gone)"),
    (OSError(errno.ENOSPC, "No space left on device"),
     "o.txt: cannot write file (No space left on device)"),
    (ValueError("bad pixels"), "o.txt: failed to write (ValueError: bad pixels)"),
])
def test_a_writer_failure_names_the_target(tmp_path, raised, message):
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    def write(temp):
        Path(temp).write_text("half")
        raise raised

    with pytest.raises(OsmapError) as info:
        write_atomically(str(tmp_path / "o.txt"), write)
    assert str(info.value) == f"{tmp_path}/{message}"
    assert os.listdir(tmp_path) == []


def test_an_incomplete_write_is_an_error(tmp_path, monkeypatch):
    from osmap_cli import output
    from osmap_cli.errors import OsmapError

    monkeypatch.setattr(output.os.path, "getsize", lambda path: 3)
    with pytest.raises(OsmapError) as info:
        output.write_bytes(str(tmp_path / "f.bin"), b"12345")
    assert str(info.value) == f"{tmp_path / 'f.bin'}: incomplete write (3 of 5 bytes)"

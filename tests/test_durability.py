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
# method osmap: the transaction is under test, not the structure method (whose particle fit on
# an 8^3 volume from this small exemplar costs seconds a run)
SOLID = ("--size", "8", "--preset", "fast", "--levels", "1", "--method", "osmap", "-q")
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


def _fail_fsync_of(monkeypatch, directory, code=errno.EIO):
    """os.fsync of DIRECTORY itself fails: the sync of the renames into it."""
    real = os.fsync

    def fsync(fd):
        if os.path.samestat(os.fstat(fd), os.stat(directory)):
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
    # the output whose step failed, by its name (the second rename of the files run is the
    # second file's: the first file's previous output stays by a hard link, a folder's is
    # moved aside by a rename of its own)
    failed = outputs[1] if (run, fault) == ("files", "second rename") else outputs[0]
    assert result.err_lines == [f"osmap: error: {failed}: cannot write file "
                                f"({os.strerror(code)})"], result.err
    assert not list(tmp_path.rglob(".osmap-*")), "temporary left"
    assert _snapshot(tmp_path) == before, "a previous output was changed"


@pytest.mark.parametrize("run", list(RUNS))
def test_a_failed_first_run_leaves_nothing(run_cli, small_samples, tmp_path, monkeypatch, run):
    """No previous outputs: the directory sync after the renames fails, the new outputs are
    taken away again."""
    command, args, _ = RUNS[run]
    shutil.copy(small_samples / "cells.png", tmp_path / "ex.png")
    monkeypatch.chdir(tmp_path)
    with monkeypatch.context() as patch:
        _fail_fsync_of(patch, tmp_path)
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


@pytest.mark.parametrize("kind", ["folder", "file"])
def test_a_link_as_target_is_replaced_and_put_back_on_failure(tmp_path, monkeypatch, kind):
    """A symbolic link (to a folder or a file) where a file goes: the link itself is replaced,
    what it points to is untouched; when the commit fails the link is back, still a link."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    pointee = tmp_path / "elsewhere"
    pointee.mkdir() if kind == "folder" else pointee.write_text("theirs")
    (tmp_path / "out.txt").symlink_to(pointee)
    with monkeypatch.context() as patch:
        _fail_fsync_of(patch, tmp_path)
        with pytest.raises(OsmapError, match=r"out\.txt: cannot write file \(Input/output"):
            write_atomically(str(tmp_path / "out.txt"), _write_text("new"))
    assert (tmp_path / "out.txt").is_symlink()
    assert os.readlink(tmp_path / "out.txt") == str(pointee)
    assert sorted(os.listdir(tmp_path)) == ["elsewhere", "out.txt"]
    write_atomically(str(tmp_path / "out.txt"), _write_text("new"))
    assert not (tmp_path / "out.txt").is_symlink() and (tmp_path / "out.txt").read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["elsewhere", "out.txt"]
    assert pointee.is_dir() if kind == "folder" else pointee.read_text() == "theirs"


def test_the_previous_file_stays_in_place_until_the_new_one_replaces_it(tmp_path, monkeypatch):
    """A reader never finds the target missing: the previous file is kept by a second hard
    link, not moved away, and one rename puts the new file in its place."""
    from osmap_cli.output import write_atomically

    target = tmp_path / "out.txt"
    write_atomically(str(target), _write_text("old"))
    real, renames = os.replace, []

    def replace(src, dst, **kwargs):
        renames.append((os.path.basename(dst), target.exists()))
        return real(src, dst, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(os, "replace", replace)
        write_atomically(str(target), _write_text("new"))
    assert renames == [("out.txt", True)]
    assert target.read_text() == "new" and os.listdir(tmp_path) == ["out.txt"]


def test_a_failed_commit_puts_the_previous_folder_back(tmp_path, monkeypatch):
    """The new folder is in place when the sync of the directory fails: it is taken away and
    the previous folder, moved aside for the commit, is moved back."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    write_atomically(str(tmp_path / "vol"), _write_folder(["a", "b"]), folder=True)
    with monkeypatch.context() as patch:
        _fail_fsync_of(patch, tmp_path)
        with pytest.raises(OsmapError, match=r"vol: cannot write file \(Input/output error\)"):
            write_atomically(str(tmp_path / "vol"), _write_folder(["c"]), folder=True)
    assert os.listdir(tmp_path) == ["vol"]
    assert sorted(os.listdir(tmp_path / "vol")) == ["a", "b"]


def test_a_restore_that_fails_too_reports_the_first_failure(tmp_path, monkeypatch):
    """The sync fails and so does putting the previous file back (best effort): the error is
    the sync's, on one line, and the previous file is not deleted (it stays under its hidden
    name)."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    write_atomically(str(tmp_path / "out.txt"), _write_text("old"))
    with monkeypatch.context() as patch:
        _fail_fsync_of(patch, tmp_path)
        _fail_replace(patch, errno.EROFS, 2)  # the first rename commits, the second restores
        with pytest.raises(OsmapError) as info:
            write_atomically(str(tmp_path / "out.txt"), _write_text("new"))
    assert str(info.value) == f"{tmp_path / 'out.txt'}: cannot write file (Input/output error)"
    assert "old" in [p.read_text() for p in tmp_path.iterdir()]


def test_a_previous_folder_that_cannot_be_removed_does_not_fail_the_run(tmp_path, monkeypatch):
    """After a successful commit the previous folder is removed as far as it goes (a busy
    mount or an open file on a network share may refuse): the run has succeeded."""
    from osmap_cli.output import write_atomically

    write_atomically(str(tmp_path / "vol"), _write_folder(["a", "b"]), folder=True)

    def busy(*args, **kwargs):
        raise OSError(errno.EBUSY, os.strerror(errno.EBUSY))

    with monkeypatch.context() as patch:
        patch.setattr(os, "rmdir", busy)
        write_atomically(str(tmp_path / "vol"), _write_folder(["c"]), folder=True)
    assert sorted(os.listdir(tmp_path / "vol")) == ["c"]


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

    target = str(tmp_path / "f.bin")
    real = os.path.getsize
    monkeypatch.setattr(output.os.path, "getsize",
                        lambda path: 3 if path == target else real(path))
    with pytest.raises(OsmapError) as info:
        output.write_bytes(target, b"12345")
    assert str(info.value) == f"{tmp_path / 'f.bin'}: incomplete write (3 of 5 bytes)"


def test_an_output_directory_that_cannot_be_written_is_named(tmp_path, monkeypatch):
    """Refused before any work, naming the directory as the user gave it ("." for none)."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import check_parent

    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    # folders that exist but may be neither written nor searched (as root every folder may)
    monkeypatch.setattr(os, "access", lambda path, mode: mode == os.F_OK)
    for target, shown in (("out.png", "."), ("sub/out.png", "sub"), ("sub/BOX/", "sub")):
        with pytest.raises(OsmapError) as info:
            check_parent(target)
        assert str(info.value) == f"{target}: output directory {shown} is not writable"
    with pytest.raises(OsmapError) as info:
        check_parent("gone/BOX/")  # a folder target given with its slash
    assert str(info.value) == "gone/BOX/: output directory gone does not exist"


def test_a_folder_target_may_end_in_a_slash(tmp_path):
    from osmap_cli.output import write_atomically

    for _ in range(2):  # made, then replaced
        write_atomically(f"{tmp_path / 'BOX'}/", _write_folder(["a"]), folder=True)
        assert os.listdir(tmp_path) == ["BOX"] and os.listdir(tmp_path / "BOX") == ["a"]


def test_a_folder_that_cannot_be_opened_to_sync_is_skipped(tmp_path, monkeypatch):
    """A directory one may write but not read cannot be opened to sync it: skipped, as a file
    system without directory syncs is; a file that cannot be opened is an error."""
    from osmap_cli.errors import OsmapError
    from osmap_cli.output import write_atomically

    real, files_too = os.open, []

    def open_(path, flags, *args, **kwargs):
        temporary = os.path.basename(path).startswith(".osmap-")
        if os.path.isdir(path) or (files_too and temporary):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))
        return real(path, flags, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(os, "open", open_)
        write_atomically(str(tmp_path / "vol"), _write_folder(["a"]), folder=True)
        assert os.listdir(tmp_path / "vol") == ["a"]
        files_too.append(True)
        with pytest.raises(OsmapError, match=r"o\.txt: cannot write file \(Permission denied\)"):
            write_atomically(str(tmp_path / "o.txt"), _write_text("x"))
    assert os.listdir(tmp_path) == ["vol"]


def test_a_transaction_discarded_twice_can_stage_again(tmp_path):
    from osmap_cli.output import Outputs

    with Outputs() as outputs:
        outputs.stage(str(tmp_path / "a.txt"), _write_text("a"))
        outputs.discard()
        outputs.discard()
        assert os.listdir(tmp_path) == []
        outputs.stage(str(tmp_path / "b.txt"), _write_text("b"))
        outputs.commit()
    assert os.listdir(tmp_path) == ["b.txt"]


# (extension, format label, what the writer lost); a PNG cut short is refused by its writer
LOSSY = [("exr", "EXR", "scanlines"), ("tif", "TIFF", "scanlines"), ("png", "PNG", "pixels"),
         ("exr", "EXR", "pixels"), ("tif", "TIFF", "pixels")]


@pytest.mark.parametrize("ext, label, lost", LOSSY, ids=[f"{c[0]}-{c[2]}" for c in LOSSY])
def test_a_writer_that_reports_success_is_checked_by_reading_back(tmp_path, monkeypatch, ext,
                                                                   label, lost):
    """Image writers do not all report a failed write (a full disk can leave a cut-off file
    behind a successful close): each image is read back, and one that lost scanlines or holds
    other pixels is an error, with nothing left behind."""
    import numpy as np

    from osmap_cli import image_write
    from osmap_cli.errors import OsmapError
    from osmap_cli.imageio import write_image

    def lossy(out, data):
        if lost == "scanlines":
            out.write_scanlines(0, data.shape[0] // 2, 0, data[:data.shape[0] // 2])
        else:
            out.write_image(data[::-1].copy())
        return True

    monkeypatch.setattr(image_write, "_write_pixels", lossy)
    pixels = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    with pytest.raises(OsmapError) as info:
        write_image(tmp_path / f"out.{ext}", pixels)
    assert str(info.value) == (f"{tmp_path / f'out.{ext}'}: failed to write {label} file (the "
                               "file on disk is incomplete: is the disk full?)")
    assert os.listdir(tmp_path) == []

"""One output transaction for every command and format: stage, verify, commit or discard.

    with Outputs() as outputs:
        outputs.stage("out/a.png", lambda temp: imageio.encode_image(temp, pixels, ...))
        outputs.stage("out/vol", write_slices, folder=True)
        outputs.commit()

Each output is written to a hidden temporary sibling of its target (a short name, so that a
target name of up to 255 bytes still works), flushed and synced to disk, and verified by its
writer (images are read back). Only when every output of the run is complete are they moved onto
their targets; if anything fails first (a full disk, a signal, a bad value) every temporary is
removed and no target is touched. The commit keeps each previous output under a hidden name
until every rename and the sync of their directories have succeeded: if one fails, the outputs
already moved are put back, so a run replaces all of its outputs or none. Error messages name
the target, never the temporary.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
from collections.abc import Callable

from osmap_cli.errors import OsmapError

__all__ = ["Outputs", "check_parent", "synced_file", "write_atomically", "write_bytes"]

TEMP_PREFIX = ".osmap-"


def _strip(path: str) -> str:
    return path.rstrip("/" + os.sep) or path


def temp_path(target: str, suffix: str = "") -> str:
    """A new hidden sibling of TARGET: .osmap-<random><suffix> in the same directory."""
    directory = os.path.dirname(os.path.abspath(_strip(target)))
    return os.path.join(directory, f"{TEMP_PREFIX}{secrets.token_hex(6)}{suffix}")


def check_parent(path: str, label: str | None = None) -> None:
    """Refuse a target whose directory is missing or not writable (before any work); the
    message starts with LABEL (default: the path)."""
    fspath = _strip(path)
    label = label or path
    parent = os.path.dirname(os.path.abspath(fspath))
    shown = os.path.dirname(fspath) or "."
    if not os.path.isdir(parent):
        what = "is not a directory" if os.path.exists(parent) else "does not exist"
        raise OsmapError(f"{label}: output directory {shown} {what}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OsmapError(f"{label}: output directory {shown} is not writable")


# a file system that cannot sync a directory says so with one of these: nothing to do there
_NO_DIRECTORY_SYNC = {errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP}


def _fsync_path(path: str) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except PermissionError:
        if os.path.isdir(path):
            return  # a directory we may write but not read cannot be opened to sync it
        raise
    try:
        os.fsync(fd)
    except OSError as exc:
        if not (exc.errno in _NO_DIRECTORY_SYNC and os.path.isdir(path)):
            raise
    finally:
        os.close(fd)


def _fsync_tree(path: str) -> None:
    """fsync a file, or every file in a folder and the folder itself."""
    if os.path.isdir(path):
        for name in sorted(os.listdir(path)):
            _fsync_tree(os.path.join(path, name))
    _fsync_path(path)


def _is_folder(path: str) -> bool:
    return os.path.isdir(path) and not os.path.islink(path)


def _set_aside(temp: str, fspath: str) -> tuple[str | None, bool]:
    """Keep the previous output at FSPATH under a hidden name until the commit is done:
    (that name or None when there is none, whether FSPATH was moved away for it). A file stays
    in place (a second hard link keeps it); a folder, which cannot be replaced in one step, and
    a file on a file system without hard links are moved."""
    if not os.path.lexists(fspath) or (_is_folder(fspath) and not _is_folder(temp)):
        return None, False  # nothing to keep, or os.replace refuses anyway
    backup = temp_path(fspath)
    if not _is_folder(fspath):
        try:
            os.link(fspath, backup, follow_symlinks=False)
            return backup, False
        except OSError:
            pass
    os.replace(fspath, backup)
    return backup, True


def _put_back(fspath: str, backup: str | None, moved: bool, replaced: bool) -> None:
    """Undo one output's commit as far as it went (best effort: this runs after a failure)."""
    with contextlib.suppress(OSError):
        if replaced and (backup is None or moved):
            aside = temp_path(fspath)
            os.replace(fspath, aside)  # the new output, removed below
            _remove(aside)
        if backup is not None and (moved or replaced):
            os.replace(backup, fspath)
        elif backup is not None:
            _remove(backup)  # a link to the untouched previous output


@contextlib.contextmanager
def synced_file(path: str):
    """open(path, "wb") whose every write, the flush, an fsync and the close are checked (a
    full disk raises OSError here, not later)."""
    with open(path, "wb") as handle:
        yield handle
        handle.flush()
        os.fsync(handle.fileno())


def write_bytes(path: str, data: bytes) -> None:
    """Write DATA to PATH (synced) and check that the file holds all of it."""
    with synced_file(path) as handle:
        handle.write(data)
    if os.path.getsize(path) != len(data):
        raise OsmapError(f"{path}: incomplete write ({os.path.getsize(path)} of {len(data)} "
                         "bytes)")


def _remove(path: str) -> None:
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.remove(path)


def _write_error(target: str, temp: str, exc: BaseException) -> OsmapError:
    if isinstance(exc, OsmapError):
        return OsmapError(str(exc).replace(temp, target))
    if isinstance(exc, OSError):
        return OsmapError(f"{target}: cannot write file ({exc.strerror or exc})")
    return OsmapError(f"{target}: failed to write ({type(exc).__name__}: {exc})")


class Outputs:
    """The files (and folders) of one run, all committed or none (see the module docstring)."""

    def __init__(self) -> None:
        self._staged: list[tuple[str, str]] = []  # (temp, target)

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def stage(self, target: str, write: Callable[[str], None], *, folder: bool = False,
              suffix: str | None = None) -> None:
        """Run write(temp) into a new temporary sibling of TARGET (a folder made empty first
        when FOLDER), then sync it. SUFFIX defaults to TARGET's extension (writers that pick
        the format by extension need it)."""
        if suffix is None:
            suffix = "" if folder else os.path.splitext(_strip(target))[1]
        temp = temp_path(target, suffix)
        try:
            if folder:
                os.mkdir(temp)
            write(temp)
            _fsync_tree(temp)
        except BaseException as exc:
            _remove(temp)
            if not isinstance(exc, Exception):
                raise  # Ctrl-C, SIGTERM: the caller reports them
            raise _write_error(target, temp, exc) from None
        self._staged.append((temp, target))

    def commit(self) -> None:
        """Move every staged output onto its target (a previous slice folder is replaced) and
        sync their directories; on any failure every target is left as it was."""
        done: list[tuple[str, str | None, bool]] = []  # (target path, backup, moved)
        target = ""
        try:
            for temp, target in self._staged:
                fspath = _strip(target)
                backup, moved = _set_aside(temp, fspath)
                try:
                    os.replace(temp, fspath)
                except BaseException:
                    _put_back(fspath, backup, moved, replaced=False)
                    raise
                done.append((fspath, backup, moved))
            for directory in sorted({os.path.dirname(os.path.abspath(p)) for p, _, _ in done}):
                target = next(t for _, t in self._staged
                              if os.path.dirname(os.path.abspath(_strip(t))) == directory)
                _fsync_path(directory)  # the renames themselves reach the disk
        except BaseException as exc:
            for fspath, backup, moved in reversed(done):
                _put_back(fspath, backup, moved, replaced=True)
            if isinstance(exc, OSError):
                raise OsmapError(f"{target}: cannot write file ({exc.strerror or exc})") from None
            raise
        self._staged = []
        for _, backup, _ in done:
            if backup is not None:
                _remove(backup)

    def discard(self) -> None:
        """Remove every staged temporary; no target is touched."""
        for temp, _ in self._staged:
            _remove(temp)
        self._staged = []


def write_atomically(target: str, write: Callable[[str], None], *, folder: bool = False) -> None:
    """One output in a transaction of its own: staged with write(temp), then committed."""
    with Outputs() as outputs:
        outputs.stage(target, write, folder=folder)
        outputs.commit()

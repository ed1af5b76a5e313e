"""Numba's cache of osmap's kernels: where it is, the portable copy that ships, and its markers.

Numba caches a kernel's machine code per signature and per CPU (its index key holds the target
CPU's name and features), in a cache folder per source folder: NUMBA_CACHE_DIR/<folder>_<hash>
when that variable is set, else the package's ``__pycache__`` when writable, else a user-wide
folder. Two kinds of entries matter here:

- **portable**: compiled for LLVM's ``generic`` CPU of the architecture when the package is built
  (``osmap_kernels/portable-cache/``, one folder per package plus ``manifest.json``). Valid on any
  CPU of the architecture, about 15 % slower. It is *seeded* into the active cache folder (its
  entries added to numba's index files there), so that numba finds it wherever its cache is.
- **host**: compiled for this CPU (in the background after a run that used the portable
  entries, or by ``osmap warmup``). Numba never loads an entry of another CPU (its index key);
  the marker that says "this folder holds host entries for every portable signature" is named
  after this CPU's identity, so a cache filled on another machine is never taken for ready.

Nothing here imports numba unless it has to (seeding, reading signatures): checking the markers
costs a few file reads, paid by every `osmap` run.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys

__all__ = ["Manifest", "cache_folder", "cpu_identity", "host_marker", "load_manifest",
           "merge_folder", "package_dir", "portable_root", "seed", "sources_digest",
           "write_manifest"]

MANIFEST = "manifest.json"
LOCK = "osmap-kernels.lock"
# The packages whose modules hold cached Numba kernels: every module under kernels/ (installed as
# osmap_kernels) and osmap_cli.surface's two. The portable build finds which ones compiled.
PACKAGES = ("osmap_kernels", "osmap_cli.surface")


def python_tag() -> str:
    """The part of numba's cache file names that depends on the interpreter ("py311")."""
    return f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"


def package_dir(package: str) -> str | None:
    """The folder of an importable package, without importing it (None if not found)."""
    import importlib.util

    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return os.path.abspath(list(spec.submodule_search_locations)[0])


def portable_root() -> str | None:
    """The portable cache shipped with the kernels (None when the package has none)."""
    folder = package_dir("osmap_kernels")
    return None if folder is None else os.path.join(folder, "portable-cache")


def _subpath(folder: str) -> str:
    # numba.core.caching._CacheLocator.get_suitable_cache_subpath, for a file in FOLDER
    import hashlib

    return "_".join([os.path.basename(folder), hashlib.sha1(folder.encode()).hexdigest()])


def cache_folder(folder: str) -> str:
    """The folder numba caches the kernels of source folder FOLDER in (its locators' order:
    NUMBA_CACHE_DIR, a writable __pycache__ beside the sources, the user-wide cache)."""
    base = os.environ.get("NUMBA_CACHE_DIR")
    if base:
        return os.path.join(base, _subpath(folder))
    in_tree = os.path.join(folder, "__pycache__")
    if _writable(in_tree):
        return in_tree
    from numba.misc.appdirs import AppDirs  # rare: read-only install

    return os.path.join(AppDirs(appname="numba", appauthor=False).user_cache_dir,
                        _subpath(folder))


def _writable(path: str) -> bool:
    if os.path.isdir(path):
        return os.access(path, os.W_OK | os.X_OK)
    parent = os.path.dirname(path)
    return os.path.isdir(parent) and os.access(parent, os.W_OK | os.X_OK)


def cpu_identity() -> str:
    """A short checksum naming this CPU model and its instruction-set features (zlib's CRC-32,
    already imported: every run computes it)."""
    import zlib

    text = ""
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as handle:
            wanted = ("vendor_id", "model name", "flags", "features", "cpu part")
            lines = []
            for line in handle:
                if not line.strip():
                    break  # the first processor describes them all
                if line.split(":", 1)[0].strip().lower() in wanted:
                    lines.append(line.strip())
            text = "\n".join(lines)
    if not text:
        import platform

        text = f"{platform.machine()} {platform.processor()}"
    return f"{zlib.crc32(text.encode()):08x}"


def sources_digest(packages) -> str:
    """sha256 over the Python sources of PACKAGES (names): the portable entries are valid only
    for these bytes (numba stamps each index with its source file's hash too)."""
    import hashlib

    digest = hashlib.sha256()
    for package in sorted(packages):
        folder = package_dir(package)
        if folder is None:
            digest.update(f"{package}: missing".encode())
            continue
        for name in sorted(os.listdir(folder)):
            if name.endswith(".py"):
                digest.update(f"{package}/{name}\0".encode())
                with open(os.path.join(folder, name), "rb") as handle:
                    digest.update(handle.read())
    return digest.hexdigest()


class Manifest(dict):
    """manifest.json of a portable cache: numba (version), python (tag), digest (of the
    sources), packages (names, each a subfolder), kernels (count)."""

    root: str = ""

    @property
    def key(self) -> str:
        return self["digest"][:16]

    def folder(self, package: str) -> str:
        return os.path.join(self.root, package)


def load_manifest(root: str | None = None) -> Manifest | None:
    """The portable cache's manifest, if there is one for this interpreter."""
    root = root or portable_root()
    if root is None:
        return None
    try:
        with open(os.path.join(root, MANIFEST), encoding="utf-8") as handle:
            manifest = Manifest(json.load(handle))
    except (OSError, ValueError):
        return None
    if manifest.get("python") != python_tag() or not manifest.get("packages"):
        return None
    manifest.root = root
    return manifest


def write_manifest(root: str, packages: list[str], signatures: int) -> None:
    """ROOT/manifest.json for the portable entries in ROOT/<package>/ (this numba, this
    interpreter, the packages' sources as they are now)."""
    import numba

    manifest = {"numba": numba.__version__, "python": python_tag(),
                "digest": sources_digest(packages), "packages": list(packages), "cpu": "generic",
                "signatures": signatures}
    os.makedirs(root, exist_ok=True)
    with open(os.path.join(root, MANIFEST), "w", encoding="utf-8") as handle:
        json.dump(manifest, handle, indent=1)


def host_marker(manifest: Manifest, suffix: str = "ready") -> str:
    """The file whose presence says: the active cache holds this CPU's entries for every
    signature of MANIFEST (suffix "failed": compiling them failed; it holds the error)."""
    folder = cache_folder(package_dir("osmap_kernels"))
    return os.path.join(folder, f"osmap-host-{manifest.key}-{cpu_identity()}.{suffix}")


def _seed_marker(manifest: Manifest, folder: str) -> str:
    return os.path.join(folder, f"osmap-portable-{manifest.key}.seeded")


def touch(path: str, text: str = "") -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    temp = f"{path}.{os.getpid()}.tmp"
    with open(temp, "w", encoding="utf-8") as handle:
        handle.write(text)
    os.replace(temp, path)


@contextlib.contextmanager
def locked(folder: str, wait: bool = True, name: str = LOCK):
    """An exclusive lock on the lock file NAME in FOLDER; yields False when WAIT is False and
    another process holds it."""
    os.makedirs(folder, exist_ok=True)
    handle = open(os.path.join(folder, name), "a")
    try:
        try:
            import fcntl
        except ImportError:  # no flock: no lock
            yield True
            return
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        yield True
    finally:
        handle.close()


def portable_usable(manifest: Manifest) -> bool:
    """Whether MANIFEST's entries can serve this installation: the same numba and the same
    kernel sources (a development tree edited since the build: no)."""
    if manifest.get("digest") != sources_digest(manifest["packages"]):
        return False
    import numba

    return manifest.get("numba") == numba.__version__


def seed(manifest: Manifest) -> None:
    """Add the portable entries to numba's active cache folders (once per folder and build)."""
    for package in manifest["packages"]:
        source = package_dir(package)
        if source is None:
            continue
        target = cache_folder(source)
        marker = _seed_marker(manifest, target)
        if os.path.exists(marker):
            continue
        with locked(target):
            if not os.path.exists(marker):
                merge_folder(manifest.folder(package), target)
                touch(marker)


def _read_index(path: str):
    """(numba version, source stamp, {key: data file}) of a numba index file, or None."""
    import pickle

    try:
        with open(path, "rb") as handle:
            version = pickle.load(handle)
            stamp, overloads = pickle.loads(handle.read())
    except Exception:  # noqa: BLE001 - an unreadable index is an empty one
        return None
    return version, stamp, overloads


def index_entries(folder: str):
    """{index file base name: (stamp, {key: data file})} of the numba index files in FOLDER
    written by this numba."""
    import numba

    found = {}
    with contextlib.suppress(FileNotFoundError):
        for name in sorted(os.listdir(folder)):
            if name.endswith(".nbi"):
                read = _read_index(os.path.join(folder, name))
                if read is not None and read[0] == numba.__version__:
                    found[name[:-4]] = read[1:]
    return found


def merge_folder(source: str, target: str, accept=None) -> int:
    """Copy every numba cache entry of SOURCE that TARGET lacks into TARGET (ACCEPT(key)
    filters them): the data files byte for byte, under free names, then numba's index file of
    each kernel rewritten with them (an index of other sources is replaced). Nothing is
    unpickled but the indexes. Returns how many entries were added."""
    import numba
    from numba.core.serialize import dumps

    os.makedirs(target, exist_ok=True)
    added = 0
    for base, (stamp, overloads) in index_entries(source).items():
        wanted = {k: v for k, v in overloads.items() if accept is None or accept(k)}
        if not wanted:
            continue
        index_path = os.path.join(target, f"{base}.nbi")
        read = _read_index(index_path)
        present = read[2] if read and read[0] == numba.__version__ and read[1] == stamp else {}
        merged = dict(present)
        used = set(present.values())
        number = 0
        for key, data_name in wanted.items():
            if key in merged:
                continue
            while True:
                number += 1
                name = f"{base}.{number}.nbc"
                if name not in used:
                    break
            with open(os.path.join(source, data_name), "rb") as handle:
                data = handle.read()
            _write_atomic(os.path.join(target, name), data)
            merged[key] = name
            used.add(name)
            added += 1
        if len(merged) > len(present):
            _write_atomic(index_path, pickle_version(numba.__version__)
                          + dumps((stamp, merged)))
    return added


def pickle_version(version: str) -> bytes:
    import pickle

    return pickle.dumps(version, protocol=-1)


def _write_atomic(path: str, data: bytes) -> None:
    temp = f"{path}.{os.getpid()}.tmp"
    with open(temp, "wb") as handle:
        handle.write(data)
    os.replace(temp, path)


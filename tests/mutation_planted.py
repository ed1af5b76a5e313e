"""Planted bugs: plausible mistakes, each planted alone in a scratch copy of the tree, must make
the test files aimed at them fail (docs/testing.md, "Planted bugs").

    python tests/mutation_planted.py                 # every bug below
    python tests/mutation_planted.py layout-global   # some of them, by name

Each bug is one text substitution in one file (it must match exactly once: a bug whose code
moved is reported, not skipped). The copy holds the tracked files with `osmap_kernels` and
`osmap_presets` linked to their folders, and is imported first (checked), so the working tree
is never touched. Prints one line a bug (caught or not, the seconds its tests took); exit
status 1 when a bug is not caught.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# name -> (file, the code, the bug, the test files aimed at it)
BUGS = {
    "schedule-linear": (
        "osmap_cli/engine.py",
        "s = (np.exp(self.phi * t / total) - np.exp(self.phi)) / (1.0 - np.exp(self.phi))",
        "s = 1.0 - t / total",
        ["tests/test_engine.py"]),
    "layout-global": (
        "osmap_cli/synth/organise.py",
        "window=search_window(exemplar_shape, out_shape, jac, opts.window_scale),",
        "window=tuple(out_shape),",
        ["tests/test_mechanisms.py"]),
    "paper-global": (
        "osmap_cli/synth/paper.py",
        "window=search_window(exemplar_shape, out_shape, jac, opts.window_scale),",
        "window=tuple(out_shape),",
        ["tests/test_mechanisms.py"]),
    "layout-isotropic": (
        "osmap_cli/synth/organise.py",
        "orientation=component_orientation(jac, opts.som_anisotropy),",
        "orientation=component_orientation(jac, 1.0),",
        ["tests/test_mechanisms.py"]),
    "one-sweep-fewer": (
        "osmap_cli/synth/pipeline.py",
        "pos = refine(pos, feat, jac_field, lo, hi, sweeps, opts,",
        "pos = refine(pos, feat, jac_field, lo, hi, sweeps - 1, opts,",
        ["tests/test_mechanisms.py"]),
    "provenance-drops-anisotropy": (
        "osmap_cli/synth/job.py",
        "if spec.kind is float and not spec.tunable and value != getattr(defaults, field.name):",
        "if spec.kind is float and not spec.tunable and value != getattr(defaults, field.name)"
        " and field.name != \"anisotropy\":",
        ["tests/test_option_roundtrip.py"]),
    "no-read-back": (
        "osmap_cli/image_write.py",
        "    _verify(fspath, name, label, fmt, depth, data)\n",
        "",
        ["tests/test_durability.py"]),
    "no-fsync-before-commit": (
        "osmap_cli/output.py",
        "            _fsync_tree(temp)\n",
        "",
        ["tests/test_durability.py"]),
    "no-put-back-after-commit": (
        "osmap_cli/output.py",
        "                _put_back(fspath, backup, moved, replaced=True)",
        "                pass",
        ["tests/test_durability.py"]),
    "backups-kept": (
        "osmap_cli/output.py",
        "            if backup is not None:\n                _remove(backup)",
        "            pass",
        ["tests/test_durability.py"]),
}


def _scratch_copy() -> Path:
    copy = Path(tempfile.mkdtemp(prefix="osmap-planted-"))
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                           check=True).stdout.decode().split("\0")
    for name in filter(None, files):
        if (ROOT / name).is_file():
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, copy / name)
    os.symlink("kernels", copy / "osmap_kernels")
    os.symlink("presets", copy / "osmap_presets")
    return copy


def _env(copy: Path) -> dict:
    return {**os.environ, "PYTHONPATH": str(copy)}


def _check_imports(copy: Path) -> None:
    found = subprocess.run([sys.executable, "-c", "import osmap_cli, osmap_kernels; "
                            "print(osmap_cli.__file__); print(osmap_kernels.__file__)"],
                           cwd=copy, env=_env(copy), capture_output=True, text=True,
                           check=True).stdout.split()
    if not all(Path(f).resolve().is_relative_to(copy.resolve()) for f in found):
        raise SystemExit(f"the scratch copy is not what gets imported: {found}")


def plant(copy: Path, name: str) -> tuple[bool, float]:
    """Run the tests of bug NAME planted in COPY; (caught, seconds). The file is restored."""
    path, code, bug, tests = BUGS[name]
    target = copy / path
    original = target.read_text("utf-8")
    if original.count(code) != 1:
        raise SystemExit(f"{name}: the code to change is not found once in {path}")
    target.write_text(original.replace(code, bug), "utf-8")
    started = time.monotonic()
    try:
        done = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p",
                               "no:cacheprovider", *tests], cwd=copy, env=_env(copy),
                              capture_output=True, text=True)
    finally:
        target.write_text(original, "utf-8")
    return done.returncode != 0, time.monotonic() - started


def main(names: list[str]) -> int:
    unknown = [n for n in names if n not in BUGS]
    if unknown:
        print(f"unknown bugs: {', '.join(unknown)}; known: {', '.join(BUGS)}", file=sys.stderr)
        return 2
    copy = _scratch_copy()
    missed = 0
    try:
        _check_imports(copy)
        for name in names or list(BUGS):
            caught, seconds = plant(copy, name)
            missed += not caught
            print(f"{name:30} {'caught' if caught else 'NOT CAUGHT':10} {seconds:6.0f} s  "
                  f"{' '.join(Path(t).name for t in BUGS[name][3])}", flush=True)
    finally:
        shutil.rmtree(copy, ignore_errors=True)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

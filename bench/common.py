"""Shared helpers for the benchmark scripts: paths, machine description, timing, Markdown.

Nothing here imports osmap itself, so the helpers also work before the package is importable.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import platform
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
BENCH_DIR = REPO_ROOT / "bench"
DOCS_DIR = REPO_ROOT / "docs"
SAMPLES_DIR = REPO_ROOT / "samples"
# Team-shared material (exemplars, peers, the quality meter). Never copied into the repo.
SHARED_DIR = Path(os.environ.get("OSMAP_SHARED", REPO_ROOT.parent / "shared")).resolve()
SMALL_EXEMPLARS = SHARED_DIR / "exemplars" / "small"
FULL_EXEMPLARS = SHARED_DIR / "exemplars"
PEERS_DIR = SHARED_DIR / "design" / "peers"
PEERS_MD = SHARED_DIR / "design" / "PEERS.md"
TEXMETRICS = SHARED_DIR / "tools" / "texmetrics.py"
# the meter runs in its own environment (../shared/tools/README.md)
TEXMETRICS_PY = Path(os.environ.get("TEXMETRICS_PYTHON", "/tmp/texmetrics-venv/bin/python"))


def measure_parser(doc: str, seeds: str | None = None, sheet: bool = True):
    """argparse parser of a measurement script: --keep DIR, and --seeds and --sheet PATH when
    asked for."""
    import argparse

    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--keep", help="write the images here (default: a temporary folder)")
    if seeds is not None:
        parser.add_argument("--seeds", default=seeds, help="comma-separated seeds")
    if sheet:
        parser.add_argument("--sheet", help="write a contact sheet of the first seed here")
    return parser


@contextlib.contextmanager
def measurement_folder(keep: str | None):
    """The folder a measurement writes its images to (`keep`, else a temporary one), once the
    texmetrics venv is known to exist (else exit with one line)."""
    if not TEXMETRICS_PY.exists():
        sys.exit(f"{TEXMETRICS_PY}: the texmetrics venv is missing (see ../shared/tools/README.md)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        yield folder


def texmetrics_coh(exemplar: Path | str, image: Path | str) -> float:
    """texmetrics.py's coh_mean of the 2D image file against the exemplar file."""
    out = subprocess.run([str(TEXMETRICS_PY), str(TEXMETRICS), str(exemplar), str(image),
                          "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)["2d"]["coh_mean"]


def tmp_root() -> Path:
    return Path(os.environ.get("TMPDIR") or "/tmp")


def shared_note(what: str) -> str:
    """The Markdown note printed when the shared folder is missing."""
    return (f"_Skipped: {what} needs the team-shared folder `{SHARED_DIR}` (exemplars, peers, "
            "texmetrics), which is not present on this machine._\n")


def rel(path: Path | str) -> str:
    """`path` relative to the repo root when inside it, else as given."""
    p = Path(path)
    try:
        return str(p.resolve().relative_to(REPO_ROOT))
    except ValueError:
        return str(p)


def shared_rel(path: Path | str) -> str:
    """A shared path spelt `../shared/...` (relative to the repo root) when possible."""
    p = Path(path).resolve()
    try:
        return "../shared/" + str(p.relative_to(SHARED_DIR))
    except ValueError:
        return str(p)


# ----------------------------------------------------------------------------- environment

def utc_now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def ram_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / 1024**2
    except (OSError, ValueError, IndexError):
        pass
    return None


def core_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def load_average() -> str:
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except OSError:
        return "?"


def package_version(name: str) -> str:
    try:
        module = __import__(name)
    except Exception:  # noqa: BLE001 - any import failure means "not available"
        return "not installed"
    return str(getattr(module, "__version__", getattr(module, "VERSION_STRING", "?")))


def git_commit() -> str:
    """Short hash, '+dirty' when the work tree differs from it; 'no commits yet' before any."""
    def git(*args):
        return subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True,
                              text=True, timeout=30)
    try:
        head = git("rev-parse", "--short", "HEAD")
        if head.returncode != 0:
            return "no commits yet"
        dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
        return head.stdout.strip() + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown (git not available)"


def machine_lines() -> list[str]:
    ram = ram_gib()
    ram_text = f"{ram:.1f} GiB RAM" if ram else "RAM unknown"
    return [
        f"- Date: {utc_now()}",
        f"- Machine: {cpu_model()}, {core_count()} cores, {ram_text}, "
        f"{platform.system()} {platform.release()}",
        f"- Python {platform.python_version()}, numpy {package_version('numpy')}, "
        f"numba {package_version('numba')}, OpenImageIO {package_version('OpenImageIO')}",
        f"- Git commit: {git_commit()}",
    ]


def stamp() -> str:
    """One line saying when, at which commit and on which machine a section was produced."""
    return f"{utc_now()}, commit {git_commit()}, {cpu_model()} ({core_count()} cores)"


# ----------------------------------------------------------------------------- the CLI

def venv_bin() -> Path:
    return Path(sys.executable).parent


def osmap_cli() -> Path | None:
    """The `osmap` script next to this interpreter, if it exists and `osmap synth --help` works."""
    exe = venv_bin() / "osmap"
    if not exe.exists():
        return None
    try:
        ok = subprocess.run([str(exe), "synth", "--help"], capture_output=True, timeout=120)
    except (OSError, subprocess.SubprocessError):
        return None
    return exe if ok.returncode == 0 else None


# ----------------------------------------------------------------------------- timing

def timed_run(cmd: Sequence[str], env: dict | None = None, cwd: Path | None = None,
              output: list | None = None):
    """Run `cmd` to completion; returns (wall seconds, user+sys CPU seconds of the child).
    With OUTPUT, its stdout is appended to that list (else discarded).

    Raises RuntimeError with the command's stderr if it fails.
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(list(cmd), env=env, cwd=cwd, text=True, stderr=subprocess.PIPE,
                          stdout=subprocess.DEVNULL if output is None else subprocess.PIPE)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"command failed ({proc.returncode}): {shlex.join(cmd)}\n"
                           f"{proc.stderr.strip()[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if output is not None:
        output.append(proc.stdout)
    return wall, cpu


class Stats:
    """Median / min / max of repeated measurements."""

    def __init__(self, values: Sequence[float]):
        self.values = list(values)
        self.median = statistics.median(self.values)
        self.min = min(self.values)
        self.max = max(self.values)

    def text(self, digits: int = 2) -> str:
        if len(self.values) == 1:
            return f"{self.median:.{digits}f}"
        return f"{self.median:.{digits}f} ({self.min:.{digits}f}–{self.max:.{digits}f})"


# ----------------------------------------------------------------------------- Markdown

def md_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table with padded columns, so it also reads well in a terminal."""
    def cell(v):
        return str(v).replace("|", "\\|")
    table = [[cell(h) for h in headers]] + [[cell(v) for v in row] for row in rows]
    widths = [max(len(r[i]) for r in table if i < len(r)) for i in range(len(headers))]
    lines = []
    for k, row in enumerate(table):
        padded = (v.ljust(w) for v, w in zip(row, widths, strict=False))
        lines.append("| " + " | ".join(padded) + " |")
        if k == 0:
            lines.append("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines) + "\n"


def fmt(value, digits: int = 2) -> str:
    if value is None:
        return "–"
    if isinstance(value, float) and value != value:  # NaN
        return "–"
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}f}"


# ----------------------------------------------------------------------------- texmetrics

def texmetrics_python() -> Path:
    """The quality meter's own interpreter, created on first use."""
    venv = tmp_root() / "texmetrics-venv"
    py = venv / "bin" / "python"
    if py.exists():
        return py
    print(f"creating the texmetrics venv at {venv} (one-off) ...", file=sys.stderr, flush=True)
    base = "python3"
    subprocess.run([base, "-m", "venv", str(venv)], check=True)
    subprocess.run([str(py), "-m", "pip", "install", "--quiet", "numpy", "scipy",
                    "scikit-image", "scikit-learn", "pillow", "openimageio"], check=True)
    return py


def texmetrics(exemplar: Path, output: Path, tileable: bool = False,
               errmap: Path | None = None) -> dict:
    """Run the independent quality meter; returns its JSON (metrics under "2d")."""
    cmd = [str(texmetrics_python()), str(TEXMETRICS), str(exemplar), str(output), "--json"]
    if tileable:
        cmd.append("--tileable")
    if errmap is not None:
        cmd += ["--errmap", str(errmap)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"texmetrics failed on {output}: {proc.stderr.strip()[-1500:]}")
    return json.loads(proc.stdout)


# ----------------------------------------------------------------------------- misc

def load_module(path: Path, name: str):
    """Import a Python file by path (None if it does not exist)."""
    if not path.exists():
        return None
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def section_main(doc: str, run, argv=None) -> int:
    """`python bench/bench_X.py [--quick]`: print the section that run(quick, log) returns."""
    import argparse
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a shorter pass")
    args = ap.parse_args(argv)
    print(run(quick=args.quick, log=lambda m: print(m, file=sys.stderr, flush=True)))
    return 0


def fresh_dir(prefix: str) -> Path:
    return Path(tempfile.mkdtemp(prefix=prefix, dir=tmp_root()))

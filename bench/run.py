"""Run the benchmarks and write BENCHMARKS.md at the repo root (`make bench`).

Sections:
  synth    speed of `osmap synth` end to end (bench/bench_synth.py), about 10 min
  quality  texmetrics scores on the dev exemplars + docs/ contact sheets (bench/quality.py),
           about 15 min; needs ../shared (skipped with a note when absent)
  surface  bench/bench_surface.py's run() (skipped with a note when the file is absent)
  solid    bench/bench_solid.py's run() (skipped with a note when the file is absent)
  carve    a 50,000-triangle mesh baked to 2048x2048 from a volume, stages, peak memory
           against mesh and map size (bench/bench_carve.py), about 3 min
  som      the classic SOM case against MiniSom (bench/bench_som.py), about 20 min
  kernels  OS-Map kernel paths and winner search against window size (bench/bench_kernels.py)
  roofline bytes and flops per kernel against measured bandwidth and flop rate (same file)
  memory   1024x1024 end to end and peak RSS against output size (bench/bench_memory.py)
  cluster  a 40-job batch with -j 2 against --scheduler local:2, per-task overhead of the
           Dask path (bench/bench_cluster.py), about 5 min; needs the `cluster` extra
  large    4096x4096 from a 256 px exemplar: wall, CPU, peak RSS against the memory guard's
           estimate (bench/bench_large.py), about 4 min on two free cores; needs ../shared
  compile  the Numba compile of each kernel from an empty cache, and warm loads
           (bench/bench_compile.py), about 3 min
  peer     osmap and the Resynthesizer engine run in turn, wall and CPU ratios
           (bench/bench_peer.py), about 3 min; needs ../shared/peers (skipped with a note)

    .venv/bin/python bench/run.py [--quick] [--only synth,som,...] [--out BENCHMARKS.md]

Sections that are not run keep their text from the previous file, so `--only quality` does not
wipe the speed table; every section records when, at which commit and on which machine it was
measured, and the command that measures it again.
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
import time
import traceback
from pathlib import Path

import common
from common import BENCH_DIR, REPO_ROOT

SECTIONS = ("synth", "quality", "surface", "solid", "carve", "som", "kernels", "roofline", "memory",
            "cluster", "large", "compile", "peer")
MARKER = "<!-- bench-section: {} -->"
MARKER_RE = re.compile(r"^<!-- bench-section: (\w+) -->\s*$", re.M)
# For files written before the markers existed: the heading each section starts with.
HEADING_PREFIX = {"synth": "## Speed", "quality": "## Quality", "surface": "## Surface",
                  "solid": "## Solid", "som": "## Classic SOM", "kernels": "## OS-Map kernels",
                  "carve": "## Carve",
                  "roofline": "## Roofline", "memory": "## Memory",
                  "cluster": "## Clusters", "large": "## Large outputs", "compile": "## Compile",
                  "peer": "## Against the Resynthesizer"}
COMMANDS = {s: f".venv/bin/python bench/run.py --only {s}" for s in SECTIONS}
# Sections written by hand from a script of their own (bench/regularity.py --bars,
# bench/guide_measure.py: too long for a bench pass) and kept as they are, each after the
# section named beside it.
KEPT = {"regular": "quality", "guides": "regular"}


def previous_sections(path: Path) -> dict[str, str]:
    """{section: text} from an earlier BENCHMARKS.md."""
    if not path.exists():
        return {}
    text = path.read_text()
    found = {}
    marks = list(MARKER_RE.finditer(text))
    if marks:
        for k, m in enumerate(marks):
            end = marks[k + 1].start() if k + 1 < len(marks) else len(text)
            found[m.group(1)] = text[m.end():end].strip("\n") + "\n"
        return found
    # no markers: split at "## " headings
    chunks = re.split(r"(?m)^(?=## )", text)
    for chunk in chunks:
        for name, prefix in HEADING_PREFIX.items():
            if chunk.startswith(prefix):
                found[name] = chunk.strip("\n") + "\n"
    return found


def run_synth(args, log) -> str:
    import bench_synth
    return bench_synth.run(quick=args.quick, log=log)


def run_quality(args, log) -> str:
    import contact_sheet
    import quality
    return quality.run(quick=args.quick, outdir=args.quality_dir, jobs=args.jobs,
                       sheets=contact_sheet.make_all, log=log)


def run_optional(name: str, title: str, args, log) -> str:
    """The section from bench/bench_<name>.py's run() (a note when the file does not exist)."""
    path = BENCH_DIR / f"bench_{name}.py"
    module = common.load_module(path, f"bench_{name}")
    if module is None:
        log(f"[{name}] {common.rel(path)} does not exist yet: section skipped")
        return (f"## {title}\n\n_Skipped: `bench/bench_{name}.py` does not exist yet "
                f"({common.utc_now()})._\n")
    params = inspect.signature(module.run).parameters
    text = module.run(quick=args.quick) if "quick" in params else module.run()
    text = text.strip("\n") + "\n"
    if COMMANDS[name] not in text:
        # add the stamp and the command under the section's first heading
        lines = text.splitlines()
        at = next((i for i, ln in enumerate(lines) if ln.startswith("## ")), None)
        quick = " --quick" if args.quick else ""
        note = f"_{common.stamp()}; reproduce with `{COMMANDS[name]}{quick}`._"
        if at is None:
            lines = [f"## {title}", "", note, "", *lines]
        else:
            lines[at + 1:at + 1] = ["", note]
        text = "\n".join(lines) + "\n"
    return text


def run_surface(args, log) -> str:
    return run_optional("surface", "Surface", args, log)


def run_solid(args, log) -> str:
    return run_optional("solid", "Solid", args, log)


def run_carve(args, log) -> str:
    import bench_carve
    return bench_carve.run(quick=args.quick, log=log)


def run_som(args, log) -> str:
    import bench_som
    return bench_som.run(quick=args.quick, log=log)


def run_kernels(args, log) -> str:
    import bench_kernels
    return bench_kernels.run_kernels(quick=args.quick, log=log)


def run_roofline(args, log) -> str:
    import bench_kernels
    return bench_kernels.run_roofline(quick=args.quick, log=log)


def run_cluster(args, log) -> str:
    import bench_cluster
    return bench_cluster.run(quick=args.quick, log=log)


def run_memory(args, log) -> str:
    import bench_memory
    return bench_memory.run(quick=args.quick, log=log)


def run_large(args, log) -> str:
    import bench_large
    return bench_large.run(quick=args.quick, log=log)


def run_compile(args, log) -> str:
    import bench_compile
    return bench_compile.run(quick=args.quick, log=log)


def run_peer(args, log) -> str:
    import bench_peer
    return bench_peer.run(quick=args.quick, log=log)


RUNNERS = {"synth": run_synth, "quality": run_quality, "surface": run_surface,
           "solid": run_solid, "carve": run_carve, "som": run_som, "kernels": run_kernels,
           "roofline": run_roofline, "memory": run_memory, "cluster": run_cluster,
           "large": run_large, "compile": run_compile, "peer": run_peer}


def _order() -> list[str]:
    """SECTIONS with each kept section placed after the one it follows."""
    order = list(SECTIONS)
    for name, after in KEPT.items():
        order.insert(order.index(after) + 1, name)
    return order


def header(ran: list[str], quick: bool, durations: dict) -> str:
    done = ", ".join(f"{s} ({durations[s] / 60:.1f} min)" for s in ran) or "none"
    lines = [
        "# osmap benchmarks",
        "",
        "Generated by `bench/run.py` (`make bench`). Reproduce everything with "
        "`.venv/bin/python bench/run.py`, one section with "
        f"`.venv/bin/python bench/run.py --only {'|'.join(SECTIONS)}`, a shorter pass with "
        "`--quick`. Sections not rerun are kept from the previous file; each section says when, "
        "at which commit and on which machine it was measured. Times are from a shared 2-core "
        "development machine: read the ratios and the baselines measured in the same run, not "
        "the absolute seconds.",
        "",
        "Last run:",
        "",
        *common.machine_lines(),
        f"- Sections run: {done}{' (--quick)' if quick else ''}",
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--quick", action="store_true",
                    help="fewer samples, runs and variants (a few minutes in all)")
    ap.add_argument("--only", help="comma-separated sections: " + ", ".join(SECTIONS))
    ap.add_argument("--out", type=Path, default=REPO_ROOT / "BENCHMARKS.md")
    ap.add_argument("--quality-dir", type=Path, default=None,
                    help="scratch folder for the quality outputs "
                         "(default ${TMPDIR:-/tmp}/osmap-quality)")
    ap.add_argument("--jobs", type=int, default=2, help="texmetrics processes in parallel")
    args = ap.parse_args(argv)
    wanted = args.only.split(",") if args.only else list(SECTIONS)
    bad = [s for s in wanted if s not in SECTIONS]
    if bad:
        ap.error(f"unknown section(s) {bad}; choose from {', '.join(SECTIONS)}")
    out_path = args.out if args.out.is_absolute() else Path.cwd() / args.out

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    texts, durations, failed = {}, {}, []
    for name in SECTIONS:
        if name not in wanted:
            continue
        log(f"=== {name} ===")
        t0 = time.perf_counter()
        try:
            texts[name] = RUNNERS[name](args, log).strip("\n") + "\n"
        except Exception:  # noqa: BLE001 - record the failure and go on with the others
            failed.append(name)
            tb = traceback.format_exc()
            log(tb)
            title = HEADING_PREFIX[name].removeprefix("## ")
            texts[name] = (f"## {title}\n\n_Failed on {common.stamp()} "
                           f"(`{COMMANDS[name]}`):_\n\n```\n{tb.strip()[-3000:]}\n```\n")
        durations[name] = time.perf_counter() - t0
        log(f"=== {name}: {durations[name] / 60:.1f} min ===")

    # read the kept sections only now: another run may have rewritten the file meanwhile
    previous = previous_sections(out_path)
    parts = [header([s for s in SECTIONS if s in texts], args.quick, durations)]
    for name in _order():
        body = texts.get(name) or previous.get(name)
        if body is None and name in KEPT:
            continue
        if body is None:
            body = (f"## {HEADING_PREFIX[name].removeprefix('## ')}\n\n"
                    f"_Not measured yet: run `{COMMANDS[name]}`._\n")
        parts.append(MARKER.format(name) + "\n\n" + body)
    out_path.write_text("\n".join(p.strip("\n") + "\n" for p in parts))
    log(f"wrote {out_path}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""Quality of `synthesize` on the development exemplars, scored by the independent meter.

Variants (all seed 1, library calls, outputs saved as 8-bit PNG and scored from the file):
  default   ../shared/exemplars/small/NAME.png (128 px) -> 256x256, default options
  paper     the same with method="paper"
  tileable  the same with tileable=True (scored with texmetrics --tileable: seam_z)
  512       ../shared/exemplars/NAME.png (longest side <= 256 px) -> 512x512, default options

Outputs go to OUTDIR/<variant>/<name>.png (default ${TMPDIR:-/tmp}/osmap-quality) with the
meter's JSON next to them (<name>.json) and the synthesis seconds in timings.json.
Synthesis runs first, one exemplar at a time (so the seconds are not disturbed by the meter);
then the meter runs on --jobs processes in parallel. --overlap starts scoring while synthesis is
still running (faster; the seconds are then noisy).

For tuning:
    python bench/quality.py --variant default --names bricks_dark_red,wood_planks_horizontal \\
        --outdir /tmp/q1 --set occupancy=1.0 --set knn=6
prints the per-exemplar table, a one-line summary of the medians and the acceptance checks.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import common
from common import FULL_EXEMPLARS, PEERS_MD, SMALL_EXEMPLARS, fmt, md_table

COMMAND = ".venv/bin/python bench/run.py --only quality"
SEED = 1
METRICS = ("coh_mean", "coh_p95", "compl", "hist", "spec", "scale", "copy_frac", "copy_side")


@dataclass(frozen=True)
class Variant:
    name: str
    source: str  # "small" or "full"
    size: int
    options: dict
    tileable: bool = False
    description: str = ""

    def exemplar(self, name: str) -> Path:
        return (SMALL_EXEMPLARS if self.source == "small" else FULL_EXEMPLARS) / f"{name}.png"


VARIANTS = {
    "default": Variant("default", "small", 256, {},
                       description="128 px exemplars -> 256x256, default options"),
    "paper": Variant("paper", "small", 256, {"method": "paper"},
                     description='128 px exemplars -> 256x256, `method="paper"`'),
    "tileable": Variant("tileable", "small", 256, {"tileable": True}, tileable=True,
                        description="128 px exemplars -> 256x256, `tileable=True`, "
                                    "scored with `--tileable` (wrap-around patches)"),
    "512": Variant("512", "full", 512, {},
                   description="full exemplars (longest side <= 256 px) -> 512x512, default "
                               "options"),
}

# Acceptance checks: (label, statistic, metric, op, threshold).
# statistic: "median" over exemplars, "max" = every exemplar, "absmaxlog2" = |log2 scale| max.
FOUNDATION = [
    ("median coh_mean", "median", "coh_mean", "<=", 3.2),
    ("median coh_p95", "median", "coh_p95", "<=", 9.0),
    ("median compl", "median", "compl", "<=", 2.8),
    ("|log2 scale| every exemplar", "absmaxlog2", "scale", "<", 0.25),
    ("median copy_side", "median", "copy_side", "<=", 64),
]
BEST_PEER = [
    ("median coh_mean", "median", "coh_mean", "<=", 1.67),
    ("median coh_p95", "median", "coh_p95", "<=", 6.97),
    ("median compl", "median", "compl", "<=", 1.68),
    ("median spec", "median", "spec", "<=", 0.05),
    ("median copy_side", "median", "copy_side", "<=", 55),
    ("max copy_side", "max", "copy_side", "<=", 80),
    ("|log2 scale| every exemplar", "absmaxlog2", "scale", "<", 0.2),
]
SEAMLESS = [("seam_z every exemplar", "max", "seam_z", "<", 3.0)]
ACCEPTANCE_VARIANTS = ("default", "tileable", "512")  # paper: for information only

# Peers' medians from ../shared/design/PEERS.md (parsed from the file when it is present;
# these copies of its figures are used only when it is absent or unparsable).
PEERS_FALLBACK = {
    "resynth": dict(coh_mean=2.01, coh_p95=7.57, compl=1.68, hist=0.63, spec=0.051,
                    abslog2scale=0.029, copy_frac=0.59, cpu_s=1.2, copy_side=55,
                    copy_side_max=73),
    "embark": dict(coh_mean=3.16, coh_p95=8.98, compl=2.82, hist=0.81, spec=0.108,
                   abslog2scale=0.088, copy_frac=0.42, cpu_s=3.2, copy_side=40,
                   copy_side_max=51),
    "quilting": dict(coh_mean=1.67, coh_p95=6.98, compl=1.99, hist=0.50, spec=0.043,
                     abslog2scale=0.016, copy_frac=0.63, cpu_s=8.4, copy_side=41,
                     copy_side_max=51),
    "opara_patch": dict(coh_mean=1.89, coh_p95=6.97, compl=2.25, hist=0.66, spec=0.055,
                        abslog2scale=0.055, copy_frac=0.55, cpu_s=1.8, copy_side=33,
                        copy_side_max=34),
    "blocks32": dict(coh_mean=2.39, coh_p95=11.57, compl=0.92, hist=0.46, spec=0.143,
                     abslog2scale=0.157, copy_frac=0.69, cpu_s=0.2, copy_side=31,
                     copy_side_max=31),
    "tile": dict(coh_mean=0.37, coh_p95=0.00, compl=0.00, hist=0.00, spec=0.031,
                 abslog2scale=0.031, copy_frac=0.95, cpu_s=0.1, copy_side=127,
                 copy_side_max=127),
}
PEER_ORDER = ("resynth", "embark", "quilting", "opara_patch", "blocks32", "tile")


def log2abs(scale) -> float | None:
    if scale is None or not scale or scale <= 0:
        return None
    return abs(math.log2(scale))


# ----------------------------------------------------------------------------- results

@dataclass
class Result:
    variant: Variant
    names: list
    metrics: dict = field(default_factory=dict)  # name -> flat dict of numbers
    seconds: dict = field(default_factory=dict)  # name -> synthesis wall seconds
    errors: dict = field(default_factory=dict)  # name -> message
    options: dict = field(default_factory=dict)  # overrides given with --set
    wall: float = 0.0  # whole variant, synthesis + scoring

    def values(self, metric: str) -> list:
        out = []
        for n in self.names:
            v = self.metrics.get(n, {}).get(metric)
            if v is not None and not (isinstance(v, float) and math.isnan(v)):
                out.append(v)
        return out

    def stat(self, statistic: str, metric: str):
        if statistic == "absmaxlog2":
            vals = [log2abs(v) for v in self.values(metric)]
            vals = [v for v in vals if v is not None]
            return max(vals) if vals else None
        vals = self.values(metric)
        if not vals:
            return None
        return statistics.median(vals) if statistic == "median" else max(vals)

    def medians(self) -> dict:
        m = {k: self.stat("median", k) for k in (*METRICS, "seam_z")}
        logs = [log2abs(v) for v in self.values("scale")]
        logs = [v for v in logs if v is not None]
        m["abslog2scale"] = statistics.median(logs) if logs else None
        m["abslog2scale_max"] = max(logs) if logs else None
        m["copy_side_max"] = self.stat("max", "copy_side")
        m["seam_z_max"] = self.stat("max", "seam_z")
        secs = [self.seconds[n] for n in self.names if n in self.seconds]
        m["seconds"] = statistics.median(secs) if secs else None
        m["n"] = len([n for n in self.names if n in self.metrics])
        return m


def checks(result: Result) -> list[tuple[str, bool | None, str, str]]:
    """[(level, passed or None when unmeasured, text, short label)] for this variant."""
    levels = [("foundation", FOUNDATION), ("best-peer", BEST_PEER)]
    if result.variant.tileable:
        levels.append(("seamless", SEAMLESS))
    out = []
    for level, rules in levels:
        for label, statistic, metric, op, limit in rules:
            value = result.stat(statistic, metric)
            if value is None:
                out.append((level, None, f"{label}: not measured", label))
                continue
            ok = value <= limit if op == "<=" else value < limit
            shown = f"{value:.3f}" if abs(value) < 1 else f"{value:.2f}"
            short = label.replace(" every exemplar", " max").replace("median ", "")
            out.append((level, ok, f"{label} {shown} {op} {limit}", f"{short} {shown}"))
    return out


def check_lines(result: Result) -> list[str]:
    scope = ("project acceptance" if result.variant.name in ACCEPTANCE_VARIANTS
             else "for information only")
    lines = []
    for level, ok, text, _ in checks(result):
        mark = "PASS" if ok else ("FAIL" if ok is False else "N/A ")
        lines.append(f"- {mark} [{result.variant.name} / {level}] {text}")
    n = len(result.names) - len(result.metrics)
    if n:
        lines.append(f"- NOTE [{result.variant.name}] {n} exemplar(s) not scored: "
                     + ", ".join(sorted(result.errors)) + " (checks use the others)")
    return [f"Checks for `{result.variant.name}` ({scope}):", *lines]


def level_summary(result: Result) -> str:
    parts = []
    for level in ("foundation", "best-peer", "seamless"):
        items = [(ok, short) for lv, ok, _, short in checks(result) if lv == level]
        if not items:
            continue
        passed = sum(1 for ok, _ in items if ok)
        failed = [short for ok, short in items if not ok]
        verdict = "PASS" if passed == len(items) else "FAIL"
        detail = f" ({'; '.join(failed)})" if failed else ""
        parts.append(f"{level} {verdict} {passed}/{len(items)}{detail}")
    return "; ".join(parts)


def compact(result: Result) -> str:
    m = result.medians()
    line = (f"{result.variant.name:>8} n={m['n']} med coh {fmt(m['coh_mean'])}/"
            f"{fmt(m['coh_p95'])} compl {fmt(m['compl'])} hist {fmt(m['hist'])} "
            f"spec {fmt(m['spec'], 3)} |log2s| {fmt(m['abslog2scale'], 3)} "
            f"(max {fmt(m['abslog2scale_max'], 3)}) copy {fmt(m['copy_frac'])} "
            f"side {fmt(m['copy_side'], 0)}/max {fmt(m['copy_side_max'], 0)}")
    if result.variant.tileable:
        line += f" seam_z med {fmt(m['seam_z'])}/max {fmt(m['seam_z_max'])}"
    line += f" synth {fmt(m['seconds'], 1)} s"
    return line


# ----------------------------------------------------------------------------- work

def exemplar_names(source: str = "small") -> list[str]:
    folder = SMALL_EXEMPLARS if source == "small" else FULL_EXEMPLARS
    return sorted(p.stem for p in folder.glob("*.png"))


def default_outdir() -> Path:
    return common.tmp_root() / "osmap-quality"


def synth_one(variant: Variant, name: str, out: Path, seed: int, overrides: dict) -> float:
    from osmap_cli.imageio import read_image, write_image
    from osmap_cli.synth import SynthOptions, synthesize

    exemplar = read_image(str(variant.exemplar(name))).pixels
    opts = SynthOptions(width=variant.size, height=variant.size, seed=seed,
                        **{**variant.options, **overrides})
    t0 = time.perf_counter()
    res = synthesize(exemplar, opts)
    seconds = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    write_image(str(out), res.pixels)
    return seconds


def warm_up(variant: Variant, name: str, overrides: dict) -> None:
    """An untimed small synthesis so the first timed one does not load/compile kernels."""
    from osmap_cli.imageio import read_image
    from osmap_cli.synth import SynthOptions, synthesize

    exemplar = read_image(str(variant.exemplar(name))).pixels
    synthesize(exemplar, SynthOptions(width=64, height=64, seed=0,
                                      **{**variant.options, **overrides}))


def flatten(meter_json: dict) -> dict:
    flat = dict(meter_json.get("2d", {}))
    for key in ("seam", "seam_z"):
        if key in meter_json:
            flat[key] = meter_json[key]
    return flat


def evaluate(variant: Variant, names: list[str], outdir: Path, seed: int = SEED, jobs: int = 2,
             reuse: bool = False, overlap: bool = False, errmap: bool = False,
             overrides: dict | None = None, log=print) -> Result:
    """Synthesize (unless reusing saved outputs), score and collect one variant."""
    overrides = dict(overrides or {})
    folder = outdir / variant.name
    folder.mkdir(parents=True, exist_ok=True)
    result = Result(variant, list(names), options=overrides)
    timings_path = folder / "timings.json"
    saved = json.loads(timings_path.read_text()) if timings_path.exists() else {}
    t_start = time.perf_counter()
    lock = threading.Lock()

    def score(name: str):
        out = folder / f"{name}.png"
        cached = folder / f"{name}.json"
        if reuse and not errmap and cached.exists() and out.exists() \
                and cached.stat().st_mtime >= out.stat().st_mtime:
            data = json.loads(cached.read_text())
            if ("seam_z" in data) == variant.tileable:  # scored the way this variant is
                with lock:
                    result.metrics[name] = flatten(data)
                return
        try:
            data = common.texmetrics(variant.exemplar(name), out, tileable=variant.tileable,
                                     errmap=folder / f"{name}_err.png" if errmap else None)
        except Exception as exc:  # noqa: BLE001 - one failure must not stop the others
            with lock:
                result.errors[name] = f"texmetrics: {exc}"
            log(f"[{variant.name}] {name}: texmetrics failed: {exc}")
            return
        (folder / f"{name}.json").write_text(json.dumps(data, indent=1))
        with lock:
            result.metrics[name] = flatten(data)

    pool = ThreadPoolExecutor(max_workers=max(1, jobs))
    futures = []
    try:
        warmed = False
        for name in names:
            src = variant.exemplar(name)
            out = folder / f"{name}.png"
            if not src.exists():
                result.errors[name] = f"missing exemplar {src}"
                log(f"[{variant.name}] {name}: missing exemplar {src}")
                continue
            if reuse and out.exists():
                if name in saved:
                    result.seconds[name] = saved[name]
            else:
                if not warmed:
                    warm_up(variant, name, overrides)
                    warmed = True
                try:
                    result.seconds[name] = synth_one(variant, name, out, seed, overrides)
                except Exception as exc:  # noqa: BLE001 - report and go on
                    result.errors[name] = f"synthesis: {type(exc).__name__}: {exc}"
                    log(f"[{variant.name}] {name}: synthesis failed: {exc}")
                    continue
                log(f"[{variant.name}] {name}: synthesized in {result.seconds[name]:.1f} s")
            if overlap:
                futures.append(pool.submit(score, name))
        saved.update(result.seconds)
        timings_path.write_text(json.dumps(saved, indent=1, sort_keys=True))
        if not overlap:
            futures = [pool.submit(score, n) for n in names if n not in result.errors]
        for f in futures:
            f.result()
    finally:
        pool.shutdown(wait=True)
    result.wall = time.perf_counter() - t_start
    log(f"[{variant.name}] done in {result.wall:.0f} s")
    return result


# ----------------------------------------------------------------------------- tables

def variant_table(result: Result) -> str:
    cols = list(METRICS) + (["seam_z"] if result.variant.tileable else []) + ["synth s"]
    rows = []
    for n in result.names:
        m = result.metrics.get(n)
        if m is None:
            rows.append([n, *(["–"] * (len(cols) - 1)),
                         fmt(result.seconds.get(n), 1) if n in result.seconds else "–"])
            continue
        row = [n]
        for c in cols[:-1]:
            digits = 3 if c in ("spec", "scale") else (0 if c == "copy_side" else 2)
            row.append(fmt(m.get(c), digits))
        row.append(fmt(result.seconds.get(n), 1))
        rows.append(row)
    med = result.medians()
    worst = {c: result.stat("max", c) for c in cols[:-1]}
    # the worst scale is the one furthest from 1 in log2
    scales = result.values("scale")
    worst["scale"] = max(scales, key=lambda s: log2abs(s) or 0) if scales else None
    for label, stats in (("**median**", med), ("worst", worst)):
        row = [label]
        for c in cols[:-1]:
            digits = 3 if c in ("spec", "scale") else (0 if c == "copy_side" else 2)
            row.append(fmt(stats.get(c), digits))
        secs = [result.seconds[n] for n in result.names if n in result.seconds]
        if secs:
            row.append(fmt(statistics.median(secs) if label.startswith("**") else max(secs), 1))
        else:
            row.append("–")
        rows.append(row)
    return md_table(["exemplar", *cols], rows)


def parse_peers(path: Path = PEERS_MD) -> tuple[dict, str]:
    """Peers' medians from PEERS.md: ({method: {metric: value}}, note)."""
    if not path.exists():
        return PEERS_FALLBACK, (f"`{common.shared_rel(path)}` is absent: the peers' medians are "
                                "the copies hard-coded in `bench/quality.py`.")
    peers: dict = {}
    try:
        text = path.read_text()

        def table_after(heading):
            block = text.split(heading, 1)[1]
            lines = []
            for ln in block.splitlines()[1:]:
                if ln.startswith("|"):
                    lines.append(ln)
                elif lines:
                    break  # the end of the first table after the heading
            header = [c.strip() for c in lines[0].replace("\\|", "").strip("|").split("|")]
            rows = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[2:]]
            return header, rows

        header, rows = table_after("## Medians over exemplars")
        keymap = {"log2 scale": "abslog2scale"}
        for row in rows:
            pairs = zip(header[2:], row[2:], strict=False)
            peers[row[0]] = {keymap.get(h, h): float(v) for h, v in pairs}
        header, rows = table_after("## Verbatim copying")
        for row in rows:
            peers.setdefault(row[0], {})
            peers[row[0]]["copy_side"] = float(row[2])
            peers[row[0]]["copy_side_max"] = float(row[3])
        missing = [p for p in PEER_ORDER if p not in peers]
        if missing:
            raise ValueError(f"missing peers {missing}")
    except (IndexError, ValueError) as exc:
        return PEERS_FALLBACK, (f"could not parse `{common.shared_rel(path)}` ({exc}): the "
                                "peers' medians are the copies hard-coded in "
                                "`bench/quality.py`.")
    return peers, (f"Peers' medians parsed from `{common.shared_rel(path)}` (their 256x256 "
                   "outputs from the same 128 px exemplars, non-tileable; `time` is their "
                   "process CPU seconds).")


def comparison_table(results: list[Result]) -> tuple[str, str]:
    peers, note = parse_peers()
    cols = ["coh_mean", "coh_p95", "compl", "hist", "spec", "abslog2scale", "copy_frac",
            "copy_side", "copy_side_max"]
    headers = ["method", "coh_mean", "coh_p95", "compl", "hist", "spec", "|log2 scale|",
               "copy_frac", "copy_side", "max copy_side", "time s"]
    digits = {"spec": 3, "abslog2scale": 3, "copy_side": 0, "copy_side_max": 0}
    rows = []
    for r in results:
        m = r.medians()
        label = f"**osmap {r.variant.name}**"
        if r.variant.name == "tileable":
            label += " (wrap-around scoring)"
        if r.variant.name == "512":
            label += " (512 px from full exemplars: not comparable)"
        rows.append([label, *[fmt(m.get(c), digits.get(c, 2)) for c in cols],
                     fmt(m["seconds"], 1) + " wall"])
    for p in PEER_ORDER:
        if p not in peers:
            continue
        m = peers[p]
        label = p if p not in ("blocks32", "tile") else f"{p} (baseline)"
        rows.append([label, *[fmt(m.get(c), digits.get(c, 2)) for c in cols],
                     fmt(m.get("cpu_s"), 1) + " cpu"])
    return md_table(headers, rows), note


def section(results: list[Result], outdir: Path, elapsed: float, quick: bool,
            sheets: list[str]) -> str:
    """The Markdown section for BENCHMARKS.md."""
    out = ["## Quality: development exemplars scored by texmetrics",
           f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`"
           f"; section took {elapsed / 60:.1f} min; load average (1 min) at the end: "
           f"{common.load_average()} (the scores do not depend on it; the times do)._",
           f"Library calls (`synthesize`, seed {SEED}), outputs written as 8-bit PNG to "
           f"`{outdir}/<variant>/<name>.png` and scored from the file by the independent meter "
           f"`{common.shared_rel(common.TEXMETRICS)} --json` (lower is better; scale 1 is "
           "right; `synth s` is the in-process wall time of `synthesize` alone, after an "
           "untimed warm-up, with the meter not running). Exemplars: "
           f"`{common.shared_rel(SMALL_EXEMPLARS)}/` and, for 512, "
           f"`{common.shared_rel(FULL_EXEMPLARS)}/` (their longest side is 106 to 256 px: "
           "not all are 256 px).",
           "### Medians against the peers"]
    table, note = comparison_table(results)
    out += [table, note]
    out.append("### Acceptance checks")
    out.append("Foundation: median coh_mean <= 3.2, coh_p95 <= 9.0, compl <= 2.8, "
               "|log2 scale| < 0.25 on every exemplar, median copy_side <= 64. Best-peer: "
               "median coh_mean <= 1.67, coh_p95 <= 6.97, compl <= 1.68, spec <= 0.05, "
               "copy_side median <= 55 and max <= 80, |log2 scale| < 0.2 on every exemplar. "
               "Tileable: the same plus seam_z < 3 on every exemplar. They apply to `default`, "
               "`tileable` and `512`; `paper` is checked for information.")
    for r in results:
        out.append("\n".join(check_lines(r)))
    for r in results:
        out.append(f"### Variant `{r.variant.name}`: {r.variant.description}")
        out.append(variant_table(r))
        if r.errors:
            out.append("Errors:\n" + "\n".join(f"- {n}: {e}" for n, e in r.errors.items()))
        out.append(f"`{r.variant.name}` took {r.wall:.0f} s (synthesis + scoring).")
    if sheets:
        out.append("### Contact sheets")
        out.append("\n".join(sheets))
    return "\n\n".join(s.strip("\n") for s in out) + "\n"


# ----------------------------------------------------------------------------- entry points

def run(quick: bool = False, outdir: Path | None = None, jobs: int = 2, sheets: bool = True,
        log=print) -> str:
    """Everything for BENCHMARKS.md: all four variants (quick: default and tileable on four
    exemplars), then the contact sheets."""
    if not SMALL_EXEMPLARS.is_dir() or not common.TEXMETRICS.exists():
        return ("## Quality: development exemplars scored by texmetrics\n\n"
                + common.shared_note("the quality section"))
    t0 = time.perf_counter()
    outdir = Path(outdir or default_outdir())
    names = exemplar_names()
    variants = ["default", "paper", "tileable", "512"]
    if quick:
        names = [n for n in ("bricks_dark_red", "gravel_green_stones", "text_newsprint",
                             "wood_planks_horizontal") if n in names] or names[:4]
        variants = ["default", "tileable"]
    results = []
    for v in variants:
        results.append(evaluate(VARIANTS[v], names, outdir, jobs=jobs, log=log))
        log(compact(results[-1]))
    save_json(results, outdir / "results.json")
    sheet_lines = []
    if sheets and not quick:
        import contact_sheet
        made = contact_sheet.make_all(outdir, log=log)
        sheet_lines = [f"- `{common.rel(p)}`: {what}" for p, what in made]
    elif sheets:
        sheet_lines = ["- not regenerated in quick mode (they need every exemplar and the "
                       "paper variant)"]
    return section(results, outdir, time.perf_counter() - t0, quick, sheet_lines)


def save_json(results: list[Result], path: Path, seed: int = SEED) -> None:
    """Every number of these results (per exemplar, medians, checks) as JSON."""
    path.write_text(json.dumps({r.variant.name: {
        "options": r.options, "seed": seed, "metrics": r.metrics,
        "seconds": r.seconds, "errors": r.errors, "medians": r.medians(),
        "checks": [{"level": lv, "pass": ok, "text": t} for lv, ok, t, _ in checks(r)],
    } for r in results}, indent=1))


def parse_value(text: str):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--variant", default="default",
                    help="comma-separated: default, paper, tileable, 512, or all")
    ap.add_argument("--names", help="comma-separated exemplar names (default: all 11)")
    ap.add_argument("--outdir", type=Path, default=default_outdir())
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--jobs", type=int, default=2, help="texmetrics processes in parallel")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a SynthOptions field (repeatable), e.g. --set knn=6")
    ap.add_argument("--reuse", action="store_true",
                    help="use the outputs (and scores) already in OUTDIR; only the missing "
                         "ones are synthesized / scored")
    ap.add_argument("--overlap", action="store_true",
                    help="score while synthesizing (faster; synthesis seconds get noisy)")
    ap.add_argument("--errmap", action="store_true", help="also write <name>_err.png heat maps")
    ap.add_argument("--markdown", action="store_true",
                    help="print the full Markdown section (with the peers' comparison)")
    ap.add_argument("--sheets", action="store_true",
                    help="also make the contact sheets from OUTDIR afterwards")
    ap.add_argument("--json", type=Path, help="write every number to this JSON file")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    args = ap.parse_args(argv)

    if not SMALL_EXEMPLARS.is_dir() or not common.TEXMETRICS.exists():
        print(common.shared_note("bench/quality.py"), file=sys.stderr)
        return 2
    variants = (list(VARIANTS) if args.variant == "all" else args.variant.split(","))
    bad = [v for v in variants if v not in VARIANTS]
    if bad:
        ap.error(f"unknown variant(s) {bad}; choose from {', '.join(VARIANTS)} or all")
    all_names = exemplar_names()
    names = args.names.split(",") if args.names else all_names
    unknown = [n for n in names if n not in all_names]
    if unknown:
        ap.error(f"unknown exemplar(s) {unknown}; known: {', '.join(all_names)}")
    overrides = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            ap.error(f"--set expects KEY=VALUE, got {item!r}")
        overrides[key.strip().replace("-", "_")] = parse_value(value.strip())
    if overrides:
        from osmap_cli.synth import SynthOptions
        try:
            SynthOptions(**overrides).validated()
        except Exception as exc:  # noqa: BLE001 - TypeError (unknown field) or OsmapError
            ap.error(f"--set: {exc}")

    def log(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    results = [evaluate(VARIANTS[v], names, args.outdir, seed=args.seed, jobs=args.jobs,
                        reuse=args.reuse, overlap=args.overlap, errmap=args.errmap,
                        overrides=overrides, log=log) for v in variants]
    sheet_lines = []
    if args.sheets:
        import contact_sheet
        sheet_lines = [f"- `{p}`: {w}" for p, w in contact_sheet.make_all(args.outdir, log=log)]
    if args.markdown:
        print(section(results, args.outdir, time.perf_counter() - t0, False, sheet_lines))
    else:
        for r in results:
            print(f"\n{r.variant.name}: {r.variant.description}"
                  + (f"; overrides {overrides}" if overrides else ""))
            print(variant_table(r))
            for name, err in r.errors.items():
                print(f"ERROR {name}: {err}")
        print()
        for r in results:
            print(compact(r))
            print(f"{'':>8} {level_summary(r)}")
    if args.json:
        save_json(results, args.json, seed=args.seed)
    return 0 if not any(r.errors for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())

"""Regular textures: does the output keep the exemplar's lattice? The figures of docs/regular.md.

For the regular development exemplars (../shared/exemplars/small/, 128 px) and the shipped
brick and weave samples, 256x256 at seed 1 (the quality section's settings), with
`--lattice off` (copies placed freely, as before the lattice existed: the same bytes) and with
the default `--lattice auto`. Each output is scored by the independent meters in their own venv:
../shared/tools/regularity.py (short, long: the output's autocorrelation at the exemplar's
lattice vectors and their multiples over the exemplar's own peak) and texmetrics.py (coh_mean,
coh_p95, copy_side); the peers' outputs (../shared/design/peers/) by the same meters.

    python bench/regularity.py [--names a,b] [--seeds 1] [--keep DIR] [--sheet PATH] [--probe]

--probe also reads the meter's figures along the lattice the synthesis keeps (for stripes, the
stripes' normal: across courses, planks or lines), and the meter's own vectors on the
exemplar itself and on a 2x2 tiling of it: the autocorrelation at each multiple, and the long
figure the exemplar's own decay gives (its multiples within half its size). The meter's
formula (../shared/tools/regularity.py, imported): a vector that is a point on a ridge of the
autocorrelation (anywhere along a course correlates) decays on the exemplar itself.
--bars reads, per exemplar, what the bar (short >= 0.75, long >= 0.6) asks of it: the meter on
(a) a 2x2 tiling of the exemplar (what a verbatim copy scores: where it is under the bar, the
bar cannot be met as the meter reads that exemplar), (b) the exemplar's own halves against each
other (top against bottom, left against right: the lattice of one read on the other), (c) osmap
on each seed (with coh_mean and copy_side), (d) the best peer (the highest lower ratio to the
bar); and the same across the stripes at their period (the lattice the synthesis keeps) for
(a) and (c).
--autocorr PATH writes, per exemplar of --names, the exemplar, a 2x2 tiling of it, its
autocorrelation (the meter's: displacements within half the exemplar each way, 0 black, its
largest off-centre value white; the meter's vectors marked red) and osmap's output at the first
seed: a lattice shows as a grid of peaks, stripes as ridges, a perspective wall as peaks that
smear with distance from the centre.
--sheet writes a contact sheet of the first seed: per row the exemplar (enlarged to 256), the
output without the lattice, with it, and the peer whose output keeps the lattice best (long).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from common import (  # noqa: E402
    PEERS_DIR,
    SAMPLES_DIR,
    SHARED_DIR,
    SMALL_EXEMPLARS,
    TEXMETRICS,
    TEXMETRICS_PY,
    measure_parser,
    measurement_folder,
)

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions, synthesize  # noqa: E402
from osmap_cli.texture.pyramid import resize  # noqa: E402

REGULAR = ("bricks_dark_red", "basket_weave_diagonal", "knit_rope_mesh", "text_newsprint",
           "wood_planks_horizontal")
SAMPLES = ("brick", "weave")
PEERS = ("quilting", "opara_patch", "resynth", "embark")
SIDE, GAP = 256, 6


def exemplar_path(name: str) -> Path:
    return SAMPLES_DIR / f"{name}.png" if name in SAMPLES else SMALL_EXEMPLARS / f"{name}.png"


def score(exemplar: Path, image: Path) -> dict:
    """The regularity meter's short / long and texmetrics' coherence and copy figures."""
    reg = json.loads(subprocess.run(
        [str(TEXMETRICS_PY), str(SHARED_DIR / "tools" / "regularity.py"), str(exemplar),
         str(image), "--json"], capture_output=True, text=True, check=True).stdout)
    tex = json.loads(subprocess.run(
        [str(TEXMETRICS_PY), str(TEXMETRICS), str(exemplar), str(image), "--json"],
        capture_output=True, text=True, check=True).stdout)["2d"]
    return {"short": reg.get("short"), "long": reg.get("long"),
            **{k: tex[k] for k in ("coh_mean", "coh_p95", "copy_side")}}


def measure(name: str, seed: int, folder: Path) -> dict:
    """Both syntheses of one exemplar at one seed, scored, with the best peer's figures."""
    source = exemplar_path(name)
    exemplar = read_image(source).pixels
    images, lattice = {}, None
    for variant in ("off", "auto"):
        result = synthesize(exemplar, SynthOptions(width=SIDE, height=SIDE, seed=seed,
                                                   lattice=variant))
        path = folder / f"{name}_{seed}_{variant}.png"
        write_image(str(path), result.pixels, 8)
        images[variant] = path
        lattice = result.lattice if variant == "auto" else lattice
    peers = {p: PEERS_DIR / p / f"{name}.png" for p in PEERS
             if (PEERS_DIR / p / f"{name}.png").exists()}
    jobs = {**images, **peers}
    with ThreadPoolExecutor(2) as pool:  # the meters run in their own processes
        scores = dict(zip(jobs, pool.map(lambda path: score(source, path), jobs.values())))
    best = max(peers, key=lambda p: scores[p]["long"] or 0.0) if peers else None
    return {"lattice": lattice, "scores": scores, "best": best, "images": jobs}


def _meter():
    """The shared regularity meter as a module (numpy and OpenImageIO only)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "shared_regularity", SHARED_DIR / "tools" / "regularity.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _profile(meter, image: np.ndarray, vector) -> list[float]:
    """The meter's autocorrelation of `image` at each multiple of `vector` that fits in half
    the image (the best within a pixel, as the meter reads it)."""
    r, (h, w) = meter.autocorr(image)
    out, k = [], 1
    while np.hypot(k * vector[0], k * vector[1]) <= min(h, w) / 2:
        out.append(meter.value(r, (h, w), (k * vector[0], k * vector[1])))
        k += 1
    return out


def probe(name: str, output: Path, without: Path, lattice) -> None:
    """Print the meter's vectors on the exemplar, a 2x2 tiling and `output`, and the meter's
    short / long along the kept lattice (the stripes' normal), also for the output made
    `without` the lattice."""
    meter = _meter()
    exemplar = meter.read(str(exemplar_path(name)))
    image = meter.read(str(output))
    tiled = np.tile(exemplar, (2, 2))
    found = meter.lattice(exemplar)
    for t in found or []:
        own = _profile(meter, exemplar, t[:2])
        print(f"  meter vector {int(t[0])},{int(t[1])} (dy,dx), peak {t[2]:.3f}: exemplar "
              f"{' '.join(f'{v:.2f}' for v in own)} (its own long {np.mean(own) / t[2]:.2f}); "
              f"2x2 tiling {' '.join(f'{v:.2f}' for v in _profile(meter, tiled, t[:2]))}; "
              f"output {' '.join(f'{v:.2f}' for v in _profile(meter, image, t[:2]))}")
    if lattice is None:
        return
    for v in lattice.vectors:  # a stripes' vector is their normal
        peak = meter.value(*meter.autocorr(exemplar), v)
        for label, img in (("exemplar", exemplar), ("2x2 tiling", tiled), ("output", image),
                           ("output without", meter.read(str(without)))):
            prof = _profile(meter, img, v)
            print(f"  kept lattice {v[0]:.1f},{v[1]:.1f} (dy,dx), {label}: short "
                  f"{prof[0] / peak:.2f}, long {np.mean(prof) / peak:.2f}")


BAR = (0.75, 0.6)


def _ratio(reading: dict) -> float:
    """How far a meter reading is from the bar: its lower share of short and long (>= 1: met)."""
    if not reading.get("regular"):
        return float("nan")
    return min(reading["short"] / BAR[0], (reading["long"] or 0.0) / BAR[1])


def _read(reading: dict) -> str:
    if not reading.get("regular"):
        return "no lattice"
    longs = "–" if reading["long"] is None else f"{reading['long']:.2f}"  # no multiple fits
    return f"{reading['short']:.2f} / {longs}"


def _across(meter, exemplar: np.ndarray, image: np.ndarray, lattice) -> str:
    """The meter's formula along the lattice the synthesis keeps (short / long)."""
    if lattice is None:
        return "–"
    r = meter.autocorr(exemplar)
    shorts, longs = [], []
    for v in lattice.vectors:
        peak = meter.value(*r, v)
        prof = _profile(meter, image, v)
        shorts.append(prof[0] / peak)
        longs += [p / peak for p in prof]
    return f"{min(shorts):.2f} / {np.mean(longs):.2f}"


def bars(name: str, seeds: list[int], folder: Path) -> None:
    """Print one exemplar's row of the bars table (see --bars above)."""
    meter = _meter()
    source = exemplar_path(name)
    exemplar = meter.read(str(source))
    h, w = exemplar.shape
    tiled = np.tile(exemplar, (2, 2))
    halves = [meter.measure(exemplar[:h // 2], exemplar[h // 2:]),
              meter.measure(exemplar[:, :w // 2], exemplar[:, w // 2:])]
    pixels = read_image(source).pixels
    own, across, lattice = [], [], None
    for seed in seeds:
        result = synthesize(pixels, SynthOptions(width=SIDE, height=SIDE, seed=seed))
        path = folder / f"{name}_{seed}_auto.png"
        write_image(str(path), result.pixels, 8)
        lattice = result.lattice
        s = score(source, path)
        own.append(f"{s['short']:.2f} / {s['long']:.2f} ({s['coh_mean']:.2f}, "
                   f"{s['copy_side']:.0f})" if s["short"] is not None else
                   f"no lattice ({s['coh_mean']:.2f}, {s['copy_side']:.0f})")
        across.append(_across(meter, exemplar, meter.read(str(path)), lattice))
    peers = {p: meter.measure(exemplar, meter.read(str(PEERS_DIR / p / f"{name}.png")))
             for p in PEERS if (PEERS_DIR / p / f"{name}.png").exists()}
    best = max(peers, key=lambda p: np.nan_to_num(_ratio(peers[p]), nan=-1.0)) if peers else None
    found = meter.lattice(exemplar)
    vectors = ", ".join(f"({int(t[0])}, {int(t[1])})" for t in found or [])
    print(f"| {name} | {vectors} | {_read(meter.measure(exemplar, tiled))} "
          f"| {_read(halves[0])}; {_read(halves[1])} | {'; '.join(own)} "
          f"| {best + ' ' + _read(peers[best]) if best else '–'} "
          f"| {_across(meter, exemplar, tiled, lattice)} | {'; '.join(across)} |", flush=True)


def autocorr_row(name: str, seed: int, folder: Path) -> list[np.ndarray]:
    """One row of the --autocorr sheet: exemplar, 2x2 tiling, autocorrelation, osmap."""
    meter = _meter()
    source = exemplar_path(name)
    pixels = read_image(source).pixels
    lum = meter.read(str(source))
    r, (h, w) = meter.autocorr(lum)
    crop = r[h // 2:h + h // 2, w // 2:w + w // 2].copy()
    off = crop.copy()
    off[h // 2 - 3:h // 2 + 4, w // 2 - 3:w // 2 + 4] = 0.0  # the central lobe
    picture = np.clip(crop / max(off.max(), 1e-6), 0, 1)
    picture = np.repeat(picture[..., None], 3, axis=2).astype(np.float32)
    for t in meter.lattice(lum) or []:
        for sign in (1, -1):
            y, x = h // 2 + sign * int(t[0]), w // 2 + sign * int(t[1])
            picture[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2] = (1.0, 0.0, 0.0)
    output = synthesize(pixels, SynthOptions(width=SIDE, height=SIDE, seed=seed)).pixels
    rgb = pixels[..., :3] if pixels.shape[2] >= 3 else np.repeat(pixels[..., :1], 3, axis=2)
    return [rgb, np.tile(rgb, (2, 2, 1)), picture, output[..., :3]]


def _header(*columns: str) -> None:
    """A Markdown table's header and rule."""
    print("| " + " | ".join(columns) + " |")
    print("| --- " * len(columns) + "|")


def fmt(row: dict) -> str:
    return (f"{row['short']:.2f} / {row['long']:.2f} | {row['coh_mean']:.2f} "
            f"| {row['coh_p95']:.2f} | {row['copy_side']:.0f}")


def main() -> None:
    parser = measure_parser(__doc__, seeds="1")
    parser.add_argument("--names", default=",".join(REGULAR + SAMPLES))
    parser.add_argument("--probe", action="store_true",
                        help="the meter's figures along the kept lattice (see above)")
    parser.add_argument("--autocorr", help="write the autocorrelation sheet here (see above)")
    parser.add_argument("--bars", action="store_true",
                        help="the bars table: tiling, halves, osmap, best peer (see above)")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    if args.autocorr:
        with measurement_folder(args.keep) as folder:
            tiles = [[_fit(im) for im in autocorr_row(name, seeds[0], folder)]
                     for name in args.names.split(",")]
        write_image(args.autocorr, sheet(tiles), 8)
        return
    if args.bars:
        with measurement_folder(args.keep) as folder:
            _header("exemplar", "meter's vectors (dy, dx)", "(a) 2x2 tiling",
                    "(b) halves: top vs bottom; left vs right",
                    "(c) osmap per seed (coh_mean, copy_side)", "(d) best peer",
                    "(a) across the stripes", "(c) across the stripes")
            for name in args.names.split(","):
                bars(name, seeds, folder)
        return
    with measurement_folder(args.keep) as folder:
        _header("exemplar", "seed", "lattice found", "without: short / long", "coh_mean",
                "coh_p95", "copy_side", "with: short / long", "coh_mean", "coh_p95", "copy_side",
                "best peer: short / long", "coh_mean")
        for name in args.names.split(","):
            for seed in seeds:
                m = measure(name, seed, folder)
                s = m["scores"]
                lattice = m["lattice"]
                found = ("none" if lattice is None else
                         ":".join(f"{v[1]:.1f},{v[0]:.1f}" for v in lattice.vectors))
                peer = (f"{m['best']} {s[m['best']]['short']:.2f} / {s[m['best']]['long']:.2f} "
                        f"| {s[m['best']]['coh_mean']:.2f}" if m["best"] else "– | –")
                print(f"| {name} | {seed} | {found} | {fmt(s['off'])} | {fmt(s['auto'])} "
                      f"| {peer} |", flush=True)
                if args.probe:
                    probe(name, m["images"]["auto"], m["images"]["off"], lattice)
                if seed == seeds[0]:
                    rows.append([exemplar_path(name), m["images"]["off"], m["images"]["auto"],
                                 m["images"].get(m["best"])])
    if args.sheet:
        write_image(args.sheet, sheet(rows), 8)


def _cell(path: Path | None) -> np.ndarray:
    """An image as a SIDE x SIDE RGB tile (smaller ones enlarged, gray made RGB; white if
    missing)."""
    if path is None:
        return np.ones((SIDE, SIDE, 3), np.float32)
    image = read_image(path).pixels
    image = image[..., :3] if image.shape[2] >= 3 else np.repeat(image[..., :1], 3, axis=2)
    if image.shape[:2] != (SIDE, SIDE):
        image = resize(np.ascontiguousarray(image), SIDE, SIDE)
    return np.clip(image, 0, 1)


def _fit(image: np.ndarray) -> np.ndarray:
    """An RGB image as a SIDE x SIDE tile (nearest neighbour: pixels and peaks stay sharp)."""
    h, w = image.shape[:2]
    ys = (np.arange(SIDE) * h // SIDE).clip(0, h - 1)
    xs = (np.arange(SIDE) * w // SIDE).clip(0, w - 1)
    return np.clip(image[ys][:, xs], 0, 1)


def sheet(rows) -> np.ndarray:
    """Rows of four cells (paths, or SIDE x SIDE images) on white, GAP px apart: for --sheet
    (exemplar, without, with, best peer)."""
    out = np.ones((len(rows) * (SIDE + GAP) - GAP, 4 * (SIDE + GAP) - GAP, 3), np.float32)
    for r, row in enumerate(rows):
        for c, cell in enumerate(row):
            y, x = r * (SIDE + GAP), c * (SIDE + GAP)
            out[y:y + SIDE, x:x + SIDE] = cell if isinstance(cell, np.ndarray) else _cell(cell)
    return out


if __name__ == "__main__":
    main()

"""Guided synthesis measured on development exemplars: the figures of docs/guide.md.

Each exemplar is two development exemplars side by side (A | B, the 128 px ones), its guide 0 | 1;
the target guide is 0 on the output's left half and 1 on its right half (192x192). Per pair
and seed (0, 1, 2) it reports, with texmetrics.py (coh_mean, in its own venv):

* the share of each output half copied from its material (from the result's positions);
* each half (4 px kept off the boundary) against its material, over an unguided synthesis of
  that material alone at the half's size (same seed): the guide's cost in coherence;
* the same half over the same columns of an unguided synthesis of that material alone at the
  whole output's size (the crop the pair forces, same seed): like with like, the half and its
  reference cut from outputs of one size at one place (an output's border columns read
  differently from its inside);
* the whole output against the two-material exemplar, over an unguided synthesis of the same
  exemplar at the same size (the issue's wording: "coherence within 1.3x of unguided");
* the whole output against the two-material exemplar, over the two materials synthesized
  alone side by side (each unguided at a half's size, same seed, joined where the target's
  halves meet): the unguided output of the pair is mostly whichever material it favours, this
  baseline is what the target asks for with no guide cost.

With --sheet PATH, a contact sheet of the first seed: per pair the exemplar (A | B), the
guided output and the unguided one (with --halves-only: the two materials alone at the
output's size, joined where the target's halves meet; docs/guide_pairs.jpg).

--pairs all measures every pair of the 11 development exemplars (55); the summary then names
the worst pairs, and --sheet shows the WORST of them (by the worse half's ratio against its
material alone at the output's size) instead of every pair. The material-alone syntheses are
made once per material and crop. --halves-only skips the unguided run and the whole-output
figures (half the time).

    python bench/guide_measure.py [--pairs a:b,c:d|all] [--seeds 0,1,2] [--keep DIR]
        [--sheet PATH] [--worst N] [--halves-only]
"""

from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor
from itertools import combinations
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from common import SMALL_EXEMPLARS, measure_parser, measurement_folder  # noqa: E402
from common import texmetrics_coh as coh  # noqa: E402

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions, synthesize  # noqa: E402

PAIRS = "gravel_green_stones:wood_planks_horizontal,marble_swirl_green:tomatoes," \
        "bark_vertical:terrazzo_granite"
SIDE, MARGIN, GAP = 192, 4, 6


def alone(name: str, pixels: np.ndarray, seed: int, folder: Path) -> tuple[Path, Path]:
    """The material synthesized alone at a half's size, once: (its first SIDE // 2 - MARGIN
    columns, the whole half)."""
    path = folder / f"alone_{name}_{pixels.shape[0]}_{seed}.png"
    whole = folder / f"alone_half_{name}_{pixels.shape[0]}_{seed}.png"
    if not (path.exists() and whole.exists()):
        half_opts = SynthOptions(width=SIDE // 2, height=SIDE, seed=seed)
        out = synthesize(pixels, half_opts).pixels
        write_image(str(whole), out, 8)
        write_image(str(path), out[:, :SIDE // 2 - MARGIN], 8)
    return path, whole


def alone_whole(name: str, pixels: np.ndarray, seed: int, folder: Path) -> Path:
    """The material synthesized alone at the whole output's size, once."""
    path = folder / f"alone_whole_{name}_{pixels.shape[0]}_{seed}.png"
    if not path.exists():
        out = synthesize(pixels, SynthOptions(width=SIDE, height=SIDE, seed=seed)).pixels
        write_image(str(path), out, 8)
    return path


def measure_pair(a: str, b: str, seed: int, folder: Path, whole: bool = True) -> dict:
    """One pair at one seed: shares, half ratios and (with `whole`) the whole-output ratios."""
    pa, pb = SMALL_EXEMPLARS / f"{a}.png", SMALL_EXEMPLARS / f"{b}.png"
    ea, eb = read_image(pa).pixels[..., :3], read_image(pb).pixels[..., :3]
    rows = min(ea.shape[0], eb.shape[0])  # the text exemplar is a few rows short of 128
    ea, eb = ea[:rows], eb[:rows]
    exemplar = np.concatenate([ea, eb], axis=1)
    guide = np.zeros(exemplar.shape[:2], np.float32)
    guide[:, ea.shape[1]:] = 1.0
    target = np.zeros((SIDE, SIDE), np.float32)
    target[:, SIDE // 2:] = 1.0
    opts = SynthOptions(width=SIDE, height=SIDE, seed=seed)
    guided = synthesize(exemplar, opts, guide=guide, target_guide=target)
    unguided = synthesize(exemplar, opts).pixels if whole else None
    half = SIDE // 2 - MARGIN
    from_b = guided.positions[..., 1] >= ea.shape[1] - 0.5
    files = {"exemplar": exemplar, "guided": guided.pixels,
             "left": guided.pixels[:, :half], "right": guided.pixels[:, SIDE // 2 + MARGIN:]}
    if whole:
        files["unguided"] = unguided
    (paths_a, half_a), (paths_b, half_b) = alone(a, ea, seed, folder), alone(b, eb, seed, folder)
    paths = {"alone_a": paths_a, "alone_b": paths_b}
    files["apart"] = np.concatenate([read_image(half_a).pixels, read_image(half_b).pixels], axis=1)
    same_a = read_image(alone_whole(a, ea, seed, folder)).pixels
    same_b = read_image(alone_whole(b, eb, seed, folder)).pixels
    files["same_a"], files["same_b"] = same_a[:, :half], same_b[:, SIDE // 2 + MARGIN:]
    files["same"] = np.concatenate([same_a[:, :SIDE // 2], same_b[:, SIDE // 2:]], axis=1)
    for name, pixels in files.items():
        paths[name] = folder / f"{a}__{b}_{seed}_{name}.png"
        write_image(str(paths[name]), pixels, 8)
    jobs = {"left": (pa, paths["left"]), "alone_a": (pa, paths["alone_a"]),
            "right": (pb, paths["right"]), "alone_b": (pb, paths["alone_b"]),
            "same_a": (pa, paths["same_a"]), "same_b": (pb, paths["same_b"])}
    if whole:
        jobs.update(guided=(paths["exemplar"], paths["guided"]),
                    unguided=(paths["exemplar"], paths["unguided"]),
                    apart=(paths["exemplar"], paths["apart"]))
    with ThreadPoolExecutor(2) as pool:  # the meter runs in its own processes
        scores = dict(zip(jobs, pool.map(lambda job: coh(*job), jobs.values())))
    halves = [(scores["left"], scores["alone_a"]), (scores["right"], scores["alone_b"])]
    return {
        "images": (exemplar, guided.pixels, unguided if whole else files["same"]),
        "share": (1 - from_b[:, :SIDE // 2].mean(), from_b[:, SIDE // 2:].mean()),
        "halves": halves,
        "half": tuple(g / alone for g, alone in halves),
        "same": (scores["left"] / scores["same_a"], scores["right"] / scores["same_b"]),
        "whole": (scores["guided"], scores["unguided"]) if whole else None,
        "apart": scores.get("apart"),
    }


def all_pairs() -> str:
    """Every pair of the development exemplars, as --pairs takes them."""
    names = sorted(p.stem for p in SMALL_EXEMPLARS.glob("*.png"))
    return ",".join(f"{a}:{b}" for a, b in combinations(names, 2))


def main() -> None:
    parser = measure_parser(__doc__, seeds="0,1,2")
    parser.add_argument("--pairs", default=PAIRS, help="a:b,c:d, or all (the 55 pairs)")
    parser.add_argument("--halves-only", action="store_true",
                        help="only the shares and the halves' readings (no unguided run, no "
                             "whole-output figures; the sheet's third column is then the two "
                             "materials alone at the output's size)")
    parser.add_argument("--worst", type=int, default=6,
                        help="with --pairs all: the sheet shows this many worst pairs")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    every = args.pairs == "all"
    pairs = all_pairs() if every else args.pairs
    with measurement_folder(args.keep) as folder:
        print("| A : B | seed | share A / B | half A / alone, half B / alone "
              "| the same, alone at the output's size | whole: guided, unguided (ratio) "
              "| whole / the two alone |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        halves, sames, wholes, aparts, rows, results = [], [], [], [], [], []
        per_material = {}
        for pair in pairs.split(","):
            a, b = pair.split(":")
            for seed in seeds:
                m = measure_pair(a, b, seed, folder, whole=not args.halves_only)
                if seed == seeds[0]:
                    rows.append(m["images"])
                results.append((a, b, seed, m))
                halves += m["half"]
                sames += m["same"]
                for name, raw in zip((a, b), m["halves"]):
                    per_material.setdefault(name, []).append(raw)
                whole = "– | –"
                if m["whole"]:
                    wholes.append(m["whole"][0] / m["whole"][1])
                    aparts.append(m["whole"][0] / m["apart"])
                    whole = (f"{m['whole'][0]:.2f}, {m['whole'][1]:.2f} ({wholes[-1]:.2f}) "
                             f"| {aparts[-1]:.2f}")
                print(f"| {a} : {b} | {seed} | {m['share'][0]:.1%} / {m['share'][1]:.1%} "
                      f"| {m['half'][0]:.2f}, {m['half'][1]:.2f} "
                      f"| {m['same'][0]:.2f}, {m['same'][1]:.2f} | {whole} |", flush=True)
        for label, ratios in (("half ratios", halves),
                              ("half ratios, alone at the output's size", sames)):
            print(f"\n{label}: median {np.median(ratios):.2f}, geometric mean "
                  f"{np.exp(np.mean(np.log(ratios))):.2f}, max {max(ratios):.2f}, over 1.3: "
                  f"{sum(h > 1.3 for h in ratios)} of {len(ratios)}; worst: " + ", ".join(
                      f"{name} {r:.2f}" for r, name in sorted(
                          ((r, f"{(a, b)[i]} beside {(b, a)[i]}") for a, b, _, m in results
                           for i, r in enumerate(m["half" if ratios is halves else "same"])),
                          reverse=True)[:5]))
        if wholes:
            print(f"whole ratios: max {max(wholes):.2f}, over 1.3: "
                  f"{sum(w > 1.3 for w in wholes)} of {len(wholes)}; over the two alone: max "
                  f"{max(aparts):.2f}, over 1.3: {sum(w > 1.3 for w in aparts)} of "
                  f"{len(aparts)}")
        shares = [min(m["share"]) for *_, m in results]
        print(f"lowest share of a half: {min(shares):.1%}; halves under 90 %: "
              f"{sum(s < 0.9 for *_, m in results for s in m['share'])} of {2 * len(results)}")
        # one seed's unguided synthesis can be luckier than another's: the seeds' means too
        print("each material, mean over the seeds of the guided half over the mean of the "
              "material alone: " + ", ".join(
                  f"{name} {np.mean([g for g, _ in raw]) / np.mean([u for _, u in raw]):.2f}"
                  for name, raw in per_material.items()))
        if every:
            worst = sorted(results, key=lambda r: -max(r[3]["same"]))
            worst = worst[:args.worst]
            print("worst pairs: " + "; ".join(
                f"{a} : {b} (seed {seed}) share {min(m['share']):.1%}, half ratios "
                f"{m['half'][0]:.2f} / {m['half'][1]:.2f} (alone at the output's size "
                f"{m['same'][0]:.2f} / {m['same'][1]:.2f})" for a, b, seed, m in worst))
            rows = [m["images"] for *_, m in worst]
    if args.sheet:
        write_image(args.sheet, sheet(rows), 8)


def sheet(rows) -> np.ndarray:
    """Rows of (exemplar, guided, unguided) side by side on white, GAP px apart."""
    height = max(max(im.shape[0] for im in row) for row in rows)
    width = max(sum(im.shape[1] for im in row) for row in rows) + GAP * 2
    out = np.ones((len(rows) * (height + GAP) - GAP, width, 3), np.float32)
    for r, row in enumerate(rows):
        x = 0
        for im in row:
            out[r * (height + GAP):r * (height + GAP) + im.shape[0], x:x + im.shape[1]] = im
            x += im.shape[1] + GAP
    return out


if __name__ == "__main__":
    main()

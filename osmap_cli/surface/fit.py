"""Building and training the OS-Map (or the classic SOM) that fits a quad grid to surface points.

Two methods share everything (points, initialisation, steps, schedule, seed, map topology):
- "osmap": the update is done in the chosen frame (cartesian, cylindrical or spherical) with a
  per-component anisotropic neighbourhood from --vary / --anisotropy;
- "som":   Kohonen's SOM: cartesian xyz, isotropic Gaussian neighbourhood.
Both search the winner over the whole map (scale 1: every point is represented once).

Initialisation: a map without wrapped axes starts from the surface's own unrolled
coordinates (embed.py, a landmark Isomap) and is refined with a small radius and learning rate;
a wrapped map, or `init="random"`, starts from randomly drawn points with the paper's wide
schedule. After each fit, folds.py checks the grid against the points (no ground truth); a
folded grid is refitted with a seed derived from (seed, fit number), up to `fold_retries` times.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.surface.frames import Frame

WRAPS = {"none": (False, False), "u": (False, True), "v": (True, False), "uv": (True, True)}
METHODS = ("osmap", "som")
INITS = ("auto", "random", "geodesic")


def parse_grid(text: str) -> tuple[int, int]:
    """'WxH' (columns along u x rows along v) -> map shape in array order (rows, cols)."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not m:
        raise OsmapError(f"--grid: expected COLSxROWS like 32x32, got {text!r}")
    cols, rows = int(m.group(1)), int(m.group(2))
    if cols < 2 or rows < 2 or cols * rows > 1 << 20:
        raise OsmapError(f"--grid: each side must be at least 2 and the map at most 1048576 "
                         f"nodes, got {text!r}")
    return rows, cols


@dataclass(frozen=True)
class VarySpec:
    """How one data component varies over the map: along 'u', 'v', both ('uv'), or along a
    direction at `angle` degrees from u toward v; `anisotropy` overrides the global value."""

    component: str
    along: str  # "u", "v", "uv" or "angle"
    angle: float = 0.0
    anisotropy: float | None = None


def parse_vary(text: str | None) -> list[VarySpec]:
    """'x=u,y=u,z=v' ; 'phi=u:0.1' (own anisotropy) ; 'x=30deg' (direction) ; 'r=uv'."""
    if text is None or not text.strip():
        return []
    out = []
    seen = set()
    for item in text.split(","):
        m = re.fullmatch(r"\s*([A-Za-z]+)\s*=\s*([A-Za-z]+|[-+]?\d+(?:\.\d*)?deg)\s*"
                         r"(?::\s*([-+]?\d*\.?\d+(?:[eE][-+]?\d+)?)\s*)?", item)
        if not m:
            raise OsmapError(f"--vary: cannot parse {item.strip()!r} (expected COMPONENT=AXIS "
                             "like x=u, z=v, r=uv, x=30deg, optionally :ANISOTROPY like x=u:0.05)")
        comp, along, aniso = m.group(1).lower(), m.group(2).lower(), m.group(3)
        if comp in seen:
            raise OsmapError(f"--vary: component {comp!r} is given twice")
        seen.add(comp)
        angle = 0.0
        if along.endswith("deg"):
            angle, along = float(along[:-3]), "angle"
        elif along == "vu":
            along = "uv"
        elif along not in ("u", "v", "uv"):
            raise OsmapError(f"--vary: {item.strip()!r}: the axis must be u, v, uv or an angle "
                             "like 30deg")
        a = None if aniso is None else float(aniso)
        if a is not None and not 0.0 <= a <= 1.0:
            raise OsmapError(f"--vary: {item.strip()!r}: the anisotropy must be in [0, 1]")
        out.append(VarySpec(comp, along, angle, a))
    return out


def orientation_for(frame: Frame, vary: list[VarySpec], anisotropy: float):
    """The engine Orientation for these specs (components not named: isotropic)."""
    from osmap_cli.engine import Orientation

    weights = np.ones((3, 2))  # (component, (v, u))
    theta = np.zeros(3)        # angle of P_k in (v, u) coordinates: P = (cos, sin)
    general = False
    for spec in vary:
        k = frame.component_index(spec.component)
        a = anisotropy if spec.anisotropy is None else spec.anisotropy
        if spec.along == "u":
            weights[k] = (a, 1.0)
            theta[k] = np.pi / 2
        elif spec.along == "v":
            weights[k] = (1.0, a)
        elif spec.along == "uv":
            weights[k] = (1.0, 1.0)
        else:
            general = True
            theta[k] = np.pi / 2 - np.deg2rad(spec.angle)
    if not general:
        return Orientation.axis_aligned(weights)
    # P_k with weight 1 (narrow), P'_k with the anisotropy (broad)
    pw = np.ones((3, 2))
    for spec in vary:
        k = frame.component_index(spec.component)
        a = anisotropy if spec.anisotropy is None else spec.anisotropy
        pw[k] = (1.0, 1.0) if spec.along == "uv" else (1.0, a)
    return Orientation.angles(theta, pw)


@dataclass
class FitConfig:
    """Everything that decides a fit (see `fit_surface`)."""

    grid: tuple[int, int] = (32, 32)           # (rows along v, cols along u)
    wrap: str = "none"                          # none | u | v | uv
    method: str = "osmap"                       # osmap | som
    frame: str = "cartesian"
    axis: np.ndarray | None = None
    center: np.ndarray | None = None
    vary: list[VarySpec] = field(default_factory=list)
    anisotropy: float = 0.0
    steps: int | None = None                    # default: STEPS_PER_NODE * nodes
    sigma: tuple[float, float] | None = None    # (max, min); default (max(grid) / 4, SIGMA_MIN)
    alpha: tuple[float, float] | None = None    # (max, min); default from the init
    seed: int = 0
    path: str = "auto"                          # engine path ("general" for benchmarks)
    init: str = "auto"                          # auto | random | geodesic


STEPS_PER_NODE = 150
SIGMA_MIN = 0.5
DEFAULT_ALPHA = (0.9, 0.01)
# After the geodesic initialisation the map is already ordered: a refinement schedule. A wider
# radius smooths the chain of columns off the roll's tight inner turn and back into layer-jumping
# states (1.5 turns: sigma_max 2 or 3 failed in every seed tried, at alpha 0.1 to 0.9).
GEODESIC_SIGMA = (1.5, 0.5)
GEODESIC_ALPHA = (0.1, 0.01)
FOLD_RETRIES = 3


@dataclass
class FitResult:
    grid_xyz: np.ndarray      # (rows, cols, 3) float64
    wrap: tuple[bool, bool]   # (v, u)
    frame: Frame
    som: object               # the trained OSMap
    steps: int
    schedule: object
    topographic_error: float = float("nan")
    seed: int = 0
    init: str = "random"      # the initialisation actually used
    folds: dict | None = None  # folds.fold_check of the grid (None: not checked)
    fits_run: int = 1         # fits trained to get this one (restarts and fold refits)
    fold_history: list = field(default_factory=list)  # (seed, folded) of every fit, in order


def init_kind(cfg: FitConfig) -> str:
    """'geodesic' or 'random': what `cfg.init` means for this config ('auto': geodesic for the
    OS-Map on a map without wrapped axes, random otherwise)."""
    if cfg.init not in INITS:
        raise OsmapError(f"--init: expected auto, random or geodesic, got {cfg.init!r}")
    if cfg.init == "geodesic" and cfg.wrap != "none":
        raise OsmapError("--init geodesic: needs a map without wrapped axes (--wrap none); "
                         "a closed surface has no 2D unrolling")
    if cfg.init != "auto":
        return cfg.init
    return "geodesic" if cfg.method == "osmap" and cfg.wrap == "none" else "random"


def default_schedule(cfg: FitConfig, init: str = "random"):
    """The schedule: --sigma / --alpha when given, else the paper's wide one after a random
    initialisation (sigma max(grid)/4 to 0.5, alpha 0.9 to 0.01) or the refinement one after a
    geodesic initialisation (GEODESIC_SIGMA, GEODESIC_ALPHA)."""
    from osmap_cli.engine import Schedule

    geo = init == "geodesic"
    if cfg.sigma is not None:
        smax, smin = cfg.sigma
    else:
        smax, smin = GEODESIC_SIGMA if geo else (max(cfg.grid) / 4.0, SIGMA_MIN)
    alpha = cfg.alpha if cfg.alpha is not None else (GEODESIC_ALPHA if geo else DEFAULT_ALPHA)
    return Schedule(alpha_max=alpha[0], alpha_min=alpha[1], sigma_max=smax, sigma_min=smin)


def build_map(cfg: FitConfig, points: np.ndarray):
    """(OSMap, Frame, frame-space data) for this config; nothing trained yet."""
    from osmap_cli.engine import Orientation, OSMap

    if cfg.wrap not in WRAPS:
        raise OsmapError(f"--wrap: expected none, u, v or uv, got {cfg.wrap!r}")
    if cfg.method not in METHODS:
        raise OsmapError(f"--method: expected osmap or som, got {cfg.method!r}")
    wrap = WRAPS[cfg.wrap]
    if cfg.method == "som":
        frame = Frame("cartesian")
        orientation = Orientation.isotropic(3, 2)
    else:
        frame = Frame.fit(cfg.frame, points, cfg.axis, cfg.center)
        orientation = orientation_for(frame, cfg.vary, cfg.anisotropy)
    som = OSMap(cfg.grid, 3, wrap=wrap, orientation=orientation, periods=frame.periods,
                path=cfg.path)
    return som, frame, frame.to_frame(points)


def _along(cfg: FitConfig, frame: Frame) -> list[tuple[int, str]]:
    """(component index, 'u' | 'v') for the components --vary ties to one map axis."""
    return [(frame.component_index(s.component), s.along) for s in cfg.vary
            if s.along in ("u", "v")]


def fit_surface(points: np.ndarray, cfg: FitConfig, progress=None) -> FitResult:
    """Train the map on the points (n, 3) and return the node positions in xyz.

    Initialisation (`init_kind`): geodesic, the nodes laid on the surface's unrolled coordinates
    (embed.py; if no embedding can be made, random is used and reported), or random, every node a
    randomly drawn data point (the same points, drawn with the same seed, for both methods).
    Steps default to STEPS_PER_NODE per node; the schedule is `default_schedule`.
    """
    from osmap_cli.surface.embed import geodesic_init

    points = np.asarray(points, np.float64)
    som, frame, data = build_map(cfg, points)
    steps = cfg.steps if cfg.steps is not None else STEPS_PER_NODE * som.size
    used = "random"
    if init_kind(cfg) == "geodesic":
        init = geodesic_init(points, cfg.grid, frame.to_frame, _along(cfg, frame), cfg.seed)
        if init is not None:
            som.weights[:] = init
            used = "geodesic"
    if used == "random":
        som.init_random(data, seed=cfg.seed)
    schedule = default_schedule(cfg, used)
    som.train(data, steps, schedule=schedule, seed=cfg.seed, progress=progress)
    xyz = frame.from_frame(som.weights.astype(np.float64)).reshape(*cfg.grid, 3)
    return FitResult(xyz, WRAPS[cfg.wrap], frame, som, steps, schedule, init=used)


def restart_seed(seed: int, restart: int) -> int:
    """Seed of restart r: the seed itself for r = 0, then derived from (seed, r)."""
    if restart == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, restart]).generate_state(1)[0])


def fit_best(points: np.ndarray, cfg: FitConfig, restarts: int = 1, progress=None,
             fold_retries: int = FOLD_RETRIES) -> FitResult:
    """Train `restarts` maps (seeds from restart_seed), check each for folds (folds.py, no ground
    truth), and while the best so far is folded train up to `fold_retries` more (the next derived
    seeds). Keeps the best: fold-free first, then the fewest fold signals, then the lowest
    topographic error on the points (ties: the first). With fold_retries < 0 nothing is checked
    and the lowest topographic error wins."""
    from dataclasses import replace

    from osmap_cli.surface.folds import fold_check
    from osmap_cli.surface.metrics import topographic_error

    check = fold_retries >= 0

    def key(res):
        if not check:
            return (res.topographic_error,)
        return (res.folds["folded"], res.folds["score"], res.topographic_error)

    best, history, r = None, [], 0
    while r < restarts or (check and best.folds["folded"] and r < restarts + fold_retries):
        seed = restart_seed(cfg.seed, r)
        result = fit_surface(points, replace(cfg, seed=seed), progress=progress)
        result.topographic_error = topographic_error(result.grid_xyz, result.wrap, points)
        result.seed = seed
        if check:
            result.folds = fold_check(result.grid_xyz, result.wrap, points, seed)
        history.append((seed, bool(check and result.folds["folded"])))
        if best is None or key(result) < key(best):
            best = result
        r += 1
    best.fits_run = r
    best.fold_history = history
    return best


def shape_config(shape, grid=(32, 32), method: str = "osmap", seed: int = 0,
                 **overrides) -> FitConfig:
    """The FitConfig `osmap surface --shape NAME` uses: the shape's recommended wrap, frame,
    axis and --vary, default steps and schedule; keyword arguments override fields."""
    from osmap_cli.surface.frames import parse_axis

    rec = shape.recommended
    cfg = FitConfig(grid=tuple(grid), wrap=rec.wrap, method=method, frame=rec.frame,
                    axis=parse_axis(rec.axis), vary=parse_vary(rec.vary),
                    anisotropy=rec.anisotropy, seed=seed)
    for key, value in overrides.items():
        setattr(cfg, key, value)
    return cfg


def fit_report(result: FitResult) -> dict:
    """The report fields of how the grid was obtained: init, fits_run, seed_used, fold_check
    ('clean', 'refitted: clean after N fits', 'folded' or 'not checked') and the fold signals
    of the kept grid (fold_gap_edges, fold_off_surface_nodes, fold_reversed_quads)."""
    out = {"init": result.init, "fits_run": int(result.fits_run), "seed_used": int(result.seed)}
    if result.folds is None:
        out["fold_check"] = "not checked"
        return out
    folded_fits = sum(1 for _, folded in result.fold_history if folded)
    if result.folds["folded"]:
        out["fold_check"] = f"folded (every one of {result.fits_run} fits)"
    elif folded_fits:
        seeds = ", ".join(str(s) for s, folded in result.fold_history if folded)
        out["fold_check"] = (f"refitted: {folded_fits} folded fit(s) found (seeds {seeds}), "
                             f"clean after {result.fits_run} fits")
    else:
        out["fold_check"] = "clean"
    for k in ("gap_edges", "off_surface_nodes", "reversed_quads"):
        out[f"fold_{k}"] = float(result.folds[k])
    return out

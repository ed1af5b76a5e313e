"""Building and training the OS-Map (or the classic SOM) that fits a quad grid to surface points.

Two methods share everything (points, initialisation, steps, schedule, seed, map topology):
- "osmap": the update is done in the chosen frame (cartesian, cylindrical or spherical) with a
  per-component anisotropic neighbourhood from --vary / --anisotropy;
- "som":   Kohonen's SOM: cartesian xyz, isotropic Gaussian neighbourhood.
Both search the winner over the whole map (scale 1: every point is represented once).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.surface.frames import Frame

WRAPS = {"none": (False, False), "u": (False, True), "v": (True, False), "uv": (True, True)}
METHODS = ("osmap", "som")


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
    alpha: tuple[float, float] = (0.9, 0.01)
    seed: int = 0
    path: str = "auto"                          # engine path ("general" for benchmarks)


STEPS_PER_NODE = 150
SIGMA_MIN = 0.5
DEFAULT_ALPHA = (0.9, 0.01)


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


def default_schedule(cfg: FitConfig):
    from osmap_cli.engine import Schedule

    smax, smin = cfg.sigma if cfg.sigma is not None else (max(cfg.grid) / 4.0, SIGMA_MIN)
    return Schedule(alpha_max=cfg.alpha[0], alpha_min=cfg.alpha[1], sigma_max=smax,
                    sigma_min=smin)


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


def fit_surface(points: np.ndarray, cfg: FitConfig, progress=None) -> FitResult:
    """Train the map on the points (n, 3) and return the node positions in xyz.

    Initialisation: every node takes a randomly drawn data point (the same points, drawn with the
    same seed, for both methods). Steps default to STEPS_PER_NODE per node; the schedule is the
    paper's with sigma from max(grid)/4 to SIGMA_MIN and alpha from 0.9 to 0.01.
    """
    points = np.asarray(points, np.float64)
    som, frame, data = build_map(cfg, points)
    steps = cfg.steps if cfg.steps is not None else STEPS_PER_NODE * som.size
    schedule = default_schedule(cfg)
    som.init_random(data, seed=cfg.seed)
    som.train(data, steps, schedule=schedule, seed=cfg.seed, progress=progress)
    xyz = frame.from_frame(som.weights.astype(np.float64)).reshape(*cfg.grid, 3)
    return FitResult(xyz, WRAPS[cfg.wrap], frame, som, steps, schedule)


def restart_seed(seed: int, restart: int) -> int:
    """Seed of restart r: the seed itself for r = 0, then derived from (seed, r)."""
    if restart == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, restart]).generate_state(1)[0])


def fit_best(points: np.ndarray, cfg: FitConfig, restarts: int = 1, progress=None) -> FitResult:
    """Train `restarts` maps (seeds from restart_seed) and keep the one with the lowest
    topographic error on the points (ties: the first)."""
    from dataclasses import replace

    from osmap_cli.surface.metrics import topographic_error

    best = None
    for r in range(restarts):
        seed = restart_seed(cfg.seed, r)
        result = fit_surface(points, replace(cfg, seed=seed), progress=progress)
        result.topographic_error = topographic_error(result.grid_xyz, result.wrap, points)
        result.seed = seed
        if best is None or result.topographic_error < best.topographic_error:
            best = result
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

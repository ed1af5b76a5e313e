"""One `osmap surface` run: points -> a fitted quad grid and its outputs.

    read (points of a built-in shape, a point cloud or a sampled mesh) -> check (enough points
    for the grid) -> compute (train the map, measure it) -> stage (OBJ / PLY / preview /
    report JSON in one transaction) -> commit

:class:`SurfaceRequest` is every option of the command as one named record, checked by
:meth:`SurfaceRequest.config` before any work.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

from osmap_cli.batch import Job
from osmap_cli.errors import OsmapError, UsageError

__all__ = ["SurfaceJob", "SurfaceRequest"]


@dataclass(frozen=True)
class SurfaceRequest:
    """The options of `osmap surface` as given (None: the shape's or the built-in default)."""

    output: str
    input_path: str | None = None
    grid: str = "32x32"
    shape: str | None = None
    turns: float | None = None
    height: float | None = None
    major_radius: float | None = None
    minor_radius: float | None = None
    radius: float | None = None
    n_points: int | None = None
    wrap: str | None = None
    method: str = "osmap"
    vary: str | None = None
    anisotropy: float | None = None
    frame: str | None = None
    axis: str | None = None
    center: str | None = None
    steps: int | None = None
    sigma: str | None = None
    alpha: str | None = None
    restarts: int = 1
    init: str = "auto"
    fold_retries: int = 3
    seed: int = 0
    ply_out: str | None = None
    report_json: str | None = None
    preview: str | None = None

    def config(self):
        """(FitConfig, built-in shape or None, map nodes); a bad value is a UsageError."""
        try:
            return _options(self)
        except UsageError:
            raise
        except OsmapError as e:
            raise UsageError(str(e)) from None

    def check_outputs(self) -> None:
        """Every output path writable and distinct, before any work."""
        from osmap_cli.surface import export

        export.check_output_path(self.output, "-o", (".obj", ".ply"))
        if self.ply_out is not None:
            export.check_output_path(self.ply_out, "--ply-out", (".ply",))
        if self.report_json is not None:
            export.check_output_path(self.report_json, "--report-json", (".json",))
        if self.preview is not None:
            from osmap_cli.imageio import output_format

            output_format(self.preview, None, 3)
        targets = [p for p in (self.output, self.ply_out, self.report_json, self.preview)
                   if p is not None]
        if len({os.path.abspath(p) for p in targets}) != len(targets):
            raise OsmapError("-o, --ply-out, --report-json and --preview must be different "
                             "files")


@dataclass(frozen=True)
class _Inputs:
    cfg: object  # fit.FitConfig
    shape: object  # a built-in shape, or None
    points: object  # (n, 3) array
    area: float | None  # a mesh's surface area
    name: str  # what the points came from, for messages and the header


@dataclass(frozen=True)
class SurfaceJob(Job):
    """A SurfaceRequest run: `execute()` returns the --report lines (one string)."""

    request: SurfaceRequest
    report: bool = False
    progress: bool = False
    replace: bool = True
    refused: str | None = None

    @property
    def exemplar(self) -> str:
        return self.request.input_path or f"--shape {self.request.shape}"

    @property
    def outputs(self) -> list[str]:
        r = self.request
        return [p for p in (r.output, r.ply_out, r.report_json, r.preview) if p is not None]

    def describe(self) -> dict:
        return {"input": self.exemplar, "outputs": self.outputs, "grid": self.request.grid,
                "seed": self.request.seed}

    def read(self) -> _Inputs:
        import numpy as np

        from osmap_cli.surface import pointio

        r = self.request
        cfg, shape_obj, nodes = r.config()
        r.check_outputs()
        rng = np.random.default_rng(r.seed)
        area = None
        if shape_obj is not None:
            name = f"--shape {r.shape}"
            points = shape_obj.sample(r.n_points or 20000, rng)
        else:
            name = r.input_path
            surf = pointio.read_surface(r.input_path)
            if surf.is_mesh:
                area = float(pointio.triangle_areas(surf.vertices, surf.triangles).sum())
                points = pointio.sample_mesh(name, surf.vertices, surf.triangles,
                                             r.n_points or 20000, rng)
            else:
                points = surf.vertices
                if r.n_points is not None and len(points) > r.n_points:
                    points = points[rng.choice(len(points), r.n_points, replace=False)]
        return _Inputs(cfg, shape_obj, points, area, name)

    def check(self, inputs: _Inputs) -> None:
        from osmap_cli.surface import pointio

        nodes = inputs.cfg.grid[0] * inputs.cfg.grid[1]
        pointio.check_points(inputs.name, inputs.points, nodes)

    def compute(self, inputs: _Inputs):
        import sys

        from osmap_cli.surface import fit

        cfg, r = inputs.cfg, self.request
        nodes = cfg.grid[0] * cfg.grid[1]
        progress = None
        total = (cfg.steps or fit.STEPS_PER_NODE * nodes) * r.restarts
        if self.progress:
            from tqdm import tqdm

            progress = tqdm(total=total, unit="step", unit_scale=True, file=sys.stderr,
                            desc="osmap surface", leave=False)
        try:
            result = fit.fit_best(inputs.points, cfg, r.restarts, progress=progress,
                                  fold_retries=r.fold_retries)
        finally:
            if progress is not None:
                progress.close()
        metrics = None
        if self.report or r.report_json or r.preview:
            from osmap_cli.surface import metrics as met

            metrics = met.evaluate(result.grid_xyz, result.wrap, inputs.shape, inputs.points,
                                   inputs.area)
            metrics["topographic_error"] = result.topographic_error
            metrics.update(fit.fit_report(result))
        return result, metrics

    def stage(self, outputs, inputs: _Inputs, computed) -> tuple[str, list[str]]:
        from osmap_cli.output import write_bytes
        from osmap_cli.surface import export

        result, metrics = computed
        r, cfg = self.request, inputs.cfg
        header = (f"osmap surface: {inputs.name}, grid {r.grid}, wrap {cfg.wrap}, method "
                  f"{r.method}, frame {result.frame.describe()}, seed {r.seed}, steps "
                  f"{result.steps}")
        outputs.stage(r.output, export.grid_writer(r.output, result.grid_xyz, result.wrap,
                                                   header))
        if r.ply_out is not None:
            outputs.stage(r.ply_out, export.grid_writer(r.ply_out, result.grid_xyz, result.wrap,
                                                        header))
        if r.preview is not None:
            from osmap_cli.imageio import encode_image
            from osmap_cli.surface.preview import render_preview

            picture = render_preview(result.grid_xyz, result.wrap, inputs.points,
                                     metrics.get("shortcut_mask") if metrics else None)
            outputs.stage(r.preview, lambda temp: encode_image(temp, picture, name=r.preview))
        if metrics is not None:
            metrics.pop("shortcut_mask", None)
        if r.report_json is not None:
            text = json.dumps(metrics, indent=2, sort_keys=True) + "\n"
            outputs.stage(r.report_json, lambda temp: write_bytes(temp, text.encode("utf-8")))
        lines = []
        if self.report:
            from osmap_cli.surface.metrics import format_report

            lines = format_report(metrics)
        warnings = []
        if result.folds is not None and result.folds["folded"]:
            from osmap_cli.surface.folds import describe

            warnings.append(f"the grid is still folded after {result.fits_run} fit(s) "
                            f"({describe(result.folds)}); try --fold-retries, --grid or --vary")
        return "\n".join(lines), warnings


def _pair(text: str | None, option: str) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        a, b = (float(t) for t in text.replace(":", ",").split(","))
    except ValueError:
        raise OsmapError(f"{option}: expected START,END like 8,0.5, got {text!r}") from None
    if not (a > 0 and b > 0 and a >= b and a < float("inf")):
        raise OsmapError(f"{option}: expected START >= END > 0, got {text!r}")
    return a, b



def _options(r: SurfaceRequest):
    """Parse and check every option: (FitConfig, built-in shape or None, map nodes)."""
    from osmap_cli.surface import fit, frames, shapes

    input_path, grid, shape, turns, height = r.input_path, r.grid, r.shape, r.turns, r.height
    major_radius, minor_radius, radius = r.major_radius, r.minor_radius, r.radius
    n_points, wrap, method, vary, anisotropy = r.n_points, r.wrap, r.method, r.vary, r.anisotropy
    frame, axis, center, steps, sigma, alpha = r.frame, r.axis, r.center, r.steps, r.sigma, r.alpha
    restarts, seed, init, fold_retries = r.restarts, r.seed, r.init, r.fold_retries

    if (input_path is None) == (shape is None):
        raise OsmapError("give exactly one of INPUT or --shape")
    if input_path is None:
        shape_obj = shapes.make_shape(shape, turns=turns, height=height,
                                      major_radius=major_radius, minor_radius=minor_radius,
                                      radius=radius)
        rec = shape_obj.recommended
    else:
        for opt, val in (("--turns", turns), ("--height", height),
                         ("--major-radius", major_radius), ("--minor-radius", minor_radius),
                         ("--radius", radius)):
            if val is not None:
                raise OsmapError(f"{opt}: only applies with --shape")
        shape_obj = None
        rec = shapes.Recommended()
    shape_grid = fit.parse_grid(grid)
    nodes = shape_grid[0] * shape_grid[1]
    if n_points is not None and n_points < 1:
        raise OsmapError(f"--points: must be positive, got {n_points}")
    if steps is not None and steps < 1:
        raise OsmapError(f"--steps: must be positive, got {steps}")
    if restarts < 1:
        raise OsmapError(f"--restarts: must be at least 1, got {restarts}")
    if fold_retries < 0:
        raise OsmapError(f"--fold-retries: must be at least 0, got {fold_retries}")
    if not 0 <= seed <= 2**63 - 1:
        raise OsmapError(f"--seed: {seed} is out of range (allowed 0 to {2**63 - 1})")
    if anisotropy is not None and not 0.0 <= anisotropy <= 1.0:
        raise OsmapError(f"--anisotropy: must be in [0, 1], got {anisotropy}")
    vary_specs = fit.parse_vary(vary if vary is not None else rec.vary)
    frame_kind = frame or rec.frame
    axis_vec = frames.parse_axis(axis if axis is not None else rec.axis)
    center_vec = frames.parse_center(center)
    # names in --vary must exist in the frame
    probe = frames.Frame(frame_kind)
    for spec in vary_specs:
        probe.component_index(spec.component)
    cfg = fit.FitConfig(grid=shape_grid, wrap=wrap or rec.wrap, method=method, frame=frame_kind,
                        axis=axis_vec, center=center_vec, vary=vary_specs,
                        anisotropy=rec.anisotropy if anisotropy is None else anisotropy,
                        steps=steps, sigma=_pair(sigma, "--sigma"),
                        alpha=_pair(alpha, "--alpha"), seed=seed, init=init)
    fit.init_kind(cfg)  # --init geodesic with a wrapped map is an option error
    if cfg.alpha is not None and cfg.alpha[0] > 1.0:
        raise OsmapError(f"--alpha: the learning rate must be at most 1, got {alpha!r}")
    return cfg, shape_obj, nodes

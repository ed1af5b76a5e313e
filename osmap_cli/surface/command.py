"""`osmap surface`: fit a fold-free quad grid to a point-sampled surface with OS-Map.

Only click and the standard library are imported here; numpy, Numba and the engine are imported
when the command runs, so `osmap --help` stays fast.
"""

from __future__ import annotations

import os
import sys

import click

from osmap_cli.errors import OsmapError

HELP = """Fit a quad grid (an OS-Map) to a point-sampled surface and write it as OBJ/PLY.

\b
INPUT is a point cloud (.ply ascii/binary, .xyz/.txt/.pts/.csv text, .npy (n, 3))
or a mesh (.obj, or .ply with faces) that is sampled uniformly by area; or give
--shape for a built-in surface. Exactly one of INPUT and --shape.

\b
Orientation in map space (--vary): which map axis each data component varies
along. COMPONENT=AXIS[:ANISOTROPY], comma separated, AXIS one of
  u      varies along u (columns), nearly constant along v
  v      varies along v (rows), nearly constant along u
  uv     isotropic (the classic SOM kernel for this component)
  30deg  varies along the direction 30 degrees from u towards v
ANISOTROPY (default --anisotropy, 0 to 1) is the kernel weight across the
chosen direction relative to 1 along it: 0 keeps the component exactly
constant across, 1 is isotropic. Components not named are isotropic.
Component names depend on --frame: cartesian x,y,z; cylindrical rho,phi,z
(about --axis through --center); spherical r,theta,phi. Angles are learned
as arc lengths (angle times the mean radius of the points) and phi wraps.

\b
Orientation in data space (--frame): the update is done in cylindrical or
spherical coordinates; the points are converted before training and the
grid converted back to xyz. This is what makes the torus work:
rho and z vary around the small circle (v), phi around the big one (u).

\b
Defaults: with --shape the shape's own settings (roll: cartesian,
x=u,y=u,z=v, wrap none; torus: cylindrical about z, rho=v,z=v,phi=u, wrap uv;
cylinder: cylindrical, rho=uv,phi=u,z=v, wrap u; sphere: spherical,
r=uv,theta=v,phi=u, wrap u); any option you give overrides them. With an
INPUT file: cartesian, isotropic, wrap none. --method som ignores --vary,
--anisotropy, --frame, --axis and --center: it runs Kohonen's SOM in xyz on
the same points with the same steps and seed; its --init auto is the random
start with the wide schedule.

\b
Training: --init auto (the default) starts a map without wrapped axes
from the surface's unrolled (geodesic) coordinates and refines it with
sigma 1.5 to 0.5 and alpha 0.1 to 0.01; a wrapped map (or --init random)
starts every node at a randomly drawn point and runs the paper's schedule
with sigma from max(grid)/4 to 0.5 and alpha from 0.9 to 0.01. STEPS
default to 150 per node; the winner is searched over the whole map.
Every fit is checked for folds against the points (edges across empty
space, nodes off the surface, quads reversed against their neighbours; no
ground truth needed); a folded grid is refitted with a derived seed up to
--fold-retries times, and --report says so. --restarts K trains K times
(seeds derived from --seed) and keeps a fold-free grid with the lowest
topographic error.

\b
Outputs: OBJ with one vertex per node, quad faces (wrap faces included on
wrapped axes) and UVs from the grid; PLY instead when -o ends in .ply, or
in addition with --ply-out. --report prints the quality metrics (shortcut
edges, flipped quads, corner-angle error, fit error, windings), distances
in units of sqrt(area / nodes); exact on built-in shapes, estimated from
local planes through the samples otherwise. --preview renders the
wireframe from two viewpoints into a PNG.

\b
Examples:
  osmap surface --shape torus -o torus.obj --grid 32x32 --report
  osmap surface --shape torus -o som.obj --method som --preview som.png
  osmap surface --shape roll --turns 1 --height 14 -o roll.obj --preview roll.png
  osmap surface scan.ply -o grid.obj --grid 48x24 --vary x=u,y=u,z=v
  osmap surface ring.xyz -o ring.obj --wrap uv --frame cylindrical --axis z \\
      --vary rho=v,z=v,phi=u --report-json metrics.json
"""


class SurfaceUsageError(OsmapError):
    """A malformed or out-of-range option value (exit code 2, like click's usage errors)."""


class _OneLineError(click.ClickException):
    """Printed by click as one line 'Error: message' (standalone) and by `osmap` as
    'osmap: error: message'."""

    def __init__(self, message: str, exit_code: int):
        super().__init__(message)
        self.exit_code = exit_code


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


@click.command("surface", help=HELP, context_settings={"max_content_width": 100})
@click.argument("input_path", metavar="[INPUT]", required=False,
                type=click.Path(dir_okay=True, path_type=str))
@click.option("-o", "--output", required=True, metavar="OUT.obj",
              help="Output grid: .obj (quads + UVs) or .ply.")
@click.option("--grid", default="32x32", show_default=True, metavar="COLSxROWS",
              help="Map size: nodes along u x nodes along v.")
@click.option("--shape", type=click.Choice(["roll", "torus", "sphere", "cylinder"]),
              help="Use a built-in surface instead of INPUT.")
@click.option("--turns", type=float, help="roll: number of turns [1].")
@click.option("--height", type=float, help="roll, cylinder: height [14, 4].")
@click.option("--major-radius", type=float, help="torus: radius of the big circle [2].")
@click.option("--minor-radius", type=float, help="torus: radius of the tube [0.7].")
@click.option("--radius", type=float, help="sphere, cylinder: radius [1].")
@click.option("--points", "n_points", type=int, metavar="N",
              help="Points drawn on a built-in shape or sampled on a mesh [20000]; a point "
                   "cloud with more points is randomly subsampled to N.")
@click.option("--wrap", type=click.Choice(["none", "u", "v", "uv"]),
              help="Map topology: which map axes wrap around [shape's, else none].")
@click.option("--method", type=click.Choice(["osmap", "som"]), default="osmap",
              show_default=True, help="osmap: oriented; som: classic SOM for comparison.")
@click.option("--vary", metavar="SPEC", help="Orientation in map space, e.g. x=u,y=u,z=v.")
@click.option("--anisotropy", type=float, default=None,
              help="Kernel weight across each --vary direction, 0..1 [0].")
@click.option("--frame", type=click.Choice(["cartesian", "cylindrical", "spherical"]),
              help="Coordinate system of the update [shape's, else cartesian].")
@click.option("--axis", default=None, metavar="AXIS",
              help="Frame axis: x, y, z, -z or a vector a,b,c [z].")
@click.option("--center", default=None, metavar="X,Y,Z",
              help="Frame centre: fit (the best-fitting circle/sphere centre), centroid, "
                   "or X,Y,Z [fit].")
@click.option("--steps", type=int, default=None, help="Training steps [150 per node].")
@click.option("--sigma", default=None, metavar="MAX,MIN",
              help="Neighbourhood radius schedule in nodes [max(grid)/4,0.5].")
@click.option("--alpha", default=None, metavar="MAX,MIN",
              help="Learning-rate schedule [0.9,0.01].")
@click.option("--restarts", type=int, default=1, show_default=True,
              help="Train K times, keep the lowest topographic error.")
@click.option("--init", "init", type=click.Choice(["auto", "random", "geodesic"]),
              default="auto", show_default=True,
              help="Start: geodesic (unrolled surface; maps without wrap) or random points; "
                   "auto: geodesic when no axis wraps.")
@click.option("--fold-retries", type=int, default=3, show_default=True,
              help="Refits (derived seeds) when the fold check finds a fold; 0: only report.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--ply-out", default=None, metavar="FILE.ply", help="Also write a PLY.")
@click.option("--report", is_flag=True, help="Print the quality metrics, one per line.")
@click.option("--report-json", default=None, metavar="FILE.json",
              help="Write the metrics as JSON.")
@click.option("--preview", default=None, metavar="FILE.png",
              help="Render the grid from two viewpoints side by side.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def surface_command(input_path, output, grid, shape, turns, height, major_radius, minor_radius,
                    radius, n_points, wrap, method, vary, anisotropy, frame, axis, center, steps,
                    sigma, alpha, restarts, init, fold_retries, seed, ply_out, report, report_json,
                    preview, quiet):
    try:
        run_surface(**locals())
    except OsmapError as e:
        code = 2 if isinstance(e, SurfaceUsageError) else 1
        raise _OneLineError(" ".join(str(e).split()), code) from None


def run_surface(*, input_path, output, grid, shape, turns, height, major_radius, minor_radius,
                radius, n_points, wrap, method, vary, anisotropy, frame, axis, center, steps,
                sigma, alpha, restarts, init, fold_retries, seed, ply_out, report, report_json,
                preview, quiet):
    """The command's work, raising OsmapError for anything the user can fix."""
    import json

    import numpy as np

    from osmap_cli.surface import export, fit, pointio

    # ---- options (exit 2), then output paths (exit 1), all checked before any work or output
    try:
        cfg, shape_obj, nodes = _options(
            input_path=input_path, grid=grid, shape=shape, turns=turns, height=height,
            major_radius=major_radius, minor_radius=minor_radius, radius=radius,
            n_points=n_points, wrap=wrap, method=method, vary=vary, anisotropy=anisotropy,
            frame=frame, axis=axis, center=center, steps=steps, sigma=sigma, alpha=alpha,
            restarts=restarts, seed=seed, init=init, fold_retries=fold_retries)
    except SurfaceUsageError:
        raise
    except OsmapError as e:
        raise SurfaceUsageError(str(e)) from None
    export.check_output_path(output, "-o", (".obj", ".ply"))
    if ply_out is not None:
        export.check_output_path(ply_out, "--ply-out", (".ply",))
    if report_json is not None:
        export.check_output_path(report_json, "--report-json", (".json",))
    if preview is not None:
        from osmap_cli.imageio import output_format

        output_format(preview, None, 3)
    targets = [p for p in (output, ply_out, report_json, preview) if p is not None]
    if len({os.path.abspath(p) for p in targets}) != len(targets):
        raise OsmapError("-o, --ply-out, --report-json and --preview must be different files")

    # ---- points
    rng = np.random.default_rng(seed)
    area = None
    if shape_obj is not None:
        name = f"--shape {shape}"
        points = shape_obj.sample(n_points or 20000, rng)
    else:
        name = input_path
        surf = pointio.read_surface(input_path)
        if surf.is_mesh:
            area = float(pointio.triangle_areas(surf.vertices, surf.triangles).sum())
            points = pointio.sample_mesh(name, surf.vertices, surf.triangles,
                                         n_points or 20000, rng)
        else:
            points = surf.vertices
            if n_points is not None and len(points) > n_points:
                points = points[rng.choice(len(points), n_points, replace=False)]
    pointio.check_points(name, points, nodes)

    # ---- training
    progress = None
    total = (cfg.steps or fit.STEPS_PER_NODE * nodes) * restarts
    if not quiet and sys.stderr.isatty():
        from tqdm import tqdm

        progress = tqdm(total=total, unit="step", unit_scale=True, file=sys.stderr,
                        desc="osmap surface", leave=False)
    try:
        result = fit.fit_best(points, cfg, restarts, progress=progress,
                              fold_retries=fold_retries)
    finally:
        if progress is not None:
            progress.close()

    # ---- metrics and outputs
    metrics = None
    if report or report_json or preview:
        from osmap_cli.surface import metrics as met

        metrics = met.evaluate(result.grid_xyz, result.wrap, shape_obj, points, area)
        metrics["topographic_error"] = result.topographic_error
        metrics.update(fit.fit_report(result))
    header = (f"osmap surface: {name}, grid {grid}, wrap {cfg.wrap}, method {method}, "
              f"frame {result.frame.describe()}, seed {seed}, steps {result.steps}")
    export.write_grid(output, result.grid_xyz, result.wrap, header)
    if ply_out is not None:
        export.write_grid(ply_out, result.grid_xyz, result.wrap, header)
    if preview is not None:
        from osmap_cli.surface.preview import write_preview

        write_preview(preview, result.grid_xyz, result.wrap, points,
                      metrics.get("shortcut_mask") if metrics else None)
    if metrics is not None:
        metrics.pop("shortcut_mask", None)
    if report_json is not None:
        export.atomic_write(report_json, json.dumps(metrics, indent=2, sort_keys=True) + "\n")
    if report:
        from osmap_cli.surface.metrics import format_report

        for line in format_report(metrics):
            click.echo(line)
    if result.folds is not None and result.folds["folded"]:
        from osmap_cli.surface.folds import describe

        click.echo(f"osmap surface: warning: the grid is still folded after {result.fits_run} "
                   f"fit(s) ({describe(result.folds)}); try --fold-retries, --grid or --vary",
                   err=True)


def _options(*, input_path, grid, shape, turns, height, major_radius, minor_radius, radius,
             n_points, wrap, method, vary, anisotropy, frame, axis, center, steps, sigma, alpha,
             restarts, seed, init="auto", fold_retries=3):
    """Parse and check every option: (FitConfig, built-in shape or None, map nodes)."""
    from osmap_cli.surface import fit, frames, shapes

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

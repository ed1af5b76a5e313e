"""`osmap surface`: fit a fold-free quad grid to a point-sampled surface with OS-Map.

The options become an osmap_cli.surface.job.SurfaceRequest; the SurfaceJob checks it, fits and
writes every output in one transaction. Only click and the standard library are imported here;
numpy, Numba and the engine are imported when the command runs, so `osmap --help` stays fast.
"""

from __future__ import annotations

import sys

import click

from osmap_cli.errors import OsmapError, UsageError

__all__ = ["surface_command"]

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
    given = {k: v for k, v in locals().items() if k not in ("report", "quiet")}
    from osmap_cli.surface.job import SurfaceJob, SurfaceRequest

    try:
        request = SurfaceRequest(**given)
        job = SurfaceJob(request=request, report=report, progress=not quiet and
                         sys.stderr.isatty())
        lines, warnings = job.execute()
    except OsmapError as e:
        code = 2 if isinstance(e, UsageError) else 1
        raise _OneLineError(" ".join(str(e).split()), code) from None
    for line in lines.splitlines():
        click.echo(line)
    for warning in warnings:
        click.echo(f"osmap surface: warning: {warning}", err=True)


class _OneLineError(click.ClickException):
    """Printed by click as one line 'Error: message' (standalone) and by `osmap` as
    'osmap: error: message'."""

    def __init__(self, message: str, exit_code: int):
        super().__init__(message)
        self.exit_code = exit_code

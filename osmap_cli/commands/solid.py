"""`osmap solid`: a solid (3D) texture whose slices along x, y and z look like the exemplar.

The command checks every option and plans every output before any work, then runs one
osmap_cli.solid.job.SolidJob per exemplar (or per --x/--y/--z set). Only click and the standard
library are imported at module level, so `osmap solid --help` stays fast.
"""

from __future__ import annotations

import os
import re

import click

from osmap_cli.commands.common import (
    CONTEXT_SETTINGS,
    batch_options,
    check_destination,
    claim_output,
    cluster_spec,
    expand_inputs,
    fill_template,
    input_fields,
    load_preset,
    real_paths,
    refusal,
    resolve_options,
    run_batch,
    show_progress,
    tuning_flags,
)
from osmap_cli.solid.formats import FORMATS, NRRD_ENCODINGS, default_name, format_for
from osmap_cli.solid.job import SolidJob
from osmap_cli.solid.methods import quality_help
from osmap_cli.solid.options import MAX_SIDE, QUALITIES, SolidOptions

__all__ = ["solid_command"]

HELP = """Synthesize a solid texture like EXEMPLAR and write it to OUT.

\b
Batches: several EXEMPLARs (or '-': paths from stdin, one per line) with
--out-dir DIR; each volume is named by --name TEMPLATE, fields {stem}
{name} {in_ext} {parent} {index} {width} {height} {depth} {seed} {preset}
{quality} and {ext} (the output format's extension: npy, nrrd, png, exr).
The format is --format, else --name's extension (none: PNG slices), else
npy. A failing exemplar is one line on stderr and does not stop the others
(--fail-fast does); an existing output is kept (reported "skipped") unless
--overwrite; an output that is an input is always refused. --json prints
one JSON object per finished job on stdout and nothing else. -j N runs N
jobs at once; the bytes do not depend on N. --x/--y/--z make one volume.

\b
--method structure (default) builds the structure first: it reads what
the exemplar shows (--analyse prints it): separate particles (stones,
chips, cells), layers (grain, rings, sediment) or a field of phases
(marble's regions and veins); builds that structure in 3D at the
exemplar's scale (particles sized by stereology, so their cuts show the
exemplar's profiles; layers as displaced planes or rings; phases as a
thresholded smooth random field); then fills in the appearance with the
optimisation below, every slice window guided by the structure, and
matches each phase's colours to the exemplar's. An exemplar with none
of these structures is made by --method osmap. --structure forces one.
Every voxel holds three exemplar positions, one per slice family (slices
normal to x, y and z). --method osmap: an OS-Map lays them out on the
coarsest volume, then a texture optimisation (Kopf et al. 2007) runs
level by level: every slice window finds its nearest exemplar window,
every voxel takes a robust mean of the colours the windows of all three
families place on it (at the coarser levels the densest colour cluster
that two families agree on), and the colours are moved most of the way
to the exemplar's histogram. --method kopf: the paper's optimisation as
published (softer). --method legacy: the search + mode pipeline of
earlier versions (boxier, paler).

\b
--x/--y/--z give one exemplar per slice family (Kopf et al. 2007): slices
normal to x (rows z, cols y), y (rows z, cols x), z (rows y, cols x) look
like that exemplar; axes not given use EXEMPLAR (which may be omitted
when all three are given). All need the same number of channels.
Anisotropic materials (wood grain along the exemplar's x): pass the grain
exemplar for two axes and an end-grain or rotated view for the third.
--orientation RX,RY,RZ turns the material (degrees about x, then y, then
z): the grain then runs along any 3D direction. The material is made
axis-aligned in a box that holds the turned volume (up to 5x the voxels
and time at oblique angles) and sampled turned (trilinear). Not with
--tileable.

\b
Output (--format, else by OUT's extension):
  .npy       float32 array (Z, Y, X, C); no metadata (NumPy has none)
  folder     no extension: PNG slices slice_0000.png ... (one per z)
  exr        (--format exr) a folder of 32-bit float EXR slices
  .png       a flipbook atlas: the z slices in a grid, row-major; name it
             NAME_COLSxROWS.png to choose the grid (else near-square);
             the grid is recorded in the metadata
  .nrrd      NRRD (sizes C X Y Z, float32), --nrrd-encoding raw|gzip
PNG is 8-bit (16-bit for a 16-bit or float exemplar). PNG, EXR and NRRD
carry the provenance (osmap version, exemplar, preset, seed, options).

\b
--uv-out FILE.npy writes float32 (Z, Y, X, 3): exemplar column u, row v
and the index (0, 1, 2 = x, y, z exemplar) each voxel was copied from;
osmap_cli.solid.render_volume(uv, maps) re-renders it on aligned maps.

\b
Presets (--preset): a built-in name ('osmap presets --solid' lists them;
"muted": fewer 1-voxel stripes, paler; "structured", "smooth" and
"legacy" select the legacy method), or a TOML
file with a [solid] table of tunables (osmap solid does not read the
[synth] presets). Tuning flags (--method, --iterations, ...) override the
preset; --quality fast|high then trades speed for quality (what each
changes for each method: --quality below).
Memory: the working set is estimated first; a size that does not fit in
the available memory (or in OSMAP_MEMORY_LIMIT, e.g. 2G) is refused.
Same inputs, options and seed give the same bytes with any thread count.

\b
Exit codes: 0 every job written or skipped, 1 a job failed (bad input,
unwritable output, runtime failure), 2 usage error, 130 interrupted.
"""

EPILOG = """\b
Examples:
  osmap solid marble.png -o marble.npy --size 128
  osmap solid terrazzo.png --analyse          # writes terrazzo_segmentation.png
  osmap solid gravel.png -o gravel.npy --size 64 --verbose --structure particles
  osmap solid marble.png -o marble_slices --size 96x64x128 --preview marble.png
  osmap solid granite.png -o granite_8x16.png --size 128 --tileable
  osmap solid --x end.png --y side.png --z side.png -o wood.nrrd --size 64
  osmap solid --x end.png --y side.png --z top.png -o log.npy --size 64 --orientation 0,30,45
  osmap solid gravel.png -o gravel.npy --size 64 --uv-out gravel_uv.npy --seed 3
  osmap solid samples/*.png --out-dir vols --format nrrd --size 64 -j 2
  ls samples/*.png | osmap solid - --out-dir vols --name '{stem}_{depth}.npy' --json
"""


class Angles(click.ParamType):
    """RX,RY,RZ degrees."""

    name = "RX,RY,RZ"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        parts = str(value).replace(" ", "").split(",")
        try:
            angles = tuple(float(p) for p in parts)
        except ValueError:
            angles = ()
        if len(angles) != 3 or not all(-360.0 <= a <= 360.0 for a in angles):
            self.fail(f"{value!r} is not three angles in degrees from -360 to 360 "
                      "(example: 0,30,45)", param, ctx)
        return angles


class VolumeSize(click.ParamType):
    """N (a cube) or XxYxZ."""

    name = "N|XxYxZ"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        text = str(value).strip()
        match = (re.fullmatch(r"(\d{1,9})\s*[xX]\s*(\d{1,9})\s*[xX]\s*(\d{1,9})", text)
                 or re.fullmatch(r"(\d{1,9})", text))
        if match is None:
            self.fail(f"{value!r} is not N or XxYxZ (examples: 128, 128x64x32)", param, ctx)
        digits = [int(d) for d in match.groups()]
        x, y, z = digits if len(digits) == 3 else digits * 3
        if min(x, y, z) < 8 or max(x, y, z) > MAX_SIDE:
            self.fail(f"{value!r}: every side must be between 8 and {MAX_SIDE}", param, ctx)
        return (x, y, z)


# The options of the volume synthesized (`osmap carve` synthesizes with them too).
VOLUME_OPTIONS = (
    click.option("--size", type=VolumeSize(), default="128", show_default=True,
                 help="Volume size in voxels: N for NxNxN, or XxYxZ."),
    click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
                 help="Random seed; the same seed gives the same volume."),
    click.option("--preset", default="default", show_default=True, metavar="NAME|FILE.toml",
                 help="Solid preset: a built-in name (see 'osmap presets --solid') or a TOML "
                      "file with [solid]."),
    click.option("--quality", type=click.Choice(QUALITIES), default="default", show_default=True,
                 help="Speed / quality trade-off on top of the preset, per method: "
                 f"{quality_help()}."),
    click.option("--tileable", is_flag=True, help="The volume wraps around in x, y and z."),
    click.option("--orientation", type=Angles(), default="0,0,0", show_default=True,
                 help="Turn the material: degrees about x, then y, then z (the grain along "
                      "any 3D direction). Not with --tileable."),
    click.option("--x", "ex_x", type=click.Path(path_type=str), default=None, metavar="FILE",
                 help="Exemplar for the slices normal to x (rows z, cols y)."),
    click.option("--y", "ex_y", type=click.Path(path_type=str), default=None, metavar="FILE",
                 help="Exemplar for the slices normal to y (rows z, cols x)."),
    click.option("--z", "ex_z", type=click.Path(path_type=str), default=None, metavar="FILE",
                 help="Exemplar for the slices normal to z (rows y, cols x)."),
)
VOLUME_PARAMS = ("size", "seed", "preset", "quality", "tileable", "orientation", "ex_x", "ex_y",
                 "ex_z")


def volume_options(function):
    """Add VOLUME_OPTIONS (--size, --seed, --preset, --quality, --tileable, --orientation,
    --x, --y, --z, in that order) to a command."""
    for decorator in reversed(VOLUME_OPTIONS):
        function = decorator(function)
    return function


def volume_settings(size, seed, preset, quality, tileable, orientation, tuning):
    """(validated SolidOptions, loaded preset) of the volume options and tuning flags."""
    loaded = load_preset(preset, "solid")
    x, y, z = size
    options = resolve_options(SolidOptions, loaded.values,
                              {"width": x, "height": y, "depth": z, "seed": seed,
                               "quality": quality, "tileable": tileable,
                               "rotate_x": orientation[0], "rotate_y": orientation[1],
                               "rotate_z": orientation[2]}, tuning)
    return options, loaded


def axis_set(base, ex_x, ex_y, ex_z, label="EXEMPLAR"):
    """(base, (x, y, z) files) of one --x/--y/--z set, the axes not given taking BASE (which
    may be None when all three are given); a usage error otherwise."""
    axis_files = [ex_x, ex_y, ex_z]
    if base is None and None in axis_files:
        raise click.UsageError(f"give {label}, or all three of --x, --y and --z")
    base = base if base is not None else ex_x
    return base, tuple(f if f is not None else base for f in axis_files)


@click.command("solid", help=HELP, epilog=EPILOG,
               short_help="Synthesize a solid (3D) texture.",
               context_settings=CONTEXT_SETTINGS)
@click.argument("exemplars", nargs=-1, type=click.Path(path_type=str), metavar="[EXEMPLAR...]")
@click.option("-o", "--output", "output", default=None, type=click.Path(path_type=str),
              metavar="OUT", help="Output volume (one exemplar): .npy, .nrrd, .png (atlas) or a "
              "folder (slices). Replaced atomically if it exists.")
@click.option("--out-dir", type=click.Path(path_type=str), default=None, metavar="DIR",
              help="Write each exemplar's volume into DIR (created if missing), named by "
              "--name; an existing output is kept unless --overwrite.")
@click.option("--name", "name_template", default=None, metavar="TEMPLATE",
              help="Output name in --out-dir (fields above). [default: {stem}.{ext}; "
              "{stem} for slice folders]")
@batch_options
@volume_options
@click.option("--format", "fmt", type=click.Choice(tuple(FORMATS)), default=None,
              help="Output format [default: from OUT's (or --name's) extension; a folder: png "
              "slices; --out-dir with the default --name: npy].")
@click.option("--nrrd-encoding", type=click.Choice(NRRD_ENCODINGS), default="raw",
              show_default=True, help="Data encoding of a NRRD output.")
@click.option("--preview", type=click.Path(path_type=str), default=None, metavar="FILE.png",
              help="Also write a preview: the cube in isometric view and its centre slices. "
              "With --out-dir: a name template in DIR (e.g. '{stem}_preview.png').")
@click.option("--uv-out", type=click.Path(path_type=str), default=None, metavar="FILE.npy",
              help="Also write float32 (Z, Y, X, 3): exemplar u (column), v (row), index. "
              "With --out-dir: a name template in DIR (e.g. '{stem}_uv.npy').")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@click.option("-v", "--verbose", is_flag=True,
              help="Also print what the method found and did (method structure: the "
              "analysis, the structure built, the structure step's seconds).")
@click.option("--analyse", is_flag=True,
              help="Make no volume: print what structure the exemplar shows (phases, particle "
              "sizes and shapes, orientation, layer spacing; what method structure would "
              "build) and write its segmentation beside it as a picture, "
              "STEM_segmentation.png (-o FILE.png: there; --out-dir: in DIR).")
@tuning_flags(SolidOptions)
def solid_command(exemplars, output, out_dir, name_template, jobs, fail_fast, json_lines,
                  overwrite, scheduler, scheduler_file, threads, size, seed, preset, quality,
                  tileable, orientation, ex_x, ex_y, ex_z, fmt, nrrd_encoding, preview, uv_out,
                  quiet, verbose, analyse, **tuning):
    cluster = cluster_spec(scheduler, scheduler_file, threads, jobs)
    options, loaded = volume_settings(size, seed, preset, quality, tileable, orientation,
                                      tuning)

    if any(f is not None for f in (ex_x, ex_y, ex_z)):
        if len(exemplars) > 1 or "-" in exemplars:
            raise click.UsageError("--x/--y/--z make one volume: give at most one EXEMPLAR")
        sets = [axis_set(exemplars[0] if exemplars else None, ex_x, ex_y, ex_z)]
    elif not exemplars:
        raise click.UsageError("give EXEMPLAR, or all three of --x, --y and --z")
    else:
        sets = [(path, (path,)) for path in expand_inputs(exemplars)]

    inputs = real_paths(f for _, files in sets for f in files)
    if analyse:
        job_list = _analyse_jobs(sets, output, out_dir, overwrite, options, inputs)
        return run_batch(job_list, jobs, fail_fast, json_lines, quiet, cluster)
    plans = _plan_outputs(sets, output, out_dir, name_template, fmt, preview, uv_out, overwrite,
                          options, loaded.name)
    from osmap_cli.presets import is_preset_path

    # recorded as osmap synth does: a file by its file name (its `name` may be anything)
    recorded = os.path.basename(preset) if is_preset_path(preset) else loaded.name
    job_list = [SolidJob(
        index=index, exemplar=base, files=files, output=main, kind=kind, options=options,
        preset=recorded, nrrd_encoding=nrrd_encoding, preview=prev, uv_out=uv,
        replace=output is not None or overwrite,
        refused=refusal([main, *(p for p in (uv, prev) if p)], inputs),
        progress=show_progress(quiet, jobs), verbose=verbose,
    ) for index, ((base, files), (main, kind, prev, uv)) in enumerate(zip(sets, plans), 1)]
    return run_batch(job_list, jobs, fail_fast, json_lines, quiet, cluster)


def _analyse_jobs(sets, output, out_dir, overwrite, options, inputs):
    """One AnalyseJob per exemplar (or set); the picture beside the exemplar, in --out-dir, or
    -o (one exemplar)."""
    from osmap_cli.solid.analyse_job import AnalyseJob, picture_name

    if output is not None and os.path.splitext(output)[1].lower() != ".png":
        raise click.BadParameter(f"{output}: --analyse writes a .png picture",
                                 param_hint="'-o'")
    if output is not None or out_dir is not None:
        check_destination(output, out_dir, len(sets), None, overwrite)
    owners: dict[str, str] = {}
    jobs = []
    for index, (base, files) in enumerate(sets, 1):
        target = output if output is not None else picture_name(base)
        if output is None and out_dir is not None:
            target = os.path.join(out_dir, os.path.basename(picture_name(base)))
        claim_output(owners, target, base)
        jobs.append(AnalyseJob(index=index, exemplar=base, files=files, output=target,
                               options=options, replace=output is not None or overwrite
                               or out_dir is None, refused=refusal([target], inputs)))
    return jobs


def _plan_outputs(sets, output, out_dir, name_template, fmt, preview, uv_out, overwrite,
                  options, preset_name):
    """[(volume output, format, preview, uv output)] per job, checked before any work."""
    for flag, path, ext in (("--preview", preview, ".png"), ("--uv-out", uv_out, ".npy")):
        if path is not None and os.path.splitext(path)[1].lower() != ext:
            raise click.BadParameter(f"{path}: must be a {ext} file", param_hint=f"'{flag}'")
    check_destination(output, out_dir, len(sets), name_template, overwrite)
    template, ext = default_name(fmt or "npy")
    plans = []
    owners: dict[str, str] = {}
    for index, (base, _) in enumerate(sets, 1):
        if output is not None:
            main, prev, uv = output, preview, uv_out
        else:
            common = input_fields(base, index)
            fields = {"stem": common["stem"], "name": common["name"], "ext": ext,
                      "in_ext": os.path.splitext(base)[1].lstrip(".").lower(),
                      "parent": common["parent"], "index": index, "width": options.width,
                      "height": options.height, "depth": options.depth, "seed": options.seed,
                      "preset": preset_name, "quality": options.quality}
            main = os.path.join(out_dir, fill_template(name_template or template, fields,
                                                       "'--name'"))
            prev, uv = (os.path.join(out_dir, fill_template(p, fields, hint)) if p else None
                        for p, hint in ((preview, "'--preview'"), (uv_out, "'--uv-out'")))
        kind = format_for(main, fmt)
        targets = [os.path.abspath(main.rstrip("/" + os.sep))]
        for flag, path in (("--preview", prev), ("--uv-out", uv)):
            if path is None:
                continue
            if os.path.abspath(path) in targets:
                raise click.BadParameter(f"{path}: is the same file as another output",
                                         param_hint=f"'{flag}'")
            targets.append(os.path.abspath(path))
        for path in (main, prev, uv):
            if path is not None:
                claim_output(owners, path, base)
        plans.append((main, kind, prev, uv))
    return plans
